"""The flicker's GM bank (imupipe.biasinit.flicker_bank: how the verification's truths and the filter's initial
variance carry a flicker) against the flicker's closed forms, and a data-identified flicker reaching the bound.

The bank's PSD over the flicker's: with u_k = f / f_k, spacing Delta = ln(f_{k+1} / f_k) and
sigma_k^2 = B^2 Delta / pi, T_k = 1 / (2 pi f_k), each term is 2 sigma_k^2 T_k / (1 + u_k^2)
= (B^2 / (2 pi f)) (2 Delta / pi) u_k / (1 + u_k^2), so the ratio to B^2 / (2 pi f) is
r(f) = (2 / pi) sum_k Delta g(s_k), g(s) = 1 / (2 cosh s), s_k = ln u_k: a Riemann sum of the integral of g, pi / 2.
Its error (docs in biasinit.flicker_bank) is

* the ripple of the infinite sum (Poisson summation, the transform of g is (pi / 2) sech(pi w / 2)):
  at most 2 sech(pi^2 / Delta);
* the terms missing below f_lo and above f_hi: for u = f / f_k >= 1, g <= 1 / u, so the missing terms below add at
  most (2 / pi) Delta (f_lo / f) e^-Delta / (1 - e^-Delta), and those above the same with f / f_hi.
"""
import math

import numpy as np
import pytest

from imupipe.biasinit import flicker_bank
from imupipe.models import FLICKER_AV, NoiseModel, gm_avar

B = 2e-4  # u
F_LO, F_HI = 1e-5, 10.0  # Hz


def _bank_psd(bank, f):
    return sum(2.0 * s * s * T / (1.0 + (2.0 * math.pi * f * T) ** 2) for s, T in bank)


def _error_bound(f, delta):
    """|r(f) - 1| bound of the module docstring: ripple + the missing terms below f_lo and above f_hi."""
    ripple = 2.0 / math.cosh(math.pi**2 / delta)
    geo = (2.0 / math.pi) * delta * math.exp(-delta) / (1.0 - math.exp(-delta))
    return ripple + geo * (F_LO / f + f / F_HI)


@pytest.mark.parametrize("per_decade", [2, 3])
def test_bank_psd_is_the_flicker_psd_over_the_band(per_decade):
    bank = flicker_bank(B, F_LO, F_HI, per_decade)
    delta = math.log(bank[0][1] / bank[1][1])
    f = np.geomspace(10 * F_LO, F_HI / 10, 400)
    r = _bank_psd(bank, f) / (B * B / (2 * math.pi * f))
    assert np.all(np.abs(r - 1.0) <= _error_bound(f, delta))
    # and the bound is not vacuous: inside two decades of the ends it is below 7 %
    assert _error_bound(f, delta).max() < 0.07


def test_bank_allan_variance_is_the_flicker_floor():
    """AV_bank / AV_flicker - 1 = integral of w (r - 1) / integral of w, w(f) = (1/f) sin^4(pi f tau) / (pi f tau)^2.
    Inside [f_a, f_b] = [10 f_lo, f_hi / 10] |r - 1| is bounded as above; outside, r lies in [0, 1 + ripple], so
    |r - 1| <= 1, times the flicker AV's share there: below f_a at most pi^2 tau^2 f_a^2 / (2 ln 2) (sin x <= x),
    above f_b at most 1 / (2 ln 2 pi^2 tau^2 f_b^2) (sin <= 1), both relative to (2 ln 2 / pi) B^2."""
    bank = flicker_bank(B, F_LO, F_HI, 2)
    delta = math.log(bank[0][1] / bank[1][1])
    fa, fb = 10 * F_LO, F_HI / 10
    for tau in (3.0, 30.0, 300.0):
        av = sum(np.asarray(gm_avar(np.array([tau]), s, T))[0] for s, T in bank)
        inner = max(_error_bound(fa, delta), _error_bound(fb, delta))
        tol = inner + math.pi**2 * tau**2 * fa**2 / (2 * math.log(2)) + 1.0 / (
            2 * math.log(2) * math.pi**2 * tau**2 * fb**2)
        assert abs(av / (FLICKER_AV * B * B) - 1.0) <= tol, tau
        assert tol < 0.1


def test_identified_flicker_reaches_the_bound_and_its_filter_p0():
    """An upper envelope holding a flicker B_up (what the identification gives when it keeps a floor) is covered by
    the bound at every frequency of the all-frequency rows, down to the floor f_floor_hz (no K forced), and the
    filter's least initial bias variance counts the flicker's bank over the verified band."""
    from imupipe.biasinit import flicker_variance
    from imupipe.bound import bound_psd

    env = NoiseModel(white=1e-3, flicker=B)
    f = np.linspace(0.0, 0.5, 181)[1:]  # a 1 Hz decimated record's bins, a 6 min window
    curves = np.asarray(env.psd_sampled(f, 1.0))[None, :]
    res = bound_psd(f, curves, None, dt=1.0, keep=["white", "flicker"], upper_model=env, span_s=4200.0,
                    f_floor_hz=1e-6)
    assert res.bounded and "gauss_markov" in res.components and res.model.random_walk == 0.0
    fl = np.geomspace(1e-6, 0.5, 300)
    assert np.all(np.asarray(res.model.psd(fl)) >= (1.0 - 1e-6) * B * B / (2 * math.pi * fl))
    # the bank's turn-on variance: sum sigma_k^2 = (B^2 / pi) n Delta
    band = (1e-6, 0.5)
    bank = flicker_bank(B, *band)
    assert flicker_variance(env, band) == pytest.approx(len(bank) * B * B * math.log(bank[0][1] / bank[1][1])
                                                        / math.pi, rel=1e-12)
