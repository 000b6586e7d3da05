"""The cap of a Gauss-Markov term of the upper envelope by the recorded Allan variances (issue 28):
:func:`imupipe.bound.allan_check.gm_sigma_cap` and :func:`imupipe.bound.allan_check.cap_gm_terms`."""

import math

import numpy as np
import pytest
from scipy.stats import binom

from imupipe.bound import upper_envelope
from imupipe.bound.allan_check import (SHORT_T_WHITE_FACTOR, cap_gm_terms, gm_bank_envelope, gm_sigma_cap,
                                      split_gm_box)
from imupipe.models import NoiseModel, gm_avar


def _gm_psd(f, sigma, T):
    """Two-sided PSD of a GM (sigma u, T s) at f Hz, u^2/Hz (imupipe.models convention)."""
    w = 2.0 * np.pi * np.asarray(f)
    return 2.0 * sigma**2 * T / (1.0 + (w * T) ** 2)


def _curve(model, tau, edf):
    return (tau, np.asarray(model.avar(tau), dtype=float), np.full_like(tau, float(edf)))


def test_the_two_properties_of_the_gm_allan_variance_the_cap_rests_on():
    """h(x) = AV/sigma^2 at x = tau/T is unimodal (peak 0.6174^2 near x = 1.893; gm_avar's docstring), so over a T
    range g(tau, T) >= the smaller of its values at the ends; and T g(tau, T) is non-decreasing in T (the open upper
    end's argument). Checked on dense grids, to the closed form's relative accuracy (1e-15, 1e-12 allowed)."""
    x = np.logspace(-6, 6, 20001)
    h = gm_avar(x, 1.0, 1.0)
    d = np.diff(h)
    k = int(np.argmax(h))
    assert np.all(d[:k] > -1e-12 * h[1:k + 1]) and np.all(d[k:] < 1e-12 * h[k:-1])
    assert x[k] == pytest.approx(1.893, rel=2e-3) and math.sqrt(h[k]) == pytest.approx(0.6174, rel=1e-3)
    # T g(tau, T) = tau h(x)/x with x = tau/T: non-decreasing in T iff h(x)/x is non-increasing in x
    r = h / x
    assert np.all(np.diff(r) <= 1e-12 * r[:-1])


def test_the_cap_at_the_truths_T_is_its_sigma_when_the_curve_is_exact():
    """A curve equal to a GM's AV (sigma 2e-3, T 50 s) plus white noise, with huge edf (upper limit -> the AV
    itself): the cap at T = 50 s is sigma to within the limit's factor 1 + z sqrt(2/edf) (z < 6 at the Bonferroni
    level here: 1 + 6 * 4.5e-5 < 1.001) and never below it; a range's cap is at least the largest pointwise cap in
    it (the closed-form bound of the sup) and an open range gives inf."""
    tau = np.logspace(-1, 3.5, 40)
    truth = NoiseModel(white=1e-4, gauss_markov=((2e-3, 50.0),))
    cur = [_curve(truth, tau, 1e9)]
    c = gm_sigma_cap(cur, 50.0, confidence=0.95)
    assert 2e-3 <= c <= 2e-3 * 1.001
    Ts = np.logspace(math.log10(20.0), math.log10(200.0), 200)
    pointwise = max(gm_sigma_cap(cur, t) for t in Ts)
    assert gm_sigma_cap(cur, 20.0, 200.0) >= pointwise * (1 - 1e-12)
    assert gm_sigma_cap(cur, 20.0, math.inf) == math.inf
    # several curves: the largest per-curve cap (the envelope covers each)
    cur2 = cur + [_curve(NoiseModel(white=1e-4, gauss_markov=((4e-3, 50.0),)), tau, 1e9)]
    assert gm_sigma_cap(cur2, 50.0) == pytest.approx(2 * c, rel=1e-3)
    with pytest.raises(ValueError, match="T_lo"):
        gm_sigma_cap(cur, 0.0)


