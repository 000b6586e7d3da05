r"""Covariance of overlapping Allan-variance estimates under a noise model, and correlated replicates.

Overlapping AV estimates at neighbouring averaging times share data, so they are strongly correlated;
a bootstrap that draws them independently gives parameter intervals that are far too narrow. For a
Gaussian record the covariance follows exactly from the model.

The overlapping estimator at :math:`\tau_i = m_i\tau_0` is
:math:`\hat\sigma_i^2 = \frac{1}{2\tau_i^2 M_i}\sum_{k<M_i} w_i(k)^2`, with
:math:`w_i(k) = \theta_{k+2m_i} - 2\theta_{k+m_i} + \theta_k`, :math:`M_i = n + 1 - 2m_i` and
:math:`\theta` the integrated rate (:func:`imupipe.allan.overlapping_avar`). For zero-mean Gaussian
:math:`w` (Isserlis), :math:`\mathrm{Cov}(w_i(k)^2, w_j(l)^2) = 2 R_{ij}(l-k)^2`, hence

.. math::

    \mathrm{Cov}(\hat\sigma_i^2, \hat\sigma_j^2) = \frac{2}{4\tau_i^2\tau_j^2 M_i M_j}
    \sum_d c_{ij}(d)\, R_{ij}(d)^2, \qquad
    R_{ij}(d) = \sum_{p,q=0}^{2} a_p a_q\, G\big((d + q m_j - p m_i)\tau_0\big),

with :math:`a = (1, -2, 1)`, :math:`c_{ij}(d)` the number of index pairs :math:`(k, l)` with
:math:`l - k = d`, and :math:`G` the generalised covariance of the phase :math:`\theta` (Matheron's
intrinsic random functions: second differences annihilate polynomials of degree <= 1, so :math:`G` is
defined up to such terms, and up to :math:`h^2` since :math:`w_i` and :math:`w_j` each take a second
difference). Per component, lag :math:`h` in s:

=============== ==================================================== ==============================
component       :math:`G(h)`                                         its AV (check)
=============== ==================================================== ==============================
white N         :math:`-N^2|h|/2`                                    :math:`N^2/\tau`
Gauss-Markov    :math:`-\sigma^2T^2(e^{-|h|/T} + |h|/T - 1)`          :func:`imupipe.models.gm_avar`
random walk K   :math:`K^2|h|^3/12`                                  :math:`K^2\tau/3`
flicker B       :math:`\frac{B^2}{2\pi} h^2\ln|h|`                   :math:`B^2\,2\ln 2/\pi`
quantization Q  :math:`Q^2[h = 0]` (white phase)                     :math:`3Q^2/\tau^2`
=============== ==================================================== ==============================

A rate ramp is deterministic and adds no variance. The diagonal is the same quantity Greenhall &
Riley's EDF algorithm evaluates for one power-law noise (:func:`imupipe.allan.edf_greenhall`):
:math:`\mathrm{edf}_i = 2\,\sigma_i^4/\mathrm{Var}(\hat\sigma_i^2)`; here it holds for any mixture.

The sum over integer lags d is exact near the breakpoints of :math:`c_{ij}R_{ij}^2` (the lags where
an argument of G is 0, and the kinks of :math:`c_{ij}`), and evaluated between them as the integral
(Gauss-Legendre on geometrically growing panels) plus the Euler-Maclaurin end terms. Between
breakpoints the summand is a polynomial of degree <= 7 for white and random-walk noise, smooth for
the others, and at least :data:`_EXACT` lags from any breakpoint; the neglected Euler-Maclaurin term
is below 1e-4 of the sum.

References
----------
.. [1] C. A. Greenhall, W. J. Riley, "Uncertainty of stability variances based on finite
       differences", Proc. 35th PTTI Meeting, 2003 (generalised autocovariance of the phase
       differences; the diagonal of this covariance).
.. [2] G. Matheron, "The intrinsic random functions and their applications", Adv. Appl. Prob. 5,
       439-468, 1973 (generalised covariances).
.. [3] L. Isserlis, Biometrika 12, 134-139, 1918 (fourth moments of Gaussian variables).
.. [4] R. B. Nelsen, "An Introduction to Copulas", 2nd ed., Springer, 2006, section 2.3 (the
       Gaussian copula used by :func:`correlated_replicates`).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from imupipe.models import expm1x

__all__ = ["phase_gencov", "avar_covariance", "correlated_replicates"]

#: Lags summed exactly next to each breakpoint before the integral takes over.
_EXACT = 32
#: Gauss-Legendre nodes per panel (exact for polynomials of degree 15).
_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)
#: Second-difference coefficients and their offsets (in units of m).
_A = np.array([1.0, -2.0, 1.0])
_P = np.array([0.0, 1.0, 2.0])
_AA = np.outer(_A, _A).ravel()  # a_p a_q, p major


def phase_gencov(model, h) -> np.ndarray:
    r"""Generalised covariance :math:`G(h)` of the phase (integrated rate) of `model`, u^2 s^2.

    Continuous part only (see the module table); the quantization term :math:`Q^2[h = 0]` is added
    by :func:`avar_covariance` at the lags where it applies, and a ramp adds nothing.

    Parameters
    ----------
    model : imupipe.models.NoiseModel
        Noise model, SI units.
    h : array_like
        Lags, s (any sign).
    """
    a = np.abs(np.asarray(h, dtype=np.float64))
    g = np.zeros_like(a)
    if model.white:
        g -= 0.5 * model.white**2 * a
    if model.random_walk:
        g += model.random_walk**2 / 12.0 * a**3
    if model.flicker:
        with np.errstate(divide="ignore", invalid="ignore"):
            g += model.flicker**2 / (2.0 * math.pi) * np.where(a > 0, a * a * np.log(np.where(a > 0, a, 1.0)), 0.0)
    for sigma, T in model.gauss_markov:
        g -= sigma**2 * T**2 * expm1x(a / T)
    return g


def _lag_nodes(mi: int, mj: int, Mi: int, Mj: int):
    """Lags d (float) and weights such that sum(w * f(d)) = sum over integer d of f(d) (see module)."""
    lo, hi = -(Mi - 1), Mj - 1
    bps = {lo, hi, 0, Mj - Mi}
    for p in range(3):
        for q in range(3):
            bps.add(p * mi - q * mj)
    b = np.array(sorted(v for v in bps if lo <= v <= hi), dtype=np.int64)
    d_parts = [b.astype(np.float64)]
    w_parts = [np.ones(b.size)]
    for b0, b1 in zip(b[:-1], b[1:]):
        inner = int(b1 - b0 - 1)
        if inner <= 0:
            continue
        if inner <= 2 * _EXACT + 2:
            d = np.arange(b0 + 1, b1, dtype=np.float64)
            d_parts.append(d)
            w_parts.append(np.ones(d.size))
            continue
        d = np.concatenate([np.arange(b0 + 1, b0 + 1 + _EXACT), np.arange(b1 - _EXACT, b1)]).astype(np.float64)
        d_parts.append(d)
        w_parts.append(np.ones(d.size))
        a, z = float(b0 + 1 + _EXACT), float(b1 - 1 - _EXACT)  # middle integers a..z, summed as integral + ends
        d_parts.append(np.array([a, z]))
        w_parts.append(np.array([0.5, 0.5]))
        half = 0.5 * (z - a)
        steps = 2.0 ** np.arange(0, max(1, math.ceil(math.log2(max(half, 1.0)))) + 1)
        offs = np.concatenate([[0.0], steps[steps < half], [half]])
        edges = np.unique(np.concatenate([a + offs, z - offs]))
        left, width = edges[:-1], np.diff(edges)
        d_parts.append((left[:, None] + 0.5 * width[:, None] * (_GL_X + 1.0)).ravel())
        w_parts.append((0.5 * width[:, None] * _GL_W).ravel())
    return np.concatenate(d_parts), np.concatenate(w_parts)


def avar_covariance(model, m, n: int, rate: float) -> np.ndarray:
    r"""Covariance matrix of overlapping AV estimates at averaging factors `m` under `model`, u^4.

    Parameters
    ----------
    model : imupipe.models.NoiseModel
        Noise model of the rate signal, SI units.
    m : array_like of int
        Averaging factors, :math:`1 \le m \le n/2` (:math:`\tau = m/\mathrm{rate}`).
    n : int
        Record length, samples.
    rate : float
        Sampling rate, Hz.

    Returns
    -------
    numpy.ndarray, shape (len(m), len(m))
        :math:`\mathrm{Cov}(\hat\sigma^2(\tau_i), \hat\sigma^2(\tau_j))` (module formula), symmetric.
    """
    m = np.asarray(m, dtype=np.int64).ravel()
    n = int(n)
    if m.size == 0 or m.min() < 1 or 2 * m.max() > n:
        raise ValueError(f"averaging factors must lie in 1..{n // 2} for {n} samples, got {m!r}")
    dt = 1.0 / float(rate)
    tau = m * dt
    M = n + 1 - 2 * m
    Q2 = float(model.quantization) ** 2
    out = np.empty((m.size, m.size))
    for i in range(m.size):
        for j in range(i, m.size):
            mi, mj, Mi, Mj = int(m[i]), int(m[j]), int(M[i]), int(M[j])
            d, wc = _pair_terms(mi, mj, Mi, Mj)
            offs = (_P[None, :] * mj - _P[:, None] * mi).ravel()  # q m_j - p m_i, p major
            arg = d[:, None] + offs[None, :]
            R = phase_gencov(model, arg * dt) @ _AA
            if Q2:
                R += Q2 * ((arg == 0) @ _AA)
            s = float(np.sum(wc * R * R))
            out[i, j] = out[j, i] = 2.0 * s / (4.0 * tau[i] ** 2 * tau[j] ** 2 * Mi * Mj)
    return out


@functools.lru_cache(maxsize=1024)
def _pair_terms(mi: int, mj: int, Mi: int, Mj: int):
    """The model-free part of entry (i, j) of :func:`avar_covariance`: the lag nodes d of :func:`_lag_nodes` and
    their weights times the pair counts, w c (lags in samples).

    Cached: a job's fits, bootstrap and pooling test draw the covariance of the same averaging factors and record
    length under many models (one per fit, replicate and pooled model), and these terms depend on neither the
    model nor the rate. About 2 x 1300 floats per pair: 4-6 MB for the 210 pairs of 20 averaging factors; at most
    1024 pairs are kept (about five record lengths). The arrays are read-only, and the operations and their order
    are those of the uncached computation, so the covariances are bit-identical to it.
    """
    d, w = _lag_nodes(mi, mj, Mi, Mj)
    c = np.clip(np.minimum(Mi, Mj - d) - np.maximum(0.0, -d), 0.0, None)
    wc = w * c
    for a in (d, wc):
        a.flags.writeable = False
    return d, wc


def correlated_replicates(mean, cov, n_rep: int, rng) -> np.ndarray:
    r"""Replicates of AV estimates with chi-squared marginals and the given correlation (Gaussian copula).

    Each point k is :math:`m_k\chi^2_{\nu_k}/\nu_k` with :math:`\nu_k = 2m_k^2/C_{kk}` (its variance
    is :math:`C_{kk}`), and the points are coupled through a Gaussian copula with correlation
    :math:`C_{kl}/\sqrt{C_{kk}C_{ll}}`: :math:`Z \sim \mathcal N(0, \rho)`,
    :math:`y_k = m_k F^{-1}_{\chi^2_{\nu_k}}(\Phi(Z_k))/\nu_k` [4].

    Parameters
    ----------
    mean : array_like, shape (p,)
        Expected AVs (the fitted model's), u^2.
    cov : array_like, shape (p, p)
        Their covariance (:func:`avar_covariance`), u^4.
    n_rep : int
        Number of replicates.
    rng : numpy.random.Generator

    Returns
    -------
    numpy.ndarray, shape (n_rep, p)
    """
    from scipy.special import chdtri, ndtr

    mean = np.asarray(mean, dtype=np.float64)
    cov = np.asarray(cov, dtype=np.float64)
    sd = np.sqrt(np.diag(cov))
    rho = cov / np.outer(sd, sd)
    # eigen-decomposition: rho is PSD in exact arithmetic; tiny negative eigenvalues are rounding
    evals, evecs = np.linalg.eigh(rho)
    root = evecs * np.sqrt(np.clip(evals, 0.0, None))
    z = rng.standard_normal((int(n_rep), mean.size)) @ root.T
    nu = 2.0 * mean**2 / sd**2
    # chdtri(nu, q) is the upper-tail inverse: chi2 quantile at 1 - q; ndtr(-z) = 1 - Phi(z)
    return mean * chdtri(nu, ndtr(-z)) / nu
