"""Tests of imupipe.avcov: covariance of overlapping Allan-variance estimates, correlated replicates.

Checked against: the model AV (each generalised covariance must give its component's AV), the exact
double sum over all index pairs (brute force on a short record), Greenhall & Riley's EDF algorithm
(the Stable32 one, :func:`imupipe.allan.edf_greenhall`) for single power-law noises, and a Monte
Carlo of simulated records. Statistical tolerances come from the Monte Carlo sample size.
"""

import numpy as np
import pytest

from imupipe.allan import edf_greenhall, overlapping_avar
from imupipe.avcov import avar_covariance, correlated_replicates, phase_gencov
from imupipe.models import NoiseModel
from imupipe.simulate import simulate

EPS = np.finfo(float).eps
MIX = NoiseModel(white=1.0, gauss_markov=((0.5, 7.0),), random_walk=0.02, flicker=0.3, quantization=0.2)


def _second_differences(m: int, L: int) -> np.ndarray:
    M = L - 2 * m
    w = np.zeros((M, L))
    r = np.arange(M)
    w[r, r], w[r, r + m], w[r, r + 2 * m] = 1.0, -2.0, 1.0
    return w


class TestGeneralisedCovariance:
    @pytest.mark.parametrize(
        "model",
        [NoiseModel(white=2.0), NoiseModel(random_walk=0.3), NoiseModel(flicker=1.5),
         NoiseModel(gauss_markov=((0.7, 0.5),)), NoiseModel(gauss_markov=((0.7, 50.0),))],
        ids=["white", "random_walk", "flicker", "gm_short", "gm_long"],
    )
    def test_gives_the_model_allan_variance(self, model):
        # AV = Var(theta(2 tau) - 2 theta(tau) + theta(0)) / (2 tau^2) = (-8 G(tau) + 2 G(2 tau)) / (2 tau^2).
        # Rounding: G carries a few eps of itself, and a GM's e^-x - 1 + x (x = h/T >= 1e-3, below that a series)
        # loses another factor 2/x to cancellation; the combination then cancels down to the AV
        tau = np.logspace(-2, 2, 9)
        g1, g2 = phase_gencov(model, tau), phase_gencov(model, 2 * tau)
        av = (-8 * g1 + 2 * g2) / (2 * tau**2)
        T = model.gauss_markov[0][1] if model.gauss_markov else 0.0
        err_g1 = np.abs(g1) * (1 + 2 * T / tau)
        err_g2 = np.abs(g2) * (1 + T / tau)
        tol = 8 * EPS * (8 * err_g1 + 2 * err_g2) / (2 * tau**2) + 8 * EPS * np.abs(model.avar(tau))
        np.testing.assert_array_less(np.abs(av - model.avar(tau)), tol)