@pytest.mark.parametrize("upper_open", [False, True])
def test_capped_terms_dominate_every_gm_the_data_allow(upper_open):
    """Integrity of the construction: with the cap of a curve (a GM + white + random walk AV, edf 30), the capped
    terms' PSD is at least that of every GM (min(sigma_up, sigma_max(T')), T') of the box, T' on a dense grid (50
    per decade; beyond the box's top end up to 1000 c when it is open above), at every f >= 1/c (open) or every f
    (closed); and below the uncapped terms somewhere (the cap removes something)."""
    tau = np.logspace(-1, 3.3, 35)
    cur = [_curve(NoiseModel(white=2e-4, gauss_markov=((1e-3, 30.0),), random_walk=1e-6), tau, 30.0)]

    def cap(lo, hi):
        return gm_sigma_cap(cur, lo, hi, confidence=0.95)

    s_up, a, c = 5e-3, 0.05, 600.0
    terms = split_gm_box(s_up, a, c)
    capped = cap_gm_terms(terms, s_up, a, c, upper_open, cap)
    env, env0 = NoiseModel(gauss_markov=capped), NoiseModel(gauss_markov=terms)
    f = np.logspace(math.log10(1.0 / c if upper_open else 1e-6), 2, 400)
    s_env = env.psd(f)
    Tp = np.logspace(math.log10(a), math.log10(c * (1000.0 if upper_open else 1.0)), 50 * 8)
    for t in Tp:
        sig = min(s_up, gm_sigma_cap(cur, t))
        assert np.all(s_env >= _gm_psd(f, sig, t) * (1 - 1e-12)), t
    assert np.all(s_env <= env0.psd(f) * (1 + 1e-12)) and np.any(s_env < 0.5 * env0.psd(f))


@pytest.mark.parametrize("capped", [False, True])
def test_the_bank_of_an_open_box_dominates_every_gm_the_data_allow(capped):
    """Integrity of the bank (gm_bank_envelope) of a box open at both ends, [a, c] = [0.05, 600] s, horizon 1200 s:
    bank + the white noise kappa sigma_up^2 a lie above every GM (min(sigma_up, sigma_max(T')), T') for T' in [a, c]
    at every f (1e-8 .. 1e3 Hz), above (sigma_up, T') for T' from 1e-6 a to a at every f, and above (min(sigma_up,
    sigma_max(T')), T') for T' from c to 1000 c from f = 1/1200 Hz on (T' on grids of 25 per decade); and far below
    the sub-box terms of split_gm_box in the band (the bank's point: w ~ sigma^2 ln(rho)/pi per term, not
    sigma^2 sqrt(r))."""
    tau = np.logspace(-1, 3.3, 35)
    cur = [_curve(NoiseModel(white=2e-4, gauss_markov=((1e-3, 30.0),), random_walk=1e-6), tau, 30.0)]
    cap = (lambda lo, hi: gm_sigma_cap(cur, lo, hi)) if capped else None

    def allowed(t):
        return min(s_up, gm_sigma_cap(cur, t)) if capped else s_up

    s_up, a, c, h = 5e-3, 0.05, 600.0, 1200.0
    bank = gm_bank_envelope(s_up, a, c, True, True, cap, estimate=(1e-3, 30.0), f_min_hz=1.0 / h)
    env = NoiseModel(white=math.sqrt(SHORT_T_WHITE_FACTOR * s_up**2 * a), gauss_markov=bank)
    f_all = np.logspace(-8, 3, 500)
    f_band = f_all[f_all >= 1.0 / h]
    e_all, e_band = env.psd(f_all), env.psd(f_band)
    for t in np.logspace(math.log10(a), math.log10(c), 25 * 5):
        assert np.all(e_all >= _gm_psd(f_all, allowed(t), t) * (1 - 1e-9)), t
    for t in np.logspace(math.log10(a) - 6, math.log10(a), 25 * 6):
        assert np.all(e_all >= _gm_psd(f_all, s_up, t) * (1 - 1e-9)), t
    for t in np.logspace(math.log10(c), math.log10(c) + 3, 25 * 3):
        assert np.all(e_band >= _gm_psd(f_band, allowed(t), t) * (1 - 1e-9)), t
    old = NoiseModel(gauss_markov=split_gm_box(s_up, a, c)).psd(f_band[f_band < 1.0])
    assert np.all(env.psd(f_band[f_band < 1.0]) < 0.6 * old)


def _open_above_fit():
    """A white + GM truth (GM 1e-3 at 30 s), its exact Allan curve (edf 30) and a fit whose GM T interval is open
    above: (truth, curves, fit)."""
    from types import SimpleNamespace

    tau = np.logspace(-1, 3.3, 35)
    truth = NoiseModel(white=2e-4, gauss_markov=((1e-3, 30.0),))
    cur = [_curve(truth, tau, 30.0)]
    fit = SimpleNamespace(params={"white": 2e-4, "gm_sigma_1": 1e-3, "gm_T_1": 30.0, "random_walk": 0.0},
                          intervals={"white": (1.9e-4, 2.1e-4), "gm_sigma_1": (5e-4, 5e-3), "gm_T_1": (1.0, math.inf)},
                          T_grid=np.logspace(-1, 2.5, 20))
    return truth, cur, fit


