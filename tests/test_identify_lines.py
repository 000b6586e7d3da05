"""The lines stage's lines as a known term of the Allan fit (imupipe.lines.line_avar, fit_allan(known_avar=)).

Simulated truth: white noise + a first-order GM + a 0.5 Hz line amplitude-modulated at 0.1 Hz (the carrier and
its +/-0.1 Hz sidebands) and a 3rd harmonic, as on the ADIS16405 accelerometer.
"""

import math

import numpy as np
import pytest

from imupipe.allan import allan_variance, overlapping_avar
from imupipe.identify import fit_allan
from imupipe.lines import Line, find_lines, line_avar, lines_by_curve
from imupipe.models import NoiseModel
from imupipe.simulate import simulate

RATE = 10.0  # Hz
N = int(6 * 3600 * RATE)  # a 6 h record
TRUTH = NoiseModel(white=2e-3, gauss_markov=((1e-3, 30.0),), dt=1.0 / RATE)  # u/sqrt(Hz), (u, s)
A, F0, DEPTH, F_MOD, A3 = 3e-3, 0.5, 0.6, 0.1, 0.9e-3  # carrier u, Hz, modulation depth, Hz, harmonic u
# the lines of the truth: (frequency Hz, amplitude u); an AM carrier A (1 + m cos) has sidebands of A m / 2
TRUE_LINES = ((F0 - F_MOD, A * DEPTH / 2), (F0, A), (F0 + F_MOD, A * DEPTH / 2), (3 * F0, A3))


def _record(seed):
    x = simulate(TRUTH, N, RATE, np.random.default_rng(seed))
    t = np.arange(N) / RATE
    return (x + A * (1 + DEPTH * np.cos(2 * np.pi * F_MOD * t)) * np.sin(2 * np.pi * F0 * t)
            + A3 * np.sin(2 * np.pi * 3 * F0 * t + 1.0))


def _fit(x, known):
    av = allan_variance(x, rate=RATE, taus="octave")
    ok = np.isfinite(av["avar"].values) & np.isfinite(av["edf"].values)
    tau, avar, edf = av["tau"].values[ok], av["avar"].values[ok], av["edf"].values[ok]
    kn = None if known is None else line_avar(tau, known)
    return fit_allan(tau, avar, edf, components=("white", "gauss_markov"), n_gm=1, n_boot=100, rng=3,
                     record_rate_hz=RATE, n_samples=N, dt=1.0 / RATE, known_avar=kn)


@pytest.mark.parametrize("f0", [0.5, 0.37])
def test_line_avar_is_a_sinusoids_measured_allan_variance(f0):
    # A sinusoid of amplitude Am at f0: AVAR = Am^2 sin^4(pi f0 tau) / (pi f0 tau)^2. The project's line model (the
    # narrowband oscillator) equals it up to O(zeta w0 tau) (the envelope's decay over 3 tau, and the oscillator's
    # low-frequency tail 4 zeta sigma^2 / (w0 tau)): with zeta = 1e-4 and tau <= 3.3 s both are below 0.3 % of the
    # sinusoid's AV where it is not near a zero (taus where sin^4 >= 0.05). The measured overlapping AV of a 3 h
    # record is the closed form to the end effects of about one period over 1e6 samples; 1 % covers both.
    rate, n, am = 100.0, int(3 * 3600 * 100), 1e-3
    x = am * np.sin(2 * np.pi * f0 * np.arange(n) / rate + 0.3)
    for m in (10, 30, 70, 100, 150, 330):
        tau = m / rate
        s4 = math.sin(math.pi * f0 * tau) ** 4
        if s4 < 0.05:
            continue
        closed = am**2 * s4 / (math.pi * f0 * tau) ** 2
        measured = overlapping_avar(x, rate, m)
        model = line_avar([tau], [(am / math.sqrt(2.0), f0, 1e-4)])[0]
        assert measured == pytest.approx(closed, rel=1e-2)
        assert model == pytest.approx(closed, rel=1e-2)


