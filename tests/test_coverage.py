"""Coverage of the identification's intervals: the REPORTED parameters (the selected components refitted,
:func:`imupipe.identify.refit_selected`) on simulated records of known truth.

R independent records per case, one interval of stated level c (0.9) per parameter and record: if the
intervals are right the number covering the truth is Binomial(R, c). The slow test (R = 200, 10 h at 10 Hz,
AV on octave taus) asserts the count inside the binomial 95 % range of c (only its lower end for a truth on
the boundary, K = 0, which every interval reaching 0 covers, and for an interval that is one-sided or widened for
GM/random-walk confounding in any record: conservative by construction, and labelled so); the fast one runs a few records of one
case and fails below the binomial 0.1 % quantile (derived, not tuned: a correct interval fails it with
probability <= 0.001). A parameter of a component the selection dropped counts as covered only when the truth
has no such component (K = 0); a one-sided interval (on a search boundary) covers when the truth lies in it.

Truths here were not used to tune the identification (the module's own tests use other values and seeds).

Run as a script for the numbers: ``python tests/test_coverage.py CASE R [hours] [seed]`` (default seed: SEED).
"""

import sys
import zlib

import numpy as np
import pytest

from imupipe.allan import allan_variance
from imupipe.identify import fit_allan, refit_selected, select_components
from imupipe.models import NoiseModel
from imupipe.simulate import simulate

RATE = 10.0  # Hz
LEVEL = 0.9
# The profile interval of T and the GM intervals given a dropped random walk were developed on DEV_SEED, N's
# profile interval on DEV_SEED and 4242; the slow test runs on SEED, which was not used in their development
# (docs/performance.md gives the seeds' numbers).
DEV_SEED, SEED = 2026, 31337

CASES = {
    # tactical gyro (rad/s): white 0.1 deg/sqrt(h), GM 1 deg/h at T = 200 s, K 0.03 (deg/h)/sqrt(s)
    "tactical_white_gm_rw": (NoiseModel(white=2.909e-5, gauss_markov=((4.848e-6, 200.0),), random_walk=1.454e-7), 1),
    # MEMS accel (m/s^2): white 0.06 m/s/sqrt(h), GMs 0.2 mg at 20 s and 0.1 mg at 600 s, K 2e-6 m/s^2/sqrt(s)
    "mems_white_2gm_rw": (NoiseModel(white=1.0e-3, gauss_markov=((1.96e-3, 20.0), (9.81e-4, 600.0)),
                                     random_walk=2.0e-6), 2),
    # white + GM, no random walk (accel-like, m/s^2)
    "white_gm": (NoiseModel(white=6.0e-4, gauss_markov=((3.0e-4, 150.0),)), 1),
}
COMPONENTS = ("white", "gauss_markov", "random_walk", "quantization")


def truth_params(model):
    out = {"white": model.white, "random_walk": model.random_walk}
    for i, (s, T) in enumerate(sorted(model.gauss_markov, key=lambda st: st[1]), start=1):
        out[f"gm_sigma_{i}"], out[f"gm_T_{i}"] = s, T
    return out


def covered(fit, name, value):
    """Does the reported (selected, refitted) interval of `name` cover `value`?"""
    if name not in fit.intervals:  # component dropped by the selection
        return value == 0.0
    lo, hi = fit.intervals[name]
    if not (np.isfinite(lo) or lo == 0.0):
        return False
    return bool(lo <= value <= hi)


def coverage(case, n_records, hours=10.0, seed=0, n_boot=100):
    """Hits per parameter over `n_records` records of `case` (and the number of records)."""
    truth, n_gm = CASES[case]
    true = truth_params(truth)
    n = int(hours * 3600 * RATE)
    rng = np.random.default_rng([seed, zlib.crc32(case.encode())])
    hits = dict.fromkeys(true, 0)
    one_sided = dict.fromkeys(true, 0)  # records where the reported interval was one-sided / upper-limit only
    confounded = dict.fromkeys(true, 0)  # records where it was widened for GM/random-walk confounding (a hull)
    for _ in range(n_records):
        av = allan_variance(simulate(truth, n, RATE, rng), RATE, taus="octave")
        t, y, e = av.tau.values, av.avar.values, av.edf.values
        full = fit_allan(t, y, e, components=COMPONENTS, n_gm=n_gm, n_boot=0)
        sel = select_components(full, t, y, e, filter_rate_hz=1.0, outage_s=3600.0)
        rep = refit_selected(full, sel, t, y, e, n_boot=n_boot, confidence=LEVEL, rng=rng, record_rate_hz=RATE, n_samples=n)
        for k, v in true.items():
            hits[k] += covered(rep, k, v)
            one_sided[k] += bool(rep.on_boundary.get(k, True)
                                 or rep.interval_kind.get(k, "").startswith("one-sided"))
            confounded[k] += "confounding" in rep.interval_kind.get(k, "")
    coverage.one_sided, coverage.confounded = one_sided, confounded
    return hits, n_records


