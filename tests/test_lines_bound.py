"""Spectral lines end to end: the bound's line column is the model's narrowband PSD, the policies do what they
say in the bound, and a filter carrying the line is verified against a truth with the line."""

import math
from dataclasses import replace

import numpy as np
import pytest

from imupipe.bound import bound_psd
from imupipe.bound.engine import _line_psd, _line_psd_sampled
from imupipe.lines import find_lines, line_policy
from imupipe.models import NoiseModel, narrowband_psd
from imupipe.simulate import simulate
from imupipe.spectra import decimate, psd
from imupipe.verify import covariance_analysis, reference_scenario, replay


# ---------------------------------------------------------------------------------------------
# 1. one home for the line formula
# ---------------------------------------------------------------------------------------------
def test_line_column_is_the_models_narrowband_psd():
    f = np.linspace(0.0, 0.5, 2001)
    for f0, z in ((0.56, 0.01), (0.12, 0.002), (7.05, 0.05)):
        m = NoiseModel(narrowband=((1.0, f0, z),))
        # the same function (no tolerance: the engine calls the model)
        assert np.array_equal(_line_psd(f, f0, z), narrowband_psd(f, 1.0, f0, z))
        assert np.array_equal(_line_psd_sampled(f, f0, z, 1.0), m.psd_sampled(f, 1.0))
        # and the closed form is the alias sum sum_k S(f + k/dt) sinc^2((f + k/dt) dt): terms fall as k^-6, so
        # |k| <= 2000 leaves a truncation below 1e-15 of the peak; 1e-9 relative allows the sum's rounding
        k = np.arange(-2000, 2001)[:, None]
        fk = f[None, :] + k
        alias = np.sum(narrowband_psd(fk, 1.0, f0, z) * np.sinc(fk) ** 2, axis=0)
        np.testing.assert_allclose(m.psd_sampled(f, 1.0), alias, rtol=1e-9, atol=1e-12 * alias.max())


def test_bound_result_model_carries_the_lines_and_its_margin_uses_them():
    f = np.linspace(0, 0.5, 901)
    N, s_line = 1e-3, 3e-3
    curves = (NoiseModel(white=N, narrowband=((s_line, 0.56, 0.01),)).psd_sampled(f, 1.0))[None, :]
    r = bound_psd(f, curves, NoiseModel(white=N), dt=1.0, keep=("white",), narrowband=((0.56, 0.01),))
    assert r.model.narrowband == ((pytest.approx(s_line, rel=1e-6), 0.56, 0.01),)
    assert r.model.white == pytest.approx(N, rel=1e-6)
    assert r.bounded and r.margin >= 1 - 1e-9
    # the model's own PSD is what the margin was computed from: without its line the margin collapses
    bare = replace(r.model, narrowband=())
    assert np.min(bare.psd_sampled(f[1:], 1.0) / curves[0, 1:]) < 0.1
    # the dict form round-trips
    assert NoiseModel.from_dict(r.model.to_dict()) == r.model


# ---------------------------------------------------------------------------------------------
# 3. the "Must show" on a simulated record
# ---------------------------------------------------------------------------------------------
RATE = 100.0
N_SAMPLES = int(2 * 3600 * RATE)  # 2 h at 100 Hz per axis
TRUTH = NoiseModel(white=1e-3, gauss_markov=((2e-4, 100.0),), random_walk=2e-6)
LINES = ((2e-3, 0.12), (4e-3, 0.56))  # (amplitude u, frequency Hz): 0.12 Hz in band, 0.56 Hz aliases to 0.44 Hz
BAND = (0.0, 0.25)  # application band of the 1 Hz decimated spectrum, Hz
WINDOW_S = 1800.0


