"""Lines found in bursts: the line search on records with a burst, as recorded and as the lines job reads them under
events.policy warn (each burst's span filled: imupipe.stages.outliers.line_search_series), with and without a
genuine stationary line through the burst.

    OPENBLAS_NUM_THREADS=1 python benchmarks/line_bursts.py --records 10

Records: 2 h at 100 Hz of a MEMS-like gyro axis (white 2e-4 rad/s/sqrt(Hz), a 100 s GM of 5e-5 rad/s, random walk 2e-6
rad/s/sqrt(s)), one burst at a random time in [600, 6600] s of each kind below (amplitudes in per-sample white sds): a
knock ringing at three tones decaying over 0.5 s for 2 s; the same knock ringing at other tones and decaying over 1.5
s; a knock ringing at one tone of 80 sds decaying over 6 s (a mount resonance of Q 100); a white-noise burst of 30 sds
for 2 s; and a vibration of 20 s (a 22 Hz tone of 5 sds with a 0.3 s rise and fall). The search as `imupipe init`
writes it (0.002 Hz, alpha 0.01, 51-bin floor, scales 1, 8, 64, the low band at 1 / 1800 Hz). A genuine 17 Hz line of
0.05 sds (power A^2 / 2) is added in the second half of the table: the table gives how often it is found and its
estimated power over the true one (median, range).
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from imupipe.lines import find_lines
from imupipe.models import NoiseModel
from imupipe.simulate import simulate
from imupipe.stages.outliers import line_search_series

RATE = 100.0
HOURS = 2.0
MODEL = NoiseModel(white=2e-4, gauss_markov=((5e-5, 100.0),), random_walk=2e-6)
SD = MODEL.white * math.sqrt(RATE)
SEARCH = dict(resolution_hz=0.002, alpha=0.01, floor_window_bins=51, scales=(1, 8, 64), low_band_resolution_hz=1 / 1800)
LINE_HZ, LINE_SDS = 17.0, 0.05


def _ringing(tones, decay_s, seconds=2.0):
    t = np.arange(int(seconds * RATE)) / RATE
    return sum(a * SD * np.exp(-t / decay_s) * np.sin(2 * np.pi * f * t + 0.4 * i) for i, (f, a) in enumerate(tones))


def bursts(rng) -> dict:
    """name -> the burst's samples (rad/s) for one record."""
    t20 = np.arange(int(20 * RATE)) / RATE
    ramp = np.clip(np.minimum(t20, 20.0 - t20) / 0.3, 0.0, 1.0)
    return {"knock, 3 tones, 0.5 s decay": _ringing(((6.1, 60.0), (14.8, 40.0), (27.5, 30.0)), 0.5),
            "knock, 2 tones, 1.5 s decay": _ringing(((9.3, 40.0), (38.0, 25.0)), 1.5),
            "knock, 5.3 Hz, 6 s decay": _ringing(((5.3, 80.0),), 6.0, seconds=48.0),
            "white burst, 30 sds, 2 s": 30.0 * SD * rng.standard_normal(int(2 * RATE)),
            "vibration, 22 Hz, 5 sds, 20 s": 5.0 * SD * ramp * np.sin(2 * np.pi * 22.0 * t20)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--records", type=int, default=10)
    ap.add_argument("--seed", type=int, default=7000)
    a = ap.parse_args(argv)
    n = int(HOURS * 3600 * RATE)
    rows = {}
    for r in range(a.records):
        rng = np.random.default_rng(a.seed + r)
        base = simulate(MODEL, n, RATE, rng)
        line = LINE_SDS * SD * np.sin(2 * np.pi * LINE_HZ * np.arange(n) / RATE + rng.uniform(0, 2 * np.pi))
        for name, b in bursts(rng).items():
            i0 = int(rng.uniform(600, HOURS * 3600 - 600) * RATE)
            for with_line in (False, True):
                x = base + line if with_line else base.copy()
                x[i0:i0 + b.size] += b
                filled, stretches = line_search_series(x, RATE, {})
                for read, y in (("as recorded", x), ("filled", filled)):
                    lines = find_lines(y, RATE, **SEARCH).lines
                    genuine = [ln for ln in lines if abs(ln.frequency_hz - LINE_HZ) < 0.01] if with_line else []
                    row = rows.setdefault((with_line, name, read), {"false": [], "found": 0, "power": [], "filled": []})
                    row["false"].append(len(lines) - len(genuine))
                    row["found"] += bool(genuine)
                    row["power"] += [genuine[0].power / (LINE_SDS * SD) ** 2 * 2.0] if genuine else []
                    row["filled"].append(sum(b1 - b0 for b0, b1 in stretches))
    print(f"{a.records} records of {HOURS:g} h at {RATE:g} Hz per row (seeds {a.seed}-{a.seed + a.records - 1})\n")
    print("| genuine 17 Hz line | burst | search reads | records with a false line | false lines, max | filled s, "
          "median | line found | line power / true, median [min, max] |")
    print("|---|---|---|---|---|---|---|---|")
    for (with_line, name, read), row in rows.items():
        f = np.array(row["false"])
        pw = (f"{np.median(row['power']):.3f} [{min(row['power']):.3f}, {max(row['power']):.3f}]" if row["power"]
              else "-")
        print(f"| {'yes' if with_line else 'no'} | {name} | {read} | {int(np.sum(f > 0))} of {f.size} | {f.max()} | "
              f"{np.median(row['filled']):.1f} | {str(row['found']) + ' of ' + str(f.size) if with_line else '-'} | "
              f"{pw if with_line else '-'} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