def test_line_avar_of_a_line_near_nyquist_is_its_samples_allan_variance():
    # Samples of a sinusoid (power P = Am^2/2) every delta: the mean of m of them has the gain
    # sin(pi f0 m delta) / (m sin(pi f0 delta)), so AVAR(m delta) = 2 P sin^4(pi f0 m delta) / (m sin(pi f0 delta))^2,
    # 1 / sinc^2(f0 delta) times the continuous formula (1.58x at 7.3 Hz in 20 Hz samples). The Line's model term
    # (sigma / block_gain) gives it; without the rate (gain 1) the line's AV is 0.63x its samples'. 1 %: the measured
    # AV's end effects (one period over 4e5 samples) and the oscillator's O(zeta w0 tau) at zeta = 1e-6.
    rate, n, am, f0 = 20.0, 400_000, 1e-3, 7.3
    x = am * np.sin(2 * np.pi * f0 * np.arange(n) / rate + 0.3)
    power = am**2 / 2.0
    kw = dict(frequency_hz=f0, power=power, amplitude=am, sigma=math.sqrt(power), width_hz=2e-5, zeta=1e-6,
              peak_ratio=1e3, f_lo_hz=7.29, f_hi_hz=7.31, resolution_hz=0.002)
    line, bare = Line(**kw, rate_hz=rate), Line(**kw)
    assert line.block_gain == pytest.approx(abs(math.sin(math.pi * f0 / rate) / (math.pi * f0 / rate)), rel=1e-12)
    for m in (1, 2, 3, 5, 7, 11):
        s4 = math.sin(math.pi * f0 * m / rate) ** 4
        if s4 < 0.05:
            continue
        closed = 2.0 * power * s4 / (m * math.sin(math.pi * f0 / rate)) ** 2
        assert overlapping_avar(x, rate, m) == pytest.approx(closed, rel=1e-2)
        assert line_avar([m / rate], [line])[0] == pytest.approx(closed, rel=1e-2)
        assert line_avar([m / rate], [bare])[0] == pytest.approx(closed * line.block_gain**2, rel=1e-2)


def test_line_avar_of_lines_adds_and_accepts_line_objects():
    tau = np.array([0.3, 1.0, 3.0])
    a = (1e-3, 0.5, 0.01)
    b = (5e-4, 1.5, 0.003)
    ln = Line(frequency_hz=0.5, power=1e-6, amplitude=math.sqrt(2e-6), sigma=1e-3, width_hz=0.01, zeta=0.01,
              peak_ratio=100.0, f_lo_hz=0.49, f_hi_hz=0.51, resolution_hz=0.01)
    np.testing.assert_allclose(line_avar(tau, [a, b]), line_avar(tau, [a]) + line_avar(tau, [b]), rtol=1e-14)
    np.testing.assert_allclose(line_avar(tau, [ln]), line_avar(tau, [a]), rtol=1e-14)
    assert np.all(line_avar(tau, []) == 0)


def test_lines_by_curve_keys_by_dataset_and_axis_and_keep_policy_knows_none():
    ln = {"frequency_hz": 0.5, "power": 1e-6, "amplitude": 1.4e-3, "sigma": 1e-3, "width_hz": 0.01, "zeta": 0.01,
          "peak_ratio": 100.0, "f_lo_hz": 0.49, "f_hi_hz": 0.51, "resolution_hz": 0.01}
    docs = {"lines/imu1/accel/x.yaml": {"dataset": "imu1", "sensor": "accel", "axis": "x", "lines": [ln]},
            "lines/imu1/accel/y.yaml": {"dataset": "imu1", "sensor": "accel", "axis": "y", "lines": []}}
    out = lines_by_curve(docs, "model")
    assert set(out) == {"imu1/x", "imu1/y"} and len(out["imu1/x"]) == 1 and out["imu1/y"] == ()
    assert lines_by_curve(docs, "keep") == {}
    assert lines_by_curve({"lab1/x": {"lines": [ln]}}, "exclude") == {"lab1/x": out["imu1/x"]}
    with pytest.raises(ValueError, match="lines"):
        lines_by_curve({"f.yaml": {"n_lines": 0}}, "model")


