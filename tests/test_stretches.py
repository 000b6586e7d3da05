"""The noisiest-stretch scan (imupipe.stretches) and where the bound takes it in (stationarity summary, bound stage,
auto candidates): closed forms of a white-noise level change, the chance level of a stationary record."""

import math
from dataclasses import replace

import numpy as np
import pytest

from imupipe.bound.auto import ENVELOPE_MODE, candidate_modes
from imupipe.stages.bound import STRETCH_LABEL, with_stretches
from imupipe.stages.stationarity import summary_stage
from imupipe.stretches import StretchLevels, stretch_levels


def _change(n, start, factor, rng):
    x = rng.standard_normal(n)
    x[int(start * n):] *= factor
    return x


@pytest.mark.parametrize("seed", [11, 12, 13, 14, 15])
def test_a_white_level_change_gives_the_noisy_stretch_over_the_average_in_every_band(seed):
    # white noise of sd 2.5 over the last third: the average PSD is (2/3 + 6.25/3) = 2.75 x the quiet level, the
    # noisy stretch's 6.25 x: gain 6.25 / 2.75 = 2.27 in every band. A band of one stretch has relative sd at most
    # sqrt(2 / edf_min) (edf counted at half the nominal); the largest of the fully noisy stretches' estimates lies
    # within -3 and +4 such sds of the closed form
    # The longer scales (1800 s and 3600 s stretches) see at most that gain: a 1800 s stretch fits in the noisy third
    # (6.25 / 2.75 again), the best 3600 s one is two thirds noisy ((1 + 2 x 6.25) / 3 / 2.75 = 1.64)
    x = _change(7200, 2 / 3, 2.5, np.random.default_rng(seed))
    s = stretch_levels(x, 1.0)
    truth = 6.25 / 2.75
    sd = math.sqrt(2.0 / s.edf_min)
    assert s.stretch_s == 900.0 and s.n_stretches == 15 and sorted(set(s.band_stretch_s)) == [900.0, 1800.0, 3600.0]
    by_scale = {L: [(r, t) for r, t, b in zip(s.ratio, s.start_s, s.band_stretch_s) if b == L] for L in (900, 1800)}
    for L in (900, 1800):
        assert all(truth * (1 - 3 * sd) <= r <= truth * (1 + 4 * sd) for r, _ in by_scale[L]), (L, by_scale[L])
        # the stretch that sets each band lies mostly in the noisy third (it starts at 4800 s - L/2 or later)
        assert min(t for _, t in by_scale[L]) >= 4800.0 - L / 2 - 1e-9
    half = [r for r, b in zip(s.ratio, s.band_stretch_s) if b == 3600]
    assert all((12.5 + 1) / 3 / 2.75 * (1 - 3 * sd) <= r <= truth for r in half), half


def test_a_stationary_record_gains_little_and_only_by_chance():
    # white noise, 40 records: the median of each band's gain (the largest of 15 overlapping band estimates, each
    # relative sd <= sqrt(2 / edf)) stays below 1 + 2 sqrt(2 / edf); a scan that compared unlike levels (windows of
    # one stretch against the record's with another normalisation) would be off by a constant factor
    rng = np.random.default_rng(2027)
    gains = np.array([stretch_levels(rng.standard_normal(36000), 1.0).ratio for _ in range(40)])
    s = stretch_levels(rng.standard_normal(36000), 1.0)
    assert np.all(np.median(gains, axis=0) <= 1 + 2 * math.sqrt(2 / s.edf_min)), np.median(gains, axis=0)
    assert np.all(np.median(gains, axis=0) >= 1.0)  # a maximum over stretches whose mean is the record's


