r"""The linear model of Allan variances and its weighted non-negative least-squares fit.

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
This module holds the columns of that model (:func:`av_basis`), the pooling of several curves into one
problem, the re-weighted NNLS at fixed time constants (:func:`_wnnls`, quasi-likelihood of gamma-distributed
AV estimates, McCullagh & Nelder 1989, chapter 8) and the profile over :math:`T` (:func:`_profile`), which
:mod:`imupipe.identify.fit`, :mod:`~imupipe.identify.select` and :mod:`~imupipe.identify.pooling` share.

All values are SI: rate unit u (rad/s or m/s^2), :math:`N` in u/sqrt(Hz), :math:`K` in u/sqrt(s),
:math:`\sigma` and :math:`B` in u, :math:`T` and :math:`\tau` in s, :math:`Q` in u s,
:math:`R` in u/s.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

try:  # optional compiled kernel: the whole re-weighted NNLS in one call (see _wnnls)
    from imupipe import _kernels
except ImportError:  # pragma: no cover - exercised where the extension is not built
    _kernels = None

__all__ = ["COMPONENTS", "av_basis"]

#: Components :func:`fit_allan` knows, in the order of the linear coefficients.
COMPONENTS = ("white", "gauss_markov", "random_walk", "flicker", "quantization", "ramp")

#: sqrt(2 ln 2 / pi): flicker ADEV plateau = 0.664 B (IEEE Std 952; docs/method.md, section "Slip: the flicker constant and Gauss-Markov").
_FLICKER_ADEV = math.sqrt(2.0 * math.log(2.0) / math.pi)


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


def _pool(tau, avar, edf, return_curve=False, known=None):
    """Concatenate one curve or several into flat arrays (curves may have different lengths: records of
    different length or rate).

    `avar`: one 1-D array, a 2-D array (curve, tau) or a sequence of 1-D arrays; `tau`: the same shape, or one
    1-D grid shared by every curve; `edf`: a scalar, the same shape as `avar`, or one 1-D array per tau of a
    shared grid. Points with non-finite or non-positive AV, tau or edf are dropped. With `return_curve`, the
    curve index of every point is returned too. With `known` (a known part of each AV, u^2, the same shape as
    `avar`: e.g. the Allan variance of the spectral lines, :func:`known_line_avar`), it is pooled the same way
    and returned last (None where not given).
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
    kn = None
    if known is not None:
        ks = _curves_of(known, "known")
        if ks is None:
            ks = [np.ravel(np.asarray(known, dtype=np.float64))]
        if len(ks) != len(ys) or any(a.size != b.size for a, b in zip(ks, ys)):
            raise ValueError(f"known (curves of {[x.size for x in ks]}) does not match avar (curves of "
                             f"{[y.size for y in ys]})")
        kn = np.concatenate(ks)[ok]
        if not (np.all(np.isfinite(kn)) and np.all(kn >= 0)):
            raise ValueError("known: the known Allan variance must be finite and >= 0 (u^2) at every usable point")
    if return_curve:
        return (t[ok], y[ok], e[ok], cid[ok]) + ((kn,) if known is not None else ())
    return (t[ok], y[ok], e[ok]) + ((kn,) if known is not None else ())


def _plus(known, held):
    """The fixed part of a fit's model (u^2 per AV point): the known AV `known` (e.g. spectral lines) plus the AV
    of a component held at a value, `held`; None when both are None (no fixed part: the fit's arithmetic is then
    exactly that of a fit without one)."""
    if known is None:
        return held
    return known if held is None else known + held


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
    comps = [c for c in components if c in COMPONENTS]
    # filled in place (the profiles call this some 10^5 times per job: no list of columns to stack)
    A = np.empty((t.size, sum(len(T) if c == "gauss_markov" else 1 for c in comps)))
    names, k = [], 0
    for c in comps:
        if c == "gauss_markov":
            key = t.tobytes()
            for i, Ti in enumerate(T):
                A[:, k + i] = _gm_column(key, float(Ti))
                names.append(f"gm_{i + 1}")
            k += len(T)
            continue
        if c == "white":
            np.divide(1.0, t, out=A[:, k])
        elif c == "random_walk":
            np.divide(t, 3.0, out=A[:, k])
        elif c == "flicker":
            A[:, k] = _FLICKER_ADEV**2
        elif c == "quantization":
            np.divide(3.0, t**2, out=A[:, k])
        else:  # ramp
            np.divide(t**2, 2.0, out=A[:, k])
        names.append(c)
        k += 1
    return A, names


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

    The iteration stops once the model moves by less than `rtol` (relative) at every tau; the default 1e-6
    moves the fitted parameters far less than their statistical uncertainty (the comparison with a 1e-9
    stop: docs/performance.md).

    `backend`: ``"c"`` (``imupipe._kernels.wnnls``: the same iteration, each NNLS by Lawson & Hanson's
    active-set method on Householder QR, 1974, ch. 23), ``"scipy"`` (:func:`scipy.optimize.nnls` per pass)
    or ``"auto"`` (the kernel when built). The fits of a job call this some 10^4 times on a few dozen taus and
    3-5 columns, where the Python path's overhead dominates the solving (docs/performance.md); the kernel's
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


def _per_curve(v, n_curves, name, dtype):
    """A scalar or one value per curve as an array of `n_curves` values."""
    a = np.asarray(v, dtype=np.float64).ravel()
    if a.size == 1:
        a = np.full(n_curves, a[0])
    elif a.size < n_curves:
        raise ValueError(f"{name}: one value per pooled curve expected ({n_curves}), got {a.size}")
    a = a[:n_curves]
    return np.rint(a).astype(dtype) if np.dtype(dtype).kind in "iu" else a.astype(dtype)