class TestAvarCovariance:
    def test_equals_the_exact_double_sum(self):
        # brute force: Cov = 2 sum_kl (W_i G W_j^T)_kl^2 / (4 tau_i^2 tau_j^2 M_i M_j), every index pair; the
        # lag quadrature is documented to 1e-4 (neglected Euler-Maclaurin term)
        n, rate = 600, 2.0
        dt = 1.0 / rate
        m = np.array([1, 3, 70, 130, 200, 300])
        L = n + 1
        idx = np.arange(L)
        G = phase_gencov(MIX, (idx[:, None] - idx[None, :]) * dt) + MIX.quantization**2 * np.eye(L)
        exact = np.empty((m.size, m.size))
        for i, a in enumerate(m):
            for j, b in enumerate(m):
                R = _second_differences(a, L) @ G @ _second_differences(b, L).T
                exact[i, j] = 2 * np.sum(R**2) / (4 * (a * dt) ** 2 * (b * dt) ** 2 * (L - 2 * a) * (L - 2 * b))
        np.testing.assert_allclose(avar_covariance(MIX, m, n, rate), exact, rtol=1e-4)

    @pytest.mark.parametrize("alpha, model", [(0, NoiseModel(white=1.0)), (-1, NoiseModel(flicker=1.0)),
                                              (-2, NoiseModel(random_walk=1.0))], ids=["WFM", "FFM", "RWFM"])
    def test_diagonal_matches_greenhall_edf(self, alpha, model):
        # edf = 2 AV^2 / Var. Greenhall & Riley use the continuous filter (F = infinity) once m (d+1) > 100, i.e.
        # m >= 34 here, and their asymptotic coefficients (a0, a1 to 3 digits) carry about 1 % at those m
        n, rate = 200_000, 10.0
        m = 2 ** np.arange(6, 16)
        C = avar_covariance(model, m, n, rate)
        edf = 2 * model.avar(m / rate) ** 2 / np.diag(C)
        np.testing.assert_allclose(edf, edf_greenhall(alpha, 2, m, n + 1), rtol=0.01)

    def test_matches_simulated_records(self):
        # R records of a mixture; per tau the variance of R AVs has relative standard error sqrt((kappa - 1)/R), with
        # kappa - 1 = 2 + 12/edf for chi-squared AVs; correlations have standard error (1 - rho^2)/sqrt(R).
        # Four standard errors each. Averaging factors m >= 4: the simulation samples GM and random walk at points,
        # the model averages them over dt, and the two differ at m = 1, 2.
        n, rate, R = 4096, 10.0, 2000
        model = NoiseModel(white=1.0, gauss_markov=((0.3, 20.0),), random_walk=0.01, quantization=0.05)
        m = 2 ** np.arange(2, 11)
        x = simulate(model, n, rate, np.random.default_rng(5), n_records=R)
        av = np.array([overlapping_avar(xi, rate, m) for xi in x])
        C = avar_covariance(model, m, n, rate)
        var_mc = av.var(axis=0, ddof=1)
        edf = 2 * model.avar(m / rate) ** 2 / np.diag(C)
        se = np.sqrt((2 + 12 / edf) / R)
        assert np.all(np.abs(np.diag(C) / var_mc - 1) < 4 * se)
        sd = np.sqrt(np.diag(C))
        rho, rho_mc = C / np.outer(sd, sd), np.corrcoef(av.T)
        assert np.all(np.abs(rho - rho_mc) < 4 * (1 - rho**2) / np.sqrt(R) + 1e-12)

    def test_neighbouring_octaves_are_strongly_correlated(self):
        # the reason for this module: white FM AVs one octave apart share half their data
        C = avar_covariance(NoiseModel(white=1.0), [64, 128], 100_000, 1.0)
        assert C[0, 1] / np.sqrt(C[0, 0] * C[1, 1]) > 0.5

    def test_rejects_factors_outside_the_record(self):
        with pytest.raises(ValueError, match="averaging factors"):
            avar_covariance(MIX, [1, 600], 1000, 1.0)


class TestCorrelatedReplicates:
    def test_mean_and_covariance(self):
        # target: the white-FM covariance at 8 octaves (edf 40 .. 1e4); R draws, four standard errors
        model, n, m = NoiseModel(white=1.0), 20_000, 2 ** np.arange(0, 8)
        C = avar_covariance(model, m, n, 1.0)
        mean = model.avar(m.astype(float))
        R = 20_000
        y = correlated_replicates(mean, C, R, np.random.default_rng(3))
        sd = np.sqrt(np.diag(C))
        np.testing.assert_array_less(np.abs(y.mean(axis=0) - mean), 4 * sd / np.sqrt(R))
        edf = 2 * mean**2 / sd**2
        np.testing.assert_array_less(np.abs(y.var(axis=0, ddof=1) / sd**2 - 1), 4 * np.sqrt((2 + 12 / edf) / R))
        rho = C / np.outer(sd, sd)
        # the copula keeps the normal-scores correlation; the Pearson one differs by O(1/edf) (edf >= 40 here)
        np.testing.assert_array_less(np.abs(np.corrcoef(y.T) - rho), 4 / np.sqrt(R) + 2.0 / edf.min())

    def test_positive_even_with_few_degrees_of_freedom(self):
        C = np.array([[2.0, 1.5], [1.5, 2.0]])  # edf 1 at mean 1
        y = correlated_replicates(np.ones(2), C, 10_000, np.random.default_rng(4))
        assert np.all(y > 0)


def test_cached_lag_terms_leave_every_covariance_unchanged():
    # the model-free terms of each entry are cached across models (imupipe.avcov._pair_terms): a covariance computed
    # with the cache warm from other models equals, bit for bit, the one computed with the cache empty, quantization
    # (the lag-0 pattern) included; and the cached arrays cannot be changed in place by a caller
    from imupipe import avcov

    m, n, rate = np.array([1, 2, 5, 13, 40, 120]), 2000, 4.0
    a = NoiseModel(white=1e-3, random_walk=2e-5, quantization=3e-4, gauss_markov=((5e-4, 30.0),))
    b = NoiseModel(white=4e-3, flicker=1e-3)
    avcov._pair_terms.cache_clear()
    cold = avar_covariance(a, m, n, rate)
    avar_covariance(b, m, n, rate)
    warm = avar_covariance(a, m, n, rate)
    assert avcov._pair_terms.cache_info().hits >= 2 * 21  # 21 pairs of 6 factors, read again twice
    assert np.array_equal(cold, warm)
    d, wc = avcov._pair_terms(1, 2, n - 1, n - 3)
    with pytest.raises(ValueError, match="read-only"):
        wc[0] = 0.0
