"""Peak memory of the outliers job's library call on one full-rate axis, against the axis's own size.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/outliers_memory.py [--duration-h 10 40] [--rate-hz 125]
        [--repeats 3] [--policy warn] [--events-policy warn] [--src DIR]

For each duration: one simulated accelerometer axis (white 2e-3 m/s^2/sqrt(Hz), a GM of 3e-4 m/s^2 with
T = 100 s, a random walk of 3e-6 m/s^2/sqrt(s): the ADIS16405-like truth of tests/test_events.py) with a knock
(0.5 g at 5 Hz for 0.2 s) at a third of the record and a mean step of 3.4 mg at two thirds, float64 as the
workflow reads it. ``imupipe.stages.outliers.outliers_stage`` (what the outliers job runs between reading
the series and writing its files: Hampel rule, stuck spans, bursts and steps) is called under
``tracemalloc``, which sees numpy's buffers; the peak of the allocations made during the call is the job's
memory beyond the series itself. Columns: samples n, the axis (8 n bytes) in MB, the peak during the call in MB and over the axis, the
series plus that peak over the axis (the job's data memory over one axis; the budget of issue 31 is 2 x one
axis + fixed), the median wall time of the call over ``--repeats`` calls (traced: tracemalloc slows numpy's
allocations a little), and the events found (kind@time s), so two trees can be compared for equal results.

``--src DIR`` imports imupipe from DIR (another checkout's ``src``) instead of the installed one: the same
script measures the tree before a change.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
import tracemalloc

import numpy as np

MB = 1e6
G = 9.80665


def record(duration_h: float, rate_hz: float, seed: int = 7) -> np.ndarray:
    """The simulated axis with a knock at n/3 and a mean step at 2n/3 (module docstring), m/s^2."""
    from imupipe.models import NoiseModel
    from imupipe.simulate import simulate

    truth = NoiseModel(white=2e-3, gauss_markov=((3e-4, 100.0),), random_walk=3e-6)
    n = int(round(duration_h * 3600.0 * rate_hz))
    x = simulate(truth, n, rate_hz, rng=seed)
    k0 = n // 3  # a knock: 0.2 s of a 5 Hz oscillation of 0.5 g
    k1 = k0 + int(round(0.2 * rate_hz))
    x[k0:k1] += 0.5 * G * np.sin(2.0 * np.pi * 5.0 * np.arange(k1 - k0) / rate_hz)
    x[2 * n // 3:] += 3.4e-3 * G
    return x


def measure(x: np.ndarray, rate_hz: float, policy: str, events_policy: str):
    """(peak MB of the allocations during one traced call, wall time s, report)."""
    import warnings

    from imupipe.stages.outliers import outliers_stage

    tracemalloc.start()
    tracemalloc.reset_peak()
    base = tracemalloc.get_traced_memory()[0]
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out, x_out = outliers_stage(x, rate_hz, units="m/s^2", dataset="bench", sensor="accel", axis="x",
                                    policy=policy, events={"policy": events_policy}, min_segment_s=0.0)
    dt = time.perf_counter() - t0
    peak = tracemalloc.get_traced_memory()[1] - base
    tracemalloc.stop()
    del x_out
    return peak / MB, dt, out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--duration-h", type=float, nargs="+", default=[10.0, 40.0])
    ap.add_argument("--rate-hz", type=float, default=125.0)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--policy", default="warn", help="outliers.policy")
    ap.add_argument("--events-policy", default="warn", help="events.policy")
    ap.add_argument("--src", default=None, help="import imupipe from this folder (another checkout's src)")
    a = ap.parse_args(argv)
    if a.src:
        sys.path.insert(0, a.src)
    import imupipe

    print(f"imupipe from {imupipe.__file__.rsplit('/', 2)[0]}; outliers.policy {a.policy}, events.policy "
          f"{a.events_policy}; {a.rate_hz:g} Hz; tracemalloc peak during outliers_stage\n")
    print("| record (h) | samples | axis (MB) | peak during the call (MB) | peak / axis "
          "| (series + peak) / axis | time (s, median) | outliers | events |")
    print("|---|---|---|---|---|---|---|---|---|")
    for h in a.duration_h:
        x = record(h, a.rate_hz)
        axis = x.nbytes / MB
        peaks, times = [], []
        for _ in range(max(1, a.repeats)):
            peak, dt, out = measure(x, a.rate_hz, a.policy, a.events_policy)
            peaks.append(peak)
            times.append(dt)
        ev = ", ".join(f"{e['kind']}@{e['time_s']:.2f}" for e in out["events"])
        peak = max(peaks)
        print(f"| {h:g} | {x.size} | {axis:.0f} | {peak:.0f} | {peak / axis:.2f} | "
              f"{(axis + peak) / axis:.2f} | {statistics.median(times):.1f} | {out['n_outliers']} | {ev} |",
              flush=True)
        del x


if __name__ == "__main__":
    main()
