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