def test_the_gain_on_a_psd_grid_never_steps_up_and_covers_each_band():
    # band 0 (0.01 ..) gain 0.8 -> 1, band 1 (0.05 ..) gain 2: 2 from 0.05 on, a ramp 2^(1 + log10(f / 0.05)) over
    # the decade below it, 1 below 0.005
    s = StretchLevels(f_lo_hz=(0.01, 0.05), f_hi_hz=(0.04, 0.5), ratio=(0.8, 2.0), start_s=(0.0, 10.0),
                      stretch_s=100.0, n_stretches=3, edf_min=120.0)
    f = np.array([0.001, 0.005, 0.01, 0.03, 0.045, 0.05, 0.2, 0.5, 0.7])
    ramp = [2.0 ** (1 + math.log10(v / 0.05)) for v in (0.01, 0.03, 0.045)]
    np.testing.assert_allclose(s.gain(f), [1.0, 1.0, *ramp, 2.0, 2.0, 2.0, 2.0], rtol=1e-12)
    # a band above a higher one: the lower band keeps its own gain up to the next band's lowest bin, then it falls
    s2 = StretchLevels(f_lo_hz=(0.01, 0.05), f_hi_hz=(0.04, 0.5), ratio=(3.0, 2.0), start_s=(0.0, 10.0),
                       stretch_s=100.0, n_stretches=3, edf_min=120.0)
    np.testing.assert_allclose(s2.gain(np.array([0.01, 0.045, 0.05, 0.4])), [3.0, 3.0, 2.0, 2.0])
    grid = np.logspace(-4, 0, 400)
    assert np.all(np.diff(np.log(s.gain(grid))) <= math.log(2.0) * np.diff(np.log10(grid)) + 1e-12)
    assert s.max_gain == 2.0
    assert StretchLevels.from_dict(s.to_dict()) == replace(s, band_stretch_s=(100.0, 100.0))


def test_segments_keep_their_stretches_inside_and_a_short_record_has_no_scan():
    rng = np.random.default_rng(5)
    quiet, noisy = rng.standard_normal(4000), 3.0 * rng.standard_normal(4000)
    s = stretch_levels(None, 1.0, views=[quiet, noisy])
    assert min(s.start_s) >= 4000.0  # the noisiest stretch lies in the second segment
    assert stretch_levels(rng.standard_normal(8 * 8 * 15), 1.0) is None  # a window of 15 samples


def _verdict(dataset, axis, stationary, p, scan):
    return {"dataset": dataset, "axis": axis, "stationary": stationary, "p_value": p, "test": "calibrated",
            "paper": {"stationary": stationary}, "calibrated": {"alpha": 0.05}, "stretches": scan}


def test_the_summary_marks_a_noisiest_stretch_only_beyond_chance():
    scan = stretch_levels(_change(7200, 2 / 3, 2.5, np.random.default_rng(1)), 1.0).to_dict()
    # 3 of 3 axes fail: beyond chance (P = 1.25e-4 < 0.05): every failing kept axis carries its scan
    three = [_verdict("d", a, False, 0.02, scan) for a in "xyz"]
    out = summary_stage(three, "warn", "gyro")
    assert all(c.get("noisiest_stretch") == scan for c in out["curves"])
    # 1 of 6 fails at p 0.02 (> 0.05 / 6): consistent with chance, no scan taken in; at p 0.001 (< 0.05 / 6) it is
    six = [_verdict(d, a, a != "x" or d != "d1", 0.02, scan) for d in ("d1", "d2") for a in "xyz"]
    assert not any(c.get("noisiest_stretch") for c in summary_stage(six, "warn", "gyro")["curves"])
    six[0]["p_value"] = 0.001
    marked = [c for c in summary_stage(six, "warn", "gyro")["curves"] if c.get("noisiest_stretch")]
    assert [(c["dataset"], c["axis"]) for c in marked] == [("d1", "x")]
    # excluded axes are not in the bound: nothing to raise
    assert not any(c.get("noisiest_stretch") for c in summary_stage(three[:2] + [_verdict("d", "q", True, 0.5, scan)],
                                                                      "exclude", "gyro")["curves"])


def test_the_bound_takes_a_raised_copy_and_the_envelope_candidate_steps_aside():
    f = np.linspace(0.0, 0.5, 11)
    scan = StretchLevels(f_lo_hz=(0.1,), f_hi_hz=(0.5,), ratio=(2.5,), start_s=(0.0,), stretch_s=900.0,
                         n_stretches=15, edf_min=120.0)
    curves, edf = {"d/x": np.ones(11), "d/y": np.ones(11)}, {"d/x": 4.0, "d/y": 4.0}
    rec = with_stretches(f, curves, edf, {"d/x": scan.to_dict()})
    new = STRETCH_LABEL.format(dataset="d", axis="x")
    assert list(rec) == [new] and rec[new]["curve"] == "d/x" and rec[new]["max_gain"] == 2.5
    np.testing.assert_allclose(curves[new], scan.gain(f))
    assert np.all(curves[new][f >= 0.1] == 2.5) and curves[new][0] == 1.0  # f = 0: below the ramp
    assert curves[new][1] == pytest.approx(2.5 ** (1 + math.log10(0.5)))  # 0.05 Hz: the ramp below 0.1 Hz
    assert edf[new] == 4.0 and new.rsplit("/", 1)[1] == "x"
    with pytest.raises(ValueError, match="no such curve"):
        with_stretches(f, curves, edf, {"e/x": scan.to_dict()})
    modes, why = candidate_modes({"upper_envelope_kind": "joint"}, stretched=[new])
    assert ENVELOPE_MODE not in modes and "change their noise level" in why


