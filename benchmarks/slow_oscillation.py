"""Integrity on a slow narrow oscillation (docs/method.md, "What bounded rests on"): white noise, a GM of 30 s, a random
walk and a damped oscillator of period about an hour whose coherence is a large part of a 10 h record, so that a
record shows one or a few random amplitudes of it. Per seed: simulate the records, run the one-call pipeline
(imupipe.api.noise_model, auto with the joint envelope, lines modelled) with the spec sheet = the broadband truth
halved, then the exact covariance analysis of the exported KF file against the whole truth (tests/exact_kf.py, which
carries the oscillator: 600 s of fixes, then a 3600 s outage). Prints one JSON row per seed and the count above 1.

    OPENBLAS_NUM_THREADS=1 python benchmarks/slow_oscillation.py --seeds $(seq 9100 9129) --f0 3e-4 --records 1
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bound_modes import halved_spec  # noqa: E402
from exact_kf import FIX_S, OUTAGE_S, kf_against_truth  # noqa: E402
from imupipe.models import NoiseModel  # noqa: E402

#: The broadband part (SI, the units of a gyro in rad/s): white 2e-4, GM 3e-5 at 30 s, random walk 5e-8.
BROADBAND = dict(white=2e-4, gauss_markov=((3e-5, 30.0),), random_walk=5e-8)


def run_case(seed: int, f0_hz: float, sd: float, zeta: float, hours: float, records: int, sensor: str,
             rate_hz: float = 10.0) -> dict:
    """One seed: bounded, worst MSE/P over fixes + outage, mean P/MSE over the outage, the exported candidate."""
    from imupipe.api import noise_model
    from imupipe.simulate import simulate

    truth = NoiseModel(**BROADBAND, narrowband=((sd, f0_hz, zeta),))
    X = simulate(truth, int(hours * 3600 * rate_hz), rate_hz, rng=np.random.default_rng(seed), n_records=records)
    curves = {f"d{i}/x": X[i] for i in range(records)}
    res = noise_model(curves, rate_hz, sensor, halved_spec(NoiseModel(**BROADBAND), sensor), outage_s=OUTAGE_S,
                      fix_s=FIX_S, n_gm=1, mode="auto", envelope="joint", lines_policy="model")
    ex = kf_against_truth(res.kf, truth, sensor, FIX_S, OUTAGE_S)
    sel = (res.verification or {}).get("auto_selection")
    return {"seed": seed, "f0_hz": f0_hz, "sd": sd, "zeta": zeta, "hours": hours, "records": records,
            "bounded": bool(res.bounded), "worst": ex["worst"], "mean_p_over_mse": ex["mean_p_over_mse_outage"],
            "exported": sel["winner"] if sel else None}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", nargs="+", type=int, required=True)
    ap.add_argument("--f0", type=float, default=3e-4, help="oscillator frequency, Hz")
    ap.add_argument("--sd", type=float, default=2e-5, help="its stationary sd (SI)")
    ap.add_argument("--zeta", type=float, default=0.02, help="its damping ratio")
    ap.add_argument("--hours", type=float, default=10.0)
    ap.add_argument("--records", type=int, default=1)
    ap.add_argument("--sensor", choices=["gyro", "accel"], default="gyro")
    a = ap.parse_args(argv)
    above = 0
    for s in a.seeds:
        r = run_case(s, a.f0, a.sd, a.zeta, a.hours, a.records, a.sensor)
        above += r["bounded"] and r["worst"] > 1 + 1e-6
        print(json.dumps(r), flush=True)
    print(f"bounded with worst MSE/P above 1: {above} of {len(a.seeds)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
