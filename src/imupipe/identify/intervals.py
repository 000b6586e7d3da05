r"""Profile intervals of the parameters of an Allan-variance fit (test inversion, helpers of
:func:`imupipe.identify.fit_allan`).

With :math:`\chi^2(x)` the fit with one parameter held at :math:`x` and everything else refitted, and
:math:`\Delta(x) = \chi^2(x) - \chi^2_{free}`, the interval is :math:`\{x : \Delta(x) \le c\}`, `c` calibrated
on bootstrap replicates (:mod:`imupipe.identify.fit`). Here: the search for its ends (doubling, then bisection)
for the random walk K, a single GM's time constant T and variance sigma^2, and any scalar amplitude; the
statistic over replicates drawn with the random walk held (the second calibration of sigma's threshold). SI units.

References: D. J. Venzon, S. H. Moolgavkar, "A Method for Computing Profile-Likelihood-Based Confidence
Intervals", Applied Statistics 37(1), 87-94, 1988.
"""

from __future__ import annotations

import math

import numpy as np

from imupipe.identify.basis import (_gm_column, _near_grid, _params_to_model, _plus, _profile,
                                    _solution_to_params, _solve_fixed)
from imupipe.identify.bootstrap import _replicates

__all__: list[str] = []


def _random_walk_upper(t, y, e, rest, n_gm, grid, chi2_free, k_hat, threshold, known=None):
    r"""Upper end of the profile interval of the random walk K: the largest :math:`k \ge \hat K` with
    :math:`\Delta(k) = \chi^2(k) - \chi^2_{free} \le` `threshold`, where :math:`\chi^2(k)` is the fit with
    :math:`K^2 \tau/3` held at :math:`k` (every other component and the GM time constants refitted). Found
    by doubling, then bisection in log k to 2 %; the bracket's upper end is returned (inf when no finite k
    reaches the threshold). `known`: a known AV in every fit (u^2 per point, :func:`imupipe.identify.fit_allan`)."""
    def delta(k):
        return _profile(t, y, e, rest, n_gm, grid, offset=_plus(known, k * k * t / 3.0))[0].chi2 - chi2_free

    # start from K-hat, or (K-hat = 0) from the K whose AV equals the data's at the longest tau
    k_lo, k_hi = k_hat, (2.0 * k_hat if k_hat > 0 else math.sqrt(3.0 * y[np.argmax(t)] / t.max()))
    for _ in range(60):
        if delta(k_hi) > threshold:
            break
        k_lo, k_hi = k_hi, 2.0 * k_hi
    else:
        return float("inf")
    for _ in range(40):
        if k_lo > 0 and k_hi / k_lo < 1.02:
            break
        k_mid = math.sqrt(k_lo * k_hi) if k_lo > 0 else 0.5 * k_hi
        if delta(k_mid) > threshold:
            k_hi = k_mid
        else:
            k_lo = k_mid
    return k_hi


def _profile_interval(delta, x_hat, threshold, step, rtol=1e-4):
    r"""Profile interval :math:`\{x \ge 0 : \Delta(x) \le c\}` of a scalar amplitude around its estimate
    `x_hat` (test inversion; helper of :func:`fit_allan`): on each side the distance from `x_hat` is doubled
    from `step` until :math:`\Delta` exceeds `threshold` (c), then bisected to `rtol` of `x_hat`, keeping the
    outside end of the bracket (never narrower than the set). The lower end is 0 when :math:`\Delta(0) \le c`
    (one-sided); the upper end inf when no finite x reaches c.

    Returns
    -------
    tuple of float
        (lower, upper), in the unit of `x_hat`.
    """
    tol = rtol * x_hat if x_hat > 0 else rtol * step

    def side(sign):
        d_in, d_out = 0.0, float(step)
        for _ in range(60):
            x = x_hat + sign * d_out
            if sign < 0 and x <= 0.0:
                if delta(0.0) <= threshold:
                    return 0.0
                d_out = x_hat
                break
            if delta(x) > threshold:
                break
            d_in, d_out = d_out, 2.0 * d_out
        else:
            return float("inf") if sign > 0 else 0.0
        while d_out - d_in > tol:
            d_mid = 0.5 * (d_in + d_out)
            if delta(x_hat + sign * d_mid) > threshold:
                d_out = d_mid
            else:
                d_in = d_mid
        return float(x_hat + sign * d_out)

    return side(-1.0), side(1.0)


def _hull(percentile, profile) -> tuple:
    """The reported interval of a profiled parameter (helper of :func:`fit_allan`): the hull of its percentile
    interval and its profile interval; a NaN percentile end (too few finite replicates) leaves the profile's."""
    (lo_p, hi_p), (lo, hi) = percentile, profile
    return (min(lo_p, lo) if np.isfinite(lo_p) else lo, max(hi_p, hi) if np.isfinite(hi_p) else hi)


