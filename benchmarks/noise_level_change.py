"""Integrity over records whose noise level changes: `imupipe init` + a run (bound.mode auto) on 2 h records whose
white noise steps up over a part of the record, and the exported model's exact covariance analysis against the truth
with the white noise of each regime (quiet, noisy). Prints a table: per case and sensor, the exported N over the
truth's, the worst MSE/P and the mean P/MSE over the verification's scenario in each regime, and the verdict.

    OPENBLAS_NUM_THREADS=1 python benchmarks/noise_level_change.py [--cases mid last first] [--workdir DIR]

Run from a checkout (it runs its Snakefile with --cores 2); about 2 min per case. The truths are those of
docs/performance.md's section on the noisiest stretch (a MEMS-like gyro and accelerometer, spec sheets at half).
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
D2R = math.pi / 180
G = 9.80665

#: case -> (start, stop) of the noisy part (fractions of the record), white noise factor (sd), rate Hz, seed
CASES = {"mid": (0.40, 0.75, 2.0, 10.0, 777), "last": (2 / 3, 1.0, 2.5, 10.0, 201),
         "first": (0.0, 0.30, 3.0, 20.0, 4242)}


def truths(gm_T_s: float = 200.0):
    """The gyro and accelerometer truths (SI :class:`imupipe.models.NoiseModel`) and a spec sheet at half (dict)."""
    from imupipe.models import NoiseModel

    gyro = NoiseModel(white=0.3 * D2R / 60, gauss_markov=((2.0 * D2R / 3600, gm_T_s),), random_walk=0.02 * D2R / 3600)
    accel = NoiseModel(white=0.1 / 60, gauss_markov=((0.1e-3 * G, gm_T_s),), random_walk=2e-6)
    spec = {"name": "HALF", "gyro": {
        "white": {"value": 0.15, "unit": "deg/sqrt(h)"},
        "gauss_markov": [{"sigma": {"value": 1.0, "unit": "deg/h"}, "T": {"value": gm_T_s, "unit": "s"}}],
        "random_walk": {"value": 0.01, "unit": "(deg/h)/sqrt(s)"}}, "accel": {
        "white": {"value": 0.05, "unit": "m/s/sqrt(h)"},
        "gauss_markov": [{"sigma": {"value": 0.05, "unit": "mg"}, "T": {"value": gm_T_s, "unit": "s"}}],
        "random_walk": {"value": 1.0e-6, "unit": "m/s^2/sqrt(s)"}}}
    return {"gyro": gyro, "accel": accel}, spec


def level_change_csv(path, truth: dict, rate_hz: float, hours: float, start: float, stop: float, factor: float,
                     seed: int) -> None:
    """Three gyro and three accel axes of `truth` (sensor -> SI model, :func:`imupipe.simulate.simulate`), white noise
    `factor` x its sd over [`start`, `stop`) (fractions of the record), gravity on z, as a CSV in deg/s and g with a time
    column."""
    from imupipe.simulate import simulate

    rng, n = np.random.default_rng(seed), int(hours * 3600 * rate_hz)
    i0, i1 = int(start * n), int(stop * n)
    cols = []
    for sensor in ("gyro",) * 3 + ("accel",) * 3:
        x = simulate(truth[sensor], n, rate_hz, rng)
        x[i0:i1] += math.sqrt(factor**2 - 1) * truth[sensor].white * math.sqrt(rate_hz) * rng.standard_normal(i1 - i0)
        cols.append(x / D2R if sensor == "gyro" else x / G)
    cols[5] = cols[5] + 1.0  # 1 g on accel z
    np.savetxt(path, np.column_stack([np.arange(n) / rate_hz] + cols), delimiter=",", fmt="%.9g", comments="",
               header="t [s],gx [deg/s],gy [deg/s],gz [deg/s],ax [g],ay [g],az [g]")


def exact_check(verify_file, truth_model, sensor: str, white_factor: float = 1.0):
    """The exact covariance analysis (:func:`imupipe.verify.covariance_analysis`) of the model a verify file exported,
    in its own scenario, against `truth_model` with its white noise times `white_factor`."""
    from imupipe.models import NoiseModel
    from imupipe.verify import covariance_analysis, reference_scenario

    v = yaml.safe_load(Path(verify_file).read_text())
    sc = v["verification"]["scenario"]
    scenario = reference_scenario(sensor, filter_rate_hz=sc["rate_hz"], fix_rate_hz=sc["fix_rate_hz"],
                                  fix_s=sc["fix_s"], outage_s=sc["horizon_s"], sigma_fix=sc["sigma_fix"],
                                  var_pos=sc["var_pos"], bias_var_floor=sc["bias_var_floor"],
                                  bias_var_floor_slow=sc["bias_var_floor_slow"], max_bias_time_s=sc["max_bias_time_s"])
    model = NoiseModel.from_dict(v["exported"]["model"])
    truth = replace(truth_model, white=white_factor * truth_model.white)
    return model, covariance_analysis(model, truth, scenario, sensor=sensor)


def run_case(name: str, workdir: Path) -> list[str]:
    start, stop, factor, rate, seed = CASES[name]
    truth, spec = truths()
    work = workdir / name
    work.mkdir(parents=True, exist_ok=True)
    (work / "spec.yaml").write_text(yaml.safe_dump(spec))
    level_change_csv(work / f"{name}.csv", truth, rate, 2.0, start, stop, factor, seed)
    py = [sys.executable, "-m"]
    subprocess.run(py + ["imupipe", "init", str(work / f"{name}.csv"), "--spec", str(work / "spec.yaml"), "--out",
                         str(work / "cfg"), "--force"], check=True, capture_output=True)
    proc = subprocess.run(py + ["snakemake", "-s", str(ROOT / "Snakefile"), "--directory", str(work / "run"),
                                "--cores", "2", "--configfile", str(work / "cfg" / "config.yaml"), "--quiet"],
                          capture_output=True, text=True)
    res = next((work / "run" / "results").iterdir())
    verdict = next((ln for ln in (res / "summary.md").read_text().splitlines() if ln.startswith("**Verdict:**")),
                   f"run exited {proc.returncode}")
    rows = []
    for sensor in ("gyro", "accel"):
        cells = []
        for f in (1.0, factor):
            model, r = exact_check(res / f"verify/spec/{sensor}.yaml", truth[sensor], sensor, f)
            cells += [f"{r.worst_ratio:.3f}", f"{r.mean_conservatism:.2f}"]
        rows.append(f"| {name} ({factor:g}x over {start:.2f}-{stop:.2f}, {rate:g} Hz) | {sensor} | "
                    f"{model.white / truth[sensor].white:.2f} | " + " | ".join(cells) + " |")
    rows.append(f"| {name} | verdict | {verdict.replace('**Verdict:** ', '')} | | | | |")
    return rows


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    ap.add_argument("--workdir", type=Path, default=None)
    args = ap.parse_args(argv)
    work = args.workdir or Path(tempfile.mkdtemp(prefix="level-change-"))
    print("| case | sensor | N / truth's | quiet worst MSE/P | quiet P/MSE | noisy worst MSE/P | noisy P/MSE |")
    print("|---|---|---|---|---|---|---|")
    for name in args.cases:
        for row in run_case(name, work):
            print(row, flush=True)


if __name__ == "__main__":
    main()
