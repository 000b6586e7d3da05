"""Coverage of the joint upper envelope (imupipe.identify.joint) by simulation: for each truth, R records (or R sets
of records) simulated from it, the identification with ``envelope_kind="joint"`` (imupipe.stages.identify.identify_sensor,
the library defaults: n_boot 100, confidence 0.95, the fix + outage span 4200 s), and per record whether the truth's
PSD lies under (a) the joint band over its frequencies 1/span .. half the rate, (b) the joint envelope model and (c)
the marginal envelope of the same refit, at every frequency of the band's grid (100 per decade). Prints a
Markdown table with the binomial 95 % range of R draws at the stated level.

    OPENBLAS_NUM_THREADS=1 python benchmarks/joint_coverage.py --truth nav_tactical two_gm --records 40 --hours 4
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bound_modes import TRUTHS  # noqa: E402

SPAN_S = 4200.0


def one(truth, hours, rate, n_data, seed, confidence):
    """The coverage indicators (band, joint envelope model, marginal envelope) of one simulated set of records, and
    the geometric mean envelope/truth over the band, joint and marginal."""
    from imupipe.allan import allan_variance
    from imupipe.identify.joint import joint_band, PER_DECADE
    from imupipe.simulate import simulate
    from imupipe.stages.identify import Curve, envelope, identify_sensor

    X = simulate(truth, int(hours * 3600 * rate), rate, rng=np.random.default_rng(seed), n_records=n_data)
    curves = []
    for i in range(n_data):
        av = allan_variance(X[i], rate, taus="octave", confidence=0.683, units="rad/s")
        a, e = av["avar"].values, av["edf"].values
        ok = np.isfinite(a) & np.isfinite(e)
        curves.append(Curve(f"d{i}/x", av["tau"].values[ok], a[ok], e[ok], int(X[i].size), rate, "x"))
    kw = dict(sensor="gyro", components=["white", "gauss_markov", "flicker", "random_walk"],
              n_gm=min(len(truth.gauss_markov), 2), n_boot=100, confidence=confidence, significance=0.05,
              relevance=0.05, filter_rate_hz=1.0, outage_s=3600.0, span_s=SPAN_S, seed=seed + 1)
    ident = identify_sensor(curves, **kw, envelope_kind="joint")
    f_lo, f_hi = 1.0 / SPAN_S, 0.5 * rate
    f = np.geomspace(f_lo, f_hi, int(np.ceil(PER_DECADE * np.log10(f_hi / f_lo))) + 1)
    fit = ident.selected
    # the band is of the refit before any re-assignment (imupipe.stages.identify.selected_and_envelope)
    band = joint_band(fit.envelope_fit, fit.envelope_kept, f, confidence)
    S = truth.psd(f)
    hi = np.ones(f.size, dtype=bool)
    env_j = ident.envelope.psd(f)
    # the marginal envelope of the same refit (without the pipeline's re-assignment step)
    env_m = envelope(fit.envelope_fit, fit.envelope_kept, curves, confidence, SPAN_S, "marginal").psd(f)
    up = band["upper"]
    return (bool(np.all(S[hi] <= up[hi])), bool(np.all(S[hi] <= env_j[hi])),
            bool(np.all(S[hi] <= env_m[hi])), float(np.exp(np.mean(np.log(env_j[hi] / S[hi])))),
            float(np.exp(np.mean(np.log(env_m[hi] / S[hi])))))


def main(argv=None) -> int:
    from scipy.stats import binom

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--truth", nargs="+", default=["nav_tactical", "two_gm"], choices=sorted(TRUTHS))
    ap.add_argument("--records", type=int, default=40)
    ap.add_argument("--datasets", type=int, default=1)
    ap.add_argument("--hours", type=float, default=4.0)
    ap.add_argument("--rate", type=float, default=10.0)
    ap.add_argument("--confidence", type=float, default=0.95)
    ap.add_argument("--seed", type=int, default=8080)
    a = ap.parse_args(argv)
    lo, hi = (binom.ppf(q, a.records, a.confidence) / a.records for q in (0.025, 0.975))
    print(f"level {a.confidence}, {a.records} draws: binomial 95 % range [{lo:.3f}, {hi:.3f}]")
    print("| truth | datasets x hours | records | band | joint envelope model | marginal envelope | "
          "geo. mean joint / truth | geo. mean marginal / truth | CPU s |")
    print("|---|---|---|---|---|---|---|---|---|")
    for tn in a.truth:
        t0 = time.process_time()
        rows = np.array([one(TRUTHS[tn], a.hours, a.rate, a.datasets, a.seed + 101 * r, a.confidence)
                         for r in range(a.records)], dtype=float)
        c = rows.mean(axis=0)
        print(f"| {tn} | {a.datasets} x {a.hours:g} h | {a.records} | {c[0]:.3f} | {c[1]:.3f} | {c[2]:.3f} | "
              f"{np.exp(np.mean(np.log(rows[:, 3]))):.2f} | {np.exp(np.mean(np.log(rows[:, 4]))):.2f} | "
              f"{time.process_time() - t0:.0f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
