"""Record consistency (imupipe.identify.consistency.record_consistency and the identify stage's table).

False-alarm level: with R records and J parameters tested the critical |z| is Phi^-1(1 - alpha / (2 R J)); under
equal truths each z is standard normal (calibrated intervals), so by Bonferroni the chance that any record is
named is at most alpha (module docstring). The simulated tests use alpha = 0.01 and three independent trios of
equal-truth records: the chance that the no-flag test fails by chance is at most 3 x 0.01 (plus the intervals'
miscalibration; the white-noise-plus-random-walk intervals of fit_allan cover near nominal: docs/performance.md).
"""

import math

import numpy as np
import pytest

from imupipe.allan import allan_variance
from imupipe.identify import fit_allan
from imupipe.identify.consistency import record_consistency
from imupipe.models import NoiseModel
from imupipe.simulate import simulate

RATE, N = 10.0, 2**19  # Hz, samples (14.6 h)
N_WHITE, K = 1e-3, 1e-4  # u/sqrt(Hz), u/sqrt(s)


def _record(k, seed):
    x = simulate(NoiseModel(white=N_WHITE, random_walk=k, dt=1.0 / RATE), N, RATE, np.random.default_rng(seed))
    av = allan_variance(x, rate=RATE, taus="octave")
    ok = np.isfinite(av["avar"].values) & np.isfinite(av["edf"].values)
    f = fit_allan(av["tau"].values[ok], av["avar"].values[ok], av["edf"].values[ok],
                  components=("white", "random_walk"), n_gm=0, n_boot=100, rng=seed, record_rate_hz=RATE,
                  n_samples=N, dt=1.0 / RATE)
    return {p: (f.params[p], *f.intervals[p]) for p in ("white", "random_walk")}


@pytest.mark.parametrize("trio", range(3))
def test_doubled_random_walk_record_is_named_and_equal_records_are_not(trio):
    equal = {f"rec{i}": _record(K, 100 * trio + i) for i in range(3)}
    res = record_consistency(equal, confidence=0.95, alpha=0.01)
    assert res["flagged"] == [], res["flagged"]
    # the critical value is the Bonferroni one over 3 records x 2 parameters
    assert res["z_crit"] == pytest.approx(3.1440, abs=1e-3) and res["n_tests"] == 6
    odd = dict(equal)
    odd["rec2"] = _record(2 * K, 100 * trio + 2)
    res = record_consistency(odd, confidence=0.95, alpha=0.01)
    assert [(r, p) for r, p, *_ in res["flagged"]] == [("rec2", "random_walk")], res["flagged"]
    assert res["rows"]["rec2"]["random_walk"]["flagged"]
    assert not res["rows"]["rec0"]["random_walk"]["flagged"]


def _rec(n, k, rel=0.05):
    """A record with N and K estimates and symmetric log-scale 95 % intervals of relative half-width `rel`."""
    f = math.exp(1.959964 * rel)
    return {"white": (n, n / f, n * f), "random_walk": (k, k / f, k * f)}


def test_z_is_the_log_distance_in_standard_errors():
    # three records with sd 0.05 in log: rec2 ln 2 above the others' mean (sd 0.05/sqrt 2):
    # z = ln 2 / (0.05 sqrt(1 + 1/2)) = 11.3
    res = record_consistency({"a": _rec(1.0, 1.0), "b": _rec(1.0, 1.0), "c": _rec(1.0, 2.0)}, 0.95, 0.01)
    assert res["rows"]["c"]["random_walk"]["z"] == pytest.approx(math.log(2) / (0.05 * math.sqrt(1.5)), rel=1e-4)
    assert [r for r, *_ in res["flagged"]] == ["c"]
    # a difference within the intervals is not named
    res = record_consistency({"a": _rec(1.0, 1.0), "b": _rec(1.0, 1.0), "c": _rec(1.0, 1.2)}, 0.95, 0.01)
    assert res["flagged"] == []


def test_two_records_are_both_named_and_one_sided_intervals_are_not_tested():
    res = record_consistency({"a": _rec(1.0, 1.0), "b": _rec(1.0, 3.0)}, 0.95, 0.01)
    assert sorted(r for r, *_ in res["flagged"]) == ["a", "b"]
    zero_k = {"white": (1.0, 0.95, 1.05), "random_walk": (0.0, 0.0, 2.0)}
    res = record_consistency({"a": _rec(1.0, 1.0), "b": _rec(1.0, 1.0), "c": zero_k}, 0.95, 0.01)
    assert res["rows"]["c"]["random_walk"]["z"] is None
    assert "not tested" in res["rows"]["c"]["random_walk"]["note"]
    with pytest.raises(ValueError, match="alpha"):
        record_consistency({"a": _rec(1, 1)}, 0.95, alpha=0.0)


def test_summary_names_the_record_and_shows_the_tables():
    from imupipe.summary import summary_sections

    rc = record_consistency({"imu1": _rec(1e-3, 1e-4), "imu2": _rec(1e-3, 1e-4), "imu3": _rec(1e-3, 2e-4)},
                            0.95, 0.01)
    rc["flagged"] = [{"dataset": r, "param": p, "z": z, "estimate": e, "others": o} for r, p, z, e, o in rc["flagged"]]
    ad = {"chi2_per_dof": 900.0, "p_value": 0.0, "adequate": False}
    identify = {"record_consistency": rc, "fit": {"adequacy": {"level": 0.01}},
                "adequacy_lines": {"pooled": {"before": ad, "after": {**ad, "chi2_per_dof": 40.0}},
                                   "per_axis": {"x": {"before": ad, "after": {"chi2_per_dof": 1.1, "p_value": 0.3,
                                                                             "adequate": True}}}}}
    first, details = summary_sections({"accel": {"identify": identify}})
    flag = [ln for ln in first.splitlines() if "record consistency" in ln]
    assert len(flag) == 1 and flag[0].startswith("- FLAG accel record consistency: imu3 K = "), flag
    assert "| imu3 |" in details and "**named**" in details
    assert "| pooled | 900 | 0 | 40 | 0 |" in details and "| axis x | 900 | 0 | 1.1 | 0.3 |" in details
    assert "still inadequate: pooled" in details and "statistical limits" in details
    # no named record, no FLAG
    rc_eq = record_consistency({"imu1": _rec(1e-3, 1e-4), "imu2": _rec(1e-3, 1e-4)}, 0.95, 0.01)
    rc_eq["flagged"] = []
    first, _ = summary_sections({"accel": {"identify": {"record_consistency": rc_eq}}})
    assert "record consistency" not in first