@pytest.fixture(scope="module")
def record():
    rng = np.random.default_rng(4)
    noise = simulate(TRUTH, N_SAMPLES, RATE, rng, n_records=3)
    t = np.arange(N_SAMPLES) / RATE
    phase = rng.uniform(0.0, 2 * np.pi, (3, len(LINES)))
    lines = sum(a * np.sin(2 * np.pi * f0 * t[None, :] + phase[:, j:j + 1]) for j, (a, f0) in enumerate(LINES))

    def spectra(y):
        out = []
        for row in y:
            d, _ = decimate(row, RATE, 1.0)
            p = psd(d, 1.0, window_s=WINDOW_S, step_s=WINDOW_S / 2)
            out.append(p["psd"].values)
        return p["frequency"].values, np.array(out)

    f, clean = spectra(noise)
    _, dirty = spectra(noise + lines)
    # detection resolution = the decimated PSD's bin spacing, so that the fixed line shape is no wider than
    # what the decimated spectrum resolves
    found = [find_lines(row, RATE, resolution_hz=1.0 / WINDOW_S, label=f"axis {i}") for i, row in
             enumerate(noise + lines)]
    return f, clean, dirty, found


def test_injected_lines_are_found_within_one_bin_and_10_percent(record):
    *_, found = record
    for res in found:
        assert len(res.lines) == len(LINES), res.label
        for (a, f0), ln in zip(LINES, sorted(res.lines, key=lambda ln: ln.frequency_hz)):
            assert abs(ln.frequency_hz - f0) <= res.resolution_hz
            assert ln.amplitude == pytest.approx(a, rel=0.10)


def _bound(f, curves, pol):
    return bound_psd(f, curves, TRUTH, dt=1.0, mode="smoothed", **pol.bound_kwargs())


def test_each_policy_does_what_it_says_in_the_bound(record):
    f, clean, dirty, found = record
    lines = [ln for res in found for ln in res.lines]
    none = _bound(f, clean, line_policy([], 1.0, BAND, "model", frequency=f))
    keep = _bound(f, dirty, line_policy(lines, 1.0, BAND, "keep", frequency=f))
    model = _bound(f, dirty, line_policy(lines, 1.0, BAND, "model", frequency=f))
    pol_ex = line_policy(lines, 1.0, BAND, "exclude", frequency=f)
    excl = _bound(f, dirty, pol_ex)
    for r in (none, keep, model, excl):
        assert r.bounded
    # keep (the paper): no line column, the broadband terms cover the lines (white noise, or here a GM of
    # T ~ 0.25 s that is white below 0.6 Hz, since the spec's white noise is a floor): inflated far above the
    # line-free bound over the whole upper band, not only at the alias
    assert keep.model.narrowband == ()
    hi = f > BAND[1]
    assert np.min(keep.model.psd_sampled(f[hi], 1.0) / none.model.psd_sampled(f[hi], 1.0)) > 3
    # model: one narrowband column per line at its full-rate frequency, no white-noise inflation for it
    assert sorted(f0 for _, f0, _ in model.model.narrowband) == pytest.approx([f0 for _, f0 in LINES],
                                                                             abs=1.0 / WINDOW_S)
    assert model.details["excluded"] == []
    # exclude: the in-band line is modelled (exclusion refused), the aliased one excluded, its bins listed
    # with the reason, every excluded bin outside the application band
    assert [d["action"] for d in sorted(pol_ex.decisions, key=lambda d: d["f0_hz"])] == ["model", "exclude"]
    assert [f0 for _, f0, _ in excl.model.narrowband] == pytest.approx([0.12], abs=1.0 / WINDOW_S)
    ((lo, hi, reason),) = pol_ex.exclude
    assert lo < 0.44 < hi and hi - lo < 0.02  # the aliased line's interval (main lobe included)
    (ex,) = excl.details["excluded"]
    assert ex["n_bins"] > 0 and "outside the application band" in ex["reason"] and ex["reason"] == reason
    inside = [float(v) for v in f[(f > 0) & (f >= lo) & (f <= hi)]]
    # exactly the bins inside the interval, all out of band (the bands are split at the interval's edges)
    assert ex["bins_hz"] == inside and min(inside) > BAND[1]
    # raw mode (rows are bins): the same bins
    raw = bound_psd(f, dirty, TRUTH, dt=1.0, mode="raw", **pol_ex.bound_kwargs())
    (exr,) = raw.details["excluded"]
    assert exr["bins_hz"] == inside and raw.bounded
    # the excluded bins were dropped from the sample constraints only: the spec is still bounded there
    assert excl.spec_margin >= 1 - 1e-9 and raw.spec_margin >= 1 - 1e-9


