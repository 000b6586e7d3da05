"""NoiseModel closed forms against mpmath, numerical AV-from-PSD, sampled PSD identities."""

import math

import mpmath
import numpy as np
import pytest

from imupipe.models import FLICKER_AV, NoiseModel, gm_avar


def _gm_avar_mp(x, sigma=1.0):
    """GM Allan variance at tau/T = x in 60-digit arithmetic (no cancellation at that precision)."""
    mpmath.mp.dps = 60
    x = mpmath.mpf(x)
    val = (2 / x) * (1 - (3 - 4 * mpmath.exp(-x) + mpmath.exp(-2 * x)) / (2 * x))
    return float(val) * sigma**2


class TestGaussMarkovAllan:
    @pytest.mark.parametrize("x", np.logspace(-9, 6, 61))
    def test_against_mpmath(self, x):
        # 1e-12 relative: the series/expm1 forms are accurate to a few ulp; the direct formula in double
        # precision has no correct digit at x = 1e-9.
        assert gm_avar(np.array([x]), 1.0, 1.0)[0] == pytest.approx(_gm_avar_mp(x), rel=1e-12)

    def test_direct_formula_would_fail(self):
        x = 1e-7
        direct = (2 / x) * (1 - (3 - 4 * math.exp(-x) + math.exp(-2 * x)) / (2 * x))
        assert abs(direct / _gm_avar_mp(x) - 1) > 1e-3  # why the series exists

    def test_peak(self):
        tau = np.linspace(1.5, 2.3, 80001)
        adev = np.sqrt(gm_avar(tau, 1.0, 1.0))
        assert tau[np.argmax(adev)] == pytest.approx(1.893, abs=1e-3)
        assert adev.max() == pytest.approx(0.6174, abs=1e-4)


class TestAvarFromPsd:
    T = 100.0
    taus = np.logspace(-1, 5, 13)  # 1e-3 T .. 1e3 T

    @pytest.mark.parametrize(
        "model",
        [
            NoiseModel(white=2e-3),
            NoiseModel(random_walk=3e-5),
            NoiseModel(gauss_markov=((1e-4, 100.0),)),
            NoiseModel(flicker=5e-5),
            NoiseModel(white=1e-3, gauss_markov=((1e-4, 100.0),), random_walk=1e-6, flicker=1e-5),
        ],
        ids=["white", "random_walk", "gauss_markov", "flicker", "sum"],
    )
    def test_equals_closed_form(self, model):
        # the factor 4 with a two-sided PSD; quadrature tolerance 1e-13 leaves 1e-6 with ample room
        np.testing.assert_allclose(model.avar_from_psd(self.taus), model.avar(self.taus), rtol=1e-6)

    def test_quantization_band_limited(self):
        m = NoiseModel(quantization=1e-4, dt=0.01)
        taus = 0.01 * np.array([1, 2, 10, 100, 1000])
        np.testing.assert_allclose(m.avar_from_psd(taus), 3 * 1e-8 / taus**2, rtol=1e-9)

    def test_flicker_constant(self):
        assert math.sqrt(FLICKER_AV) == pytest.approx(0.664, abs=5e-4)


class TestPsd:
    def test_two_and_one_sided(self):
        m = NoiseModel(white=1e-3, gauss_markov=((1e-4, 50.0),))
        f = np.logspace(-4, 0, 9)
        np.testing.assert_allclose(m.psd(f, onesided=True), 2 * m.psd(f))
        np.testing.assert_allclose(m.psd(f), 1e-6 + 2e-8 * 50 / (1 + (2 * np.pi * f * 50) ** 2))

    def test_gm_bounds_gm_iff(self):
        f = np.logspace(-6, 3, 400)
        a = NoiseModel(gauss_markov=((2.0, 10.0),)).psd(f)
        b = NoiseModel(gauss_markov=((1.0, 30.0),)).psd(f)  # sigma^2 T: 40 vs 30; sigma^2/T: 0.4 vs 0.033
        assert np.all(a >= b)

    def test_invalid(self):
        with pytest.raises(ValueError, match="white"):
            NoiseModel(white=-1.0)
        with pytest.raises(ValueError, match=r"gauss_markov\[0\]"):
            NoiseModel(gauss_markov=((1.0, 0.0),))