@pytest.fixture(scope="module")
def line_record():
    x = _record(1)
    return x, find_lines(x, RATE, resolution_hz=0.005)


def test_lines_found_with_amplitudes_within_10_percent(line_record):
    _, search = line_record
    found = {round(ln.frequency_hz, 1): ln.amplitude for ln in search.lines}
    for f, amp in TRUE_LINES:
        assert round(f, 1) in found, f"line at {f} Hz not found: {sorted(found)}"
        assert found[round(f, 1)] == pytest.approx(amp, rel=0.10)


def test_fit_with_known_lines_covers_the_gm_and_without_absorbs_the_line(line_record):
    x, search = line_record
    known = _fit(x, search.lines)
    # with the lines known: the GM's and the white noise's 95 % intervals cover the truth (fixed seed; each misses
    # in 5 % of records) and the model describes the data (p above the adequacy level 0.01)
    for name, true in (("white", TRUTH.white), ("gm_sigma_1", 1e-3), ("gm_T_1", 30.0)):
        lo, hi = known.intervals[name]
        assert lo <= true <= hi, (name, lo, hi)
    assert known.adequacy["adequate"], known.adequacy
    assert known.known.size and np.max(known.known) > 0
    # the fitted model holds the fitted components only (the line stays the lines stage's / the bound's term)
    assert not known.model.narrowband
    # without them the GM stands in for the line: T near the line's period, the truth outside T's interval, and
    # the fit rejected
    blind = _fit(x, None)
    lo, hi = blind.intervals["gm_T_1"]
    assert not lo <= 30.0 <= hi, (lo, hi)
    assert blind.params["gm_T_1"] < 5.0
    assert not blind.adequacy["adequate"]
    assert blind.adequacy["chi2_per_dof"] > 10 * known.adequacy["chi2_per_dof"]


def test_known_none_is_the_fit_without_it():
    rng = np.random.default_rng(5)
    x = simulate(TRUTH, 2**16, RATE, rng)
    av = allan_variance(x, rate=RATE, taus="octave")
    ok = np.isfinite(av["avar"].values) & np.isfinite(av["edf"].values)
    args = (av["tau"].values[ok], av["avar"].values[ok], av["edf"].values[ok])
    kw = dict(components=("white", "gauss_markov"), n_gm=1, n_boot=20, rng=1, record_rate_hz=RATE, n_samples=2**16)
    a = fit_allan(*args, **kw)
    b = fit_allan(*args, known_avar=np.zeros(int(ok.sum())), **kw)
    assert a.params["white"] == pytest.approx(b.params["white"], rel=1e-9)
    assert a.intervals["gm_T_1"] == pytest.approx(b.intervals["gm_T_1"], rel=1e-6)
    with pytest.raises(ValueError, match="known"):
        fit_allan(*args, known_avar=np.zeros(3), **kw)


