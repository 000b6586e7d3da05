"""Integrity and conservatism when a sensor type's axes differ (issue 32): the pooling test should reject one model
for every curve, the identification then fits each axis, and the auto bound may build its envelope candidate on the
dominating model of the per-axis joint envelopes (each at 1 - 0.05/k). Per case, every axis's exported filter (the
KF file's ``per_axis`` entry: its own model, or the global one) is analysed exactly against that axis's truth.

    OPENBLAS_NUM_THREADS=1 python benchmarks/axes_differ.py --case noisy_z shape_z --datasets 1 3 --seed 6161

Truths: a base truth on x and y, a changed one on z (``noisy_z``: white noise x 2 and GM sigma x 1.5; ``shape_z``:
the GM's T x 5; ``rw_z``: random walk x 3; ``subtle_z``: random walk x 1.25, a difference the pooling test often
accepts: an outside evaluation's gyro z, 20 % above x and y, was under-stated by the pooled band; ``equal_*``: z the
same as x and y, for the cost of holding the envelope candidate above each axis's own envelope). Spec sheet = the base truth halved. 10 h records at 10 Hz, the Welch
window by the workflow's rule, fixes 600 s at 1 Hz then a 3600 s outage (tests/exact_kf.py). Prints a Markdown table:
pooled or not, the envelope candidate's reason, the exported mode, and per axis the worst MSE/P and mean P/MSE over
the outage of the filter that axis gets.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

from bound_modes import halved_spec  # noqa: E402
from exact_kf import FIX_S, OUTAGE_S, kf_against_truth  # noqa: E402
from imupipe.models import NoiseModel  # noqa: E402

BASE = {
    "noisy_z": NoiseModel(white=2e-5, gauss_markov=((1.5e-5, 1200.0),), random_walk=1e-7),
    "shape_z": NoiseModel(white=1.5e-3, gauss_markov=((8e-4, 60.0),), random_walk=5e-6),
    "rw_z": NoiseModel(white=5e-5, gauss_markov=((4e-5, 20.0), (2e-5, 600.0)), random_walk=5e-8),
    "subtle_z": NoiseModel(white=2e-5, gauss_markov=((1.5e-5, 1200.0),), random_walk=1e-7),
    # the axes equal: what the envelope candidate's per-axis target costs where the pooled band alone would do
    "equal_tactical": NoiseModel(white=2e-5, gauss_markov=((1.5e-5, 1200.0),), random_walk=1e-7),
    "equal_mems": NoiseModel(white=1.5e-3, gauss_markov=((8e-4, 60.0),), random_walk=5e-6),
    "equal_two_gm": NoiseModel(white=5e-5, gauss_markov=((4e-5, 20.0), (2e-5, 600.0)), random_walk=5e-8),
}


def changed(case: str, t: NoiseModel) -> NoiseModel:
    """The z axis's truth of `case`."""
    if case == "noisy_z":
        return replace(t, white=2 * t.white, gauss_markov=tuple((1.5 * s, T) for s, T in t.gauss_markov))
    if case == "shape_z":
        return replace(t, gauss_markov=tuple((s, 5 * T) for s, T in t.gauss_markov))
    if case.startswith("equal"):
        return t
    if case == "subtle_z":
        return replace(t, random_walk=1.25 * t.random_walk)
    return replace(t, random_walk=3 * t.random_walk)


def run_case(case: str, sensor: str, n_data: int, seed: int, hours: float = 10.0, rate_hz: float = 10.0) -> dict:
    from imupipe.api import noise_model
    from imupipe.simulate import simulate

    base = BASE[case]
    truths = {"x": base, "y": base, "z": changed(case, base)}
    rng = np.random.default_rng(seed)
    n = int(hours * 3600 * rate_hz)
    curves = {}
    for ax, t in truths.items():
        X = simulate(t, n, rate_hz, rng=rng, n_records=n_data)
        curves |= {f"d{i}/{ax}": X[i] for i in range(n_data)}
    t0 = time.process_time()
    res = noise_model(curves, rate_hz, sensor, halved_spec(base, sensor), window_s=None, step_s=None,
                      outage_s=OUTAGE_S, fix_s=FIX_S, n_gm=min(len(base.gauss_markov), 2), mode="auto",
                      envelope="joint")
    cpu = time.process_time() - t0
    kf = res.kf
    per_axis = kf.get("per_axis") or {}
    axes = {}
    for ax, t in truths.items():
        entry = {**kf, **per_axis[ax]} if ax in per_axis else kf
        e = kf_against_truth(entry, t, sensor, FIX_S, OUTAGE_S)
        axes[ax] = (per_axis.get(ax, {}).get("model", "global"), e["worst"], e["mean_p_over_mse_outage"])
    sel = (res.verification or {}).get("auto_selection") or {}
    ident = res.records["identify"]
    return {"case": case, "sensor": sensor, "n_data": n_data, "seed": seed, "bounded": bool(res.bounded),
            "pooled": (ident.get("pooling") or {}).get("consistent"), "winner": sel.get("winner"),
            "envelope": res.records["bound"].get("auto_envelope_candidate", "-"), "axes": axes, "cpu_s": cpu}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--case", nargs="+", default=sorted(BASE), choices=sorted(BASE))
    ap.add_argument("--datasets", nargs="+", type=int, default=[1, 3])
    ap.add_argument("--sensors", nargs="+", default=["accel", "gyro"])
    ap.add_argument("--seed", type=int, default=6161)
    ap.add_argument("--hours", type=float, default=10.0, help="each record's length, h")
    a = ap.parse_args(argv)
    print("| case | sensor | datasets | pooled | bounded | exported | envelope candidate | x: model, worst MSE/P, "
          "P/MSE | y | z | CPU s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for case in a.case:
        for sensor in a.sensors:
            for nd in a.datasets:
                r = run_case(case, sensor, nd, a.seed + 17 * nd, hours=a.hours)
                cells = " | ".join(f"{m}, {w:.3f}, {c:.2f}" for m, w, c in r["axes"].values())
                env = r["envelope"].split(":")[0] if r["envelope"] else "-"
                print(f"| {case} | {sensor} | {nd} | {r['pooled']} | {r['bounded']} | {r['winner']} | {env} | "
                      f"{cells} | {r['cpu_s']:.0f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