def _gm_T_profile_limits(t, y, e, comps, grid, chis, chi2_free, threshold, m0=None, known=None):
    r"""Profile interval of a single GM time constant (test inversion; helper of :func:`fit_allan`).

    With :math:`\chi^2(T)` the fit with the time constant held at :math:`T` (every coefficient refitted,
    :func:`_solve_fixed`) and :math:`\Delta(T) = \chi^2(T) - \chi^2_{free}`, the interval is the hull of
    :math:`\{T : \Delta(T) \le` `threshold` :math:`\}`: on the fit's T grid (`grid`, s, with its statistics
    `chis`), each end then refined by bisection in :math:`\ln T` between the last grid point inside and the
    first outside, to 2 %, keeping the outside end of the bracket (the interval is never narrower than the
    set). An end whose set reaches the first or last grid point is not bounded by the data within the search:
    it is returned as 0 (lower) or inf (upper), with a flag.

    Returns
    -------
    tuple
        (lower s, upper s, lower_open, upper_open): the open flags are True where the set reaches the
        search's end (one-sided interval).
    """
    g = np.asarray(grid, dtype=np.float64)
    inside = np.flatnonzero(np.asarray(chis) - chi2_free <= threshold)
    if inside.size == 0 or g.size < 2:
        # no grid point within the threshold (an optimum narrower than the grid step): no profile interval, the
        # percentile interval alone is reported
        return float("nan"), float("nan"), False, False

    def delta(T):
        held = {} if known is None else {"offset": known}  # (a fixed part only with known lines)
        return _solve_fixed(t, y, e, comps, (T,), m0=m0, **held).chi2 - chi2_free

    def edge(T_in, T_out):
        for _ in range(40):
            if T_out / T_in < 1.02 and T_in / T_out < 1.02:
                break
            T_mid = math.sqrt(T_in * T_out)
            if delta(T_mid) <= threshold:
                T_in = T_mid
            else:
                T_out = T_mid
        return T_out

    i_lo, i_hi = int(inside[0]), int(inside[-1])
    lower_open, upper_open = i_lo == 0, i_hi == g.size - 1
    lower = 0.0 if lower_open else edge(g[i_lo], g[i_lo - 1])
    upper = float("inf") if upper_open else edge(g[i_hi], g[i_hi + 1])
    return float(lower), float(upper), lower_open, upper_open


def _gm_sigma_held(t, y, e, rest, s2, grid, m0=None, known=None):
    r"""The fit with a single GM's variance held at `s2` (u^2), its time constant and every other coefficient
    refitted (helper of the GM sigma's profile interval in :func:`fit_allan`): :math:`\min_T \chi^2` of the
    components `rest` (the fit's without ``gauss_markov``) with the fixed part :math:`s_2\, g(\tau; T)`, on
    `grid` (s) and then by Brent's method in :math:`\ln T` between the best point's neighbours (as
    :func:`_profile`). With `s2` = 0 the GM is absent and T plays no part.

    Returns
    -------
    _Solution
        The held fit (``T`` the optimal time constant, s; empty for `s2` = 0).
    """
    from imupipe.search import refine_between_neighbours

    if not s2 > 0.0:
        return _solve_fixed(t, y, e, rest, (), m0=m0, offset=known)
    tb = np.ascontiguousarray(t, dtype=np.float64).tobytes()

    def solve(T, m_start):
        sol = _solve_fixed(t, y, e, rest, (), m0=m_start, offset=_plus(known, s2 * _gm_column(tb, float(T))))
        sol.T = (float(T),)
        return sol

    g = np.sort(np.asarray(grid, dtype=np.float64))
    best, m_start = None, m0
    sols = []
    for T in g:
        sols.append(solve(T, m_start))
        m_start = sols[-1].m
    i = int(np.argmin([sol.chi2 for sol in sols]))
    best = sols[i]
    if g.size >= 2:
        res = refine_between_neighbours(lambda lt: solve(math.exp(lt), best.m).chi2, g, i, 1e-3)
        if res is not None and res.fun < best.chi2:
            cand = solve(math.exp(res.x), best.m)
            if cand.chi2 < best.chi2:
                best = cand
    return best


def _sigma_deltas_at_k(t, y, e, comps, rest, no_gm, n_gm, grid, bgrid, k, n_boot, rng, bootstrap, dt, cid, ms,
                       lengths, rates, known=None):
    r"""The GM sigma's profile statistic over bootstrap replicates drawn from the fit with the random walk held
    at `k` (u/sqrt(s); helper of the second calibration of ``gm_sigma_profile`` in :func:`fit_allan`).

    The fit with :math:`K^2\tau/3` held at `k` and every other coefficient and the GM time constant refitted
    (the fit the random walk's profile limit is read from, :func:`_random_walk_upper`) is the model the
    replicates are drawn from, with the same generator as the main bootstrap (`bootstrap`; `ms`, `lengths`,
    `rates` per curve for ``correlated`` and ``series``). Each replicate gets the free fit (components `comps`,
    T on `bgrid`) and the fit with the GM's variance held at that model's :math:`\sigma_k^2`
    (:func:`_gm_sigma_held`, T searched within a factor 4 of the replicate's optimum, as in the main bootstrap);
    the statistic is :math:`\max(\chi^2_\sigma(\sigma_k) - \chi^2_{free}, 0)`, dimensionless.

    Returns
    -------
    numpy.ndarray
        `n_boot` values of the statistic (NaN where a replicate's fit failed).
    """
    held, _ = _profile(t, y, e, rest, n_gm, grid, offset=_plus(known, k * k * t / 3.0))
    p_k = _solution_to_params(held, rest, n_gm)
    p_k["random_walk"] = float(k)
    s2 = p_k.get("gm_sigma_1", 0.0) ** 2
    model_k = _params_to_model(p_k, dt)
    mean = np.maximum(held.m, 1e-300)
    out = np.full(int(n_boot), np.nan)
    for b, ystar in enumerate(_replicates(bootstrap, model_k, mean, e, cid, ms, lengths, rates, n_boot, rng,
                                          known=known)):
        try:  # a replicate AV many decades below its mean (a held K far above the data's) overflows the weights
            sol, _ = _profile(t, ystar, e, comps, n_gm, bgrid, offset=known)
            local = _near_grid(bgrid, sol.T[0]) if sol.T and np.isfinite(sol.T[0]) else bgrid
            held_s = _gm_sigma_held(t, ystar, e, no_gm, s2, local, m0=sol.m, known=known)
        except ValueError:  # the NumPy path's NNLS refuses the overflowed weights: the replicate's fit failed
            continue
        out[b] = max(held_s.chi2 - sol.chi2, 0.0)
    return out
