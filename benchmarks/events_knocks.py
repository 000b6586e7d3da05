"""The step scan at ringing knocks: false steps where a knock rings, and a tilt near a knock (found, its size, its
interval's coverage), by simulation (imupipe.events.detect_events at its defaults).

    OPENBLAS_NUM_THREADS=1 python benchmarks/events_knocks.py

Records: 1 h at 100 Hz of an accelerometer axis (white 6e-4 m/s^2/sqrt(Hz), a GM of 2e-4 m/s^2 at 300 s, random walk
1e-5 m/s^2/sqrt(s)). False steps: one 6.6 Hz knock of 90 per-sample sds decaying over 0.5, 2, 5 or 8 s at a random
time, 4 records per decay (seeds 5200 + decay x 100 + r). Tilts: a 3 mg step at a random time in [900, 2700] s and an
8.1 + 19.7 Hz knock (60 and 25 sds, decay 4 s) starting -2, 0.5, 5 or 20 s before it, 6 records per offset (seeds
9100-9105): a step found within 30 s, its size over the truth, how often its 95 % interval covers the truth, and
how often its reported range (``within_burst_s``, or its time +- 2 s) holds the truth. Lone steps: the same 3 mg
step at a random time without a knock, 40 records (seeds 600-639): found, and how its size falls within its 95 %
interval (z = (size - truth) / (half-width / 1.96): covered where |z| < 1.96). Run on an earlier tree (its src on
PYTHONPATH) to compare; docs/performance.md, 2026-12-07.
"""

from __future__ import annotations

import math

import numpy as np

from imupipe.events import detect_events
from imupipe.models import NoiseModel
from imupipe.simulate import simulate

RATE = 100.0
G = 9.80665
ACC = NoiseModel(white=6e-4, gauss_markov=((2e-4, 300.0),), random_walk=1e-5)
SD = ACC.white * math.sqrt(RATE)
N = int(3600 * RATE)
STEP = 3e-3 * G


def _steps(x):
    return [e for e in detect_events(x, RATE, sensor="accel")["events"] if e["kind"] in ("step", "transient")]


def false_steps() -> dict:
    """decay (s) -> records of 4 with a step or transient at a lone knock."""
    out = {}
    for tau in (0.5, 2.0, 5.0, 8.0):
        out[tau] = 0
        for r in range(4):
            rng = np.random.default_rng(5200 + r + int(tau * 100))
            x = simulate(ACC, N, RATE, rng)
            t = np.arange(int(8 * tau * RATE)) / RATE
            i0 = int(rng.uniform(600, 3000) * RATE)
            x[i0:i0 + t.size] += 90 * SD * np.exp(-t / tau) * np.sin(2 * np.pi * 6.6 * t)
            out[tau] += bool(_steps(x))
    return out


def tilts() -> dict:
    """offset (s) -> (found, size / true median, interval covers, range holds the time), of 6."""
    t = np.arange(int(40 * RATE)) / RATE
    knock = SD * np.exp(-t / 4.0) * (60 * np.sin(2 * np.pi * 8.1 * t) + 25 * np.sin(2 * np.pi * 19.7 * t + 1))
    out = {}
    for off in (-2.0, 0.5, 5.0, 20.0):
        found, sizes, cover, held = 0, [], 0, 0
        for r in range(6):
            rng = np.random.default_rng(9100 + r)
            x = simulate(ACC, N, RATE, rng)
            ts = rng.uniform(900, 2700)
            x[int(ts * RATE):] += STEP
            ik = int((ts - off) * RATE)
            x[ik:ik + knock.size] += knock
            near = [e for e in _steps(x) if e["kind"] == "step" and abs(e["time_s"] - ts) < 30]
            if near:
                e = min(near, key=lambda e: abs(e["time_s"] - ts))
                found += 1
                sizes.append(e["size"] / STEP)
                cover += e["size_low"] <= STEP <= e["size_high"]
                lo, hi = e.get("within_burst_s") or (e["time_s"] - 2.0, e["time_s"] + 2.0)
                held += lo <= ts <= hi
        out[off] = (found, float(np.median(sizes)) if sizes else float("nan"), cover, held)
    return out


def lone_steps(records: int = 40) -> tuple:
    """(found, covered, sd of z, mean of z) of a lone 3 mg step in `records` records (module docstring)."""
    z = []
    for r in range(records):
        rng = np.random.default_rng(600 + r)
        x = simulate(ACC, N, RATE, rng)
        ts = rng.uniform(900, 2700)
        x[int(ts * RATE):] += STEP
        near = [e for e in _steps(x) if e["kind"] == "step" and abs(e["time_s"] - ts) < 30]
        if near:
            e = near[0]
            z.append((e["size"] - STEP) / ((e["size_high"] - e["size_low"]) / 2 / 1.96))
    z = np.array(z)
    return z.size, int(np.sum(np.abs(z) < 1.96)), float(z.std()), float(z.mean())


def main() -> int:
    fs = false_steps()
    print("| knock decay (s) | records with a step at a lone knock |")
    print("|---|---|")
    for tau, k in fs.items():
        print(f"| {tau:g} | {k} of 4 |")
    print("\n| tilt after the knock's start (s) | found | size / true, median | 95 % interval covers | "
          "reported range holds its time |")
    print("|---|---|---|---|---|")
    for off, (f, sz, cov, held) in tilts().items():
        print(f"| {off:g} | {f} of 6 | {sz:.3f} | {cov} of {f} | {held} of {f} |")
    found, covered, sd, mean = lone_steps()
    print(f"\nlone 3 mg steps: found {found} of 40, 95 % interval covers {covered} of {found}; z sd {sd:.2f}, mean "
          f"{mean:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
