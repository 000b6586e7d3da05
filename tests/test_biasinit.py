"""The bias a filter starts with (imupipe.biasinit): the slow-bias family, its worst member, the least initial
bias variance and its use by the verification, checked by exact covariance analysis against known truths."""

from __future__ import annotations

import math

import numpy as np
import pytest

from imupipe.biasinit import (RECORD_FACTOR, bias_initialisation, filter_p0, max_bias_time, slow_bias_family,
                              worst_member)
from imupipe.models import NoiseModel
from imupipe.verify import covariance_analysis, reference_scenario, state_space

RECORD_S = 36000.0  # a 10 h record


def slow_truth(sensor, T_factor=3.0):
    """White noise + one GM of T = T_factor x the record (the issue's case: T = 108 000 s, 10 h records)."""
    if sensor == "accel":
        return NoiseModel(white=1e-4, gauss_markov=((3e-4, T_factor * RECORD_S),))
    return NoiseModel(white=1e-5, gauss_markov=((1e-5, T_factor * RECORD_S),))


def as_seen_by_records(truth, inflate=1.2):
    """What a bound of mean-removed records of `truth` is: white + the random walk of the GM's drift
    K_eff = sigma sqrt(2 / T), both inflated."""
    (s, T), = truth.gauss_markov
    return NoiseModel(white=inflate * truth.white, random_walk=inflate * s * math.sqrt(2.0 / T))


def halved(m):
    return NoiseModel(white=0.5 * m.white, gauss_markov=tuple((0.5 * s, T) for s, T in m.gauss_markov),
                      random_walk=0.5 * m.random_walk)


def test_family_sigma_and_drift_identity():
    # sigma^2 = K_eff^2 T / 2 inverts K_eff^2 = 2 sigma^2 / T for the truth's own T
    truth = slow_truth("accel")
    fam = slow_bias_family([as_seen_by_records(truth, 1.0)], RECORD_S, 108000.0, "spec")
    assert fam.sigma(108000.0) == pytest.approx(3e-4, rel=1e-12)
    assert fam.T_min_s == RECORD_S and fam.worst == (pytest.approx(3e-4, rel=1e-12), 108000.0)
    # a GM slower than the record counts in the drift, a faster one does not
    m = NoiseModel(gauss_markov=((2e-4, 5 * RECORD_S), (1e-3, 100.0)), random_walk=1e-7)
    fam = slow_bias_family([m], RECORD_S, 1e6, "config")
    assert fam.k_eff**2 == pytest.approx(1e-14 + 2 * 4e-8 / (5 * RECORD_S), rel=1e-12)
    assert slow_bias_family([NoiseModel(white=1e-4, gauss_markov=((1e-3, 100.0),))], RECORD_S, 1e6, "c") is None
    wm = worst_member(m, fam)
    assert wm.random_walk == 0 and (1e-3, 100.0) in wm.gauss_markov and fam.worst in wm.gauss_markov


def test_max_bias_time_sources():
    spec_slow = NoiseModel(gauss_markov=((1e-4, 2 * RECORD_S),))
    spec_fast = NoiseModel(gauss_markov=((1e-4, 800.0),), random_walk=1e-6)
    assert max_bias_time(spec_slow, RECORD_S) == (2 * RECORD_S, "spec sheet: longest GM time constant")
    assert max_bias_time(spec_fast, RECORD_S)[0] == RECORD_FACTOR * RECORD_S
    assert max_bias_time(spec_fast, RECORD_S, 5e5) == (5e5, "config: identify.max_bias_time_s")
    with pytest.raises(ValueError, match="max_bias_time_s"):
        max_bias_time(spec_fast, RECORD_S, -1.0)


@pytest.mark.parametrize("sensor", ["accel", "gyro"])
def test_worst_member_is_the_longest_T(sensor):
    # the claim behind checking only T_max: for a fixed filter, MSE grows with T at fixed drift, at every step
    filt = as_seen_by_records(slow_truth(sensor))
    fam = slow_bias_family([filt], RECORD_S, 20 * RECORD_S, "config")
    sc = reference_scenario(sensor)
    prev = None
    for T in (RECORD_S, 3 * RECORD_S, 10 * RECORD_S, 20 * RECORD_S):
        truth = NoiseModel(white=filt.white, gauss_markov=((fam.sigma(T), T),))
        mse = covariance_analysis(filt, truth, sc).mse
        if prev is not None:
            assert np.all(mse >= prev * (1 - 1e-9))
        prev = mse


