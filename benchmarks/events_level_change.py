"""The event scan (imupipe.events.detect_events) on records whose white noise changes level, and its power on mean
steps, by simulation: how many events an event-free record with a noise-level change reports (none is a step or an
excursion of the mean; the stationarity test is what sees a level change), and how often a mean step of a given
size is found (within 2 s of it) on an otherwise stationary record.

    OPENBLAS_NUM_THREADS=1 python benchmarks/events_level_change.py --records 20

Each record: 2 h at 20 Hz of white noise 1e-3 u/sqrt(Hz) and a GM of 2e-4 u at T 200 s; `--factor`: the white
noise's sd times this over the second half; `--step`: a mean step of this size (u) at 0.37 of the record. Prints
two Markdown tables.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from imupipe.events import detect_events
from imupipe.models import NoiseModel
from imupipe.simulate import simulate

RATE_HZ, HOURS = 20.0, 2.0
TRUTH = NoiseModel(white=1e-3, gauss_markov=((2e-4, 200.0),))


def record(rng, factor: float = 1.0, step: float = 0.0) -> tuple[np.ndarray, int]:
    n = int(HOURS * 3600 * RATE_HZ)
    x = simulate(TRUTH, n, RATE_HZ, rng)
    if factor != 1.0:
        x[n // 2:] += np.sqrt(factor**2 - 1.0) * TRUTH.white * np.sqrt(RATE_HZ) * rng.standard_normal(n - n // 2)
    t0 = int(0.37 * n)
    x[t0:] += step
    return x, t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--factor", nargs="+", type=float, default=[1.0, 1.5, 2.0, 3.0])
    ap.add_argument("--step", nargs="+", type=float, default=[2e-3, 3e-3, 4e-3, 6e-3], help="u")
    ap.add_argument("--records", type=int, default=20)
    ap.add_argument("--seed", type=int, default=4401)
    a = ap.parse_args(argv)
    print("| white sd factor, second half | records | steps and excursions per record | records with any |")
    print("|---|---|---|---|")
    for i, factor in enumerate(a.factor):
        counts = []
        for r in range(a.records):
            x, _ = record(np.random.default_rng([a.seed, 0, i, r]), factor=factor)
            counts.append(sum(e["kind"] != "burst" for e in detect_events(x, RATE_HZ)["events"]))
        print(f"| {factor:g} | {a.records} | {np.mean(counts):.2f} | {np.count_nonzero(counts)} |", flush=True)
    print("\n| mean step (u) | records | found within 2 s | other events per record |")
    print("|---|---|---|---|")
    for i, step in enumerate(a.step):
        found, other = 0, []
        for r in range(a.records):
            x, t0 = record(np.random.default_rng([a.seed, 1, i, r]), step=step)
            events = [e for e in detect_events(x, RATE_HZ)["events"] if e["kind"] != "burst"]
            hit = [e for e in events if abs(e["index"] - t0) <= 2 * RATE_HZ]
            found += bool(hit)
            other.append(len(events) - len(hit))
        print(f"| {step:g} | {a.records} | {found} | {np.mean(other):.2f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
