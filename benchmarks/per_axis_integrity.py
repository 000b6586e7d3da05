"""How often a per-axis model under-states its axis's error: one 2 h record of three gyro axes at 20 Hz of an outside
evaluation's truth (N 0.2 deg/sqrt(h), GM 1 deg/h at 1200 s, K 0.08 (deg/h)/sqrt(s)), axis x scaled so that the
pooling test rejects one model and each axis gets its own, spec sheet at half, the API with ``mode="auto"`` and the
joint envelope, 600 s of fixes + 1800 s of outage. Per seed the exact covariance analysis (tests/exact_kf.py) of the
KF file's global model and of each axis's own model against that axis's truth; the table counts the models whose
worst MSE/P exceeds 1 and lists them.

    OPENBLAS_NUM_THREADS=1 python benchmarks/per_axis_integrity.py [--seeds 630 930] [--x-scale 2] [--out FILE]

About 5 s per seed on one core. ``--out`` also writes one line per seed (the models' worst MSE/P).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "benchmarks"))
D2R = math.pi / 180


def truth():
    from imupipe.models import NoiseModel

    return NoiseModel(white=0.2 * D2R / 60, gauss_markov=((1.0 * D2R / 3600, 1200.0),), random_walk=0.08 * D2R / 3600)


def scaled(t, k: float):
    from imupipe.models import NoiseModel

    return NoiseModel(white=k * t.white, gauss_markov=tuple((k * s, T) for s, T in t.gauss_markov),
                      random_walk=k * t.random_walk)


def run_seed(seed: int, x_scale: float) -> dict:
    """One seed: {"pooled": bool, "bounded": bool, "global": worst MSE/P over the axes, "own": {axis: worst},
    "own_p_over_mse": {axis: mean P/MSE over the outage}}."""
    from bound_modes import halved_spec
    from exact_kf import kf_against_truth
    from imupipe.api import noise_model
    from imupipe.simulate import simulate

    t = truth()
    scale = {"x": x_scale, "y": 1.0, "z": 1.0}
    rng, n = np.random.default_rng(seed), 2 * 3600 * 20
    curves = {f"r/{ax}": scale[ax] * simulate(t, n, 20.0, rng) for ax in "xyz"}
    res = noise_model(curves, 20.0, "gyro", halved_spec(t, "gyro"), outage_s=1800.0, fix_s=600.0, mode="auto",
                      envelope="joint", lines_policy="model", stationarity=False, events=False)
    kf, per = res.kf, res.kf.get("per_axis") or {}
    out = {"pooled": bool(res.records["identify"]["pooling"]["consistent"]), "bounded": bool(res.bounded),
           "global": max(kf_against_truth(kf, scaled(t, scale[ax]), "gyro", 600.0, 1800.0)["worst"] for ax in "xyz"),
           "own": {}, "own_p_over_mse": {}}
    for ax in "xyz":
        if per.get(ax, {}).get("model") == "own":
            r = kf_against_truth({**kf, **per[ax]}, scaled(t, scale[ax]), "gyro", 600.0, 1800.0)
            out["own"][ax], out["own_p_over_mse"][ax] = r["worst"], r["mean_p_over_mse_outage"]
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", nargs=2, type=int, default=[630, 930], metavar=("FIRST", "STOP"))
    ap.add_argument("--x-scale", type=float, default=2.0)
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args(argv)
    rows, log = [], (args.out.open("w") if args.out else None)
    for seed in range(*args.seeds):
        r = run_seed(seed, args.x_scale)
        rows.append((seed, r))
        if log:
            own = " ".join(f"{ax} own {v:.3f}" for ax, v in r["own"].items())
            log.write(f"{seed} {'pooled' if r['pooled'] else 'per-axis'} {r['bounded']} global {r['global']:.3f} "
                      f"{own}\n")
            log.flush()
    own = [(s, ax, v) for s, r in rows for ax, v in r["own"].items()]
    over = [(s, ax, v) for s, ax, v in own if v > 1.0 + 1e-6]
    cons = [v for _, r in rows for v in r["own_p_over_mse"].values()]
    print("| seeds | runs bounded | per-axis path | own models | above 1 | worst | median own P/MSE | global models "
          "above 1 |")
    print("|---|---|---|---|---|---|---|---|")
    print(f"| {args.seeds[0]}-{args.seeds[1] - 1} | {sum(r['bounded'] for _, r in rows)} of {len(rows)} | "
          f"{sum(not r['pooled'] for _, r in rows)} | {len(own)} | {len(over)} | "
          f"{max((v for _, _, v in own), default=float('nan')):.3f} | "
          f"{float(np.median(cons)) if cons else float('nan'):.2f} | {sum(r['global'] > 1.0 + 1e-6 for _, r in rows)} |")
    for s, ax, v in over:
        print(f"- seed {s}, axis {ax}: worst MSE/P {v:.3f}")


if __name__ == "__main__":
    main()