def test_identification_stage_takes_the_lines_files_lines_as_known_terms():
    # two 2 h records with the line on axis x: the stage's fits know each curve's lines (keyed dataset/axis), the
    # identify record says which and how much of the AV they carry, and chi2/dof falls with them
    from imupipe.stages.identify import Curve, identify_sensor

    n = int(2 * 3600 * RATE)
    curves, lines = [], {}
    for i, seed in enumerate((11, 12)):
        x = _record(seed)[:n]
        av = allan_variance(x, rate=RATE, taus="octave")
        ok = np.isfinite(av["avar"].values) & np.isfinite(av["edf"].values)
        curves.append(Curve(f"rec{i}/x", av["tau"].values[ok], av["avar"].values[ok], av["edf"].values[ok], n, RATE,
                            "x"))
        lines[f"rec{i}/x"] = find_lines(x, RATE, resolution_hz=0.005).lines
    kw = dict(sensor="accel", components=["white", "gauss_markov", "random_walk"], n_gm=1, n_boot=20,
              confidence=0.95, significance=0.05, relevance=0.05, filter_rate_hz=RATE, outage_s=600.0,
              pooling_n_boot=19)
    rec = identify_sensor(curves, lines=lines, envelope_lines=True, **kw).record
    assert set(rec["lines_known"]) == {"rec0/x", "rec1/x"}
    assert any(abs(ln["f0_hz"] - F0) < 0.01 for ln in rec["lines_known"]["rec0/x"]["lines"])
    assert rec["lines_known"]["rec0/x"]["max_avar_share"] > 0.3
    al = rec["adequacy_lines"]
    assert al["per_axis"]["x"]["after"]["chi2_per_dof"] < 0.2 * al["per_axis"]["x"]["before"]["chi2_per_dof"]
    # the GM is the truth's (30 s), not the line's (about 1 s); the model has no line term (the bound adds it)
    T = rec["model_selected"]["gauss_markov"][0]["T"]
    assert 10.0 < T < 100.0, T
    # the envelope the bound covers and the verification runs against holds the lines as lines (merged as the bound
    # merges them), not as a GM
    nb = rec["upper_envelope_model"]["narrowband"]
    assert any(abs(t["f0_hz"] - F0) < 0.01 for t in nb)
    assert all(g["T"] > 10.0 for g in rec["upper_envelope_model"]["gauss_markov"])
    no_env = identify_sensor(curves, lines=lines, **kw).record  # the default: off
    assert "narrowband" not in no_env["upper_envelope_model"]
    # the workflow's: only the lines below the decimated Nyquist frequency (an aliased line would inflate the bound)
    above = identify_sensor(curves, lines=lines, envelope_lines=True, envelope_lines_below_hz=0.5 * F0, **kw).record
    assert "narrowband" not in above["upper_envelope_model"]
    assert rec["record_consistency"]["flagged"] == []
    # without the lines the stage's GM takes the line
    blind = identify_sensor(curves, **kw).record
    assert blind["adequacy_lines"] is None and "lines_known" not in blind
    # (a GM of T < 5 s, or, where its T is not one the records resolve, re-assigned to the white noise it acts as)
    gms = blind["model_selected"]["gauss_markov"]
    assert (gms and gms[0]["T"] < 5.0) or blind["gm_reassigned"], (gms, blind["gm_reassigned"])


def test_the_envelope_holds_each_line_at_the_upper_confidence_limit_of_its_power():
    """An outside evaluation's 150 deg/h line (0.3 Hz, damping 0.002; two 2 h records) was estimated at 141 deg/h,
    the envelope carried the estimate, and a filter on the bound under-stated its error in the first step (MSE/P
    1.003). The envelope now takes each line at P1 nu / chi2_nu(1 - c), nu = 2 K max(1, Gamma / df) (one complex
    Fourier coefficient per segment for a line narrower than a bin), and the merged line at its largest power and
    fewest degrees of freedom (an upper limit at least every member's)."""
    from scipy.stats import chi2

    from imupipe.lines import Line, merge_lines
    from imupipe.stages.identify import _with_lines

    def line(p, dof, f=0.3):
        return Line(frequency_hz=f, power=p, amplitude=math.sqrt(2 * p), sigma=math.sqrt(p), width_hz=0.002,
                    zeta=0.002 / 0.6, peak_ratio=500.0, f_lo_hz=f - 0.01, f_hi_hz=f + 0.01, resolution_hz=0.002,
                    dof=dof)

    env = {"white": 1e-5, "gauss_markov": [], "random_walk": 0.0}
    out = _with_lines(env, {"a/z": [line(4.0e-7, 28.0)], "b/z": [line(4.6e-7, 56.0)]}, confidence=0.95)
    (term,) = out["narrowband"]
    assert term["sigma"] ** 2 == pytest.approx(4.6e-7 * 28.0 / chi2.ppf(0.05, 28.0), rel=1e-12)
    assert merge_lines([line(4.0e-7, 28.0), line(4.6e-7, 56.0)])[0].dof == 28.0
    # a lines file written before the degrees of freedom were recorded: the estimate, as before
    assert _with_lines(env, {"a/z": [line(4.0e-7, None)]})["narrowband"][0]["sigma"] == pytest.approx(math.sqrt(4e-7))


