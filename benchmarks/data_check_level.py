"""False-alarm rate of the bound's data check (imupipe.bound.datacheck, docs/method.md "The data check") by simulation:
with the model equal to the truth (its PSD as sampled), the fraction of record sets whose sample PSDs' lower
confidence limits (imupipe.spectra.chi2_lower, family-wise over every curve and bin at the confidence) lie above it
somewhere; the nominal rate is 1 - confidence. Prints a Markdown table with the binomial 95 % range.

    OPENBLAS_NUM_THREADS=1 python benchmarks/data_check_level.py --sets 300
"""

from __future__ import annotations

import argparse
import math
import sys

import numpy as np
from scipy.stats import binom

from imupipe.models import NoiseModel
from imupipe.simulate import simulate
from imupipe.spectra import chi2_lower, psd

TRUTHS = {
    "white + GM": NoiseModel(white=math.radians(0.3) / 60.0, gauss_markov=((math.radians(3.0) / 3600.0, 300.0),)),
    "random-walk dominated": NoiseModel(white=1e-4, random_walk=2e-6),
    "four-GM 1/f floor": NoiseModel(white=3e-4, gauss_markov=tuple((6e-5, T) for T in (10.0, 100.0, 1000.0, 1e4)),
                                    random_walk=2e-7),
}


def refused(truth, rng, records: int, hours: float, rate: float, window_s: float, confidence: float) -> bool:
    """Whether the check refuses the truth itself on one simulated set of records."""
    n = int(hours * 3600 * rate)
    X = np.asarray(simulate(truth, n, rate, rng=rng, n_records=records)).reshape(records, n)
    sp = [psd(x, rate, window_s=window_s, step_s=window_s / 2) for x in X]
    f = sp[0]["frequency"].values
    S = np.array([s["psd"].values for s in sp])
    nu = np.array([s["edf"].values for s in sp])
    k = f > 0
    lo = chi2_lower(S[:, k], nu[:, k], confidence, n_tests=int(k.sum()) * records)
    return bool(np.any(lo > truth.psd_sampled(f[k], 1.0 / rate)[None, :]))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sets", type=int, default=300)
    ap.add_argument("--records", type=int, default=2)
    ap.add_argument("--hours", type=float, default=3.0)
    ap.add_argument("--rate", type=float, default=1.0, help="Hz (the decimated rate the bound compares at)")
    ap.add_argument("--window-s", type=float, default=2700.0)
    ap.add_argument("--confidence", type=float, default=0.95)
    ap.add_argument("--seed", type=int, default=77)
    a = ap.parse_args(argv)
    lo, hi = binom.ppf(0.025, a.sets, 1 - a.confidence), binom.ppf(0.975, a.sets, 1 - a.confidence)
    print(f"| truth | sets refused of {a.sets} | rate | nominal {1 - a.confidence:g}: binomial 95 % range |")
    print("|---|---|---|---|")
    for name, truth in TRUTHS.items():
        rng = np.random.default_rng(a.seed)
        r = sum(refused(truth, rng, a.records, a.hours, a.rate, a.window_s, a.confidence) for _ in range(a.sets))
        print(f"| {name} | {r} | {r / a.sets:.3f} | {lo:.0f}-{hi:.0f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
