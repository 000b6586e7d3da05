"""`imupipe plan`'s auto columns against runs of three-axis records: the predicted in-band inflation and mean P/MSE
(imupipe.plan.auto_prediction: the pooled joint envelope of the expected curves) beside the same two numbers of the
model the run exports (imupipe.api.noise_model with `bound.mode: auto` and the joint envelope, as `imupipe init`
writes, on records simulated from the model with imupipe.simulate; three axes per record), both against the model over
the reference scenario (imupipe.verify.reference_scenario: 600 s of fixes, a 3600 s outage, a 1 Hz filter). A run's
envelope candidate also lies above each axis's own envelope and the spec sheet (here the model itself), and the
other candidates above every sample PSD: the column is what the export must at least cover (the table's note).

    OPENBLAS_NUM_THREADS=1 python benchmarks/plan_auto_axes.py --spec config/specs/stim300.yaml --sensor gyro \
        --hours 2 --records 1 2 --rate 100 --seeds 3

Prints a Markdown table: per plan the column, the runs' median [min, max] and the winners. About 20 s per run at
2.5 h x 6 curves of 100 Hz on one core.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace

import numpy as np


def run_once(model, spec, sensor: str, hours: float, records: int, rate: float, seed: int) -> dict:
    """One simulated run: `records` records of three axes, `hours` h at `rate` Hz, drawn from `model`; the exported
    model's in-band inflation and mean P/MSE against `model` over the reference scenario, its worst MSE/P, the
    winner of auto."""
    from imupipe.api import noise_model
    from imupipe.models import NoiseModel
    from imupipe.simulate import simulate
    from imupipe.verify import covariance_analysis, reference_scenario

    sc = reference_scenario(sensor)
    X = simulate(model, int(hours * 3600 * rate), rate, rng=np.random.default_rng(seed), n_records=3 * records)
    curves = {f"r{i // 3 + 1}/{'xyz'[i % 3]}": X[i] for i in range(3 * records)}
    res = noise_model(curves, rate, sensor, spec, mode="auto", envelope="joint", outage_s=float(sc.outage_s),
                      fix_s=float(sc.fix_s), filter_rate_hz=1.0 / float(sc.dt), window_s=None, step_s=None)
    exported = NoiseModel.from_dict(res.contract["model"])
    truth = replace(model, narrowband=(), ramp=0.0, quantization=0.0)
    f_hi = 0.5 / float(sc.dt)
    f = np.geomspace(1.0 / float(sc.outage_s), f_hi, int(100 * np.log10(f_hi * sc.outage_s)) + 1)
    v = covariance_analysis(exported, truth, sc)
    sel = (res.verification or {}).get("auto_selection") or {}
    return {"inflation": float(np.median(np.sqrt(exported.psd(f) / truth.psd(f)))),
            "conservatism": float(v.mean_conservatism), "worst": float(v.worst_outage_ratio),
            "winner": sel.get("winner", "-"), "bounded": bool(res.bounded)}


def _span(values) -> str:
    v = np.asarray(values, dtype=float)
    return f"{np.median(v):.2f} [{v.min():.2f}, {v.max():.2f}]"


def main(argv=None) -> int:
    from imupipe.plan import auto_prediction, load_model
    from imupipe.specsheet import load_spec

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--spec", required=True, help="spec sheet YAML: the model the records are drawn from")
    ap.add_argument("--sensor", choices=("gyro", "accel"), required=True)
    ap.add_argument("--hours", type=float, nargs="+", default=[2.0])
    ap.add_argument("--records", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--rate", type=float, default=100.0, help="record rate, Hz")
    ap.add_argument("--seeds", type=int, default=3, help="simulated runs per plan")
    ap.add_argument("--seed0", type=int, default=7301)
    a = ap.parse_args(argv)
    model, _, _ = load_model(a.sensor, spec=a.spec)
    spec = load_spec(a.spec)
    print("| sensor | hours | records x axes | plan: inflation | plan: P/MSE | runs: inflation | runs: P/MSE | "
          "runs: worst MSE/P | exported | CPU s per run |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for h in a.hours:
        for r in a.records:
            p = auto_prediction(model, h, r, 3, a.rate, a.sensor)
            runs, t0 = [], time.process_time()
            for s in range(a.seeds):
                runs.append(run_once(model, spec, a.sensor, h, r, a.rate, a.seed0 + s))
            cpu = (time.process_time() - t0) / max(a.seeds, 1)
            winners = ", ".join(sorted({x["winner"] for x in runs}))
            print(f"| {a.sensor} | {h:g} | {r} x 3 | {p['inflation']:.2f} | {p['conservatism']:.2f} | "
                  f"{_span([x['inflation'] for x in runs])} | {_span([x['conservatism'] for x in runs])} | "
                  f"{max(x['worst'] for x in runs):.3f} | {winners} | {cpu:.0f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
