"""How often an exported model under-states its axis's error where a gyro's axes differ, over seeds: one 2 h record of
three gyro axes, spec sheet at half (of axis x's truth), the API with ``mode="auto"`` and the joint envelope, 600 s of
fixes + 1800 s of outage. Per seed the exact covariance analysis (tests/exact_kf.py) of the KF file's global model
and of each axis's own model against that axis's truth; the table counts the models whose worst MSE/P exceeds 1.

Cases (``--case``):
- ``per_axis`` (default): an outside evaluation's truth (N 0.2 deg/sqrt(h), GM 1 deg/h at 1200 s, K 0.08
  (deg/h)/sqrt(s)) at 20 Hz, axis x scaled by ``--x-scale`` (2) so that the pooling test rejects one model and each
  axis gets its own;
- ``rw4_y``, ``rw2_y``: another evaluation's truth (N 0.25 deg/sqrt(h), GM 2 deg/h at 1500 s, K 0.03 (deg/h)/sqrt(s))
  at 10 Hz, axis y's random walk 4x or 2x: the pooling test mostly accepts one model.

    OPENBLAS_NUM_THREADS=1 python benchmarks/per_axis_integrity.py [--case per_axis] [--seeds 630 930] [--out FILE]

About 2-5 s per seed on one core. ``--out`` also writes one line per seed (the models' worst MSE/P).
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


def case_truths(case: str, x_scale: float):
    """(axis -> SI truth, record rate Hz, the spec sheet's truth) of a case (module docstring)."""
    from imupipe.models import NoiseModel

    if case == "per_axis":
        t = truth()
        return {"x": scaled(t, x_scale), "y": t, "z": t}, 20.0, t

    def gyro(K):
        return NoiseModel(white=0.25 * D2R / 60, gauss_markov=((2.0 * D2R / 3600, 1500.0),), random_walk=K * D2R / 3600)

    k = {"rw4_y": 4.0, "rw2_y": 2.0}[case]
    return {"x": gyro(0.03), "y": gyro(k * 0.03), "z": gyro(0.03)}, 10.0, gyro(0.03)


def run_seed(seed: int, x_scale: float, case: str = "per_axis") -> dict:
    """One seed: {"pooled": bool, "bounded": bool, "global": worst MSE/P over the axes, "own": {axis: worst},
    "own_p_over_mse": {axis: mean P/MSE over the outage}, "global_p_over_mse": {axis: the same of the global}}."""
    from bound_modes import halved_spec
    from exact_kf import kf_against_truth
    from imupipe.api import noise_model
    from imupipe.simulate import simulate

    truths, rate, sheet = case_truths(case, x_scale)
    rng, n = np.random.default_rng(seed), int(2 * 3600 * rate)
    curves = {f"r/{ax}": simulate(truths[ax], n, rate, rng) for ax in "xyz"}
    res = noise_model(curves, rate, "gyro", halved_spec(sheet, "gyro"), outage_s=1800.0, fix_s=600.0, mode="auto",
                      envelope="joint", lines_policy="model", stationarity=False, events=False)
    kf, per = res.kf, res.kf.get("per_axis") or {}
    g = {ax: kf_against_truth(kf, truths[ax], "gyro", 600.0, 1800.0) for ax in "xyz"}
    out = {"pooled": bool(res.records["identify"]["pooling"]["consistent"]), "bounded": bool(res.bounded),
           "global": max(r["worst"] for r in g.values()), "own": {}, "own_p_over_mse": {},
           "global_p_over_mse": {ax: r["mean_p_over_mse_outage"] for ax, r in g.items()}}
    for ax in "xyz":
        if per.get(ax, {}).get("model") == "own":
            r = kf_against_truth({**kf, **per[ax]}, truths[ax], "gyro", 600.0, 1800.0)
            out["own"][ax], out["own_p_over_mse"][ax] = r["worst"], r["mean_p_over_mse_outage"]
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", choices=["per_axis", "rw4_y", "rw2_y"], default="per_axis")
    ap.add_argument("--seeds", nargs=2, type=int, default=[630, 930], metavar=("FIRST", "STOP"))
    ap.add_argument("--x-scale", type=float, default=2.0)
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args(argv)
    rows, log = [], (args.out.open("w") if args.out else None)
    for seed in range(*args.seeds):
        r = run_seed(seed, args.x_scale, args.case)
        rows.append((seed, r))
        if log:
            own = " ".join(f"{ax} own {v:.3f}" for ax, v in r["own"].items())
            log.write(f"{seed} {'pooled' if r['pooled'] else 'per-axis'} {r['bounded']} global {r['global']:.3f} "
                      f"{own}\n")
            log.flush()
    own = [(s, ax, v) for s, r in rows for ax, v in r["own"].items()]
    over = [(s, ax, v) for s, ax, v in own if v > 1.0 + 1e-6]
    cons = [v for _, r in rows for v in r["own_p_over_mse"].values()]
    g_over = [(s, r["global"]) for s, r in rows if r["global"] > 1.0 + 1e-6]
    g_cons = {ax: float(np.median([r["global_p_over_mse"][ax] for _, r in rows])) for ax in "xyz"}
    print("| case | seeds | runs bounded | per-axis path | own models | above 1 | worst | median own P/MSE | global "
          "models above 1 | worst global | median global P/MSE x, y, z |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    print(f"| {args.case} | {args.seeds[0]}-{args.seeds[1] - 1} | {sum(r['bounded'] for _, r in rows)} of "
          f"{len(rows)} | {sum(not r['pooled'] for _, r in rows)} | {len(own)} | {len(over)} | "
          f"{max((v for _, _, v in own), default=float('nan')):.3f} | "
          f"{float(np.median(cons)) if cons else float('nan'):.2f} | {len(g_over)} | "
          f"{max(r['global'] for _, r in rows):.3f} | {', '.join(f'{v:.2f}' for v in g_cons.values())} |")
    for s, ax, v in over:
        print(f"- seed {s}, axis {ax}: worst MSE/P {v:.3f}")
    for s, v in g_over:
        print(f"- seed {s}, global model: worst MSE/P {v:.3f} over the axes")


if __name__ == "__main__":
    main()
