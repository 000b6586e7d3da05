r"""Bounded scalar minimisation without importing :mod:`scipy.optimize` (~0.7 s of a job's start).

The per-axis bound jobs (30 per spec sheet) and the identification refine one Gauss-Markov time constant
in :math:`\ln T` between two grid neighbours; this is the only use of :mod:`scipy.optimize` on those paths,
and its import cost more than the search itself. :func:`minimize_bounded` is Brent's method (golden-section
steps with parabolic interpolation, Brent 1973, ch. 5; the ``fmin`` procedure of Forsythe, Malcolm & Moler
1977), the same method and stopping rule as ``scipy.optimize.minimize_scalar(method="bounded")``: on the same
function it evaluates the same points in the same order (``tests/test_search.py`` checks this point by point
on many functions), so the results of the workflow do not change.

References
----------
R. P. Brent, *Algorithms for Minimization without Derivatives*, Prentice-Hall, 1973, chapter 5.
G. E. Forsythe, M. A. Malcolm, C. B. Moler, *Computer Methods for Mathematical Computations*,
Prentice-Hall, 1977, section 8.2 (``fmin``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

__all__ = ["BoundedMinimum", "log_grid", "minimize_bounded", "refine_between_neighbours"]

#: Relative tolerance on x: the square root of the double-precision machine epsilon (as rounded in scipy).
_SQRT_EPS = math.sqrt(2.2e-16)
#: Golden-section fraction (3 - sqrt 5) / 2.
_GOLDEN = 0.5 * (3.0 - math.sqrt(5.0))


class BoundedMinimum(NamedTuple):
    """Result of :func:`minimize_bounded`: the best point ``x``, its value ``fun``, the number of function
    evaluations ``nfev`` and whether the tolerance was reached (``success``; False after `maxiter`)."""

    x: float
    fun: float
    nfev: int
    success: bool


def _sign(v: float) -> float:
    """+1 for v >= 0, -1 below (a step direction: zero counts as positive)."""
    return -1.0 if v < 0 else 1.0


def minimize_bounded(fun: Callable[[float], float], lo: float, hi: float, xatol: float = 1e-5,
                     maxiter: int = 500) -> BoundedMinimum:
    r"""Minimum of a scalar function on the interval [lo, hi] by Brent's method.

    Each step is a parabola through the three best points when it falls inside the bracket and moves by less
    than half the step before last, and a golden-section step into the larger part of the bracket otherwise;
    no point is evaluated closer than ``tol1`` to the current best. Stops when the best point lies within
    :math:`2\,tol_1 - (b - a)/2` of the bracket's middle, :math:`tol_1 = \sqrt{\epsilon}\,|x| + xatol/3`.

    Parameters
    ----------
    fun : callable
        float -> float, the function to minimise.
    lo, hi : float
        The interval, lo < hi (units of x).
    xatol : float, optional
        Absolute tolerance on x (units of x). Default 1e-5, scipy's.
    maxiter : int, optional
        Most function evaluations. Default 500, scipy's.

    Returns
    -------
    BoundedMinimum
        ``x``, ``fun``, ``nfev``, ``success``.

    Raises
    ------
    ValueError
        lo >= hi or non-finite bounds.
    """
    a, b = float(lo), float(hi)
    if not (math.isfinite(a) and math.isfinite(b)) or a >= b:
        raise ValueError(f"minimize_bounded: expected finite bounds lo < hi, got lo = {lo!r}, hi = {hi!r}")
    # x: best point so far; w: second best; v: the previous value of w (Brent's names)
    x = w = v = a + _GOLDEN * (b - a)
    fx = float(fun(x))
    fw = fv = fx
    nfev = 1
    d = e = 0.0  # the last step and the one before
    mid = 0.5 * (a + b)
    tol1 = _SQRT_EPS * abs(x) + xatol / 3.0
    tol2 = 2.0 * tol1
    success = True
    while abs(x - mid) > tol2 - 0.5 * (b - a):
        golden = True
        if abs(e) > tol1:
            # parabola through (x, fx), (w, fw), (v, fv): its vertex is x + p / q
            r = (x - w) * (fx - fv)
            q = (x - v) * (fx - fw)
            p = (x - v) * q - (x - w) * r
            q = 2.0 * (q - r)
            if q > 0.0:
                p = -p
            q = abs(q)
            e_prev, e = e, d
            if abs(p) < abs(0.5 * q * e_prev) and q * (a - x) < p < q * (b - x):
                golden = False
                d = p / q
                u = x + d
                if u - a < tol2 or b - u < tol2:  # not too close to the ends
                    d = tol1 * _sign(mid - x)
        if golden:
            e = (a - x) if x >= mid else (b - x)
            d = _GOLDEN * e
        u = x + _sign(d) * max(abs(d), tol1)
        fu = float(fun(u))
        nfev += 1
        if fu <= fx:
            if u >= x:
                a = x
            else:
                b = x
            v, fv = w, fw
            w, fw = x, fx
            x, fx = u, fu
        else:
            if u < x:
                a = u
            else:
                b = u
            if fu <= fw or w == x:
                v, fv = w, fw
                w, fw = u, fu
            elif fu <= fv or v == x or v == w:
                v, fv = u, fu
        mid = 0.5 * (a + b)
        tol1 = _SQRT_EPS * abs(x) + xatol / 3.0
        tol2 = 2.0 * tol1
        if nfev >= maxiter:
            success = False
            break
    return BoundedMinimum(x, fx, nfev, success)


def log_grid(lo_log10: float, hi_log10: float, per_decade: float, min_points: int = 1):
    r"""Log-spaced grid from :math:`10^{lo}` to :math:`10^{hi}` with `per_decade` points per decade
    (rounded to a whole count, both ends included, at least `min_points`): the grid of Gauss-Markov time
    constants (s) profiled by the identification and the bound before the refinement of
    :func:`refine_between_neighbours`. Returns a numpy array."""
    import numpy as np

    n = max(int(min_points), int(round((hi_log10 - lo_log10) * per_decade)) + 1)
    return np.logspace(lo_log10, hi_log10, n)


def refine_between_neighbours(fun: Callable[[float], float], grid, i: int, xatol: float) -> BoundedMinimum | None:
    r"""Profile refinement of one time constant: :func:`minimize_bounded` of ``fun(ln T)`` between the
    grid neighbours of the best grid point ``grid[i]`` (the point itself at either end), in :math:`\ln T`
    with absolute tolerance `xatol` (0.001 = 0.1 % in T). None when that interval is empty (a one-point
    grid). Shared by :func:`imupipe.identify.fit_allan` (T by the fit statistic) and
    :func:`imupipe.bound.bound_psd` (T by the LP objective)."""
    lo = math.log(grid[max(i - 1, 0)])
    hi = math.log(grid[min(i + 1, len(grid) - 1)])
    if not hi > lo:
        return None
    return minimize_bounded(fun, lo, hi, xatol=xatol)
