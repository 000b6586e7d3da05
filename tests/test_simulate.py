"""Simulated components have the statistics of their definitions (tolerances from sampling spread)."""

import importlib

import numpy as np
import pytest

from imupipe.models import NoiseModel
from imupipe.simulate import simulate

simulate_module = importlib.import_module("imupipe.simulate")  # the package exports the function of that name


def test_white_variance(rng):
    n, rate, N = 200_000, 100.0, 1e-3
    x = simulate(NoiseModel(white=N), n, rate, rng)
    # var estimate has relative std sqrt(2/n) = 0.0032: 5 sigma
    assert x.var() == pytest.approx(N**2 * rate, rel=5 * np.sqrt(2 / n))


def test_gauss_markov_lag1_and_variance(rng):
    n, rate, sigma, T = 400_000, 10.0, 2.0, 0.5
    x = simulate(NoiseModel(gauss_markov=((sigma, T),)), n, rate, rng)
    phi = np.exp(-1 / (rate * T))
    r1 = np.dot(x[1:], x[:-1]) / np.dot(x, x)
    # AR(1) lag-1 estimate std ~ sqrt((1-phi^2)/n) = 0.0007; variance with n_eff = n (1-phi)/(1+phi)
    assert r1 == pytest.approx(phi, abs=5 * np.sqrt((1 - phi**2) / n))
    n_eff = n * (1 - phi) / (1 + phi)
    assert x.var() == pytest.approx(sigma**2, rel=5 * np.sqrt(2 / n_eff))


def test_random_walk_increments(rng):
    n, rate, K = 200_000, 50.0, 1e-4
    x = simulate(NoiseModel(random_walk=K), n, rate, rng)
    d = np.diff(x)
    assert d.var() == pytest.approx(K**2 / rate, rel=5 * np.sqrt(2 / n))


def test_flicker_allan_flat(rng):
    from imupipe.allan import overlapping_avar

    B, rate, n = 1e-3, 1.0, 2**18
    avs = np.mean([overlapping_avar(simulate(NoiseModel(flicker=B), n, rate, rng), rate, np.array([16, 64, 256]))
                   for _ in range(8)], axis=0)
    # flat at (2 ln2/pi) B^2 within 15 %: 8 records, edf of several hundred per tau, plus the missing
    # sub-1/(n dt) part of the spectrum
    np.testing.assert_allclose(avs, 0.4413 * B**2, rtol=0.15)


def test_bad_arguments():
    with pytest.raises(ValueError, match="n >= 2"):
        simulate(NoiseModel(white=1.0), 1, 1.0)
    with pytest.raises(ValueError, match="rate"):
        simulate(NoiseModel(white=1.0), 10, 0.0)


def test_batch_records_have_the_model_statistics_and_are_independent(rng):
    # n_records rows: each row a record of the model. Steady-state GM + white: the variance across
    # rows at a fixed sample (n_records draws: rel. std sqrt(2/n_records)) at the first and last sample
    # (GM started at steady state), and the lag-1 correlation between rows ~ 0 (std 1/sqrt(n))
    N, sigma, T, rate, n, rows = 1e-3, 2e-3, 5.0, 10.0, 400, 20_000
    x = simulate(NoiseModel(white=N, gauss_markov=((sigma, T),)), n, rate, rng, n_records=rows)
    assert x.shape == (rows, n)
    total = sigma**2 + N**2 * rate
    for k in (0, n - 1):
        assert x[:, k].var() == pytest.approx(total, rel=5 * np.sqrt(2 / rows))
    phi = np.exp(-1 / (rate * T))
    r1 = np.mean(x[:, 1:] * x[:, :-1]) / total  # within-row lag-1 correlation
    assert r1 == pytest.approx(phi * sigma**2 / total, abs=5 / np.sqrt(rows * n) * 2)
    across = np.corrcoef(x[0], x[1])[0, 1]  # two different records
    assert abs(across) < 5 * np.sqrt(1 + 2 * phi / (1 - phi)) / np.sqrt(n)


@pytest.mark.skipif(simulate_module._kernels is None, reason="imupipe._kernels not built")
def test_ar1_kernel_is_lfilter(rng):
    """The compiled Gauss-Markov recursion does lfilter's operations in lfilter's order: bit-identical."""
    from scipy.signal import lfilter

    e = rng.standard_normal((3, 5000))
    for phi in (0.0, 0.5, 1.0 - 1e-9):
        expected = lfilter([1.0], [1.0, -phi], e, axis=-1)
        got = simulate_module._ar1(e.copy(), phi)
        assert np.array_equal(got, expected)
    with pytest.raises(ValueError, match="whole number of rows"):
        simulate_module._kernels.ar1(np.zeros(10), 0.5, 3)


def test_narrowband_steady_state_and_autocovariance(rng):
    # 20000 independent records: variance at the first and last sample (started at steady state) and the
    # lag-1 and lag-25 covariances against the closed form R(t) = Re[A e^{lambda t}]; each estimate has
    # relative std about sqrt(2/rows) = 0.01: 5 sigma
    from imupipe.models import _nb_lambda

    sigma, f0, zeta, rate, n, rows = 2.0, 0.56, 0.05, 100.0, 60, 20_000
    x = simulate(NoiseModel(narrowband=((sigma, f0, zeta),)), n, rate, rng, n_records=rows)
    tol = 5 * np.sqrt(2 / rows)
    for k in (0, n - 1):
        assert x[:, k].var() == pytest.approx(sigma**2, rel=tol)
    lam, c = _nb_lambda(f0, zeta)
    for lag in (1, 25):
        r = sigma**2 * np.real((1 - 1j * c) * np.exp(lam * lag / rate))
        est = np.mean(x[:, -1] * x[:, -1 - lag])
        assert est == pytest.approx(r, abs=tol * sigma**2)


def test_narrowband_welch_psd(rng):
    # Welch (one-sided, hann, 64 segments) of a simulated line: the band power around the line against the
    # model's, and the total against sigma^2. The line's correlation time 1/(zeta w0) = 1.6 s in a 13 100 s
    # record gives ~4000 independent stretches: relative std of a power estimate ~ sqrt(2/4000) = 0.022;
    # 5 sigma = 0.11
    from scipy.signal import welch

    sigma, f0, zeta, rate = 1.0, 2.0, 0.05, 20.0
    m = NoiseModel(narrowband=((sigma, f0, zeta),))
    x = simulate(m, 64 * 4096, rate, rng)
    f, p = welch(x, fs=rate, nperseg=4096, noverlap=0)
    band = (f > 1.5) & (f < 2.5)
    df = f[1] - f[0]
    est = np.sum(p[band]) * df
    ff = np.linspace(1.5, 2.5, 20001)
    truth = 2 * np.trapezoid(m.psd(ff), ff)
    assert est == pytest.approx(truth, rel=0.11)
    # total variance is sigma^2 (one-sided integral of the Welch PSD)
    assert np.sum(p) * df == pytest.approx(sigma**2, rel=0.11)


def test_narrowband_discrete_matches_lyapunov():
    # Phi P0 Phi^T + Qd = P0 (steady state is invariant under the exact discretisation)
    from imupipe.simulate import narrowband_discrete

    phi, Qd, P0 = narrowband_discrete(0.3, 0.56, 0.02, 0.01)
    np.testing.assert_allclose(phi @ P0 @ phi.T + Qd, P0, rtol=1e-9, atol=1e-12 * P0.max())
