"""False-alarm rate of the line search (imupipe.lines.find_lines) on line-free records, by simulation: the fraction
of records of a truth without spectral lines in which the search reports any line, against its family-wise level
alpha per record and axis (docs/method.md, "Spectral lines"), with the binomial 95 % range of that count.

    OPENBLAS_NUM_THREADS=1 python benchmarks/lines_false_alarm.py --records 100

Truths: the default run's (config/truth/stim300_like.yaml, gyro and accel: white, GM, flicker, random walk) at its
10 h at 125 Hz, and a MEMS-like one (white 1e-3 u/sqrt(Hz), a GM of 2e-4 u at T 200 s) at 2 h at 20 Hz, the length
and rate of an outside evaluation's records (few Welch segments: a higher threshold, each detection 3-4x its floor),
also with its white noise 2x and 3x its sd over the second half (a level change: segments of unequal level).
Records drawn as the workflow draws them (imupipe.simulate.simulate_chunks), the search at the default settings.

With ``--low-band`` the search runs as `imupipe init` writes it (scales 1, 8, 64 and the low band at 1 / psd.window_s
and at half its spacing, each at alpha / 5) on 2 h records at 20 Hz of five truths (the STIM-300-like gyro and accel
of an outside evaluation, the MEMS GM, a steep random walk, flicker), and the table counts the records with a line in
the low band, whose share of the level is 2 alpha / 5 (its floor window narrows toward 0 Hz: docs/method.md,
"Narrowband lines and outliers"):

    OPENBLAS_NUM_THREADS=1 python benchmarks/lines_false_alarm.py --low-band --records 200 --alpha 0.2
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
from scipy.stats import binom

from imupipe.lines import find_lines
from imupipe.models import NoiseModel
from imupipe.simulate import simulate_chunks
from imupipe.specsheet import load_spec

ROOT = Path(__file__).resolve().parents[1]


def cases() -> dict:
    """name -> (truth, hours, rate Hz, white noise sd factor over the second half)."""
    sheet = load_spec(ROOT / "config" / "truth" / "stim300_like.yaml")
    mems = NoiseModel(white=1e-3, gauss_markov=((2e-4, 200.0),))
    return {"default gyro": (sheet.models["gyro"], 10.0, 125.0, 1.0),
            "default accel": (sheet.models["accel"], 10.0, 125.0, 1.0),
            "mems 2 h at 20 Hz": (mems, 2.0, 20.0, 1.0),
            "mems, white 2x over the second half": (mems, 2.0, 20.0, 2.0),
            "mems, white 3x over the second half": (mems, 2.0, 20.0, 3.0)}


def low_band_cases() -> dict:
    """name -> (truth, hours, rate Hz, 1.0) of the ``--low-band`` table (SI, module docstring)."""
    d = math.pi / 180.0
    return {"STIM-300-like gyro": (NoiseModel(white=0.15 / 60 * d, gauss_markov=((1.5 / 3600 * d, 1500.0),),
                                              random_walk=0.02 / 3600 * d), 2.0, 20.0, 1.0),
            "STIM-300-like accel": (NoiseModel(white=0.05 / 60, gauss_markov=((0.05e-3 * 9.80665, 800.0),),
                                               random_walk=1.25e-6), 2.0, 20.0, 1.0),
            "mems": (NoiseModel(white=1e-3, gauss_markov=((2e-4, 200.0),)), 2.0, 20.0, 1.0),
            "steep random walk": (NoiseModel(white=1e-3, random_walk=2e-5), 2.0, 20.0, 1.0),
            "flicker": (NoiseModel(white=1e-4, flicker=3e-5), 2.0, 20.0, 1.0)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--records", type=int, default=100)
    ap.add_argument("--alpha", type=float, default=0.01)
    ap.add_argument("--resolution-hz", type=float, default=0.002)
    ap.add_argument("--seed", type=int, default=555)
    ap.add_argument("--low-band", action="store_true", help="init's search; count the low band's lines")
    a = ap.parse_args(argv)
    if a.low_band:
        return _low_band_table(a)
    lo, hi = binom.ppf(0.025, a.records, a.alpha), binom.ppf(0.975, a.records, a.alpha)
    print(f"| truth | records | segments | records with a line | expected at alpha {a.alpha:g} (95 % range) | "
          "peak/floor of the detections |")
    print("|---|---|---|---|---|---|")
    for i, (name, (truth, hours, rate, factor)) in enumerate(cases().items()):
        n = int(hours * 3600 * rate)
        hits, ratios, segments = 0, [], 0
        for r in range(a.records):
            rng = np.random.default_rng([a.seed, i, r])
            x = np.empty(n)
            for start, c in simulate_chunks(truth, n, rate, rng):
                x[start:start + c.size] = c
            if factor != 1.0:  # a noise-level change: no line, but segments of unequal level
                x[n // 2:] += math.sqrt(factor**2 - 1.0) * truth.white * math.sqrt(rate) * rng.standard_normal(n - n // 2)
            res = find_lines(x, rate, resolution_hz=a.resolution_hz, alpha=a.alpha)
            segments = res.n_segments
            hits += bool(res.lines)
            ratios += [round(ln.peak_ratio, 2) for ln in res.lines]
        print(f"| {name} | {a.records} | {segments} | {hits} | {a.records * a.alpha:g} ({lo:g} to {hi:g}) | "
              f"{', '.join(map(str, ratios)) or '-'} |", flush=True)
    return 0


def _low_band_table(a) -> int:
    """The ``--low-band`` table (module docstring)."""
    from imupipe.defaults import psd_window_step

    share = 2 * a.alpha / 5  # the low band's two searches of five
    lo, hi = binom.ppf(0.025, a.records, share), binom.ppf(0.975, a.records, share)
    print(f"| truth | records | low band tested (Hz) | records with a low-band line | expected at 2 alpha / 5 = "
          f"{share:g} (95 % range) | their frequencies (Hz) |")
    print("|---|---|---|---|---|---|")
    for i, (name, (truth, hours, rate, _)) in enumerate(low_band_cases().items()):
        n = int(hours * 3600 * rate)
        hits, freqs, band = 0, [], ""
        for r in range(a.records):
            rng = np.random.default_rng([a.seed, 100 + i, r])
            x = np.empty(n)
            for start, c in simulate_chunks(truth, n, rate, rng):
                x[start:start + c.size] = c
            res = find_lines(x, rate, resolution_hz=a.resolution_hz, alpha=a.alpha, scales=(1, 8, 64),
                             low_band_resolution_hz=1.0 / psd_window_step(hours * 3600.0)[0])
            lows = [b for b in (res.low_band, res.low_band_finer) if b]
            top = max(b["f_max_hz"] + b["resolution_hz"] for b in lows)
            band = f"{min(b['f_min_hz'] for b in lows):.4f}-{max(b['f_max_hz'] for b in lows):.4f}"
            mine = [ln.frequency_hz for ln in res.lines if ln.frequency_hz <= top]
            hits += bool(mine)
            freqs += [round(v, 4) for v in mine]
        print(f"| {name} | {a.records} | {band} | {hits} | {a.records * share:g} ({lo:g} to {hi:g}) | "
              f"{', '.join(map(str, freqs)) or '-'} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
