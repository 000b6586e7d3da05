"""The line search's resolution against the PSD window's bin spacing (an outside evaluation's finding: a line below the
search's band, 0.052 Hz at the default 0.002 Hz and 51-bin floor, is covered by inflating broadband terms). Per case
and seed: one record of the truth (the `line` broadband part of benchmarks/line_integrity.py plus the case's line),
the one-call pipeline (auto, joint envelope, lines modelled) per row of ``--rows``: ``default`` (resolution 0.002
Hz), ``low_band`` (0.002 Hz and the band below its first tested bin at 1/window_s, `lines_low_band_resolution_hz`,
as `imupipe init` writes it), ``fine`` (the whole search at 1/window_s); the window by the workflow's rule for the
record; the exact analysis of tests/exact_kf.py. Prints one line per row: the worst MSE/P, the median and range of
mean P/MSE, the narrowband terms exported, bounded runs.

    OPENBLAS_NUM_THREADS=1 python benchmarks/line_resolution.py low 4 20 21 22 23 24 25 [--rows default low_band]

Cases: ``low`` a line of sd 1e-3 rad/s at 0.03 Hz, damping 1e-3; ``mid`` 1e-3 at 0.05 Hz, 5e-4; ``damped`` 1e-3 at
0.04 Hz, 5e-3 (an outside evaluation's); ``hf`` 3e-4 at 7.3 Hz, 2e-4; ``none`` no line. Arguments: case, hours, rate (Hz), seeds.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from line_integrity import BROADBAND, exported_against_truth  # noqa: E402
from imupipe.models import NoiseModel  # noqa: E402

#: The cases' lines (sigma rad/s, f0 Hz, damping).
CASES = {"low": ((1e-3, 0.03, 1e-3),), "mid": ((1e-3, 0.05, 5e-4),), "hf": ((3e-4, 7.3, 2e-4),), "none": (),
         "damped": ((1e-3, 0.04, 5e-3),)}


def run(case: str, hours: float, rate: float, seeds, resolution_hz: float, low_band_resolution_hz=None) -> list:
    """(worst MSE/P, mean P/MSE over the outage, narrowband terms exported, bounded) per seed: one record each,
    :func:`line_integrity.exported_against_truth` with the ``line`` broadband part."""
    truth = NoiseModel(**BROADBAND["line"], narrowband=CASES[case])
    out = [exported_against_truth(truth, "line", seed, hours, 1, "gyro", rate, resolution_hz,
                                  lines_low_band_resolution_hz=low_band_resolution_hz) for seed in seeds]
    return [(r["worst"], r["mean_p_over_mse"], r["narrowband_terms"], r["bounded"]) for r in out]


def main(argv=None) -> int:
    from imupipe.defaults import psd_window_step

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("case", choices=sorted(CASES))
    ap.add_argument("hours", type=float)
    ap.add_argument("rate", type=float, help="record rate, Hz")
    ap.add_argument("seeds", type=int, nargs="+")
    ap.add_argument("--rows", nargs="+", choices=("default", "low_band", "fine"), default=["default", "low_band"])
    a = ap.parse_args(argv)
    window, _ = psd_window_step(a.hours * 3600.0, 1.0)
    rows = {"default": (0.002, None), "low_band": (0.002, 1.0 / window), "fine": (1.0 / window, None)}
    for row in a.rows:
        res, low = rows[row]
        o = run(a.case, a.hours, a.rate, a.seeds, res, low)
        pm = [x[1] for x in o]
        print(f"{a.case} {a.hours:g} h, {row}: resolution {res:.3g} Hz"
              + (f", low band {low:.3g} Hz" if low else "") + f" (window {window:.0f} s): worst MSE/P "
              f"{max(x[0] for x in o):.3f}, mean P/MSE median {np.median(pm):.3g} [{min(pm):.3g}, {max(pm):.3g}], "
              f"lines exported {[x[2] for x in o]}, bounded {sum(x[3] for x in o)} of {len(o)}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
