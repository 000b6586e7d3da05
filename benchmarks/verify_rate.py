"""Wall time of the exact covariance verification at filter rates 1 / 100 / 1000 Hz (600 s fixes + 3600 s outage).

Closed form (imupipe.covariance via verify.covariance_analysis) beside the reference step loop
(verify.covariance_analysis_steps). The step loop is timed on a shortened scenario (fix_s and outage_s
scaled by `--step-fraction` at rates >= 100 Hz) and its time scaled by the step count (it is linear in the
number of steps); those rows say "estimated". The replay is not included: benchmarks/verify_job.py times the
whole verify job (analyses, replay, reduction).

`--fix-rate` sets the fix rate (Hz; default: a fix at every filter step), as ``verify.fix_rate_hz`` does.

Usage: OPENBLAS_NUM_THREADS=1 python benchmarks/verify_rate.py [--rates 1 100 1000] [--fix-rate 1]
"""

import argparse
import time

from imupipe.models import NoiseModel
import imupipe.verify as V
from imupipe.verify import covariance_analysis, covariance_analysis_steps, reference_scenario

MODELS = {  # a bound-like model per sensor: white + GM + random walk + flicker (SI)
    "accel": NoiseModel(white=1e-3, gauss_markov=((5e-4, 300.0),), random_walk=1e-5, flicker=3e-5),
    "gyro": NoiseModel(white=5e-5, gauss_markov=((2e-5, 300.0),), random_walk=5e-7, flicker=1e-6),
}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rates", type=float, nargs="+", default=[1.0, 100.0, 1000.0])
    ap.add_argument("--step-fraction", type=float, default=0.02)
    ap.add_argument("--fix-rate", type=float, default=None, help="Hz (default: every filter step)")
    a = ap.parse_args()
    print(f"{'sensor':6} {'rate_Hz':>8} {'fix_Hz':>7} {'steps':>9} {'closed_s':>9} {'closed_cpu_s':>12} "
          f"{'step_loop_cpu_s':>15}  note")
    for sensor, m in MODELS.items():
        for r in a.rates:
            fr = a.fix_rate if a.fix_rate is not None and a.fix_rate <= r else None
            sc = reference_scenario(sensor, filter_rate_hz=r, fix_rate_hz=fr)
            V._FILTER_CACHE.clear()  # the filter's Riccati recursion included
            t0, c0 = time.perf_counter(), time.process_time()
            v = covariance_analysis(m, m, sc)
            tc, cc = time.perf_counter() - t0, time.process_time() - c0
            f = 1.0 if r < 100 else a.step_fraction
            scs = reference_scenario(sensor, filter_rate_hz=r, fix_s=600.0 * f, outage_s=3600.0 * f, fix_rate_hz=fr)
            c0 = time.process_time()
            covariance_analysis_steps(m, m, scs)
            ts = (time.process_time() - c0) * sc.n_steps / scs.n_steps
            note = "measured" if f == 1.0 else f"estimated from {scs.n_steps} steps"
            fix = "every" if fr is None else f"{fr:g}"
            print(f"{sensor:6} {r:8g} {fix:>7} {sc.n_steps:9d} {tc:9.2f} {cc:12.2f} {ts:15.1f}  {note}; "
                  f"worst ratio {v.worst_ratio:.6f}", flush=True)


if __name__ == "__main__":
    main()