class TestPsdSampled:
    f = np.linspace(1e-4, 0.5, 501)

    def test_white_exact(self):
        np.testing.assert_allclose(NoiseModel(white=3e-3).psd_sampled(self.f, 1.0), 9e-6, rtol=1e-15)

    def _alias_sum(self, model, f, dt, kmax=20000):
        k = np.arange(-kmax, kmax + 1)[:, None]
        g = f[None, :] + k / dt
        return (model.psd(g) * np.sinc(g * dt) ** 2).sum(axis=0)

    @pytest.mark.parametrize(
        "model",
        [NoiseModel(random_walk=1e-5), NoiseModel(gauss_markov=((1e-3, 3.0),)), NoiseModel(gauss_markov=((1e-3, 300.0),))],
        ids=["rw", "gm_short", "gm_long"],
    )
    def test_closed_forms_equal_alias_sums(self, model):
        f = np.linspace(0.01, 0.49, 25)
        # truncated alias sum: the tail beyond |k| = 20000 is below 1e-12 relative for these decays (~k^-4)
        np.testing.assert_allclose(model.psd_sampled(f, 1.0), self._alias_sum(model, f, 1.0), rtol=1e-9)

    def test_low_frequency_limit(self):
        m = NoiseModel(random_walk=1e-5, gauss_markov=((1e-3, 300.0),))
        f = np.array([1e-5])
        assert m.psd_sampled(f, 1.0)[0] == pytest.approx(m.psd(f)[0], rel=1e-4)

    def test_round_trip(self):
        m = NoiseModel(white=1.0, gauss_markov=[(2.0, 3.0)], random_walk=4.0)
        assert NoiseModel.from_dict(m.to_dict()) == m
        assert set(m.components()) == {"white", "gauss_markov", "random_walk"}


def _alias_sum_nb(model, f, dt, kmax):
    k = np.arange(-kmax, kmax + 1)[:, None]
    g = f[None, :] + k / dt
    return (model.psd(g) * np.sinc(g * dt) ** 2).sum(axis=0)