def test_the_line_power_upper_limit_covers_a_simulated_damped_line():
    """Coverage by simulation of the upper limit above: the evaluation's line (150 deg/h at 0.3 Hz, damping 0.002,
    white 0.1 deg/sqrt(h); one 2 h record at 20 Hz, resolution 0.002 Hz: K = 14 segments, nu <= 28) in 40 records of
    their own seeds; the limit at 0.95 must cover the true power in at least 34 of 40 (P(X <= 33 | 40, 0.95) = 0.014)
    and the power estimate must be unbiased to within its spread (median power / truth in [0.8, 1.2])."""
    from scipy.stats import chi2

    from imupipe.lines import find_lines
    from imupipe.models import NoiseModel
    from imupipe.simulate import simulate

    d = math.pi / 180 / 3600
    s, f0, rate = 150 * d, 0.3, 20.0
    m = NoiseModel(white=0.1 * math.pi / 180 / 60, narrowband=((s, f0, 0.002),))
    rng = np.random.default_rng(2718)
    covered, ratios = 0, []
    for _ in range(40):
        res = find_lines(simulate(m, int(2 * 3600 * rate), rate, rng=rng), rate, resolution_hz=0.002)
        ln = max((x for x in res.lines if abs(x.frequency_hz - f0) < 0.02), key=lambda x: x.power)
        # 2 per independent look, at most 2K = 28 (imupipe.lines.line_looks: about K looks at this damping)
        assert ln.dof == pytest.approx(2 * ln.independent_segments) and ln.dof <= 28.0
        covered += ln.power * ln.dof / chi2.ppf(0.05, ln.dof) >= s * s
        ratios.append(ln.power / s**2)
    assert covered >= 34, covered
    assert 0.8 <= float(np.median(ratios)) <= 1.2


def test_the_known_terms_scale_interval_is_each_lines_power_interval():
    """scale_interval: [nu / chi2_nu(c), nu / chi2_nu(1 - c)] of P / P_hat, the common part over the lines. With
    nu = 2 the chi-square quantile is closed-form, chi2_2(q) = -2 ln(1 - q): [-1 / ln(1 - c), -1 / ln c]."""
    from imupipe.identify.known import scale_interval

    c = 0.95
    lo, hi = scale_interval([2.0], c)
    assert lo == pytest.approx(-1.0 / math.log(1.0 - c), rel=1e-12)
    assert hi == pytest.approx(-1.0 / math.log(c), rel=1e-12)
    lo2, hi2 = scale_interval([2.0, 50.0], c)  # the narrower line's interval inside the wider one's
    assert lo < lo2 < 1.0 < hi2 < hi
    assert scale_interval([2.0, None], c) == (1.0, 1.0)  # a line without degrees of freedom: no calibration


def _exact_curve(tau, s_line, known_scale):
    """The exact AV of white noise plus a damped 0.04 Hz line (the data, with edf of a 4 h record at 20 Hz), and
    the line's AV times `known_scale` as the known term."""
    from imupipe.models import narrowband_avar

    white = 8.7e-5  # u/sqrt(Hz)
    line = narrowband_avar(tau, s_line, 0.04, 5e-3)
    y = white**2 / tau + line
    edf = np.maximum(4.0, 288000.0 * 0.05 / tau / 1.5)  # about n / m for white noise, floored at the long taus
    return y, edf, known_scale * line