def test_the_pooled_mode_pools_a_datasets_raised_copies_apart_from_the_records():
    from imupipe.stages.bound import _pool_groups

    curves = ["d/x", "d/y", "e/x", "d noisiest stretch/x", "d noisiest stretch/y"]
    stretched = {"d noisiest stretch/x": {}, "d noisiest stretch/y": {}}
    assert _pool_groups(curves, stretched, pooled=True) == ["all", "all", "all", "d noisiest stretch",
                                                             "d noisiest stretch"]
    assert _pool_groups(curves, stretched, pooled=False) == ["x", "y", "x", "d noisiest stretch/x",
                                                              "d noisiest stretch/y"]
    assert _pool_groups(curves[:3], {}, pooled=True) is None


def test_the_stretch_test_sees_a_white_change_the_segment_tests_miss_and_rarely_simulates_a_stationary_record():
    # an outside evaluation: white noise 3x over 8 % of a GM-dominated accelerometer record passed the stationarity
    # test (p 0.11-0.66) while the scan's gains were 3.5-4.1; the stretch test on the axis's own stationary null
    # rejects it at its Monte Carlo floor (0 of 999 null records reach its statistic)
    from imupipe.allan import allan_variance
    from imupipe.models import NoiseModel
    from imupipe.simulate import simulate
    from imupipe.stages.stationarity import stationarity_stage
    from imupipe.stretches import SCREEN, stretch_test

    rng = np.random.default_rng(4711)
    m = NoiseModel(white=0.2, gauss_markov=((0.2, 300.0),))
    x = simulate(m, 7200, 1.0, rng)
    x[3600:4176] += math.sqrt(8) * 0.2 * rng.standard_normal(576)
    av = allan_variance(x, 1.0, taus=8)
    v = stationarity_stage(x, 1.0, dataset="d", sensor="accel", axis="x", allan=(av.tau, av.avar, av.edf), n_sim=199)
    assert v["stretch_test"]["p_value"] == pytest.approx(1 / 1000) and v["stretch_test"]["n_sim"] == 999
    out = summary_stage([v, {**v, "axis": "y", "stretch_test": {"p_value": 0.5}}], "warn", "accel",
                        papers=[{"stationary": True}] * 2)
    marked = [c["axis"] for c in out["curves"] if c.get("noisiest_stretch")]
    assert marked == ["x"] and out["curves"][0]["stretch_test_p"] == pytest.approx(1e-3)
    # stationary records of three shapes: the statistic passes the screen in a few of 100 (its 95th percentile is
    # about 2.8); a record below it is not simulated
    over = sum(stretch_levels(simulate(m, 7200, 1.0, rng), 1.0).statistic >= SCREEN for _ in range(100))
    assert over <= 10
    quiet = simulate(NoiseModel(white=1.0), 7200, 1.0, rng)
    t = stretch_test(quiet, 1.0, NoiseModel(white=1.0), seed=1)
    assert (t["p_value"] is None and t["n_sim"] == 0) or t["p_value"] > 0.01


def test_the_summary_records_which_rule_took_a_curve_in():
    scan = stretch_levels(_change(7200, 2 / 3, 2.5, np.random.default_rng(1)), 1.0).to_dict()
    three = [_verdict("d", a, False, 0.02, scan) for a in "xyz"]
    assert {c["taken_in_by"] for c in summary_stage(three, "warn", "gyro")["curves"]} == {"failures beyond chance"}
    six = [_verdict(d, a, a != "x" or d != "d1", 0.02, scan) for d in ("d1", "d2") for a in "xyz"]
    six[0]["p_value"] = 0.001
    six[1]["stretch_test"] = {"p_value": 0.001}
    by = {(c["dataset"], c["axis"]): c.get("taken_in_by") for c in summary_stage(six, "warn", "gyro")["curves"]}
    assert by[("d1", "x")] == "own p-value" and by[("d1", "y")] == "stretch test" and by[("d2", "z")] is None
