"""Coverage of a spectral line's power limit with its independent looks (imupipe.lines.line_looks; docs/method.md,
"Narrowband lines and outliers"): per case, simulated records of a damped line (or a constant sinusoid) over white
noise, imupipe.lines.find_lines at 0.002 Hz, and whether the upper limit P1 nu / chi2_nu(0.05) covers the true power
with nu = 2K max(1, Gamma/df) (segments counted as independent) and with the line's own dof (2 looks max(1,
Gamma/df)). Prints a Markdown table: the looks' median and 5-95 % range, covered counts, median limit/estimate.

    OPENBLAS_NUM_THREADS=1 python benchmarks/line_looks.py --set developed held_out
"""

from __future__ import annotations

import argparse
import math
import sys

import numpy as np
from scipy.stats import chi2

from imupipe.lines import find_lines
from imupipe.models import NoiseModel
from imupipe.simulate import simulate

#: (f0 Hz, amplitude deg/h, damping, hours, rate Hz, seed, draws, constant sinusoid?)
SETS = {
    "developed": [(0.3, 150, 0.0002, 2.0, 20.0, 42, 100, False), (0.3, 150, 0.002, 2.0, 20.0, 42, 100, False),
                  (0.3, 150, 0.01, 2.0, 20.0, 42, 100, False), (0.3, 150, 0.002, 2.0, 20.0, 42, 100, True),
                  (0.3, 150, 0.0002, 10.0, 20.0, 7, 100, False)],
    "held_out": [(2.5, 40, 3e-5, 2.0, 100.0, 101, 60, False), (1.1, 60, 1e-4, 6.0, 50.0, 202, 60, False),
                 (1.1, 60, 1e-4, 6.0, 50.0, 203, 60, True), (0.7, 80, 0.001, 4.0, 20.0, 204, 60, False)],
}
WHITE = 0.1 * math.pi / 180 / 60  # 0.1 deg/sqrt(h) in rad/s/sqrt(Hz)


def run(f0, amp, zeta, hours, rate, seed, n, sine, resolution_hz=0.002) -> str:
    """One table row."""
    s = amp * math.pi / 180 / 3600
    m = NoiseModel(white=WHITE) if sine else NoiseModel(white=WHITE, narrowband=((s, f0, zeta),))
    rng = np.random.default_rng(seed)
    N = int(hours * 3600 * rate)
    t = np.arange(N) / rate
    cov_2k = cov_l = 0
    f_2k, f_l, looks = [], [], []
    for _ in range(n):
        x = simulate(m, N, rate, rng=rng)
        if sine:
            x = x + math.sqrt(2) * s * np.sin(2 * math.pi * f0 * t + rng.uniform(0, 2 * math.pi))
        r = find_lines(x, rate, resolution_hz=resolution_hz)
        ln = max((c for c in r.lines if abs(c.frequency_hz - f0) < 0.02), key=lambda c: c.power)
        nu = 2 * r.effective_segments * max(1, ln.width_hz / r.resolution_hz)
        a, b = nu / chi2.ppf(0.05, nu), ln.dof / chi2.ppf(0.05, ln.dof)
        cov_2k += ln.power * a >= s * s
        cov_l += ln.power * b >= s * s
        f_2k.append(a)
        f_l.append(b)
        looks.append(ln.independent_segments)
    what = f"{f0} Hz, {amp} deg/h, " + ("a constant sinusoid" if sine else f"damping {zeta}")
    return (f"| {what} | {hours:g} h at {rate:g} Hz, seed {seed} | {r.n_segments} | {np.median(looks):.1f} "
            f"[{np.percentile(looks, 5):.1f}, {np.percentile(looks, 95):.1f}] | {cov_2k} of {n} | {cov_l} of {n} | "
            f"{np.median(f_2k):.2f} | {np.median(f_l):.2f} |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--set", nargs="+", choices=sorted(SETS), default=["developed", "held_out"])
    a = ap.parse_args(argv)
    print("| line | records | K | looks, median [5 %, 95 %] | covered, 2K | covered, 2 looks | limit/estimate, 2K | "
          "limit/estimate, 2 looks |")
    print("|---|---|---|---|---|---|---|---|")
    for name in a.set:
        for case in SETS[name]:
            print(run(*case), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