class TestNarrowband:
    """Second-order Gauss-Markov (damped oscillator) term: interfaces item 1."""

    params = [(1e-2, 0.56, 0.01), (1.0, 3.0, 0.3), (2.0, 1e-3, 0.9)]

    @pytest.mark.parametrize("p", params)
    def test_psd_integrates_to_variance(self, p):
        sigma, f0, zeta = p
        m = NoiseModel(narrowband=(p,))
        # two-sided: integral over -inf..inf = 2 * int_0^inf; log-f trapezoid, 2e5 points across 19 decades
        # resolve the peak (relative width 2 zeta >= 0.02 >> the 2e-4 log step); the tails left out are
        # S(0) f_lo ~ (4 zeta/w0) f0 1e-12 and ~ 1e-21 of sigma^2: far below 1e-8
        u = np.linspace(np.log(f0 * 1e-12), np.log(f0 * 1e7), 200_001)
        f = np.exp(u)
        var = 2 * np.trapezoid(m.psd(f) * f, u)
        assert var == pytest.approx(sigma**2, rel=1e-8)

    @pytest.mark.parametrize("p", params)
    def test_avar_equals_psd_integral(self, p):
        # closed form against 4 int S2 sin^4/(pi f tau)^2 df on a dense log grid (trapezoid on a smooth
        # integrand in log f: errors measured below 1e-11; 1e-8 leaves room): a check independent of QUADPACK
        m = NoiseModel(narrowband=(p,))
        u = np.linspace(np.log(1e-9), np.log(1e5), 1_000_001)
        f = np.exp(u)
        s = m.psd(f)
        for tau in np.logspace(-3, 3, 7):
            ref = np.trapezoid(4 * s * np.sin(np.pi * f * tau) ** 4 / (np.pi * f * tau) ** 2 * f, u)
            assert m.avar(np.array([tau]))[0] == pytest.approx(ref, rel=1e-8)

    @pytest.mark.parametrize("p", params)
    def test_avar_equals_avar_from_psd(self, p):
        # QUADPACK with the peak kept in the split head interval (avar_from_psd): measured agreement <= 5e-8
        # (the slowest case, f0 = 1 mHz with zeta = 0.9, is limited by the QAWF tail); 1e-6 leaves room
        import warnings

        m = NoiseModel(white=1e-3, narrowband=(p,))
        taus = np.logspace(-3, 1, 5)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # QUADPACK's round-off notes on the tiny head of long-T cases
            np.testing.assert_allclose(m.avar(taus), m.avar_from_psd(taus), rtol=1e-6)

    def test_avar_limits(self):
        sigma, f0, zeta = 1e-2, 0.56, 0.01
        m = NoiseModel(narrowband=((sigma, f0, zeta),))
        # tau -> 0: the oscillator is mean-square differentiable, adjacent tau-means differ by about x' tau,
        # so AV -> tau^2 Var(x') / 2 = tau^2 w0^2 sigma^2 / 2 (relative correction O(zeta w0 tau))
        w0 = 2 * np.pi * f0
        t = np.array([1e-7, 2e-7])
        np.testing.assert_allclose(m.avar(t), t**2 * w0**2 * sigma**2 / 2, rtol=1e-5)
        # tau >> 1/(zeta w0): AV -> S2(0)/tau (white-like), the PSD at 0 is q/w0^4 = 4 zeta sigma^2 / w0
        tau = 1e7
        assert m.avar(np.array([tau]))[0] == pytest.approx(4 * zeta * sigma**2 / w0 / tau, rel=1e-4)

    @pytest.mark.parametrize("dt", [1.0, 0.3, 0.01])
    def test_psd_sampled_equals_alias_sum(self, dt):
        m = NoiseModel(narrowband=((1e-2, 0.56, 0.01),))
        f = np.linspace(1e-3, 0.5 / dt, 41)
        ref = _alias_sum_nb(m, f, dt, 50_000)
        # tail of the truncated sum ~ sum_{|k|>M} (k/dt)^-6: negligible. The closed form loses digits
        # relative to the peak (a sum of terms of the peak's size), so compare with an absolute tolerance
        # of 1e-12 of the peak plus 1e-10 relative
        np.testing.assert_allclose(m.psd_sampled(f, dt), ref, rtol=1e-10, atol=1e-12 * ref.max())

    def test_psd_sampled_folds_the_line(self):
        # a line at 0.56 Hz averaged over 1 s shows at 0.44 Hz with the sinc^2 attenuation
        m = NoiseModel(narrowband=((1e-2, 0.56, 0.002),))
        f = np.linspace(0.0005, 0.5, 1000)
        s = m.psd_sampled(f, 1.0)
        assert f[np.argmax(s)] == pytest.approx(0.44, abs=1e-3)
        # total variance of the decimated line = sum of the block-mean variance = 2 int_0^0.5 S_d df;
        # for a narrow line it is sigma^2 sinc^2(f0 dt) within a few zeta
        var = 2 * np.trapezoid(m.psd_sampled(np.linspace(0, 0.5, 200_001), 1.0), np.linspace(0, 0.5, 200_001))
        assert var == pytest.approx(1e-4 * np.sinc(0.56) ** 2, rel=0.02)

    def test_round_trip_and_components(self):
        m = NoiseModel(white=1e-3, narrowband=((1e-2, 0.56, 0.01), (2e-3, 7.0, 0.05)))
        d = m.to_dict()
        assert d["narrowband"][0] == {"sigma": 1e-2, "f0_hz": 0.56, "zeta": 0.01}
        assert NoiseModel.from_dict(d) == m
        assert set(m.components()) == {"white", "narrowband_0", "narrowband_1"}
        assert set(NoiseModel(narrowband=((1.0, 1.0, 0.1),)).components()) == {"narrowband"}
        assert "narrowband" not in NoiseModel(white=1.0).to_dict()
        # the sum of the components' PSDs is the model's PSD
        f = np.logspace(-3, 1, 50)
        total = sum(c.psd(f) for c in m.components().values())
        np.testing.assert_allclose(total, m.psd(f), rtol=1e-14)

    def test_invalid(self):
        with pytest.raises(ValueError, match=r"narrowband\[0\].zeta"):
            NoiseModel(narrowband=((1.0, 1.0, 1.0),))
        with pytest.raises(ValueError, match=r"narrowband\[0\].f0_hz"):
            NoiseModel(narrowband=((1.0, 0.0, 0.1),))
        with pytest.raises(ValueError, match=r"narrowband\[1\]"):
            NoiseModel(narrowband=((1.0, 1.0, 0.1), (1.0, 2.0)))
        with pytest.raises(ValueError, match="f0_hz"):
            NoiseModel.from_dict({"narrowband": [{"sigma": 1.0, "zeta": 0.1}]})