def test_upper_envelope_with_the_cap_keeps_the_estimate_and_records_each_term():
    """The envelope of a fit whose GM T interval is open above: a bank (gm_bank_envelope), never below the fitted
    GM in PSD from 1/horizon on, below the uncapped sub-box terms, one record with the bank."""
    truth, cur, fit = _open_above_fit()
    rec = []
    env = upper_envelope(fit, ["white", "gauss_markov"], span_s=1200.0, cap_record=rec,
                         gm_cap=lambda lo, hi: gm_sigma_cap(cur, lo, hi))
    env0 = upper_envelope(fit, ["white", "gauss_markov"], span_s=1200.0)
    f = np.logspace(math.log10(1 / 1200.0), 1, 200)
    assert np.all(env.psd(f) >= truth.psd(f) * (1 - 1e-12))
    assert np.all(env.psd(f) <= env0.psd(f) * (1 + 1e-12))
    assert len(rec) == 1 and rec[0]["T_range_s"][1] == math.inf and len(rec[0]["bank"]) == len(env.gauss_markov)
    assert rec[0]["sigma_used"] < rec[0]["sigma_box"]  # sigma_max falls below 5e-3 somewhere in [1, 316] s


def test_a_failed_bank_programme_falls_back_to_the_sub_box_terms(monkeypatch):
    """When the bank's linear programme returns no weights (HiGHS once returned status "Not Set" on a simulated
    record), the envelope covers the open box by split_gm_box's uncapped sub-box terms, which dominate every GM of
    the box (their own test above), says so in the cap record, and is equal to the envelope without the cap."""
    from types import SimpleNamespace

    import scipy.optimize

    truth, cur, fit = _open_above_fit()
    env0 = upper_envelope(fit, ["white", "gauss_markov"], span_s=1200.0)
    monkeypatch.setattr(scipy.optimize, "linprog",
                        lambda *a, **k: SimpleNamespace(status=4, x=None, message="HiGHS Status 0: Not Set"))
    rec = []
    env = upper_envelope(fit, ["white", "gauss_markov"], span_s=1200.0, cap_record=rec,
                         gm_cap=lambda lo, hi: gm_sigma_cap(cur, lo, hi))
    assert env.gauss_markov == env0.gauss_markov and env.white == env0.white
    assert len(rec) == 1 and "Not Set" in rec[0]["bank_failed"] and rec[0]["T_range_s"][1] == math.inf
    # and the identify file's record of it (stages.identify.gm_cap_record) says so
    from imupipe.stages.identify import gm_cap_record

    out = gm_cap_record(SimpleNamespace(gm_cap_record=rec))
    assert out[0]["sigma_cap"] is None and not out[0]["capped"] and "no weights" in out[0]["note"]
    assert out[0]["sub_boxes"] == rec[0]["sub_boxes"]


@pytest.mark.slow
def test_capped_envelope_covers_a_gm_truth_longer_than_the_record_with_the_stated_probability():
    """Simulation with known truth: a GM of T 4000 s (sigma 1e-3) plus white noise (1e-3 /sqrt(Hz)) on records of
    1500 s at 2 Hz, T longer than the record; the fit's box sigma <= 5 sigma, T in [1 s, inf) (open above), horizon
    1200 s. On each of 100 records the bank (gm_bank_envelope) capped by that record's Allan variance (95 %,
    Bonferroni over its taus) must dominate the truth's PSD for f >= 1/1200 Hz, and the cap at the truth's T must
    reach its sigma. Both hold on the event that every upper limit holds (probability >= 0.95), so misses ~
    Binomial(100, <= 0.05): at most its 0.999 quantile (13) allowed."""
    from imupipe import allan_variance
    from imupipe.simulate import simulate

    truth = NoiseModel(white=1e-3, gauss_markov=((1e-3, 4000.0),))
    rate, n, reps, h = 2.0, 3000, 100, 1200.0
    x = simulate(truth, n, rate, rng=2812, n_records=reps)
    s_up, a, c = 5e-3, 1.0, max(300.0, h / (2 * math.pi))
    f = np.logspace(math.log10(1.0 / h), math.log10(rate / 2), 100)
    gm_truth = _gm_psd(f, 1e-3, 4000.0)
    misses, below = 0, 0
    for r in range(reps):
        av = allan_variance(x[r] - x[r].mean(), rate)
        cur = [(av["tau"].values, av["avar"].values, av["edf"].values)]
        capped = gm_bank_envelope(s_up, a, c, False, True, lambda lo, hi: gm_sigma_cap(cur, lo, hi, confidence=0.95),
                                  f_min_hz=1.0 / h)
        misses += int(np.any(NoiseModel(gauss_markov=capped).psd(f) < gm_truth * (1 - 1e-12)))
        below += int(gm_sigma_cap(cur, 4000.0, confidence=0.95) < 1e-3)  # the cap itself at the truth's T
    allowed = binom.ppf(0.999, reps, 0.05)
    # the sharp statement is the cap's (2 of 300 below the truth on 300 records when written; with the point AV
    # instead of its upper limit about half would be); the bank covers every allowed GM and so misses less often
    assert below <= allowed and misses <= allowed