def test_model_policy_bound_without_its_line_is_within_10_percent_of_the_lineless_bound(record):
    """Same noise (same seed), the lines added on top: the broadband part of the bound with the lines modelled
    is the bound of the record without them, to the issue's 10 %. Smoothed mode: in raw mode N is set by the
    single highest periodogram ordinate, and the line columns' tails cover a few ordinates next to the lines,
    so N moves by the spread of the top order statistics (measured 12 % on one of five seeds); band averages
    remove that. Measured on seeds 0-4: worst 5.5 % (N), 8 % (T), 2 % (sigma), 0.2 % (K)."""
    f, clean, dirty, found = record
    lines = [ln for res in found for ln in res.lines]
    none = _bound(f, clean, line_policy([], 1.0, BAND, "model", frequency=f)).model
    model = _bound(f, dirty, line_policy(lines, 1.0, BAND, "model", frequency=f)).model
    assert model.white == pytest.approx(none.white, rel=0.10)
    assert model.random_walk == pytest.approx(none.random_walk, rel=0.10)
    assert len(model.gauss_markov) == len(none.gauss_markov) == 1
    (s1, T1), (s0, T0) = model.gauss_markov[0], none.gauss_markov[0]
    assert s1 == pytest.approx(s0, rel=0.10) and T1 == pytest.approx(T0, rel=0.10)


# ---------------------------------------------------------------------------------------------
# 2. verification of a filter with a line
# ---------------------------------------------------------------------------------------------
# A slow, lightly damped oscillation that matters over an outage: 2 mHz, zeta 0.05 (Q = 10), sigma 10x the
# white noise's one-second level: its velocity error sigma / w0 = 0.8 m/s dominates the white noise's
# N sqrt(t) = 0.06 m/s after an hour.
LINE = (1e-3, 2e-3, 0.05)
BASE = NoiseModel(white=1e-4, gauss_markov=((2e-5, 300.0),))


def test_filter_with_the_line_is_verified_against_a_truth_with_the_line():
    sc = reference_scenario("accel", filter_rate_hz=1.0, fix_s=600.0, outage_s=1800.0)
    truth = replace(BASE, narrowband=(LINE,))
    matched = covariance_analysis(truth, truth, sc)
    # matched filter: its P is the true MSE (to the recursions' rounding)
    assert matched.passed and matched.worst_ratio == pytest.approx(1.0, abs=1e-6)
    assert "nb" in matched.details["truth_states"] and "nb_dot" in matched.details["filter_states"]
    # a filter that ignores the line under-states its error
    blind = covariance_analysis(BASE, truth, sc)
    assert not blind.passed and blind.worst_ratio > 2
    # a line of larger variance bounds the true one (same shape: PSD larger at every f): the filter is conservative
    wide = covariance_analysis(replace(BASE, narrowband=((1.5 * LINE[0], LINE[1], LINE[2]),)), truth, sc)
    assert wide.passed and wide.worst_ratio < 1


def test_bound_with_a_line_column_verifies():
    """The bound of the truth's sampled PSD with the line's column exports a filter that passes against the
    truth; the same bound without its line column does not."""
    truth = replace(BASE, narrowband=(LINE,))
    f = np.linspace(0.0, 0.5, 3601)
    r = bound_psd(f, truth.psd_sampled(f, 1.0)[None, :], None, dt=1.0, keep=("white", "gauss_markov"),
                  narrowband=((LINE[1], LINE[2]),))
    assert r.bounded and len(r.model.narrowband) == 1
    sc = reference_scenario("accel", filter_rate_hz=1.0, fix_s=600.0, outage_s=1800.0)
    assert covariance_analysis(r.model, truth, sc).passed
    assert not covariance_analysis(replace(r.model, narrowband=()), truth, sc).passed
    assert math.isfinite(r.model.narrowband[0][0])