# Measured (python tests/test_coverage.py CASE 200 10 SEED; all numbers and the rules in docs/performance.md,
# 2026-12-02), binomial 95 % range of 200 intervals at 0.9: [0.855, 0.94]. N's profile interval was developed on
# seeds 2026 and 4242; on SEED: tactical N 0.935, K 0.895 (21 records one-sided), GM sigma 0.86, T 0.91 (21
# widened); white + GM N 0.875, K 0.985 (truth 0), GM sigma 0.925, T 0.91; MEMS two GMs (with the two-GM search
# bounded to its grid) N 0.885, K 1.0 (196 one-sided), GM 1 sigma 0.93 / T 0.955, GM 2 sigma 0.985 / T 0.95
# (190-196 records widened for confounding: only the lower end applies).
# A single GM's sigma has its profile interval since 2026-12-03 (developed on seeds 2026 and 4242; verified on
# 555, 8080, 7777: tactical GM sigma 0.905, 0.845, 0.935, white + GM 0.89, 0.925; on SEED 0.93 and 0.88;
# docs/performance.md). Its threshold is the larger of two calibrations (fitted model, K at its profile upper
# limit) since later that day: verified on 1212 and 6060 (tactical GM sigma 0.945, 0.965, white + GM 0.905, 0.88),
# on the seen 8080 0.875; SEED not re-run with it.


@pytest.mark.slow
@pytest.mark.parametrize("case", list(CASES))
def test_coverage_200_records(case):
    from scipy.stats import binom

    R = 200
    hits, _ = coverage(case, R, hours=10.0, seed=SEED)
    lo, hi = binom.ppf(0.025, R, LEVEL), binom.ppf(0.975, R, LEVEL)
    true = truth_params(CASES[case][0])
    # a truth on the parameter's boundary (K = 0) is covered by every interval reaching 0, an upper limit
    # given for a component the data do not show ([0, upper]) is conservative by design, and so is an interval
    # widened for GM/random-walk confounding (the hull with the fit with a random walk, labelled so in
    # interval_kind: the data cannot separate the two, the interval says so and covers both): coverage >= the
    # level there, so only the lower end is asserted where the truth is 0 or any record's interval was
    # one-sided or widened
    upper_applies = {k: true[k] != 0.0 and coverage.one_sided[k] == 0 and coverage.confounded[k] == 0
                     for k in hits}
    assert all(lo <= h and (h <= hi or not upper_applies[k]) for k, h in hits.items()), (hits, lo, hi)


def test_coverage_fast():
    # 12 records of 2 h of the white + GM case; a correct 90 % interval covers at least binom.ppf(0.001, 12, 0.9)
    # = 7 of them with probability >= 0.999
    from scipy.stats import binom

    R = 12
    hits, _ = coverage("white_gm", R, hours=2.0, seed=7, n_boot=40)
    k_min = binom.ppf(0.001, R, LEVEL)
    assert k_min == 7
    assert all(h >= k_min for h in hits.values()), hits


if __name__ == "__main__":
    case, R = sys.argv[1], int(sys.argv[2])
    hours = float(sys.argv[3]) if len(sys.argv) > 3 else 10.0
    seed = int(sys.argv[4]) if len(sys.argv) > 4 else SEED
    h, n = coverage(case, R, hours=hours, seed=seed)
    print(case, R, hours, "seed", seed, {k: round(v / n, 3) for k, v in h.items()},
          "one-sided", coverage.one_sided, "confounded", coverage.confounded)
