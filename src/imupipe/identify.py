r"""Identification of IMU noise components from Allan variances.

The Allan variance (AV) of a sum of independent processes is the sum of their AVs, and for a
fixed Gauss-Markov (GM) time constant :math:`T` every component's AV is linear in its squared
coefficient (IEEE Std 952 Annex C; Gallon et al. 2021, eqs. 5, 10, 11; docs/method.md, section "Allan variance from a PSD"):

.. math::

    \sigma^2(\tau) = \underbrace{N^2 \frac{1}{\tau}}_{\text{white}}
    + \sum_i \underbrace{\sigma_i^2\, g(\tau; T_i)}_{\text{Gauss-Markov}}
    + \underbrace{K^2 \frac{\tau}{3}}_{\text{random walk}}
    + \underbrace{B^2 \frac{2\ln 2}{\pi}}_{\text{flicker}}
    + \underbrace{Q^2 \frac{3}{\tau^2}}_{\text{quantization}}
    + \underbrace{R^2 \frac{\tau^2}{2}}_{\text{ramp}},

with :math:`g(\tau; T)` the AV of a unit-variance first-order GM (:func:`imupipe.models.gm_avar`).
:func:`fit_allan` therefore solves a weighted non-negative least-squares problem for the squared
coefficients at each trial :math:`T` and profiles :math:`T`; :func:`slope_line` is the classic
graphical reading (IEEE Std 952, Kalibr, MATLAB ``allanvar`` examples) kept for comparison;
:func:`select_components` keeps only what the data show and the application needs.

All values are SI: rate unit u (rad/s or m/s^2), :math:`N` in u/sqrt(Hz), :math:`K` in u/sqrt(s),
:math:`\sigma` and :math:`B` in u, :math:`T` and :math:`\tau` in s, :math:`Q` in u s,
:math:`R` in u/s.

References
----------
.. [1] IEEE Std 952-1997 (R2008), "IEEE Standard Specification Format Guide and Test Procedure for
       Single-Axis Interferometric Fiber Optic Gyros", Annex C.
.. [2] E. Gallon, M. Joerger, B. Pervan, "Development of Stochastic IMU Error Models for INS/GNSS
       Integration", ION GNSS+ 2021, section II.2 and eq. 19.
.. [3] W. J. Riley, "Handbook of Frequency Stability Analysis", NIST SP 1065, 2008, section 5.
.. [4] P. McCullagh, J. A. Nelder, "Generalized Linear Models", 2nd ed., Chapman & Hall, 1989,
       chapter 8 (gamma errors: variance proportional to the squared mean, iteratively
       re-weighted least squares).
.. [5] N. El-Sheimy, H. Hou, X. Niu, "Analysis and Modeling of Inertial Sensors Using Allan
       Variance", IEEE Trans. Instrum. Meas. 57(1), 140-149, 2008.
.. [6] D. J. Venzon, S. H. Moolgavkar, "A Method for Computing Profile-Likelihood-Based Confidence
       Intervals", Applied Statistics 37(1), 87-94, 1988.
.. [7] A. C. Davison, D. V. Hinkley, "Bootstrap Methods and their Application", Cambridge University
       Press, 1997, chapter 5 (confidence intervals).
.. [8] R. L. Berger, D. D. Boos, "P Values Maximized Over a Confidence Set for the Nuisance Parameter",
       Journal of the American Statistical Association 89(427), 1012-1016, 1994.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field, replace

import numpy as np

try:  # optional compiled kernel: the whole re-weighted NNLS in one call (see _wnnls)
    from imupipe import _kernels
except ImportError:  # pragma: no cover - exercised where the extension is not built
    _kernels = None

__all__ = [
    "COMPONENTS",
    "AllanFit",
    "fit_allan",
    "slope_line",
    "select_components",
    "refit_selected",
    "pooling_test",
    "av_basis",
]

#: Components :func:`fit_allan` knows, in the order of the linear coefficients.
COMPONENTS = ("white", "gauss_markov", "random_walk", "flicker", "quantization", "ramp")

#: sqrt(2 ln 2 / pi): flicker ADEV plateau = 0.664 B (IEEE Std 952; docs/method.md, section "Slip: the flicker constant and Gauss-Markov").
_FLICKER_ADEV = math.sqrt(2.0 * math.log(2.0) / math.pi)

# Components removed together with the tested one in the refit test of select_components: a rate
# ramp (tau^2) absorbs a random walk's rise at the longest taus, and is not a filter state.
_SUBSTITUTES = {"random_walk": ("ramp",), "white": ("quantization",)}


# ---------------------------------------------------------------------------------------------
# input handling and AV basis
# ---------------------------------------------------------------------------------------------
def _curves_of(a, name):
    """`a` as a list of 1-D float arrays (one per curve), or None for a single 1-D array / scalar."""
    if isinstance(a, (list, tuple)) and len(a) and np.ndim(a[0]) >= 1:
        return [np.ravel(np.asarray(x, dtype=np.float64)) for x in a]
    try:
        arr = np.asarray(a, dtype=np.float64)
    except ValueError as exc:  # ragged nested sequence
        raise ValueError(f"{name}: give one array per curve (curves may differ in length): {exc}") from None
    if arr.ndim == 2:
        return list(arr)
    if arr.ndim > 2:
        raise ValueError(f"{name}: 1-D or 2-D (curve, tau) expected, got shape {arr.shape}")
    return None


def _pool(tau, avar, edf, return_curve=False):
    """Concatenate one curve or several into flat arrays (curves may have different lengths: records of
    different length or rate).

    `avar`: one 1-D array, a 2-D array (curve, tau) or a sequence of 1-D arrays; `tau`: the same shape, or one
    1-D grid shared by every curve; `edf`: a scalar, the same shape as `avar`, or one 1-D array per tau of a
    shared grid. Points with non-finite or non-positive AV, tau or edf are dropped. With `return_curve`, the
    curve index of every point is returned too.
    """
    ys = _curves_of(avar, "avar")
    if ys is None:
        ys = [np.ravel(np.asarray(avar, dtype=np.float64))]
    ts = _curves_of(tau, "tau")
    if ts is None:
        t1 = np.ravel(np.asarray(tau, dtype=np.float64))
        if len(ys) == 1 and t1.size == ys[0].size:
            ts = [t1]
        elif all(y.size == t1.size for y in ys):
            ts = [t1] * len(ys)
        else:
            raise ValueError(f"tau ({t1.size} values) does not match avar (curves of {[y.size for y in ys]})")
    if len(ts) != len(ys) or any(a.size != b.size for a, b in zip(ts, ys)):
        raise ValueError(f"tau (curves of {[x.size for x in ts]}) and avar (curves of {[y.size for y in ys]}) "
                         "do not match")
    if not isinstance(edf, (list, tuple)) and np.ndim(edf) == 0:
        es = [np.full(y.size, float(edf)) for y in ys]
    else:
        es = _curves_of(edf, "edf")
        if es is None:
            e1 = np.ravel(np.asarray(edf, dtype=np.float64))
            if all(y.size == e1.size for y in ys):
                es = [e1] * len(ys)
            else:
                raise ValueError(f"edf ({e1.size} values) does not match avar (curves of {[y.size for y in ys]})")
        if len(es) != len(ys) or any(a.size != b.size for a, b in zip(es, ys)):
            raise ValueError(f"edf (curves of {[x.size for x in es]}) does not match avar (curves of "
                             f"{[y.size for y in ys]})")
    t, y, e = np.concatenate(ts), np.concatenate(ys), np.concatenate(es)
    cid = np.concatenate([np.full(v.size, i, dtype=np.int64) for i, v in enumerate(ys)])
    ok = np.isfinite(t) & np.isfinite(y) & np.isfinite(e) & (t > 0) & (y > 0) & (e > 0)
    if ok.sum() < 2:
        raise ValueError("fewer than 2 usable Allan variance points (finite, positive tau, avar, edf)")
    if return_curve:
        return t[ok], y[ok], e[ok], cid[ok]
    return t[ok], y[ok], e[ok]


def _check_components(components, n_gm):
    comps = tuple(components)
    unknown = sorted(set(comps) - set(COMPONENTS))
    if unknown:
        raise ValueError(f"unknown component(s) {unknown}; choose from {COMPONENTS}")
    if "gauss_markov" in comps and int(n_gm) < 1:
        comps = tuple(c for c in comps if c != "gauss_markov")
    return tuple(c for c in COMPONENTS if c in comps)  # canonical order


def av_basis(tau, components=COMPONENTS, T=()):
    r"""AV of each component per unit squared coefficient (columns of the linear model).

    Columns, in `components` order (``gauss_markov`` contributes one column per time constant):
    :math:`1/\tau` (white, per :math:`N^2`), :math:`g(\tau; T_i)` (GM, per :math:`\sigma_i^2`),
    :math:`\tau/3` (random walk, per :math:`K^2`), :math:`2\ln 2/\pi` (flicker, per :math:`B^2`),
    :math:`3/\tau^2` (quantization, per :math:`Q^2`), :math:`\tau^2/2` (ramp, per :math:`R^2`).

    Parameters
    ----------
    tau : array_like
        Averaging times, s.
    components : sequence of str, optional
        Subset of :data:`COMPONENTS`. Default all.
    T : sequence of float, optional
        GM time constants, s (one column each when ``"gauss_markov"`` is in `components`).

    Returns
    -------
    A : numpy.ndarray
        Shape (len(tau), n_columns), s^-1, 1, s, 1, s^-2, s^2 per column as above (AV per squared
        coefficient).
    names : list of str
        Column labels (``"white"``, ``"gm_1"``, ... ``"random_walk"``, ...).
    """
    t = np.asarray(tau, dtype=np.float64)
    cols, names = [], []
    for c in components:
        if c == "white":
            cols.append(1.0 / t)
            names.append("white")
        elif c == "gauss_markov":
            for i, Ti in enumerate(T):
                cols.append(_gm_column(t.tobytes(), float(Ti)))
                names.append(f"gm_{i + 1}")
        elif c == "random_walk":
            cols.append(t / 3.0)
            names.append("random_walk")
        elif c == "flicker":
            cols.append(np.full_like(t, _FLICKER_ADEV**2))
            names.append("flicker")
        elif c == "quantization":
            cols.append(3.0 / t**2)
            names.append("quantization")
        elif c == "ramp":
            cols.append(t**2 / 2.0)
            names.append("ramp")
    if not cols:
        return np.zeros((t.size, 0)), names
    return np.stack(cols, axis=1), names


@functools.lru_cache(maxsize=1024)
def _gm_column(tau_bytes: bytes, T: float) -> np.ndarray:
    """GM column of :func:`av_basis` (AV per unit sigma^2 at the float64 taus packed in `tau_bytes`), cached:
    every bootstrap replicate profiles the same T grid on the same taus, and the axes of one record length
    share their taus, so most columns are computed once per job (at most 1024 kept, ~2 kB each)."""
    from imupipe.models import gm_avar

    col = np.asarray(gm_avar(np.frombuffer(tau_bytes, dtype=np.float64), 1.0, T), dtype=np.float64)
    col.flags.writeable = False
    return col


# ---------------------------------------------------------------------------------------------
# weighted NNLS with re-weighting
# ---------------------------------------------------------------------------------------------
_KERNEL_MAX_COLUMNS = 16  # imupipe._kernels.wnnls's limit (WNNLS_MAX_K)


def _wnnls(A, y, edf, n_iter=30, rtol=1e-6, m0=None, offset=None, backend="auto"):
    r"""Non-negative quasi-likelihood fit of AVs with variance :math:`2 m^2/\nu`.

    Iteratively re-weighted NNLS: weights :math:`w_k = \sqrt{\nu_k/2}/m_k` evaluated on the
    current model :math:`m = o + A p` (first pass on the data, or on `m0`, e.g. the solution at a
    neighbouring GM time constant); `offset` :math:`o` is a fixed part of the model (a component held at a
    given value), zero by default. Returns ``(p, m, chi2)`` with the Pearson statistic
    :math:`\chi^2 = \sum \tfrac{\nu_k}{2} ((y_k - m_k)/m_k)^2`.

    The iteration stops once the model moves by less than `rtol` (relative) at every tau. At 1e-6 the
    default run's pooled fits agree with a 1e-9 stop to 1e-6 relative and their bootstrap replicates to
    1.4e-4 at most (a parameter near zero), far inside the parameters' statistical uncertainty, for a
    fifth less time.

    `backend`: ``"c"`` (``imupipe._kernels.wnnls``: the same iteration, each NNLS by Lawson & Hanson's
    active-set method on Householder QR, 1974, ch. 23), ``"scipy"`` (:func:`scipy.optimize.nnls` per pass)
    or ``"auto"`` (the kernel when built). The fits of a job call this ~10^4 times on a few dozen taus and
    3-5 columns, where the Python path spends ~0.4 ms per call around ~0.05 ms of solving; the kernel's
    results agree with it to rounding amplified by the conditioning, or within `rtol` where rounding moves
    the stopping pass (tested).
    """
    n, k = A.shape
    if k == 0:  # nothing to fit: the model is the offset alone (none: no model, chi2 infinite)
        if offset is None:
            return np.zeros(0), np.zeros_like(y), float("inf")
        m = np.maximum(offset, 1e-6 * y)
        r = (y - m) / m
        return np.zeros(0), m, float(np.sum(edf / 2.0 * r * r))
    if backend == "c" or (backend == "auto" and _kernels is not None and k <= _KERNEL_MAX_COLUMNS):
        p, m = np.empty(k), np.empty(n)
        f64 = functools.partial(np.ascontiguousarray, dtype=np.float64)
        chi2 = _kernels.wnnls(f64(A), f64(y), f64(edf), None if m0 is None else f64(m0),
                              None if offset is None else f64(offset), int(n_iter), float(rtol), p, m)
        return p, m, chi2
    from scipy.optimize import nnls

    s = np.sqrt(edf / 2.0)
    m = y.copy() if m0 is None else np.maximum(m0, 1e-6 * y)
    target = y if offset is None else y - offset
    p = np.zeros(k)
    for _ in range(n_iter):
        w = s / m
        Aw = A * w[:, None]
        col = np.sqrt(np.sum(Aw * Aw, axis=0))
        col[col == 0] = 1.0
        try:
            ps, _ = nnls(Aw / col, target * w, maxiter=50 * k)
        except RuntimeError:  # iteration limit: keep the last solution
            break
        p = ps / col
        m_new = A @ p if offset is None else offset + A @ p
        # a model that vanishes at some tau cannot weight that point: floor it at 1e-6 of the data
        m_new = np.maximum(m_new, 1e-6 * y)
        done = np.max(np.abs(m_new - m) / m) < rtol
        m = m_new
        if done:
            break
    r = (y - m) / m
    chi2 = float(np.sum(edf / 2.0 * r * r))
    return p, m, chi2


def _default_T_grid(tau, per_decade=8, T_min_s=None):
    # `T_min_s` (s, optional): the shortest T the record resolves (a few sample intervals of the decimated
    # series, identify.fit_tau_min_samples * dt); the grid starts at max(tau_min, T_min_s).
    # a GM with T below the shortest tau looks like white noise; one whose AV peak (1.89 T) lies
    # beyond the longest tau looks like a random walk (and a random walk with K^2 = 2 sigma^2/T
    # dominates it): outside [tau_min, tau_max/2] T is not identifiable and only feeds confounding
    from imupipe.search import log_grid

    t = np.asarray(tau)
    lo, hi = math.log10(t.min()), math.log10(t.max() / 2.0)
    if T_min_s is not None:
        if not (np.isfinite(T_min_s) and T_min_s > 0):
            raise ValueError(f"T_min_s (shortest resolved GM time constant, s) must be positive, got {T_min_s!r}")
        lo = max(lo, math.log10(T_min_s))
    if hi <= lo:
        hi = lo + 1.0
    return log_grid(lo, hi, per_decade, min_points=3)


@dataclass
class _Solution:
    p: np.ndarray
    names: list
    T: tuple
    chi2: float
    m: np.ndarray


def _solve_fixed(t, y, e, comps, T, m0=None, offset=None):
    A, names = av_basis(t, comps, T)
    p, m, chi2 = _wnnls(A, y, e, m0=m0, offset=offset)
    return _Solution(p, names, tuple(float(x) for x in T), chi2, m)


def _profile(t, y, e, comps, n_gm, T_grid, refine=True, offset=None):
    """Best solution over GM time constants (grid, then bounded refinement in log T); `offset`: a fixed
    part of the model (:func:`_wnnls`). One GM: Brent's method in ln T between the grid neighbours
    (:func:`imupipe.search.minimize_bounded`, scipy's bounded method without its import)."""
    from imupipe.search import refine_between_neighbours

    solve = functools.partial(_solve_fixed, offset=offset)
    if "gauss_markov" not in comps:
        sol = solve(t, y, e, comps, ())
        return sol, (np.zeros(0), np.zeros(0))
    grid = np.sort(np.asarray(T_grid, dtype=np.float64))
    if n_gm == 1:
        # each grid point starts from its neighbour's model (same optimum, fewer re-weightings)
        sols, m0 = [], None
        for T in grid:
            sols.append(solve(t, y, e, comps, (T,), m0=m0))
            m0 = sols[-1].m
        chis = np.array([sol.chi2 for sol in sols])
        i = int(np.argmin(chis))
        best = sols[i]
        if refine and grid.size >= 2:
            res = refine_between_neighbours(lambda lt: solve(t, y, e, comps, (math.exp(lt),), m0=best.m).chi2,
                                            grid, i, 1e-3)
            if res is not None:
                cand = solve(t, y, e, comps, (math.exp(res.x),), m0=best.m)
                if cand.chi2 < best.chi2:
                    best = cand
        return best, (grid, chis)
    # several GM terms: coarse grid over increasing tuples, then Nelder-Mead on log T, bounded to the grid's
    # range: the callers restrict the grid on purpose (select_components keeps T three octaves above the
    # shortest tau so that no GM stands in for the white noise under test, and below tau_max/8 for the random
    # walk); an unbounded simplex left that range (T = 4e-4 s against a grid from 0.8 s: the white noise
    # "not shown" and dropped in two-GM records)
    from itertools import combinations

    from scipy.optimize import minimize

    coarse = grid[:: max(1, grid.size // 12)]
    best = None
    for Ts in combinations(coarse, n_gm):
        sol = solve(t, y, e, comps, Ts)
        if best is None or sol.chi2 < best.chi2:
            best = sol
    if refine:
        log_range = (math.log(grid[0]), math.log(grid[-1]))
        res = minimize(
            lambda lt: solve(t, y, e, comps, tuple(np.exp(np.sort(lt)))).chi2,
            np.log(best.T),
            method="Nelder-Mead",
            bounds=[log_range] * n_gm,
            options={"xatol": 1e-3, "fatol": 1e-6, "maxiter": 400},
        )
        cand = solve(t, y, e, comps, tuple(np.exp(np.sort(res.x))))
        if cand.chi2 < best.chi2:
            best = cand
    return best, (coarse, np.array([]))


def _near_grid(grid, T, factor=4.0):
    """The grid points within `factor` of T (at least the 3 nearest): a local T search."""
    d = np.abs(np.log(grid / T))
    near = grid[d <= math.log(factor)]
    return near if near.size >= 3 else np.sort(grid[np.argsort(d)[:3]])


def _random_walk_upper(t, y, e, rest, n_gm, grid, chi2_free, k_hat, threshold):
    r"""Upper end of the profile interval of the random walk K: the largest :math:`k \ge \hat K` with
    :math:`\Delta(k) = \chi^2(k) - \chi^2_{free} \le` `threshold`, where :math:`\chi^2(k)` is the fit with
    :math:`K^2 \tau/3` held at :math:`k` (every other component and the GM time constants refitted). Found
    by doubling, then bisection in log k to 2 %; the bracket's upper end is returned (inf when no finite k
    reaches the threshold)."""
    def delta(k):
        return _profile(t, y, e, rest, n_gm, grid, offset=k * k * t / 3.0)[0].chi2 - chi2_free

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


def _gm_T_profile_limits(t, y, e, comps, grid, chis, chi2_free, threshold, m0=None):
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
        return _solve_fixed(t, y, e, comps, (T,), m0=m0).chi2 - chi2_free

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


def _gm_sigma_held(t, y, e, rest, s2, grid, m0=None):
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
        return _solve_fixed(t, y, e, rest, (), m0=m0)
    tb = np.ascontiguousarray(t, dtype=np.float64).tobytes()

    def solve(T, m_start):
        sol = _solve_fixed(t, y, e, rest, (), m0=m_start, offset=s2 * _gm_column(tb, float(T)))
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


def _child_rng(rng):
    """An independent generator spawned from `rng` without advancing its stream (so the draws `rng` makes
    afterwards, e.g. a caller's next simulated record, are the same with or without the extra calibration);
    `rng` itself when it has no seed sequence to spawn from."""
    try:
        return rng.spawn(1)[0]
    except (AttributeError, TypeError, ValueError):
        return rng


def _replicates(bootstrap, model, mean, e, cid, ms, lengths, rates, n_boot, rng):
    """The bootstrap's replicate Allan variances, one array per replicate (floored at 1e-300), drawn from `model`
    (SI; its ``dt`` the first curve's sample interval when unset) with the estimator's mean `mean`: ``correlated``
    (every replicate at once, with the exact correlation of the overlapping AV estimates, :func:`_correlated_draws`),
    ``series`` (a simulated record per curve and replicate, its overlapping AV at the averaging factors `ms`), else
    independent scaled chi-squared draws of `e` degrees of freedom. `cid` the curve of each point, `lengths` and
    `rates` per curve (samples, Hz). One generator for the main bootstrap and the second calibration of a GM sigma's
    profile in :func:`fit_allan`, so both draw alike from `rng`."""
    if bootstrap in ("correlated", "series"):
        sim_model = model if model.dt is not None else replace(model, dt=1.0 / float(rates[0]))
    if bootstrap == "correlated":
        draws = _correlated_draws(sim_model, mean, ms, cid, lengths, rates, int(n_boot), rng)
    elif bootstrap == "series":
        from imupipe.allan import overlapping_avar
        from imupipe.simulate import simulate
    for b in range(int(n_boot)):
        if bootstrap == "correlated":
            ystar = draws[b]
        elif bootstrap == "series":
            ystar = np.empty_like(mean)
            for ci in range(int(cid.max()) + 1):
                x = simulate(replace(sim_model, dt=1.0 / float(rates[ci])), int(lengths[ci]), float(rates[ci]), rng)
                for j in np.flatnonzero(cid == ci):
                    ystar[j] = overlapping_avar(x, float(rates[ci]), int(ms[j]))
        else:
            ystar = mean * rng.chisquare(e) / e
        yield np.maximum(ystar, 1e-300)


def _sigma_deltas_at_k(t, y, e, comps, rest, no_gm, n_gm, grid, bgrid, k, n_boot, rng, bootstrap, dt, cid, ms,
                       lengths, rates):
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
    held, _ = _profile(t, y, e, rest, n_gm, grid, offset=k * k * t / 3.0)
    p_k = _solution_to_params(held, rest, n_gm)
    p_k["random_walk"] = float(k)
    s2 = p_k.get("gm_sigma_1", 0.0) ** 2
    model_k = _params_to_model(p_k, dt)
    mean = np.maximum(held.m, 1e-300)
    out = np.full(int(n_boot), np.nan)
    for b, ystar in enumerate(_replicates(bootstrap, model_k, mean, e, cid, ms, lengths, rates, n_boot, rng)):
        sol, _ = _profile(t, ystar, e, comps, n_gm, bgrid)
        local = _near_grid(bgrid, sol.T[0]) if sol.T and np.isfinite(sol.T[0]) else bgrid
        held_s = _gm_sigma_held(t, ystar, e, no_gm, s2, local, m0=sol.m)
        out[b] = max(held_s.chi2 - sol.chi2, 0.0)
    return out


def _solution_to_params(sol, comps, n_gm):
    """Flat SI parameter dict (coefficients are square roots of the fitted squared ones)."""
    params = {c: 0.0 for c in comps if c != "gauss_markov"}
    gm = []
    for name, v in zip(sol.names, sol.p):
        if name.startswith("gm_"):
            i = int(name[3:]) - 1
            gm.append((math.sqrt(max(v, 0.0)), sol.T[i]))
        else:
            params[name] = math.sqrt(max(v, 0.0))
    gm = sorted(gm, key=lambda st: st[1])
    flat = dict(params)
    if "gauss_markov" in comps:
        for i in range(n_gm):
            s, T = gm[i] if i < len(gm) else (0.0, float("nan"))
            flat[f"gm_sigma_{i + 1}"] = s
            flat[f"gm_T_{i + 1}"] = T if s > 0 else float("nan")
    return flat


def _params_to_model(flat, dt=None):
    from imupipe.models import NoiseModel

    gm = []
    i = 1
    while f"gm_sigma_{i}" in flat:
        s, T = flat[f"gm_sigma_{i}"], flat[f"gm_T_{i}"]
        if s > 0 and np.isfinite(T):
            gm.append((s, T))
        i += 1
    kw = {k: flat.get(k, 0.0) for k in ("white", "random_walk", "flicker", "quantization", "ramp")}
    return NoiseModel(gauss_markov=tuple(gm), dt=dt, **kw)


def _adequacy(chi2, dof, chi2_boot, chi2_cov, level):
    r"""Goodness of fit of an AV fit (helper of :func:`fit_allan`).

    Three calibrations, the first available is used for ``p_value``:

    * ``bootstrap``: the Pearson :math:`\chi^2` against its values on the bootstrap replicates (each drawn
      from the fitted model with the AVs' exact correlation, and refitted the same way): :math:`p = (1 +
      \#\{\chi^{2*} \ge \chi^2\})/(1 + B)` (a parametric-bootstrap goodness-of-fit test, Davison &
      Hinkley 1997, section 4.2); over-dispersion :math:`\phi = \chi^2 / \overline{\chi^{2*}}`. When no
      replicate reaches the observed value, p is the smaller of 1/(1 + B) and the covariance p below.
    * ``covariance``: the generalised statistic with the exact AV covariance (:func:`_chi2_covariance`)
      against :math:`\chi^2_{dof}`; :math:`\phi` = statistic/dof.
    * ``independent``: Pearson :math:`\chi^2` against :math:`\chi^2_{dof}` as if the AV points were
      independent (they are not: optimistic); :math:`\phi = \chi^2/dof`.

    ``adequate = p > level`` (a Monte Carlo p-value (1 + #)/(1 + B) <= level rejects at exact level when
    level (1 + B) is an integer; level 0 turns the verdict, and so the widening, off); ``widening`` :math:`= \sqrt{\max(\phi, 1)}`.
    """
    from scipy.special import chdtrc

    boot = np.asarray(chi2_boot, dtype=np.float64)
    boot = boot[np.isfinite(boot)]
    out = {"chi2": float(chi2), "dof": int(dof), "chi2_per_dof": float(chi2 / dof) if dof > 0 else float("nan"),
           "chi2_covariance": None if chi2_cov is None else float(chi2_cov), "level": float(level)}
    if boot.size >= 20:
        n_ge = int(np.count_nonzero(boot >= chi2))
        p = (1.0 + n_ge) / (1.0 + boot.size)
        phi = float(chi2 / max(np.mean(boot), 1e-300))
        method = f"bootstrap (Pearson chi2 against {boot.size} correlated replicates refitted)"
        if n_ge == 0 and chi2_cov is not None and dof > 0:
            # beyond every replicate: the tail from the covariance statistic (finer than 1/(1 + B))
            p = min(p, float(chdtrc(dof, chi2_cov)))
            method += "; beyond every replicate, tail p from the covariance statistic"
        out["p_value_resolution"] = 1.0 / (1.0 + boot.size)
    elif chi2_cov is not None and dof > 0:
        p = float(chdtrc(dof, chi2_cov))
        phi = float(chi2_cov / dof)
        method = "covariance (generalised chi2 with the exact AV covariance, chi2(dof) reference)"
    elif dof > 0:
        p = float(chdtrc(dof, chi2))
        phi = float(chi2 / dof)
        method = "independent (Pearson chi2 against chi2(dof); AV correlation ignored: optimistic)"
    else:
        p, phi, method = float("nan"), float("nan"), "none (no degrees of freedom left)"
    out.update(p_value=float(p), method=method, overdispersion=phi,
               adequate=bool(level <= 0 or not np.isfinite(p) or p > level),
               widening=float(math.sqrt(max(phi, 1.0))) if np.isfinite(phi) else 1.0)
    return out


# ---------------------------------------------------------------------------------------------
# public API
# ---------------------------------------------------------------------------------------------
@dataclass
class AllanFit:
    r"""Result of :func:`fit_allan` (all values SI).

    Attributes
    ----------
    model : imupipe.models.NoiseModel
        Fitted model (components with zero coefficient are absent).
    params : dict
        Flat parameters: ``white`` (N, u/sqrt(Hz)), ``random_walk`` (K, u/sqrt(s)), ``flicker``
        (B, u), ``quantization`` (Q, u s), ``ramp`` (R, u/s), ``gm_sigma_i`` (u), ``gm_T_i`` (s,
        NaN when that GM term vanished); GM terms sorted by increasing T.
    intervals : dict
        Parameter -> (lower, upper) percentile interval of the parametric bootstrap at level
        `confidence` (NaN where no bootstrap was run); the random walk's upper end is the larger of the
        percentile and the profile limit (`random_walk_profile`); a single GM's time constant ``gm_T_1`` and the
        white noise are the hull of the percentile and the profile interval (`gm_T_profile`, `white_profile`),
        a single GM's ``gm_sigma_1`` its profile interval (`gm_sigma_profile`).
    p_zero : dict
        Parameter -> fraction of bootstrap refits with that coefficient exactly zero (NNLS at its
        constraint): a large value means the data do not pin the component down.
    confidence : float
        Level of `intervals`.
    chi2 : float
        Pearson statistic :math:`\sum \tfrac{\nu}{2} ((y - m)/m)^2` at the optimum.
    dof : int
        Number of points minus number of free parameters (coefficients + GM time constants).
    n_points : int
        Number of AV points fitted (all pooled curves).
    components : tuple of str
        Components allowed in the fit.
    n_gm : int
        Number of GM terms allowed.
    T_profile : tuple of numpy.ndarray
        (T grid in s, chi2 at each T) of the profile (single-GM case).
    bootstrap : numpy.ndarray
        Bootstrap parameter samples, shape (n_boot, len(param_names)).
    param_names : list of str
        Column names of `bootstrap`.
    notes : list of str
        Warnings for the reader (confounding, unresolved components).
    random_walk_profile : dict
        ``threshold`` (the bootstrap quantile of the profile statistic), ``upper`` (the profile limit of K,
        u/sqrt(s)) and ``percentile_upper``; empty without a bootstrap or a random-walk component.
    gm_T_profile : dict
        ``threshold`` (the bootstrap quantile of the profile statistic of T, a chi2 difference), ``lower`` and
        ``upper`` (the profile interval of ``gm_T_1``, s; 0 or inf where it reaches the end of the T search:
        one-sided, see `interval_kind`), ``percentile_lower`` and ``percentile_upper`` (s); empty without a
        bootstrap or with other than one GM term.
    white_profile : dict
        ``threshold`` (a chi2 difference), ``lower`` and ``upper`` (the profile interval of N, u/sqrt(Hz)),
        ``percentile_lower`` and ``percentile_upper``; empty without a bootstrap or a fitted white noise.
    gm_sigma_profile : dict
        ``threshold`` (a chi2 difference: the larger of ``threshold_fitted``, the calibration under the fitted
        model, and ``threshold_k_upper``, the one under the fit with K at ``k_calibration``, the random walk's
        profile upper limit, u/sqrt(s); these two NaN without a random walk), ``lower`` and ``upper`` (the
        profile interval of ``gm_sigma_1``, u: the reported interval when ``used``), ``percentile_lower`` and
        ``percentile_upper`` (u, for comparison; the reported interval when not ``used``: T on an end of the
        search); empty without a bootstrap or with other than one GM term.
    """

    model: object
    params: dict
    intervals: dict
    p_zero: dict
    confidence: float
    chi2: float
    dof: int
    n_points: int
    components: tuple
    n_gm: int
    T_profile: tuple = field(repr=False, default=(np.zeros(0), np.zeros(0)))
    bootstrap: np.ndarray = field(repr=False, default_factory=lambda: np.zeros((0, 0)))
    param_names: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    T_grid: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))
    random_walk_profile: dict = field(default_factory=dict)
    gm_T_profile: dict = field(default_factory=dict)
    white_profile: dict = field(default_factory=dict)
    gm_sigma_profile: dict = field(default_factory=dict)
    adequacy: dict = field(default_factory=dict)
    on_boundary: dict = field(default_factory=dict)
    interval_kind: dict = field(default_factory=dict)
    selected: object = field(repr=False, default=None)
    selection: dict = field(repr=False, default_factory=dict)
    #: the intervals before the over-dispersion widening of an inadequate fit (equal to `intervals` when the
    #: fit is adequate): the fitted model's own statistical limits, which the bound's envelope below the
    #: lowest PSD bin uses (imupipe.bound.upper_envelope)
    intervals_statistical: dict = field(default_factory=dict)

    def conservative(self) -> dict:
        """The integrity side of every amplitude parameter (``white``, ``random_walk``, ``flicker``,
        ``gm_sigma_i``, ...): the upper end of its interval where there is one (NaN intervals: the estimate),
        same units as :attr:`params`. Time constants are not included: which end of T is conservative depends
        on the application band."""
        out = {}
        for k, v in self.params.items():
            if k.startswith("gm_T"):
                continue
            hi = self.intervals.get(k, (np.nan, np.nan))[1]
            out[k] = float(max(v, hi)) if np.isfinite(hi) else float(v)
        return out

    def to_dict(self) -> dict:
        """Plain dict for YAML: SI values, intervals, chi2, notes, adequacy, boundary flags."""

        def fl(x):
            x = float(x)
            return x if math.isfinite(x) else None

        return {
            "units": "SI (u = rad/s or m/s^2): white u/sqrt(Hz), random_walk u/sqrt(s), flicker u, "
            "quantization u*s, ramp u/s, gm_sigma u, gm_T s; random_walk_profile: threshold 1 (a chi2 "
            "difference), upper and percentile_upper u/sqrt(s); gm_T_profile: threshold 1 (a chi2 difference), "
            "lower, upper, percentile_lower, percentile_upper s (null: infinite, one-sided); white_profile: threshold 1, "
            "lower, upper, percentile_lower, percentile_upper u/sqrt(Hz); gm_sigma_profile: threshold, "
            "threshold_fitted, threshold_k_upper 1, lower, upper, percentile_lower, percentile_upper u, "
            "k_calibration u/sqrt(s) (null: no random walk fitted); T_search_s: shortest "
            "and longest time constant searched, s",
            "params": {k: fl(v) for k, v in self.params.items()},
            "intervals": {k: [fl(a), fl(b)] for k, (a, b) in self.intervals.items()},
            "p_zero": {k: fl(v) for k, v in self.p_zero.items()},
            "confidence": float(self.confidence),
            "chi2": fl(self.chi2),
            "dof": int(self.dof),
            "n_points": int(self.n_points),
            "components": list(self.components),
            "n_gm": int(self.n_gm),
            "n_bootstrap": int(self.bootstrap.shape[0]),
            "random_walk_profile": {k: fl(v) for k, v in self.random_walk_profile.items()},
            **({"gm_T_profile": {k: fl(v) for k, v in self.gm_T_profile.items()}} if self.gm_T_profile else {}),
            **({"white_profile": {k: fl(v) for k, v in self.white_profile.items()}} if self.white_profile else {}),
            **({"gm_sigma_profile": {k: (bool(v) if k == "used" else fl(v)) for k, v in self.gm_sigma_profile.items()}}
               if self.gm_sigma_profile else {}),
            "notes": list(self.notes),
            "adequacy": {k: (fl(v) if isinstance(v, (float, np.floating)) else v)
                         for k, v in self.adequacy.items()},
            "on_boundary": {k: bool(v) for k, v in self.on_boundary.items()},
            "interval_kind": dict(self.interval_kind),
            # the time constants searched (s): where a one-sided T interval stops being data
            **({"T_search_s": [float(np.min(self.T_grid)), float(np.max(self.T_grid))]} if self.T_grid.size else {}),
            "conservative": {k: fl(v) for k, v in self.conservative().items()},
            **({"intervals_statistical": {k: [fl(a), fl(b)] for k, (a, b) in self.intervals_statistical.items()}}
               if self.intervals_statistical and self.intervals_statistical != self.intervals else {}),
            **({"selected": self.selected.to_dict()} if isinstance(self.selected, AllanFit) else {}),
        }


def fit_allan(
    tau,
    avar,
    edf,
    components=COMPONENTS,
    n_gm: int = 1,
    T_grid=None,
    n_boot: int = 200,
    confidence: float = 0.95,
    rng=None,
    dt: float | None = None,
    bootstrap: str = "correlated",
    rate: float | None = None,
    n_samples=None,
    adequacy_level: float = 0.01,
    T_min_samples: float | None = None,
) -> AllanFit:
    r"""Fit noise components to one or several (pooled) Allan-variance curves.

    For fixed GM time constants :math:`T_i` the AV is linear in
    :math:`\theta = (N^2, \sigma_i^2, K^2, B^2, Q^2, R^2) \ge 0` (:func:`av_basis`,
    :math:`\sigma^2(\tau) = A(\tau; T)\,\theta`). An AV estimate with :math:`\nu` equivalent
    degrees of freedom is approximately :math:`m\,\chi^2_\nu/\nu`, i.e. variance
    :math:`2 m^2/\nu` (NIST SP 1065, section 5.2), so :math:`\theta` solves

    .. math::

        \min_{\theta \ge 0} \sum_k \frac{\nu_k}{2}
        \left(\frac{y_k - A_k \theta}{m_k}\right)^2, \qquad m = A\theta ,

    by non-negative least squares (:func:`scipy.optimize.nnls`) with the weights re-evaluated on the
    model until :math:`m` stops changing (quasi-likelihood of gamma-distributed data; weights from
    the data alone would bias the fit low). :math:`T` is profiled on a log grid and refined by a
    bounded scalar search (Nelder-Mead in :math:`\log T` for several GM terms).

    Uncertainty: parametric bootstrap, refitting each replicate (T profile included); intervals are
    percentiles at `confidence`. Overlapping AV estimates at neighbouring taus share data and are
    strongly correlated; the replicate generator must keep that:

    * ``"correlated"`` (default): the exact covariance of the overlapping estimates under the
      fitted model (:func:`imupipe.avcov.avar_covariance`, records of `n_samples` at `rate`), drawn
      with chi-squared marginals through a Gaussian copula
      (:func:`imupipe.avcov.correlated_replicates`). Milliseconds per replicate.
    * ``"series"``: whole records simulated from the fitted model and their AV recomputed (the
      same distribution up to the copula approximation; one record per replicate and curve).
    * ``"chi2"``: :math:`y^*_k = m_k \chi^2_{\nu_k}/\nu_k` independently per point. It ignores the
      correlation, and its intervals are too narrow (about 60 % coverage for N at a nominal 95 %);
      kept for comparison only.

    The random walk K needs more: a K > 0 that the GM absorbs is fitted near 0, and replicates drawn
    from that fit rarely reach the truth (its percentile interval covered about 79 % over 320
    records at a nominal 90 %). Its upper end is therefore also taken from the profile of the fit
    statistic (test inversion): with :math:`\chi^2(k)` the fit with :math:`K = k` held and everything
    else refitted, :math:`\Delta(k) = \chi^2(k) - \chi^2_{free}`, the limit is the largest
    :math:`k \ge \hat K` with :math:`\Delta(k) \le c`, where `c` is the `confidence` quantile of
    :math:`\Delta` over the bootstrap replicates evaluated at the K they were drawn with (so the
    correlation of the AV points and the boundary K >= 0 are in the calibration, not a chi-squared
    assumption). The reported upper end is the larger of the two; the profile costs about a third more
    time than the bootstrap alone.

    A single GM's time constant gets the same construction on both sides (the percentile interval of T
    covered 82 % over 200 tactical-gyro records at a nominal 90 %, GM and random walk trading off):
    :math:`\Delta(T) = \chi^2(T) - \chi^2_{free}` with T held and every coefficient refitted, evaluated on
    the fit's T grid and bisected at the ends (:func:`_gm_T_profile_limits`), threshold the `confidence`
    quantile of :math:`\Delta` of the replicates at the T they were drawn with (one extra fixed-T solve
    per replicate); the reported interval is the hull of the percentile and the profile interval, and an
    end the profile leaves open at the end of the search is 0 or inf, labelled one-sided in
    ``interval_kind``. With two GM terms T has the percentile interval only.

    The white noise N gets it too (its percentile interval covered 0.85-0.88 over 200-record sets of 10 h
    records at a nominal 0.9, where a short GM and quantization trade off against it):
    :math:`\Delta(n) = \chi^2(N = n) - \chi^2_{free}` with N held at n, every other coefficient refitted and
    the GM time constants held at the free fit's optimum, the same statistic on every replicate (N held at
    the N it was drawn with, T at the replicate's own optimum), so the calibration matches the statistic;
    both ends bisected to 1e-4 N (:func:`_profile_interval`, one extra fixed-T solve per replicate), the
    reported interval the hull of the percentile and the profile interval (``white_profile``).

    A single GM's sigma gets the profile interval alone (``gm_sigma_profile``): with
    :math:`\chi^2_\sigma(s) = \min_{T,\,\theta' \ge 0} \chi^2` of the fit with :math:`\sigma^2 g(\tau; T)` held
    at :math:`s^2 g(\tau; T)` (a fixed part of the model) and T and every other coefficient :math:`\theta'`
    refitted (:func:`_gm_sigma_held`: the fit's T grid, then Brent's method in :math:`\ln T`),
    :math:`\Delta(s) = \chi^2_\sigma(s) - \chi^2_{free}`, the interval is :math:`\{s \ge 0 : \Delta(s) \le c\}`,
    both ends bisected to 1e-3 sigma (:func:`_profile_interval`); a lower end 0 (:math:`\Delta(0) \le c`: the data
    do not exclude the GM's absence) is labelled one-sided. Profiling T (and with it K) is the point: sigma, T and
    K trade off along a ridge of the fit statistic (the GM's AV plateau :math:`\approx \sigma^2` against the
    random walk's rise), and the percentile interval, drawn around the fitted point of that ridge, missed on
    the side the estimate had moved to. The threshold is

    .. math::

        c = \max\bigl(q_c(\Delta^* \mid \hat\theta),\; q_c(\Delta^* \mid \tilde\theta_{K_u})\bigr),

    :math:`q_c` the `confidence` quantile of the same statistic over bootstrap replicates, each held at the sigma it
    was drawn with (T searched within a factor 4 of the replicate's own optimum: a better T missed only enlarges c),
    the replicates drawn once from the fitted model :math:`\hat\theta` and once, as many, from
    :math:`\tilde\theta_{K_u}`, the fit with K held at its profile upper limit :math:`K_u` (the
    ``random_walk_profile`` upper end) and everything else refitted (:func:`_sigma_deltas_at_k`; skipped without a
    random walk or when :math:`K_u \le \hat K`). Why two: :math:`\Delta(\sigma_{true})` is not pivotal, its
    distribution depends on the nuisance K (how much of a wrong sigma T and K can absorb depends on the random
    walk's rise across the GM's plateau), and a K fitted below the truth (the GM absorbing part of the random walk)
    was measured to give thresholds below the quantile at the truth, where the interval misses
    (docs/performance.md). Taking the larger quantile over the K the data allow (the fitted one and the upper end of
    its interval) is conservative over that nuisance range: the usual treatment of a nuisance parameter in bootstrap
    test inversion, calibrating at the least favourable value within its confidence set (Berger & Boos [8] maximise
    over the whole set; here two points of it, the estimate and K's upper end, the side the measured shortfall came
    from; Davison & Hinkley [7], chapters 4 and 5). The second bootstrap repeats the replicates' free fits and
    sigma's held fit (not the other held fits): about 40 % more CPU for the identify job's calls
    (docs/performance.md). Its replicates come from a generator spawned from `rng`, so the draws `rng` makes
    afterwards are unchanged.
    Profile-likelihood intervals: Venzon & Moolgavkar [6]; their calibration by the bootstrap: Davison &
    Hinkley [7], chapter 5. The percentile ends are kept in ``gm_sigma_profile`` (the hull with them
    over-covered). Measured coverage, the seeds used for development and for verification, and the cost:
    docs/performance.md (the GM sigma profile interval and its threshold).

    Coverage of the ``"correlated"`` intervals on simulated 10 h records (tests/test_coverage.py, nominal
    90 %): N, K, a single GM's sigma and T, and the two-GM case, for the reported (selected, refitted:
    :func:`refit_selected`) intervals, measured on seeds not used in development against the binomial range
    of 200 records; the numbers, per seed and rule, are in docs/performance.md.

    With one 10 h record GM and rate random walk are confounded (docs/method.md, section "Identification"): K is often
    fitted as 0 and the GM parameters have 50-200 % spread, while white noise is recovered to < 1 %.
    The result's `notes` say so when the bootstrap shows it.

    Parameters
    ----------
    tau : array_like or sequence of array_like
        Averaging times, s. Several curves (axes, datasets of one sensor type) are pooled when
        given as a sequence of arrays, or as a 2-D `avar` sharing one tau grid.
    avar : array_like or sequence of array_like
        Allan variances, u^2 (e.g. (rad/s)^2).
    edf : float or array_like or sequence of array_like
        Equivalent degrees of freedom of each AV point (e.g. the ``edf`` variable of
        :func:`imupipe.allan.allan_variance`).
    components : sequence of str, optional
        Components to fit, subset of :data:`COMPONENTS`. Default all six.
    n_gm : int, optional
        Number of GM terms. Default 1.
    T_grid : array_like, optional
        Trial GM time constants, s. Default: 8 per decade from tau_min to tau_max/2 (outside, a
        GM is indistinguishable from white noise or from a random walk).
    T_min_samples : float, optional
        With the default grid: its shortest T is at least ``T_min_samples * dt`` s (a GM of T a few sample
        intervals acts as white noise; config identify.fit_tau_min_samples). Needs `dt`. Default None (tau_min).
    n_boot : int, optional
        Bootstrap replicates (0 for none). Default 200.
    confidence : float, optional
        Level of the percentile intervals. Default 0.95.
    rng : numpy.random.Generator or int, optional
        Random generator (or seed) for the bootstrap. Default ``numpy.random.default_rng()``.
    dt : float, optional
        Sample interval, s, stored in the returned model (needed by quantization's PSD).
    bootstrap : {"correlated", "series", "chi2"}, optional
        Replicate generator (see above). Default ``"correlated"``.
    rate : float or sequence of float, optional
        Sampling rate of the records the AVs come from, Hz, one for all curves or one per pooled curve
        (records of different rates pool: each curve's averaging factors are tau * its rate); needed by
        ``correlated`` and ``series`` and by the covariance adequacy statistic.
    n_samples : int or sequence of int, optional
        Record length(s) in samples, one per pooled curve (``correlated`` and ``series``).
    adequacy_level : float, optional
        Level of the goodness-of-fit test (``adequacy``). Default 0.01; 0 turns the verdict off.

    Returns
    -------
    AllanFit
        Model, parameters, intervals, chi2 and notes; ``adequacy`` (``chi2``, ``dof``, ``chi2_per_dof``,
        ``p_value``, ``adequate``, ``method``, ``overdispersion``, ``widening``, ``chi2_covariance``: see
        :func:`_adequacy`), ``on_boundary`` and ``interval_kind`` per parameter.

    Notes
    -----
    Adequacy: the Pearson statistic is calibrated on the bootstrap replicates (drawn with the exact
    correlation of the overlapping AV estimates, refitted the same way), so neither the correlation nor the
    fitted parameters need a chi-squared approximation; without a bootstrap, the generalised statistic
    with the exact AV covariance is referred to chi2(dof). When the fit is inadequate
    (p <= `adequacy_level`) the notes say so and every interval is widened on the log scale by
    :math:`\sqrt{\phi}`, :math:`\phi` the over-dispersion (observed statistic over its bootstrap mean;
    quasi-likelihood, McCullagh & Nelder 1989, section 4.5): a 0.15 % interval on a fit with
    chi2/dof = 5000 becomes about 10 %, and it is still labelled indicative.

    Boundaries: a GM time constant on the first or last value of the search (the data want a shorter or
    longer T than is identifiable) is flagged ``on_boundary``; its interval is one-sided ((0, upper] or
    [lower, inf)), never collapsed on the grid value. A coefficient fitted as 0 is flagged too (interval
    [0, upper]).

    Raises
    ------
    ValueError
        Mismatched inputs, fewer than 2 usable points, unknown components.
    """
    t, y, e, cid = _pool(tau, avar, edf, return_curve=True)
    comps = _check_components(components, n_gm)
    if bootstrap not in ("correlated", "chi2", "series"):
        raise ValueError(f"bootstrap must be 'correlated', 'chi2' or 'series', got {bootstrap!r}")
    if bootstrap in ("correlated", "series") and n_boot > 0:
        if rate is None or n_samples is None:
            raise ValueError(
                f"the {bootstrap} bootstrap needs the records' rate (Hz) and n_samples (per curve): pass "
                "rate= and n_samples= (allan_variance(...).attrs 'rate_hz' and 'n_samples'), or n_boot=0"
            )
        n_curves = int(cid.max()) + 1
        lengths = _per_curve(n_samples, n_curves, "n_samples", np.int64)
        rates = _per_curve(rate, n_curves, "rate", np.float64)
        if np.any(~np.isfinite(rates) | (rates <= 0)) or np.any(lengths < 2):
            raise ValueError(f"rate (Hz) must be positive and n_samples >= 2 per curve, got {rates}, {lengths}")
    n_gm = int(n_gm) if "gauss_markov" in comps else 0
    if T_min_samples is not None and dt is None:
        raise ValueError("T_min_samples needs dt (s, the decimated series' sample interval)")
    T_min_s = None if T_min_samples is None else float(T_min_samples) * float(dt)
    grid = _default_T_grid(t, T_min_s=T_min_s) if T_grid is None else np.asarray(T_grid, dtype=np.float64)
    if "gauss_markov" in comps and (grid.size == 0 or np.any(grid <= 0)):
        raise ValueError("T_grid must hold positive time constants (s)")

    best, profile = _profile(t, y, e, comps, n_gm, grid)
    params = _solution_to_params(best, comps, n_gm)
    model = _params_to_model(params, dt)
    names = list(params)

    c = float(confidence)
    if not 0.0 < c < 1.0:
        raise ValueError(f"confidence must lie in (0, 1), got {confidence!r}")
    rng = np.random.default_rng(rng)
    boots = np.full((int(n_boot), len(names)), np.nan)
    chi2_boot = np.full(int(n_boot), np.nan)
    # the random walk's profile interval (see the docstring): the statistic at the bootstrap's own K
    k_deltas = np.full(int(n_boot), np.nan) if n_boot > 0 and "random_walk" in comps else None
    rest = tuple(comp for comp in comps if comp != "random_walk")
    k2_hat = params.get("random_walk", 0.0) ** 2
    # the single GM time constant's profile interval (see the docstring): the statistic at the fitted T
    T_hat = params.get("gm_T_1", float("nan")) if n_gm == 1 else float("nan")
    t_deltas = np.full(int(n_boot), np.nan) if n_boot > 0 and np.isfinite(T_hat) and grid.size >= 2 else None
    # the white noise's profile interval (see the docstring): the statistic at the fitted N, the GM time
    # constants held at each fit's own optimum (the same statistic on the data and on every replicate)
    n_hat = params.get("white", float("nan"))
    n_deltas = np.full(int(n_boot), np.nan) if n_boot > 0 and "white" in comps and n_hat > 0 else None
    no_white = tuple(comp for comp in comps if comp != "white")
    # the single GM variance's profile interval (see the docstring): the statistic at the fitted sigma, T and
    # every other coefficient refitted (the same statistic on the data and on every replicate)
    s_hat = params.get("gm_sigma_1", float("nan")) if n_gm == 1 else float("nan")
    s_deltas = np.full(int(n_boot), np.nan) if n_boot > 0 and s_hat > 0 and grid.size >= 2 else None
    no_gm = tuple(comp for comp in comps if comp != "gauss_markov")
    if n_boot > 0:
        # bootstrap grid: a little coarser than the fit's, same span
        bgrid = grid if grid.size <= 30 else np.logspace(math.log10(grid[0]), math.log10(grid[-1]), 30)
        # per curve, for the correlated and series bootstraps: averaging factors, lengths (samples), rates (Hz)
        per_curve = ((np.rint(t * rates[cid]).astype(np.int64), lengths, rates) if bootstrap != "chi2"
                     else (None, None, None))
        for b, ystar in enumerate(_replicates(bootstrap, model, best.m, e, cid, *per_curve, n_boot, rng)):
            sol, _ = _profile(t, ystar, e, comps, n_gm, bgrid)
            chi2_boot[b] = sol.chi2
            pb = _solution_to_params(sol, comps, n_gm)
            boots[b] = [pb[k] for k in names]
            if k_deltas is not None:
                # the replicate's fit with K held at the value it was drawn with; T searched near the
                # replicate's own optimum (a better T missed only enlarges the threshold: conservative)
                local = _near_grid(bgrid, sol.T[0]) if n_gm == 1 else bgrid
                held = _profile(t, ystar, e, rest, n_gm, local, offset=k2_hat * t / 3.0)[0]
                k_deltas[b] = max(held.chi2 - sol.chi2, 0.0)
            if t_deltas is not None:
                # the replicate's fit with T held at the value it was drawn with
                held_T = _solve_fixed(t, ystar, e, comps, (T_hat,), m0=sol.m)
                t_deltas[b] = max(held_T.chi2 - sol.chi2, 0.0)
            if n_deltas is not None:
                held_N = _solve_fixed(t, ystar, e, no_white, sol.T, m0=sol.m, offset=n_hat * n_hat / t)
                n_deltas[b] = max(held_N.chi2 - sol.chi2, 0.0)
            if s_deltas is not None:
                # the replicate's fit with sigma held at the value it was drawn with, T searched near the
                # replicate's own optimum (a better T missed only enlarges the threshold: conservative)
                local = _near_grid(bgrid, sol.T[0]) if sol.T and np.isfinite(sol.T[0]) else bgrid
                held_s = _gm_sigma_held(t, ystar, e, no_gm, s_hat * s_hat, local, m0=sol.m)
                s_deltas[b] = max(held_s.chi2 - sol.chi2, 0.0)
    lo_q, hi_q = 100 * (1 - c) / 2, 100 * (1 + c) / 2
    intervals, p_zero = {}, {}
    for j, k in enumerate(names):
        col = boots[:, j]
        if k.startswith("gm_sigma"):
            pz = np.mean(col == 0) if col.size else float("nan")
        elif k.startswith("gm_T"):
            pz = np.mean(~np.isfinite(col)) if col.size else float("nan")
        else:
            pz = np.mean(col == 0) if col.size else float("nan")
        p_zero[k] = float(pz)
        fin = col[np.isfinite(col)]
        if fin.size >= max(5, 0.5 * col.size):
            intervals[k] = (float(np.percentile(fin, lo_q)), float(np.percentile(fin, hi_q)))
        else:
            intervals[k] = (float("nan"), float("nan"))

    random_walk_profile = {}
    if k_deltas is not None and np.isfinite(k_deltas).any():
        threshold = float(np.quantile(k_deltas[np.isfinite(k_deltas)], c))
        k_up = _random_walk_upper(t, y, e, rest, n_gm, grid, best.chi2, math.sqrt(k2_hat), threshold)
        lo_k, hi_k = intervals["random_walk"]
        random_walk_profile = {"threshold": threshold, "upper": k_up, "percentile_upper": hi_k}
        intervals["random_walk"] = (lo_k, max(hi_k, k_up) if np.isfinite(hi_k) else k_up)

    white_profile = {}
    if n_deltas is not None and np.isfinite(n_deltas).any():
        threshold = float(np.quantile(n_deltas[np.isfinite(n_deltas)], c))
        lo_p, hi_p = intervals["white"]

        def delta_n(x):
            return _solve_fixed(t, y, e, no_white, best.T, m0=best.m, offset=x * x / t).chi2 - best.chi2

        step = (hi_p - n_hat) if np.isfinite(hi_p) and hi_p > n_hat else 1e-3 * n_hat
        n_lo, n_up = _profile_interval(delta_n, n_hat, threshold, step)
        white_profile = {"threshold": threshold, "lower": n_lo, "upper": n_up,
                         "percentile_lower": lo_p, "percentile_upper": hi_p}
        intervals["white"] = _hull((lo_p, hi_p), (n_lo, n_up))

    gm_sigma_profile = {}
    if s_deltas is not None and np.isfinite(s_deltas).any() and "gm_sigma_1" in intervals:
        threshold_fitted = float(np.quantile(s_deltas[np.isfinite(s_deltas)], c))
        # the same statistic calibrated under the fit with K at its profile upper limit (see the docstring:
        # the statistic's distribution depends on K), the larger threshold kept
        k_up = random_walk_profile.get("upper", float("nan"))
        threshold_k_upper, k_cal = float("nan"), float("nan")
        if np.isfinite(k_up) and k_up > math.sqrt(k2_hat):
            k_cal = float(k_up)
            k_deltas_up = _sigma_deltas_at_k(t, y, e, comps, rest, no_gm, n_gm, grid, bgrid, k_cal, int(n_boot),
                                             _child_rng(rng), bootstrap, dt, cid, *per_curve)
            if np.isfinite(k_deltas_up).any():
                threshold_k_upper = float(np.quantile(k_deltas_up[np.isfinite(k_deltas_up)], c))
        threshold = max(threshold_fitted, threshold_k_upper) if np.isfinite(threshold_k_upper) else threshold_fitted
        lo_p, hi_p = intervals["gm_sigma_1"]

        def delta_s(x):
            return _gm_sigma_held(t, y, e, no_gm, x * x, grid, m0=best.m).chi2 - best.chi2

        step = (hi_p - s_hat) if np.isfinite(hi_p) and hi_p > s_hat else 1e-2 * s_hat
        s_lo, s_up = _profile_interval(delta_s, s_hat, threshold, step, rtol=1e-3)
        gm_sigma_profile = {"threshold": threshold, "lower": s_lo, "upper": s_up,
                            "percentile_lower": lo_p, "percentile_upper": hi_p,
                            "threshold_fitted": threshold_fitted, "threshold_k_upper": threshold_k_upper,
                            "k_calibration": k_cal}
        # the profile interval alone (not the hull with the percentile one: the hull over-covered, 0.95-0.97
        # of 100-record sets at a nominal 0.9, each alone 0.91-0.92; docs/performance.md, 2026-12-03)
        intervals["gm_sigma_1"] = (float(s_lo), float(s_up))

    gm_T_profile, T_open = {}, (False, False)
    if t_deltas is not None and np.isfinite(t_deltas).any() and profile[1].size == profile[0].size:
        threshold = float(np.quantile(t_deltas[np.isfinite(t_deltas)], c))
        T_lo, T_up, lo_open, up_open = _gm_T_profile_limits(t, y, e, comps, profile[0], profile[1], best.chi2,
                                                            threshold, m0=best.m)
        lo_p, hi_p = intervals.get("gm_T_1", (np.nan, np.nan))
        if np.isfinite(T_lo) or T_lo == 0.0:
            gm_T_profile = {"threshold": threshold, "lower": T_lo, "upper": T_up,
                            "percentile_lower": lo_p, "percentile_upper": hi_p}
            intervals["gm_T_1"] = _hull((lo_p, hi_p), (T_lo, T_up))
            T_open = (lo_open, up_open)

    notes = []
    if n_boot > 0:
        if "random_walk" in comps and p_zero.get("random_walk", 0) > 0.2:
            notes.append(
                f"random walk K is fitted as 0 in {100 * p_zero['random_walk']:.0f} % of bootstrap "
                "replicates: the record does not pin it down (GM/random-walk confounding; docs/method.md, "
                "section 'Identification')"
            )
        for i in range(1, n_gm + 1):
            s_lo, s_hi = intervals.get(f"gm_sigma_{i}", (np.nan, np.nan))
            if params[f"gm_sigma_{i}"] > 0 and np.isfinite(s_hi) and s_hi > 3 * max(s_lo, 1e-300):
                notes.append(
                    f"GM term {i}: sigma interval [{s_lo:.3g}, {s_hi:.3g}] spans more than a factor 3 "
                    "(poorly identified; GM and random walk trade off)"
                )
    n_free = int(np.count_nonzero(best.p)) + n_gm
    dof = int(t.size - n_free)
    # adequacy: the Pearson statistic against its own null distribution (AV correlation included)
    chi2_cov = None
    if rate is not None and n_samples is not None:
        n_curves = int(cid.max()) + 1
        lengths = _per_curve(n_samples, n_curves, "n_samples", np.int64)
        rates = _per_curve(rate, n_curves, "rate", np.float64)
        ms_all = np.rint(t * rates[cid]).astype(np.int64)
        cov_model = model if model.dt is not None else replace(model, dt=1.0 / float(rates[0]))
        try:
            chi2_cov = _chi2_covariance(y, best.m, cov_model, ms_all, cid, lengths, rates)
        except ValueError:  # averaging factors outside the record (inconsistent n_samples): no statistic
            chi2_cov = None
    adequacy = _adequacy(best.chi2, dof, chi2_boot if bootstrap != "chi2" else np.zeros(0), chi2_cov,
                         float(adequacy_level))
    on_boundary, interval_kind = {}, {}
    for k in names:
        on_boundary[k], interval_kind[k] = False, "two-sided"
    if n_gm and grid.size >= 2:
        g = np.sort(grid)
        for i in range(1, n_gm + 1):
            T_i = params.get(f"gm_T_{i}", float("nan"))
            if not np.isfinite(T_i):
                continue
            lo_i, hi_i = intervals.get(f"gm_T_{i}", (np.nan, np.nan))
            if T_i <= g[0] * (1 + 1e-3):
                # the data want a T at or below the shortest the search allows: only an upper end is known
                on_boundary[f"gm_T_{i}"] = True
                interval_kind[f"gm_T_{i}"] = "one-sided (upper end only; T at the lower end of the search)"
                up = max(hi_i if np.isfinite(hi_i) else -np.inf, g[1])
                intervals[f"gm_T_{i}"] = (0.0, float(up))
                notes.append(f"GM term {i}: T = {T_i:.3g} s sits on the lowest time constant searched; T is only "
                             f"bounded above ({up:.3g} s) and the term may be white noise seen through the "
                             "shortest tau")
            elif T_i >= g[-1] * (1 - 1e-3):
                on_boundary[f"gm_T_{i}"] = True
                interval_kind[f"gm_T_{i}"] = "one-sided (lower end only; T at the upper end of the search)"
                low = min(lo_i if np.isfinite(lo_i) else np.inf, g[-2])
                intervals[f"gm_T_{i}"] = (float(low), float("inf"))
                notes.append(f"GM term {i}: T = {T_i:.3g} s sits on the longest time constant searched; T is only "
                             f"bounded below ({low:.3g} s): the term is confounded with a random walk")
    if any(T_open) and not on_boundary.get("gm_T_1", False):
        side = "shortest" if T_open[0] else "longest"
        interval_kind["gm_T_1"] = (f"one-sided (the profile interval reaches the {side} time constant searched: "
                                   + ("lower end 0" if T_open[0] else "upper end inf")
                                   + ("; both ends open" if all(T_open) else "") + ")")
        notes.append(f"GM term 1: the data do not bound T {'below' if T_open[0] else 'above'} within the search "
                     f"({grid.min():.3g}-{grid.max():.3g} s) at {100 * c:.0f} % (profile of the fit statistic); "
                     "the interval is one-sided")
    if gm_sigma_profile and on_boundary.get("gm_T_1", False):
        # T on an end of the search: the GM is white noise seen through the shortest tau (level 2 sigma^2 T) or a
        # random walk seen through the longest (drift 2 sigma^2 / T), and with T held at that end sigma trades with
        # the white noise or the random walk, so its profile need not close (ADIS16405 gyro z, T on the longest
        # 655 s: widened upper end 6.7e27 rad/s); sigma is not identified there, so the percentile interval (the rule
        # before the profile) is reported and the profile kept beside it. A T inside the search keeps the profile.
        gm_sigma_profile["used"] = False
        intervals["gm_sigma_1"] = (float(gm_sigma_profile["percentile_lower"]),
                                   float(gm_sigma_profile["percentile_upper"]))
        notes.append("GM term 1: T on an end of the search, so sigma's profile interval is not identified "
                     f"([{gm_sigma_profile['lower']:.3g}, {gm_sigma_profile['upper']:.3g}]); the percentile "
                     "interval is reported")
    elif gm_sigma_profile:
        gm_sigma_profile["used"] = True
    if gm_sigma_profile and gm_sigma_profile["used"] and gm_sigma_profile["lower"] == 0.0:
        interval_kind["gm_sigma_1"] = ("one-sided (the profile interval reaches sigma = 0: the data do not exclude "
                                       "the GM's absence)")
    for k in names:
        if not k.startswith("gm_T") and params[k] == 0.0 and k in intervals:
            on_boundary[k] = True  # NNLS at its constraint: the interval's lower end is 0, one-sided
            interval_kind[k] = "one-sided (coefficient fitted as 0: upper end only)"
            lo_k, hi_k = intervals[k]
            intervals[k] = (0.0, hi_k)
    if n_boot > 0 and "random_walk" in comps and p_zero.get("random_walk", 0) > 0.2:
        interval_kind["random_walk"] = ("confounded with the GM: only the upper end is reliable (use it for "
                                        "bounding)")
        for i in range(1, n_gm + 1):
            if not on_boundary.get(f"gm_sigma_{i}") and f"gm_sigma_{i}" in interval_kind:
                interval_kind[f"gm_sigma_{i}"] = ("confounded with the random walk: only the upper end is "
                                                  "reliable (use it for bounding)")
    intervals_statistical = dict(intervals)
    if not adequacy["adequate"]:
        f = adequacy["widening"]
        for k, (lo_k, hi_k) in list(intervals.items()):
            est = params[k]
            if not (np.isfinite(est) and est > 0):
                continue
            # quasi-likelihood over-dispersion: the spread about the estimate scales by sqrt(phi),
            # on the log scale so a positive parameter keeps a positive interval
            # (in numpy floats: a widened end beyond the float range is 0 or inf, not an OverflowError)
            with np.errstate(over="ignore", under="ignore"):
                lo_w = est * np.float64(lo_k / est) ** f if np.isfinite(lo_k) and lo_k > 0 else lo_k
                hi_w = est * np.float64(hi_k / est) ** f if np.isfinite(hi_k) and hi_k > 0 else hi_k
            intervals[k] = (float(lo_w), float(hi_w))
        notes.append(
            f"the model does not describe the data: chi2/dof = {adequacy['chi2_per_dof']:.3g}, p = "
            f"{adequacy['p_value']:.3g} <= {adequacy_level:g} ({adequacy['method']}); the intervals are widened "
            f"by the over-dispersion factor {f:.3g} (quasi-likelihood) and are indicative only: a component is "
            "missing (e.g. a spectral line) or the pooled curves differ (see the pooling test)"
        )
    return AllanFit(
        model=model,
        params=params,
        intervals=intervals,
        p_zero=p_zero,
        confidence=c,
        chi2=best.chi2,
        dof=dof,
        n_points=int(t.size),
        components=comps,
        n_gm=n_gm,
        T_profile=profile,
        bootstrap=boots,
        param_names=names,
        notes=notes,
        T_grid=grid,
        random_walk_profile=random_walk_profile,
        gm_T_profile=gm_T_profile,
        white_profile=white_profile,
        gm_sigma_profile=gm_sigma_profile,
        adequacy=adequacy,
        on_boundary=on_boundary,
        interval_kind=interval_kind,
            intervals_statistical=intervals_statistical,
)


def _per_curve(v, n_curves, name, dtype):
    """A scalar or one value per curve as an array of `n_curves` values."""
    a = np.asarray(v, dtype=np.float64).ravel()
    if a.size == 1:
        a = np.full(n_curves, a[0])
    elif a.size < n_curves:
        raise ValueError(f"{name}: one value per pooled curve expected ({n_curves}), got {a.size}")
    a = a[:n_curves]
    return np.rint(a).astype(dtype) if np.dtype(dtype).kind in "iu" else a.astype(dtype)


def _correlated_draws(model, mean, ms, cid, lengths, rates, n_boot, rng):
    """Bootstrap AV replicates of every pooled curve: chi2 marginals, the model's correlation.

    Curves are independent records; within a curve the covariance is
    :func:`imupipe.avcov.avar_covariance` of the fitted model (computed once per distinct grid and
    record length and rate; `rates` one per curve, Hz).
    """
    from imupipe.avcov import correlated_replicates

    out = np.empty((n_boot, mean.size))
    for ci, sel, cov in _curve_covariances(model, ms, cid, lengths, rates):
        out[:, sel] = correlated_replicates(mean[sel], cov, n_boot, rng)
    return out


def _curve_covariances(model, ms, cid, lengths, rates):
    """(curve, point indices, AV covariance under `model`) of every pooled curve, u^4; one computation per
    distinct (averaging factors, record length, rate)."""
    from imupipe.avcov import avar_covariance

    cache = {}
    for ci in np.unique(cid):
        sel = np.flatnonzero(cid == ci)
        key = (tuple(ms[sel]), int(lengths[ci]), float(rates[ci]))
        if key not in cache:
            cache[key] = avar_covariance(model, ms[sel], int(lengths[ci]), float(rates[ci]))
        yield int(ci), sel, cache[key]


def _chi2_covariance(y, m, model, ms, cid, lengths, rates):
    r"""Generalised (Mahalanobis) statistic :math:`\sum_c r_c^T C_c^{-1} r_c`, :math:`r = y - m`, with
    :math:`C_c` the exact covariance of curve c's overlapping AV estimates under `model`
    (:func:`imupipe.avcov.avar_covariance`); eigen-directions below 1e-10 of the largest are left out (the
    AVs of neighbouring taus are nearly collinear). Dimensionless."""
    total = 0.0
    for _, sel, cov in _curve_covariances(model, ms, cid, lengths, rates):
        d = np.sqrt(np.diag(cov))
        rho = cov / np.outer(d, d)
        w, v = np.linalg.eigh(rho)
        keep = w > 1e-10 * w.max()
        z = v[:, keep].T @ ((y[sel] - m[sel]) / d)
        total += float(np.sum(z * z / w[keep]))
    return total


def slope_line(tau, adev, slope_tol: float = 0.25) -> dict:
    r"""Classic slope-line reading of an Allan deviation (IEEE Std 952 Annex C; Kalibr; MATLAB).

    * White (angle/velocity random walk): the :math:`-1/2` line through the point whose local
      log-log slope is closest to :math:`-1/2`, read at :math:`\tau = 1` s:
      :math:`N = \sigma(\tau_k)\sqrt{\tau_k}`.
    * Random walk: the :math:`+1/2` line through the point whose slope is closest to
      :math:`+1/2`, read at :math:`\tau = 3` s: :math:`K = \sigma(\tau_k)\sqrt{3/\tau_k}`
      (from :math:`\sigma^2 = K^2 \tau/3`).
    * Bias instability (flicker): :math:`B = \min \sigma / 0.664`, with
      :math:`0.664 = \sqrt{2\ln 2/\pi}`.

    The lines are drawn through :math:`\tau_k` (``tau_white``, ``tau_random_walk``), which can be far from
    the read-off tau: where the curve at 1 s (3 s) is not on the slope, the line's value there differs from
    the curve's. So the curve itself at the read-off taus is given too, interpolated linearly in
    :math:`(\log\tau, \log\sigma)` (None outside the curve): ``adev_at_1s`` (u; equal to N in u/sqrt(Hz)
    where the -1/2 line holds at 1 s) and ``adev_at_3s`` (u; :math:`K = \sigma(3\,s)` there).

    Local slopes are centred differences of :math:`\log\sigma` against :math:`\log\tau`. A line
    is reported only if the closest slope is within `slope_tol` of its nominal value; otherwise
    the value is None.

    Parameters
    ----------
    tau : array_like
        Averaging times, s, increasing.
    adev : array_like
        Allan deviation, u (e.g. rad/s).
    slope_tol : float, optional
        Accepted distance from +-1/2. Default 0.25.

    Returns
    -------
    dict
        ``white`` (N, u/sqrt(Hz)), ``random_walk`` (K, u/sqrt(s)), ``flicker`` (B, u),
        ``tau_white``, ``slope_white``, ``tau_random_walk``, ``slope_random_walk``, ``tau_min``
        (s), ``adev_min``, ``adev_at_1s``, ``adev_at_3s`` (u), ``method``.
    """
    t = np.asarray(tau, dtype=np.float64)
    s = np.asarray(adev, dtype=np.float64)
    ok = np.isfinite(t) & np.isfinite(s) & (t > 0) & (s > 0)
    t, s = t[ok], s[ok]
    if t.size < 3:
        raise ValueError("slope_line needs at least 3 positive, finite points")
    order = np.argsort(t)
    t, s = t[order], s[order]
    slope = np.gradient(np.log(s), np.log(t))
    out = {"method": "slope lines (IEEE Std 952 Annex C): N from the -1/2 line through tau_white read at tau=1 s, "
                     "K from the +1/2 line through tau_random_walk read at tau=3 s, B=min(ADEV)/0.664; "
                     "adev_at_1s/adev_at_3s: the curve itself there"}
    for name, at in (("adev_at_1s", 1.0), ("adev_at_3s", 3.0)):
        inside = t[0] <= at <= t[-1]
        out[name] = float(np.exp(np.interp(math.log(at), np.log(t), np.log(s)))) if inside else None
    i = int(np.argmin(np.abs(slope + 0.5)))
    if abs(slope[i] + 0.5) <= slope_tol:
        out.update(white=float(s[i] * math.sqrt(t[i])), tau_white=float(t[i]), slope_white=float(slope[i]))
    else:
        out.update(white=None, tau_white=None, slope_white=float(slope[i]))
    j = int(np.argmin(np.abs(slope - 0.5)))
    if abs(slope[j] - 0.5) <= slope_tol:
        out.update(
            random_walk=float(s[j] * math.sqrt(3.0 / t[j])), tau_random_walk=float(t[j]),
            slope_random_walk=float(slope[j]),
        )
    else:
        out.update(random_walk=None, tau_random_walk=None, slope_random_walk=float(slope[j]))
    k = int(np.argmin(s))
    out.update(flicker=float(s[k] / _FLICKER_ADEV), tau_min=float(t[k]), adev_min=float(s[k]))
    return out


def _refit_model(sol, comps, n_gm):
    """NoiseModel of a refit (helper of select_components)."""
    return _params_to_model(_solution_to_params(sol, comps, n_gm))


def _component_av(model, name, tau):
    """AV of one named component of `model` at tau (u^2)."""
    from imupipe.models import NoiseModel, gm_avar

    t = np.asarray(tau, dtype=np.float64)
    if name == "gauss_markov":
        out = np.zeros_like(t)
        for sg, T in model.gauss_markov:
            out = out + np.asarray(gm_avar(t, sg, T), dtype=np.float64)
        return out
    kw = {name: getattr(model, name)}
    return np.asarray(NoiseModel(**kw).avar(t), dtype=np.float64)


def _present(model):
    out = []
    for c in COMPONENTS:
        v = getattr(model, c)
        if (c == "gauss_markov" and len(v) > 0) or (c != "gauss_markov" and v > 0):
            out.append(c)
    return out


#: Components select_components decides on the data alone, whatever their share of the band: (reason kept, reason
#: dropped). White noise is a state-free part of every filter model; without a random walk the reduced model
#: (Gallon et al. 2021, eq. 19) is allowed.
_DATA_ONLY = {
    "white": ("kept: the data show a white noise (a -1/2 slope no other kept component gives)",
              "dropped: not significant against the AV confidence"),
    "random_walk": ("kept: the data show a random walk (eq. 17 with the p state)",
                    "dropped: no random walk in the data, reduced model (eq. 19) allowed"),
}


def _shown_by(z_shows: bool, chi2_shows: bool, chi2_ran: bool) -> str:
    """Which data test of :func:`select_components` showed a component, as the reason sentence says it."""
    if z_shows and chi2_shows:
        return "shown by the z test and by the chi-squared test of the refit"
    if z_shows:
        return "shown by the z test" + (", not by the chi-squared test of the refit" if chi2_ran else "")
    if chi2_shows:
        return "shown by the chi-squared test of the refit, not by the z test"
    return "shown by neither the z test nor the chi-squared test of the refit" if chi2_ran else "not shown by the z test"


def select_components(
    fit: AllanFit,
    tau,
    avar,
    edf,
    band_hz=None,
    rate_hz: float | None = None,
    horizon_s: float | None = None,
    significance: float = 0.05,
    relevance: float = 0.05,
    lr_test: bool = True,
) -> dict:
    r"""Keep only the components the data show and the application needs.

    Data test (per component :math:`c` of ``fit.model``): the data are refitted without
    :math:`c` (AV :math:`m_{-c}`); with the fitted total AV :math:`m(\tau)` and the AV estimate's
    standard deviation :math:`m\sqrt{2/\nu}`, the part of the component that the other components
    cannot absorb is significant if

    .. math::

        z_c = \max_k \frac{|m(\tau_k) - m_{-c}(\tau_k)|}{m(\tau_k)\sqrt{2/\nu_k}}
        > z_{1 - \alpha/(n J)},

    (Bonferroni over the :math:`n` AV points and the :math:`J` components tested,
    :math:`\alpha` = `significance`), or, when `lr_test`, if the refit's :math:`\chi^2` exceeds the
    full fit's by more than :math:`\chi^2_{d}(1-\alpha/J)` (:math:`d` = number of parameters
    removed). Comparing with a refit, not with the component's own fitted contribution, matters:
    components that substitute for each other (quantization + a short-T GM for part of the white
    noise) can each carry a large fitted contribution that the data do not require. For the random walk the test asks the paper's question, "does the AV rise at the long
    end?": the null drops the rate ramp too (it absorbs the rise and is no filter state) and caps
    the GM time constants at :math:`\tau_{max}/8`, so that a GM cannot mimic a +1/2 slope over the
    last octaves; a random walk and a GM with :math:`T` near the record length are
    indistinguishable there (docs/method.md, section "Identification"), and keeping the random-walk state is the integrity side.
    Keeping a component on either test is the conservative side. Both tests
    treat the AV points as independent; overlapping AV estimates at neighbouring taus are
    positively correlated, so the nominal level is approximate (a component fitted to a chance
    fluctuation at the shortest taus is the typical false positive).

    Band test: the component matters if somewhere in the application's band it carries at least
    `relevance` of the model AV, :math:`\max_{\tau \in [\tau_a, \tau_b]} \sigma_c^2/\sigma^2 \ge`
    `relevance`, with :math:`\tau_a = 1/(2 f_{hi})` and :math:`\tau_b = 1/(2 f_{lo})` (the AV at
    :math:`\tau` responds mostly to :math:`f \approx 1/(2\tau)`). The band is `band_hz`, or
    :math:`(1/\text{horizon}, \text{rate}/2)` from the filter rate and horizon; without either, every
    component is taken as relevant.

    Decision: keep = data test and band test, except the random walk, which is kept whenever the data
    show it: the paper's reduced model without the random-walk state (Gallon et al. 2021, eq. 19) is
    allowed only when the AV shows no random walk.

    Parameters
    ----------
    fit : AllanFit
        Result of :func:`fit_allan` on the same data.
    tau, avar, edf : array_like or sequences
        The AV data of the fit (pooled the same way), s, u^2, 1.
    band_hz : tuple of float, optional
        (f_lo, f_hi) of the application, Hz.
    rate_hz : float, optional
        Filter rate, Hz (f_hi = rate_hz/2) when `band_hz` is not given.
    horizon_s : float, optional
        Filter horizon (longest interval the filter must propagate without aiding), s
        (f_lo = 1/horizon_s).
    significance : float, optional
        Family-wise level :math:`\alpha`. Default 0.05.
    relevance : float, optional
        Minimum share of the model AV inside the band. Default 0.05.
    lr_test : bool, optional
        Also apply the chi-squared (likelihood-ratio-like) test of the refit. Default True.

    Returns
    -------
    dict
        ``kept`` (list of component names), ``dropped``, ``reasons`` (name -> sentence),
        ``details`` (name -> z and its critical value ``z_crit``, tau at max z, delta chi2 and its critical value
        ``delta_chi2_crit`` :math:`\chi^2_{d}(1-\alpha/J)`, band share, ``shown_by_z``, ``shown_by_chi2``);
        each reason names the test(s) that showed the component and prints both critical values, ``reduced_model``
        (True when eq. 19 without random walk is allowed), ``band_hz``, ``significance``,
        ``relevance``.
    """
    # scipy.special, not scipy.stats (same functions, 0.5 s less of import): -ndtri(p) is the
    # standard normal upper quantile norm.isf(p), chdtri(df, p) the chi-squared one chi2.isf(p, df)
    from scipy.special import chdtri, ndtri

    t, y, e = _pool(tau, avar, edf)
    model = fit.model
    m = np.asarray(model.avar(t), dtype=np.float64)
    sd = m * np.sqrt(2.0 / e)
    present = _present(model)
    if "white" in fit.components and "white" not in present:
        # a white noise the full fit gave to quantization and a GM at the shortest T is still tested: the
        # selected model must not lose it (n_gm = 2 did in most records)
        present = ["white"] + present
    n_tested = max(1, len(present))
    # Bonferroni over the AV points and over the components tested
    zcrit = float(-ndtri(significance / (t.size * n_tested)))

    if band_hz is not None:
        f_lo, f_hi = (float(band_hz[0]), float(band_hz[1]))
    elif rate_hz is not None or horizon_s is not None:
        f_hi = float(rate_hz) / 2.0 if rate_hz is not None else 0.5 / float(t.min())
        f_lo = 1.0 / float(horizon_s) if horizon_s is not None else 0.5 / float(t.max())
    else:
        f_lo = f_hi = None
    if f_lo is not None and not (0 < f_lo < f_hi):
        raise ValueError(f"band must satisfy 0 < f_lo < f_hi, got ({f_lo}, {f_hi})")
    if f_lo is not None:
        tb = np.logspace(math.log10(0.5 / f_hi), math.log10(0.5 / f_lo), 200)
        m_band = np.asarray(model.avar(tb), dtype=np.float64)

    kept, dropped, reasons, details = [], [], {}, {}
    for c in COMPONENTS:
        if c not in present:
            if c in fit.components:
                dropped.append(c)
                reasons[c] = "fitted coefficient is zero"
                details[c] = {"z": 0.0}
            continue
        removed = (c,) + _SUBSTITUTES.get(c, ())
        comps = tuple(x for x in fit.components if x not in removed)
        d_chi2 = chi2_crit = None
        lr_shows = False
        if comps:
            n_removed = sum(fit.n_gm * 2 if x == "gauss_markov" else 1 for x in removed if x in fit.components)
            grid = fit.T_grid if fit.T_grid.size else _default_T_grid(t)
            if c == "random_walk":
                # the null must not rise at the long end: its GM peak (1.89 T) stays two octaves
                # below the longest tau, so a +1/2 slope there counts as random-walk evidence
                grid = grid[grid <= t.max() / 8.0]
                if grid.size == 0:
                    comps = tuple(x for x in comps if x != "gauss_markov")
            elif c == "white":
                # nor mimic white noise at the short end: a GM with T well below tau has AV 2 sigma^2 T/tau,
                # a -1/2 slope; its T stays three octaves above the shortest tau
                grid = grid[grid >= 8.0 * t.min()]
                if grid.size == 0:
                    comps = tuple(x for x in comps if x != "gauss_markov")
            alt, _ = _profile(t, y, e, comps, fit.n_gm, grid)
            m_null = np.asarray(_refit_model(alt, comps, fit.n_gm).avar(t), dtype=np.float64)
            if lr_test:
                d_chi2 = float(alt.chi2 - fit.chi2)
                chi2_crit = float(chdtri(n_removed, significance / n_tested))
                lr_shows = bool(d_chi2 > chi2_crit)
        else:
            m_null = np.zeros_like(m)
        # the part of the component the other components cannot absorb, against the AV's spread
        z = np.abs(m - m_null) / sd
        k = int(np.argmax(z))
        shows = bool(z[k] > zcrit)
        data = shows or lr_shows
        share = None
        if f_lo is not None:
            share = float(np.max(_component_av(model, c, tb) / m_band))
            relevant = share >= relevance
        else:
            relevant = True
        details[c] = {"z": float(z[k]), "z_crit": zcrit, "tau_at_max_z": float(t[k]),
                      "delta_chi2": d_chi2, "delta_chi2_crit": chi2_crit, "band_share": share,
                      "shown_by_z": shows, "shown_by_chi2": lr_shows}
        why = (
            f"{_shown_by(shows, lr_shows, d_chi2 is not None)}; "
            f"max z = {z[k]:.3g} at tau = {t[k]:.3g} s (critical {zcrit:.3g})"
            + (f", refit without it: delta chi2 = {d_chi2:.3g} (critical {chi2_crit:.3g})"
               if d_chi2 is not None else "")
            + (f", band share {share:.3g}" if share is not None else "")
        )
        if c in _DATA_ONLY:
            keep, reason = data, _DATA_ONLY[c][0 if data else 1]
        elif data and relevant:
            keep, reason = True, "kept: significant in the AV and relevant in the band"
        elif not data:
            keep, reason = False, "dropped: not significant against the AV confidence"
        else:
            keep, reason = False, f"dropped: below {relevance:g} of the model AV inside the band"
        (kept if keep else dropped).append(c)
        reasons[c] = f"{reason}; {why}"
    if "flicker" in kept:
        reasons["flicker"] += " (not a Kalman-filter state: represented by a GM in the bound)"
    return {
        "kept": kept,
        "dropped": dropped,
        "reasons": reasons,
        "details": details,
        "reduced_model": "random_walk" not in kept,
        "band_hz": None if f_lo is None else [f_lo, f_hi],
        "significance": float(significance),
        "relevance": float(relevance),
    }


def refit_selected(fit: AllanFit, selection: dict, tau, avar, edf, **fit_kwargs) -> AllanFit:
    r"""The selected model refitted: :func:`fit_allan` on the same data with only the components
    :func:`select_components` kept, attached to `fit` as ``fit.selected`` (an :class:`AllanFit`) and returned.

    The parameters to report and bound are this refit's, not the full fit's: in the full fit quantization
    and a short-T GM absorb part of the white noise (N biased low by 0.1-0.2 %, intervals that under-cover);
    dropped components no longer take a share of the AV. Flicker, when kept, stays a component of the refit
    (the bound represents it). The GM count is the full fit's when ``gauss_markov`` is kept.

    Parameters
    ----------
    fit : AllanFit
        The full fit.
    selection : dict
        :func:`select_components` of `fit` on the same data (its ``kept``).
    tau, avar, edf : array_like or sequences
        The data of `fit`.
    **fit_kwargs
        Passed to :func:`fit_allan` (``n_boot``, ``confidence``, ``rng``, ``rate``, ``n_samples``, ``dt``,
        ``T_grid``, ...); ``components`` and ``n_gm`` are set here. Default ``confidence`` that of `fit`.

    A random walk the selection dropped (the data do not show it) is not thereby absent: with a bootstrap,
    the refit also carries ``random_walk`` = 0 with the interval [0, upper], the upper limit of the fit with
    the random walk (its profile limit), flagged ``on_boundary``: the integrity side for the bound. Measured:
    a MEMS truth with K = 2e-6 m/s^2/sqrt(s) under two GMs (10 h at 10 Hz) had K dropped in 99 % of records.

    Returns
    -------
    AllanFit
        The refit; its ``selection`` is `selection`. When nothing is kept, ValueError.
    """
    kept = tuple(c for c in COMPONENTS if c in selection.get("kept", ()))
    if not kept:
        raise ValueError("select_components kept no component: nothing to refit")
    kw = dict(fit_kwargs)
    kw.pop("components", None)
    kw.pop("n_gm", None)
    kw.setdefault("confidence", fit.confidence)
    if fit.T_grid.size and "T_grid" not in kw:
        kw["T_grid"] = fit.T_grid
    sel = fit_allan(tau, avar, edf, components=kept, n_gm=max(fit.n_gm, 1) if "gauss_markov" in kept else 0,
                    **kw)
    sel.selection = dict(selection)
    sel.notes = [f"refit of the selected components {list(kept)}"] + list(sel.notes)
    if "random_walk" in fit.components and "random_walk" not in kept and kw.get("n_boot", 200) > 0:
        # not shown by the data is not shown absent: the upper limit K the data cannot exclude (the fit with
        # the random walk, its profile limit) is reported for bounding; the estimate stays 0
        comps_rw = tuple(c for c in COMPONENTS if c in kept or c == "random_walk")
        with_rw = fit_allan(tau, avar, edf, components=comps_rw,
                            n_gm=max(fit.n_gm, 1) if "gauss_markov" in kept else 0, **kw)
        up = with_rw.intervals.get("random_walk", (np.nan, np.nan))[1]
        if np.isfinite(up) or up == np.inf:
            sel.params["random_walk"] = 0.0
            sel.intervals["random_walk"] = (0.0, float(up))
            # and before any over-dispersion widening: the limit the upper envelope reads (imupipe.bound)
            up_stat = (with_rw.intervals_statistical or with_rw.intervals).get("random_walk", (np.nan, up))[1]
            sel.intervals_statistical["random_walk"] = (0.0, float(up_stat))
            sel.on_boundary["random_walk"] = True
            sel.interval_kind["random_walk"] = ("dropped by the selection (not shown by the data): upper limit "
                                                "from the fit with a random walk, for bounding")
            sel.notes.append(f"random walk not shown by the data but not excluded either: K <= {up:.3g} u/sqrt(s) "
                             f"at {100 * kw['confidence']:.0f} % (fit with the random walk); a bound covers it")
        _hull_gm_intervals(sel, with_rw)
    fit.selected = sel
    fit.selection = dict(selection)
    return sel


def _profiled_in(fit: AllanFit, name: str) -> bool:
    """Is `fit`'s interval of `name` a profile interval (a single GM's T or sigma)? Helper of
    :func:`_hull_gm_intervals`."""
    return (name == "gm_T_1" and bool(fit.gm_T_profile)) or (
        name == "gm_sigma_1" and bool(fit.gm_sigma_profile) and fit.gm_sigma_profile.get("used", True))


def _hull_gm_intervals(sel: AllanFit, with_rw: AllanFit) -> None:
    """The GM intervals of `sel` (a refit without the random walk) given what the fit with a random walk
    (`with_rw`, same data) allows, in place; helper of :func:`refit_selected`.

    A GM and a random walk trade off in records of a few hours: without the random walk the GM absorbs its rise
    (a longer T, a larger sigma), and the refit's intervals, conditional on K = 0, can exclude the truth
    (measured: a tactical gyro truth with K > 0, 10 h at 10 Hz, K dropped in about 10 % of the records, GM T
    and sigma missed in most of those). The fit with the random walk contains both models (K >= 0), so:

    * a single GM's time constant and sigma, whose intervals there are (or include) profile intervals (test
      inversion in the larger model, calibrated whichever model holds), are taken from the fit with the random
      walk (measured, development seeds: with the random walk dropped the refit's own sigma interval missed the
      tactical truth in all 19 of 200 records, above it; the hull with the larger fit's percentile interval in
      5 of them, its lower end just above the truth; that fit's profile interval in none);
    * a percentile-only interval (the GM intervals of two GM terms) is the hull of the two: the percentile
      interval of the larger model is centred on an estimate the random walk pulls low when the truth has none
      (measured: GM sigma covered 0.85 of 100 white + GM records without a random walk, 0.90 for the refit's
      own), the refit's on one pushed high when it has one.
    """
    def hull(dst, src, name):
        """`dst[name]` replaced by the rule above from `src`; True when it changed."""
        if name not in src or name not in dst:
            return False
        lo_s, hi_s = dst[name]
        lo_w, hi_w = src[name]
        if not (np.isfinite(hi_w) or hi_w == np.inf) or not (np.isfinite(lo_w) or lo_w == 0.0):
            return False  # the term vanished in the fit with the random walk: nothing to take from it
        if _profiled_in(with_rw, name):
            lo, hi = lo_w, hi_w
        else:
            lo = lo_w if not np.isfinite(lo_s) else min(lo_s, lo_w)
            hi = hi_w if not (np.isfinite(hi_s) or hi_s == np.inf) else max(hi_s, hi_w)
        if (lo, hi) == (lo_s, hi_s):
            return False
        dst[name] = (float(lo), float(hi))
        return True

    for name in list(sel.intervals):
        if not name.startswith(("gm_sigma_", "gm_T_")):
            continue
        # the statistical intervals (before any over-dispersion widening, what the upper envelope reads) too
        if sel.intervals_statistical:
            hull(sel.intervals_statistical, with_rw.intervals_statistical or with_rw.intervals, name)
        if not hull(sel.intervals, with_rw.intervals, name):
            continue
        profiled = _profiled_in(with_rw, name)
        kind = with_rw.interval_kind.get(name, "two-sided")
        if kind.startswith("one-sided"):
            sel.interval_kind[name] = kind + " (from the fit with the random walk)"
        elif profiled:
            sel.interval_kind[name] = "two-sided (the fit with the random walk's: GM/random-walk confounding)"
        elif not sel.interval_kind.get(name, "").startswith("one-sided"):
            sel.interval_kind[name] = "two-sided (hull with the fit with the random walk: GM/random-walk confounding)"
    if with_rw.gm_T_profile and "gm_T_1" in sel.intervals and "gm_T_1" in with_rw.intervals:
        sel.gm_T_profile = dict(with_rw.gm_T_profile)  # the profile the reported T interval comes from
    if with_rw.gm_sigma_profile and "gm_sigma_1" in sel.intervals and "gm_sigma_1" in with_rw.intervals:
        sel.gm_sigma_profile = dict(with_rw.gm_sigma_profile)  # the same for sigma
    sel.notes.append("GM intervals given the dropped random walk: T and sigma of a single GM from the fit with the "
                     "random walk (its profile intervals), the GM intervals of two GM terms the hull of the refit's "
                     "and that fit's (docs/method.md, section 'Identification')")

def pooling_test(
    tau,
    avar,
    edf,
    components=("white", "gauss_markov", "random_walk"),
    n_gm: int = 1,
    rate=None,
    n_samples=None,
    labels=None,
    n_boot: int = 99,
    level: float = 0.01,
    T_grid=None,
    rng=None,
) -> dict:
    r"""Are several AV curves (axes, units of one sensor type) consistent with one model?

    Statistic: the drop of the fit statistic from one pooled fit to one fit per curve, relative to the
    per-curve fits' own misfit (an F-type ratio, so a misfit every curve shares, e.g. a component the model
    lacks, does not count as a difference between curves; the median over curves, so that one badly fitted
    curve does not hide the differences between the others):

    .. math::

        F = \frac{(\chi^2_{pooled} - \sum_c \chi^2_c) / d_1}{\mathrm{median}_c(\chi^2_c / \mathrm{dof}_c)},
        \quad d_1 = (C - 1)\,p,

    with :math:`p` the number of free parameters (coefficients + GM time constants). Calibration: `n_boot`
    replicates of every curve drawn from the pooled fit with the exact correlation of the overlapping AV
    estimates (:func:`imupipe.avcov.avar_covariance`, each curve with its own record length and rate), refitted
    pooled and per curve; :math:`p = (1 + \#\{F^* \ge F\})/(1 + B)` (parametric bootstrap likelihood-ratio
    test, Davison & Hinkley 1997, section 4.2). ``consistent = p > level`` (exact level when level (1 + B) is
    an integer: B = 99 at 0.01, 19 at 0.05).

    Parameters
    ----------
    tau, avar, edf : sequences of array_like
        One curve each (different lengths allowed), s, u^2, 1.
    components, n_gm, T_grid : as :func:`fit_allan`.
    rate : float or sequence of float
        Sampling rate of each curve's record, Hz.
    n_samples : int or sequence of int
        Record length of each curve, samples.
    labels : sequence of str, optional
        Curve labels (e.g. ``"imu1/x"``) for the result.
    n_boot : int, optional
        Bootstrap replicates. Default 99.
    level : float, optional
        Level of the test. Default 0.01.
    rng : numpy.random.Generator or int, optional

    Returns
    -------
    dict
        ``consistent``, ``statistic`` (F), ``p_value``, ``p_value_resolution``, ``level``, ``d1``, ``d2`` (sum of
        the per-curve dof),
        ``chi2_pooled``, ``method``, ``pooled`` (parameters of the pooled fit), ``per_curve`` (list of
        ``{label, params, chi2, dof, chi2_per_dof, p_value, adequate}`` with the covariance adequacy of each
        curve's own fit, SI parameters as :attr:`AllanFit.params`), ``note``.
    """
    t, y, e, cid = _pool(tau, avar, edf, return_curve=True)
    n_curves = int(cid.max()) + 1
    if rate is None or n_samples is None:
        raise ValueError("pooling_test needs rate= (Hz) and n_samples= per curve (the bootstrap draws each "
                         "curve with its own record length and rate)")
    rates = _per_curve(rate, n_curves, "rate", np.float64)
    lengths = _per_curve(n_samples, n_curves, "n_samples", np.int64)
    labels = [f"curve_{i}" for i in range(n_curves)] if labels is None else [str(v) for v in labels]
    if len(labels) != n_curves:
        raise ValueError(f"labels: one per curve expected ({n_curves}), got {len(labels)}")
    kw = dict(components=components, n_gm=n_gm, T_grid=T_grid, n_boot=0)
    comps = _check_components(components, n_gm)
    grid = _default_T_grid(t) if T_grid is None else np.asarray(T_grid, dtype=np.float64)
    ngm = int(n_gm) if "gauss_markov" in comps else 0
    sels = [np.flatnonzero(cid == c) for c in range(n_curves)]

    def stat(yy):
        pooled, _ = _profile(t, yy, e, comps, ngm, grid)
        per = [_profile(t[s], yy[s], e[s], comps, ngm, grid)[0] for s in sels]
        n_free = pooled.p.size + ngm
        d1 = max((n_curves - 1) * n_free, 1)
        d2 = max(int(sum(s.size - (sol.p.size + ngm) for s, sol in zip(sels, per))), 1)
        chi2_per = float(sum(sol.chi2 for sol in per))
        # each curve's own misfit per degree of freedom; the median, so that one badly fitted curve does not
        # hide the differences between the others
        phi = float(np.median([sol.chi2 / max(s.size - (sol.p.size + ngm), 1) for s, sol in zip(sels, per)]))
        return (pooled.chi2 - chi2_per) / d1 / max(phi, 1e-300), pooled, per, d1, d2

    F, pooled, per, d1, d2 = stat(y)
    rng = np.random.default_rng(rng)
    model = _params_to_model(_solution_to_params(pooled, comps, ngm), 1.0 / float(rates[0]))
    ms = np.rint(t * rates[cid]).astype(np.int64)
    F_boot = np.empty(0)
    if n_boot > 0 and n_curves > 1:
        draws = _correlated_draws(model, pooled.m, ms, cid, lengths, rates, int(n_boot), rng)
        F_boot = np.array([stat(np.maximum(d, 1e-300))[0] for d in draws])
    d2 = int(sum(s.size - (sol.p.size + ngm) for s, sol in zip(sels, per)))
    p = (1.0 + np.count_nonzero(F_boot >= F)) / (1.0 + F_boot.size) if F_boot.size else float("nan")
    per_curve = []
    for c, (s, sol) in enumerate(zip(sels, per)):
        params = _solution_to_params(sol, comps, ngm)
        m_c = _params_to_model(params, 1.0 / float(rates[c]))
        dof_c = int(s.size - np.count_nonzero(sol.p) - ngm)
        try:
            chi2_cov = _chi2_covariance(y[s], sol.m, m_c, ms[s], np.zeros(s.size, dtype=np.int64), lengths[[c]],
                                        rates[[c]])
        except ValueError:
            chi2_cov = None
        ad = _adequacy(sol.chi2, dof_c, np.zeros(0), chi2_cov, float(level))
        per_curve.append({"label": labels[c], "params": {k: float(v) for k, v in params.items()},
                          "chi2": float(sol.chi2), "dof": dof_c, "chi2_per_dof": ad["chi2_per_dof"],
                          "p_value": ad["p_value"], "adequate": ad["adequate"], "rate_hz": float(rates[c]),
                          "n_samples": int(lengths[c])})
    consistent = bool(not np.isfinite(p) or p > level)
    if n_curves == 1:
        note = "one curve: nothing to pool"
    elif consistent:
        note = f"the {n_curves} curves are consistent with one model (p = {p:.3g} > {level:g}): pooled fit used"
    else:
        note = (f"the {n_curves} curves are not consistent with one model (p = {p:.3g} <= {level:g}): identify per "
                "curve (or per group); the per-curve parameters are given, and a bound must cover every curve")
    return {
        "consistent": consistent,
        "statistic": float(F),
        "p_value": float(p),
        "p_value_resolution": 1.0 / (1.0 + F_boot.size) if F_boot.size else None,
        "level": float(level),
        "d1": int(d1),
        "d2": int(d2),
        "chi2_pooled": float(pooled.chi2),
        "method": ("F = ((chi2_pooled - sum chi2_curve)/d1)/median(chi2_curve/dof_curve), calibrated on "
                   f"{F_boot.size} replicates of the pooled fit with the exact AV correlation (per-curve "
                   "length and rate), refitted pooled and per curve"),
        "pooled": {k: float(v) for k, v in _solution_to_params(pooled, comps, ngm).items()},
        "per_curve": per_curve,
        "units": "params SI as AllanFit.params (white u/sqrt(Hz), random_walk u/sqrt(s), gm_sigma u, gm_T s); "
                 "statistics dimensionless; rate_hz Hz",
        "note": note,
    }