@pytest.mark.slow
def test_adis16405_imu2_z_gyro_open_box_through_its_own_allan_variance(shared_data):
    """The case that set the ADIS16405 gyro's Kalibr spread (docs/performance.md, 2026-12-05 and 2026-12-06): imu2's
    z axis keeps a GM (3.4e-4 rad/s at T 345 s, the longest T searched) whose T interval is open at both ends, sigma
    up to 3.74e-4 rad/s (77.1 deg/h); its box runs from 0.0106 s (the shortest T searched) to 345 s, horizon 1200 s.
    The record's own Allan variance (95 %, Bonferroni over its taus) leaves that sigma allowed near T = 20 s only
    just (sigma_max 62 deg/h there, below it); the sub-box terms put 130 deg/h at each of five T, an ADEV of about
    100 deg/h from 0.1 s to 328 s against a recorded 33-47 deg/h. The bank is above every GM the data allow (T' from
    1e-6 a to 1000 c, from f = 1/1200 Hz on; kappa white noise for T' < a) and its ADEV stays within 1.3x of the
    flicker-like floor 0.664 sigma_up (the least any sum above every GM of the box can reach, up to the cap) from
    0.1 s to 655 s."""
    rdata = pytest.importorskip("rdata")
    from imupipe import allan_variance

    path = shared_data / "adis16405" / "raw" / "adis_16405_imu2.rda"
    if not path.exists():
        pytest.skip(f"{path.name} not in the shared data folder")
    rec = np.asarray(rdata.read_rda(str(path))["adis_16405_imu2"])
    z = rec[:, 2] * math.pi / 180.0  # deg/s -> rad/s (the dataset sheet's gyro_unit)
    av = allan_variance(z - z.mean(), 100.0)
    ok = np.isfinite(av["avar"].values) & np.isfinite(av["edf"].values)
    cur = [(av["tau"].values[ok], av["avar"].values[ok], av["edf"].values[ok])]
    s_up, a, c, h = 3.74e-4, 0.0106, 345.0, 1200.0
    assert gm_sigma_cap(cur, 20.0) < s_up

    def allowed(t):
        return min(s_up, gm_sigma_cap(cur, t))

    bank = gm_bank_envelope(s_up, a, c, True, True, lambda lo, hi: gm_sigma_cap(cur, lo, hi),
                            estimate=(3.4e-4, 345.0), f_min_hz=1.0 / h)
    env = NoiseModel(white=math.sqrt(SHORT_T_WHITE_FACTOR * s_up**2 * a), gauss_markov=bank)
    f = np.logspace(math.log10(1.0 / h), 1.7, 300)
    e = env.psd(f)
    for t in np.logspace(math.log10(a) - 6, math.log10(c) + 3, 250):
        assert np.all(e >= _gm_psd(f, s_up if t < a else allowed(t), t) * (1 - 1e-9)), t
    q = np.array([0.1, 1.0, 10.0, 82.0, 328.0, 655.0])
    adev = np.sqrt(NoiseModel(gauss_markov=bank).avar(q))
    # 0.664 sigma: the ADEV of the flicker PSD sigma^2/(2 pi f), the supremum over T of a GM's PSD at one sigma
    assert np.all(adev <= 1.3 * 0.664 * s_up)
    old = np.sqrt(NoiseModel(gauss_markov=split_gm_box(s_up, a, c)).avar(q))
    assert np.all(adev[:5] < 0.65 * old[:5]) and adev[5] < 0.8 * old[5]  # written: 0.47-0.61, 0.71 at 655 s
