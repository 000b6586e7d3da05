"""The line search at several resolutions (`lines.scales`, docs/method.md "Narrowband lines and outliers"): its false
alarms on line-free records, and a wide resonance through the one-call pipeline at scales [1] and [1, 8, 64].

    OPENBLAS_NUM_THREADS=1 python benchmarks/line_scales.py false-alarm --rate 100 --hours 2 --records 40 --seed 7000
    OPENBLAS_NUM_THREADS=1 python benchmarks/line_scales.py resonance --seed 11 --zeta 0.003

``false-alarm``: line-free records of coloured noise (white 0.3 deg/sqrt(h), GMs of 3 deg/h at 600 s and 5 deg/h at
5 s, random walk 0.04 (deg/h)/sqrt(s), quantization 2e-6 rad), `find_lines` at 0.002 Hz with scales [1],
[1, 8, 64], and [1, 8, 64] with the low band at 1/window_s (`imupipe init`'s setting; the window by the workflow's
rule for the record): the records with a line (alpha 0.01 per record). ``resonance``: three axes of 2 h at 100 Hz
(white 0.3 deg/sqrt(h), GM 2 deg/h at 300 s, random walk 0.01 (deg/h)/sqrt(s), a 40 Hz line of sd 6x the white noise's
per-sample sd at damping `--zeta`), `imupipe.api.noise_model` (auto, joint envelope, lines modelled, spec = the
broadband truth halved), the exact analysis of tests/exact_kf.py over 600 s of fixes and an 1800 s outage.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bound_modes import halved_spec  # noqa: E402
from exact_kf import FIX_S, kf_against_truth  # noqa: E402
from imupipe.models import NoiseModel  # noqa: E402

_D = math.pi / 180.0


def false_alarms(rate: float, hours: float, records: int, seed: int) -> dict:
    """Records (of `records`, seeds `seed`, `seed` + 1, ...) in which each setting finds a line."""
    from imupipe.defaults import psd_window_step
    from imupipe.lines import find_lines
    from imupipe.simulate import simulate

    low = 1.0 / psd_window_step(hours * 3600.0, 1.0)[0]
    m = NoiseModel(white=0.3 / 60 * _D, gauss_markov=((3 / 3600 * _D, 600.0), (5 / 3600 * _D, 5.0)),
                   random_walk=0.04 / 3600 * _D, quantization=2e-6)
    hits = {"[1]": 0, "[1, 8, 64]": 0, "[1, 8, 64] and the low band": 0}
    for s in range(records):
        x = simulate(m, int(hours * 3600 * rate), rate, rng=np.random.default_rng(seed + s))
        hits["[1]"] += bool(find_lines(x, rate, resolution_hz=0.002).lines)
        hits["[1, 8, 64]"] += bool(find_lines(x, rate, resolution_hz=0.002, scales=(1, 8, 64)).lines)
        hits["[1, 8, 64] and the low band"] += bool(find_lines(x, rate, resolution_hz=0.002, scales=(1, 8, 64),
                                                               low_band_resolution_hz=low).lines)
    return {"rate_hz": rate, "hours": hours, "records": records, "with_a_line": hits}


def resonance(seed: int, zeta: float) -> list:
    """Per setting: lines modelled, full fit chi2/dof, exported N / truth's, mean P/MSE, worst MSE/P, bounded."""
    from imupipe.api import noise_model
    from imupipe.simulate import simulate

    white = 0.3 / 60 * _D
    base = dict(white=white, gauss_markov=((2 / 3600 * _D, 300.0),), random_walk=0.01 / 3600 * _D)
    truth = NoiseModel(**base, narrowband=((6 * white * 10.0, 40.0, zeta),))
    X = simulate(truth, int(2 * 3600 * 100.0), 100.0, rng=np.random.default_rng(seed), n_records=3)
    curves = {f"d0/{a}": X[i] for i, a in enumerate("xyz")}
    out = []
    for scales in ((1,), (1, 8, 64)):
        r = noise_model(curves, 100.0, "gyro", halved_spec(NoiseModel(**base), "gyro"), outage_s=1800.0, fix_s=FIX_S,
                        n_gm=1, mode="auto", envelope="joint", lines_policy="model", lines_scales=scales)
        ex = kf_against_truth(r.kf, truth, "gyro", FIX_S, 1800.0)
        out.append({"seed": seed, "zeta": zeta, "scales": list(scales), "lines": len(r.bound.model.narrowband),
                    "chi2_dof_full": round(r.fit.chi2 / r.fit.dof, 1),
                    "N_over_truth": round(r.bound.model.white / white, 2),
                    "mean_p_over_mse": round(float(ex["mean_p_over_mse_outage"]), 2),
                    "worst": round(float(ex["worst"]), 4), "bounded": bool(r.bounded)})
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="what", required=True)
    fa = sub.add_parser("false-alarm")
    fa.add_argument("--rate", type=float, default=100.0, help="Hz")
    fa.add_argument("--hours", type=float, default=2.0)
    fa.add_argument("--records", type=int, default=40)
    fa.add_argument("--seed", type=int, default=7000)
    rs = sub.add_parser("resonance")
    rs.add_argument("--seed", type=int, default=11)
    rs.add_argument("--zeta", type=float, default=0.003)
    a = ap.parse_args(argv)
    rows = [false_alarms(a.rate, a.hours, a.records, a.seed)] if a.what == "false-alarm" else resonance(a.seed, a.zeta)
    for row in rows:
        print(json.dumps(row), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