def test_a_line_column_is_held_at_the_upper_envelopes_line():
    """A line column is held at least at the upper envelope's term at its frequency (the identified line at the
    upper confidence limit of its power): the records' PSD at the line's estimate, the envelope at 2.5x it (a line
    of few looks). Without the envelope's line the LP sets the column from the records (the estimate, to the LP's
    rounding); with it, the column's variance is the envelope's; a term at another frequency sets no floor."""
    truth = replace(BASE, narrowband=(LINE,))
    f = np.linspace(0.0, 0.5, 3601)
    kw = dict(dt=1.0, keep=("white", "gauss_markov"), narrowband=((LINE[1], LINE[2]),))
    own = bound_psd(f, truth.psd_sampled(f, 1.0)[None, :], None, **kw).model.narrowband[0][0]
    assert own == pytest.approx(LINE[0], rel=0.05)
    high = replace(BASE, narrowband=((math.sqrt(2.5) * LINE[0], LINE[1], LINE[2]),))
    held = bound_psd(f, truth.psd_sampled(f, 1.0)[None, :], None, upper_model=high, **kw).model.narrowband[0][0]
    assert held**2 >= 2.5 * LINE[0] ** 2 * (1 - 1e-9)
    # the floor is the envelope's term within the column's half-power half-width zeta f0 (2 mHz +- 0.1 mHz)
    from imupipe.bound.engine import _line_floors

    near = replace(BASE, narrowband=((2 * LINE[0], 1.04 * LINE[1], LINE[2]),))
    far = replace(BASE, narrowband=((2 * LINE[0], 1.06 * LINE[1], LINE[2]),))
    assert _line_floors(((LINE[1], LINE[2]),), near) == pytest.approx((4 * LINE[0] ** 2,))
    assert _line_floors(((LINE[1], LINE[2]),), far) == (0.0,) and _line_floors(((LINE[1], LINE[2]),), None) == (0.0,)


def test_three_axes_with_a_low_band_line_on_one_are_bounded_with_the_line_at_its_limit():
    """An outside evaluation's case: x and z line-free, y with a 0.03 Hz line (1e-4 rad/s, damping 1e-3), one 5 h
    record at 20 Hz, the low band searched at 1/window_s, auto with the joint envelope. The line's power limit from
    four segments' looks is about 2x its estimate; every candidate carried the estimate and failed its verification
    against the envelope in the fixes (MSE/P 1.17: NOT BOUNDED) while bounding the truth. Now each candidate's line
    is at least the envelope's (at it where the sample spectra ask for less): BOUNDED, and against the truth of the
    line's axis the exported filter's worst MSE/P <= 1."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from exact_kf import kf_against_truth

    from imupipe.api import noise_model
    from imupipe.defaults import psd_window_step

    d = math.pi / 180
    bb = dict(white=0.25 / 60 * d, gauss_markov=((2 / 3600 * d, 600.0),), random_walk=0.03 / 3600 * d)
    plain, lined = NoiseModel(**bb), NoiseModel(**bb, narrowband=((1e-4, 0.03, 1e-3),))
    rng, n = np.random.default_rng(22), 5 * 3600 * 20
    curves = {"d/x": simulate(plain, n, 20.0, rng=rng), "d/y": simulate(lined, n, 20.0, rng=rng),
              "d/z": simulate(plain, n, 20.0, rng=rng)}
    window, _ = psd_window_step(5 * 3600.0, 1.0)
    spec = Path(__file__).resolve().parents[1] / "config" / "specs" / "stim300.yaml"
    res = noise_model(curves, 20.0, "gyro", spec, mode="auto",
                      envelope="joint", lines_policy="model", lines_scales=(1, 8, 64),
                      lines_low_band_resolution_hz=1.0 / window, outage_s=3600.0, fix_s=600.0)
    assert res.bounded, res.contract.get("failed_checks")
    (line,) = res.records["identify"]["upper_envelope_model"]["narrowband"]
    assert abs(line["f0_hz"] - 0.03) < 1e-3 and any(s >= line["sigma"] * (1 - 1e-12) and abs(f - line["f0_hz"]) < 1e-9
                                                      for s, f, _ in res.bound.model.narrowband)
    assert kf_against_truth(res.kf, lined, "gyro", 600.0, 3600.0)["worst"] <= 1.0


def test_replay_of_simulated_records_with_a_line_matches_the_exact_mse():
    """Independent route: records simulated at 10 Hz by the exact oscillator recursion (imupipe.simulate), block
    averaged by the replay to the 1 Hz filter, against the covariance analysis of the continuous line states
    integrated into velocity (Van Loan). n_eff = 8 x 24000 / 1200 = 160 windows: relative SE sqrt(2/160) = 0.11 of
    each step's MSE; the mean ratio over the outage is checked to 3 SE (conservative: steps are correlated, so
    their mean varies less than one step's). The same records against the filter without the line fail."""
    truth = replace(BASE, narrowband=(LINE,))
    sc = reference_scenario("accel", filter_rate_hz=1.0, fix_s=300.0, outage_s=900.0)
    rec = simulate(truth, 24000 * 10, 10.0, rng=np.random.default_rng(11), n_records=8)
    r = replay(truth, list(rec), 10.0, sc)
    exact = covariance_analysis(truth, truth, sc)
    assert r.details["n_eff"] == pytest.approx(160.0)
    out = slice(sc.n_fix, None)
    assert np.mean(r.mse[out] / exact.mse[out]) == pytest.approx(1.0, abs=3 * r.details["relative_standard_error"])
    assert r.passed
    assert not replay(BASE, list(rec), 10.0, sc).passed