@pytest.mark.parametrize("sensor", ["accel", "gyro"])
def test_old_p0_understates_and_the_floor_covers(sensor):
    truth = slow_truth(sensor)
    filt = as_seen_by_records(truth)
    # the rule before: p starts at K^2 (fix_s + horizon_s); the truth's GM starts stationary -> under-stated
    old = covariance_analysis(filt, truth, reference_scenario(sensor))
    assert old.worst_ratio > 1.1, old.worst_ratio
    # the floor from the records' drift extrapolated to the spec sheet's T (the spec is the truth halved)
    bi = bias_initialisation(filt, spec=halved(truth), record_s=RECORD_S)
    assert bi.rests_on == "records" and bi.T_max_s == truth.gauss_markov[0][1]
    assert bi.required == pytest.approx(1.2**2 * truth.gauss_markov[0][0] ** 2, rel=1e-9)
    sc = reference_scenario(sensor, bias_var_floor=bi.required, max_bias_time_s=bi.T_max_s)
    new = covariance_analysis(filt, truth, sc)
    assert new.worst_ratio <= 1.0 + 1e-6, new.worst_ratio
    # and the family's worst member, which the verification runs, passes too
    assert covariance_analysis(filt, worst_member(filt, bi.family), sc).passed


def test_floor_keeps_p_as_a_random_constant():
    m = NoiseModel(white=1e-4, gauss_markov=((1e-5, 100.0),))
    assert filter_p0(m, 4e-10, 4200.0) == pytest.approx(4e-10 - 1e-10)
    sc = reference_scenario("accel", bias_var_floor=4e-10)
    _, Qd, P0, _, states = state_space(m, sc)
    i = states.index("p")
    assert P0[i, i] == pytest.approx(3e-10) and Qd[i, i] == 0.0
    # no floor: no p state (the reduced model of eq. 19)
    assert "p" not in state_space(m, reference_scenario("accel"))[4]


def test_truth_random_walk_starts_stationary():
    m = NoiseModel(white=1e-4, random_walk=1e-6)
    sc = reference_scenario("accel", max_bias_time_s=1e5)
    _, _, P0t, _, st = state_space(m, sc, role="truth")
    assert P0t[st.index("p"), st.index("p")] == pytest.approx(1e-12 * 0.5e5)
    _, _, P0f, _, sf = state_space(m, sc, role="filter")
    assert P0f[sf.index("p"), sf.index("p")] == pytest.approx(1e-12 * (sc.fix_s + sc.outage_s))


def test_spec_turn_on_bias(tmp_path):
    from imupipe.specsheet import SpecError, load_spec

    p = tmp_path / "s.yaml"
    p.write_text("accel:\n  white: {value: 0.05, unit: m/s/sqrt(h)}\n  turn_on_bias: {value: 2, unit: mg}\n")
    sheet = load_spec(p)
    assert sheet.turn_on_bias["accel"] == pytest.approx(2e-3 * 9.80665)
    assert "turn_on_bias" not in sheet.models["accel"].to_dict()
    bi = bias_initialisation(sheet.models["accel"], spec=sheet.models["accel"],
                             turn_on_bias=sheet.turn_on_bias["accel"], record_s=RECORD_S)
    assert bi.rests_on == "spec sheet" and bi.required == pytest.approx((2e-3 * 9.80665) ** 2)
    p.write_text("accel:\n  white: {value: 0.05, unit: m/s/sqrt(h)}\n  turn_on_bias: 2\n")
    with pytest.raises(SpecError, match="turn_on_bias"):
        load_spec(p)


def test_a_slow_bias_is_not_carried_by_a_fast_filter_state():
    """A truth whose bias is slower than the run (a random walk started at K^2 T_max / 2) against a filter that
    holds most of the initial variance in a GM of T = 168 s: with the fast GM counted (the slow floor 0) the filter
    lets that estimate decay and under-states its error; with the slow part on p it holds. filter_p0 puts the slow
    deficit on p, and a filter GM at least as slow as the run counts against it."""
    from imupipe.verify import covariance_analysis, reference_scenario

    K, T_max = 2.64e-6, 360000.0
    V = K * K * T_max / 2
    truth = NoiseModel(white=5e-5, random_walk=K)
    filt = NoiseModel(white=6e-5, gauss_markov=((math.sqrt(0.7 * V), 168.0),), random_walk=1.1 * K)
    worst = {}
    for slow in (0.0, V):
        sc = reference_scenario("accel", fix_s=600.0, outage_s=3600.0, bias_var_floor=V, bias_var_floor_slow=slow,
                                max_bias_time_s=T_max)
        worst[slow] = covariance_analysis(filt, truth, sc).worst_ratio
    assert worst[0.0] > 1.0 + 1e-6 and worst[V] <= 1.0 + 1e-6, worst
    assert filter_p0(filt, V, 4200.0, V) == pytest.approx(V)  # the fast GM does not count against the slow part
    slow_gm = NoiseModel(white=6e-5, gauss_markov=((math.sqrt(0.7 * V), 5000.0),))
    assert filter_p0(slow_gm, V, 4200.0, V) == pytest.approx(0.3 * V)  # a GM slower than the run does