class TestFlickerSampled:
    """Hurwitz-zeta closed form of the flicker alias sum against the brute-force sum."""

    def test_equals_brute_force(self):
        m = NoiseModel(flicker=1e-3)
        for dt in (1.0, 0.01):
            f = np.linspace(1e-4, 1.7, 25) / dt  # beyond the Nyquist frequency too (the sum is periodic in x)
            x = f * dt
            ref = _alias_sum_nb(m, f, dt, 20_000)
            # truncation error of the reference: sum_{|k|>M} sin^2(pi x)/(pi^2 |x+k|^3) <= sin^2/(pi^2 (M-2)^2),
            # while the sum is >= sin^2/(pi^2 x'^3) >= 8 sin^2/pi^2 (x' = distance to the nearest whole number
            # <= 1/2): relative error <= 1/(8 (M-2)^2) = 3.1e-10 at M = 20000, plus summation rounding of
            # 4e4 terms (~1e-13)
            np.testing.assert_allclose(m.psd_sampled(f, dt), ref, rtol=5e-10)
            assert np.all(x > 0)

    def test_low_frequency_limit_and_zero(self):
        m = NoiseModel(flicker=1e-3)
        # f -> 0: only k = 0 survives, S_d -> S2(f) = B^2/(2 pi f) (relative correction O(x^2))
        f = np.array([1e-6])
        assert m.psd_sampled(f, 1.0)[0] == pytest.approx(m.psd(f)[0], rel=1e-9)
        assert np.isinf(m.psd_sampled(np.array([0.0]), 1.0)[0])

    def test_fast(self):
        import time

        m = NoiseModel(white=1e-3, flicker=1e-4)
        f = np.linspace(1e-4, 0.5, 4001)
        t0 = time.perf_counter()
        for _ in range(20):
            m.psd_sampled(f, 1.0)
        # the former alias sum took ~0.3 s per call here; the closed form ~1 ms: 0.5 s for 20 calls is lenient
        assert time.perf_counter() - t0 < 0.5


def test_flicker_cache_is_content_keyed():
    # the cache is keyed by the grid's content: a changed grid gives its own values, a repeated one the same
    import imupipe.models as models

    m = NoiseModel(flicker=1e-3)
    f = np.linspace(1e-3, 0.5, 101)
    a = m.psd_sampled(f, 1.0)
    f2 = f.copy()
    f2[50] = 0.3
    b = m.psd_sampled(f2, 1.0)
    assert b[50] == pytest.approx(m.psd_sampled(np.array([0.3]), 1.0)[0], rel=1e-14)
    np.testing.assert_array_equal(m.psd_sampled(f, 1.0), a)
    a[:] = 0.0  # the returned PSD is the caller's to modify
    assert np.all(m.psd_sampled(f, 1.0) > 0)
    assert not models._flicker_alias_sum(f).flags.writeable


def test_from_dict_reads_a_bound_yaml_section():
    # the `bound` section of a bound YAML: nulls for absent components, GM and lines as dicts
    from imupipe.kalibr import model_of_bound

    section = {"white": 1e-4, "gauss_markov": [{"sigma": 2e-5, "T": 300.0}], "random_walk": None,
               "narrowband": [{"sigma": 1e-5, "f0_hz": 0.45, "zeta": 0.01}]}
    m = NoiseModel.from_dict(section)
    assert m == NoiseModel(white=1e-4, gauss_markov=((2e-5, 300.0),), narrowband=((1e-5, 0.45, 0.01),))
    assert model_of_bound({"bound": section}) == m  # the lines are kept (Kalibr then refuses them by name)


def test_scaled_multiplies_the_psd_and_the_allan_variance():
    # every term's PSD and AV is its squared coefficient times a shape, so scaling each squared coefficient by k
    # scales both by k at every frequency and tau (the bound's dense and data lifts rest on this)
    m = NoiseModel(white=2e-4, gauss_markov=((1e-4, 150.0), (5e-5, 2000.0)), random_walk=2e-7, flicker=1e-5,
                   quantization=2e-6, ramp=1e-9, narrowband=((3e-4, 0.3, 0.01),), dt=0.1)
    f, tau = np.geomspace(1e-5, 5.0, 200), np.geomspace(0.1, 1e4, 60)
    k = 2.7
    np.testing.assert_allclose(m.scaled(k).psd(f), k * m.psd(f), rtol=1e-12)
    np.testing.assert_allclose(m.scaled(k).psd_sampled(f, 0.1), k * m.psd_sampled(f, 0.1), rtol=1e-12)
    np.testing.assert_allclose(m.scaled(k).avar(tau), k * m.avar(tau), rtol=1e-12)
    assert m.scaled(k).gauss_markov[1][1] == 2000.0 and m.scaled(k).narrowband[0][1:] == (0.3, 0.01)
    with pytest.raises(ValueError, match="factor"):
        m.scaled(0.0)