def test_process_looks_is_one_draw_only_for_an_unresolved_line_whose_amplitude_does_not_wander():
    from imupipe.lines import process_looks

    assert process_looks(14.0, 14, 0.002, 0.002) == 1.0  # no bin wider, no wander: one draw
    assert process_looks(5.0, 14, 0.002, 0.002) == 5.0  # wanders over 14 segments: its measured looks
    assert process_looks(2.35, 4, 2.78e-4, 2.78e-4) == 1.0  # 4 segments (the low band's): their looks say little
    assert process_looks(14.0, 14, 0.01, 0.002) == 14.0  # resolved: coherence 1/(pi Gamma) under a segment


@pytest.mark.slow
def test_a_detected_line_coherent_beyond_the_record_is_held_at_one_draw_of_its_amplitude():
    """An outside evaluation's case: an accelerometer (white 0.05 m/s/sqrt(h), GM 0.05 mg at 800 s, K 1.25e-6
    m/s^2/sqrt(s)) with a 0.01 Hz line of damping 1e-3 (sd 3.32e-3 m/s^2, coherence time 15 900 s), one 4 h record at
    20 Hz (seed 126), the low band at 1/3600 Hz. The record's line came out at 0.39x its sd with no measurable wander
    over the 4 segments; its K = 4 looks gave an upper limit at 0.95 under the truth, and the filter on the bound
    under-stated its error in the fixes (MSE/P 1.156, the evaluation's analysis and tests/exact_kf.py alike). One draw
    of the amplitude (nu = 2): the envelope holds the line at 19.5x its power and the exported filter bounds the truth
    (0.999998; mean P/MSE over the outage 2.29 -> 2.34)."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from exact_kf import kf_against_truth

    from imupipe.api import noise_model
    from imupipe.defaults import psd_window_step

    truth = NoiseModel(white=0.05 / 60, gauss_markov=((0.05e-3 * 9.80665, 800.0),), random_walk=1.25e-6,
                       narrowband=((0.00332, 0.01, 1e-3),))
    rate, n = 20.0, int(4 * 3600 * 20.0)
    x = simulate(truth, n, rate, rng=np.random.default_rng(126)) + 9.80665
    window, _ = psd_window_step(4 * 3600.0)
    spec = Path(__file__).resolve().parents[1] / "config" / "specs" / "stim300.yaml"
    res = noise_model({"rec0/x": x}, rate, "accel", spec, mode="auto", envelope="joint", lines_policy="model",
                      lines_scales=(1, 8, 64), lines_low_band_resolution_hz=1.0 / window, outage_s=3600.0, fix_s=600.0)
    (line,) = [ln for ln in res.records["identify"]["upper_envelope_model"]["narrowband"] if abs(ln["f0_hz"] - 0.01)
               < 1e-3]
    assert line["sigma"] > 0.00332  # the one-draw limit lies above the truth (the K-look one: 0.67x it)
    assert res.bounded
    assert kf_against_truth(res.kf, truth, "accel", 600.0, 3600.0)["worst"] <= 1.0