def test_a_known_term_below_the_lines_allan_variance_is_calibrated_and_a_weak_one_is_not():
    """A damped line's power from a few looks of the PSD is uncertain by tens of per cent; where its Allan
    variance dominates, a known term 0.7x the line's leaves a residual the broadband columns cannot fit. On exact
    AVs the calibration finds the scale that restores the line (1 / 0.7, within its interval at nu = 11) and the
    fit statistic falls to ~0; a line whose AV is a 1e-6 share of the data keeps its PSD estimate (scale 1: the
    fit cannot see it)."""
    from imupipe.identify.known import calibrated_known

    tau = 0.05 * 2.0 ** np.arange(17)
    kw = dict(components=("white", "gauss_markov", "random_walk"), n_gm=1, T_grid=np.geomspace(0.1, 1000.0, 25),
              confidence=0.95)
    y, edf, known = _exact_curve(tau, 1e-3, 0.7)
    (scaled,), (rec,) = calibrated_known([tau], [y], [edf], [known], [[11.0]], **kw)
    assert rec["calibrated"] and rec["scale"] == pytest.approx(1.0 / 0.7, rel=1e-3) and not rec["at_interval_end"]
    assert rec["chi2_scaled"] < 1e-3 * rec["chi2_unscaled"]
    assert np.allclose(scaled, known / 0.7, rtol=1e-3)
    y, edf, known = _exact_curve(tau, 1e-7, 0.7)
    (scaled,), (rec,) = calibrated_known([tau], [y], [edf], [known], [[11.0]], **kw)
    assert not rec["calibrated"] and rec["scale"] == 1.0 and np.array_equal(scaled, known)
    # a known term at a tenth of the line: the scale stops at its interval's end (nu = 11: 2.87) and says so
    y, edf, known = _exact_curve(tau, 1e-3, 0.1)
    (_,), (rec,) = calibrated_known([tau], [y], [edf], [known], [[11.0]], **kw)
    assert rec["calibrated"] and rec["at_interval_end"] and rec["scale"] == pytest.approx(rec["interval"][1])
    # a curve without a line has no record and its zeros pass through
    (z,), (none,) = calibrated_known([tau], [y], [edf], [np.zeros_like(tau)], [[]], **kw)
    assert none is None and not np.any(z)


@pytest.mark.slow
def test_a_damped_line_whose_psd_power_is_low_no_longer_turns_into_a_random_walk():
    """An outside evaluation's case: a 0.04 Hz line of damping 5e-3 (sd 1e-3 rad/s) over white noise, a 600 s GM
    and a random walk of 0.04 (deg/h)/sqrt(s), one 4 h record at 20 Hz (seed 12), lines searched with the low band
    at 1/3600 Hz. The line's PSD power came out 0.65x its Allan variance's; with it as a fixed known term the full
    fit was rejected (chi2/dof 118) and the selected model was a random walk 810x the truth's (the exported filter's
    mean P/MSE over the outage 485). Calibrated, the fit is adequate and the selected model has no random walk
    above 10x the truth's."""
    from imupipe.api import noise_model
    from imupipe.specsheet import parse_spec

    d = math.pi / 180
    truth = NoiseModel(white=0.3 / 60 * d, gauss_markov=((3 / 3600 * d, 600.0),), random_walk=0.04 / 3600 * d,
                       narrowband=((1e-3, 0.04, 5e-3),))
    rate = 20.0
    x = simulate(truth, int(4 * 3600 * rate), rate, rng=np.random.default_rng(12))
    spec = parse_spec({"name": "truth halved", "gyro": {
        "white": {"value": 0.15, "unit": "deg/sqrt(h)"},
        "gauss_markov": [{"sigma": {"value": 1.5, "unit": "deg/h"}, "T": {"value": 600.0, "unit": "s"}}],
        "random_walk": {"value": 0.02, "unit": "(deg/h)/sqrt(s)"}}})
    res = noise_model({"d0/x": x}, rate, "gyro", spec, outage_s=3600.0, fix_s=600.0, n_gm=1, mode="auto",
                      envelope="joint", lines_policy="model", lines_resolution_hz=0.002,
                      lines_low_band_resolution_hz=1.0 / 3600.0)
    scale = res.records["identify"]["lines_known"]["d0/x"]["av_scale"]
    assert scale["calibrated"] and 1.0 < scale["scale"] <= scale["interval"][1]
    assert res.fit.chi2 / res.fit.dof < 5.0
    assert res.selected.model.random_walk < 10.0 * truth.random_walk
    assert res.bounded
