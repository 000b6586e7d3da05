"""imupipe.search.minimize_bounded against scipy.optimize.minimize_scalar(method="bounded") (the same method):
point-by-point identical evaluation sequences on many functions, bracket positions and tolerances."""

import math

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from imupipe.search import minimize_bounded


def _trace(fun):
    calls = []

    def f(x):
        calls.append(float(x))
        return fun(float(x))

    return f, calls


FUNCTIONS = {
    "parabola": lambda c: (lambda x: (x - c) ** 2),
    "quartic": lambda c: (lambda x: (x - c) ** 4 + 0.1 * x),
    "cosine": lambda c: (lambda x: -math.cos(3.0 * (x - c))),
    "abs": lambda c: (lambda x: abs(x - c)),  # no parabola fits: golden steps
    "plateau": lambda c: (lambda x: min(1.0, (x - c) ** 2)),  # flat away from the minimum
    "monotone": lambda c: (lambda x: math.exp(x - c)),  # minimum at the lower end
    "log_T_like": lambda c: (lambda x: math.exp(x - c) + math.exp(c - x) + 0.01 * (x - c) ** 3),
}


@pytest.mark.parametrize("name", sorted(FUNCTIONS))
@pytest.mark.parametrize("xatol", [1e-5, 1e-3, 1e-9])
def test_same_points_as_scipy(name, xatol):
    rng = np.random.default_rng(7)
    for _ in range(25):
        lo = float(rng.uniform(-5.0, 5.0))
        hi = lo + float(rng.uniform(1e-3, 10.0))
        c = float(rng.uniform(lo - 1.0, hi + 1.0))
        f1, ours = _trace(FUNCTIONS[name](c))
        f2, theirs = _trace(FUNCTIONS[name](c))
        res = minimize_bounded(f1, lo, hi, xatol=xatol)
        ref = minimize_scalar(f2, bounds=(lo, hi), method="bounded", options={"xatol": xatol})
        assert ours == theirs  # exact: the same arithmetic in the same order
        assert res.x == float(ref.x) and res.fun == float(ref.fun) and res.nfev == ref.nfev
        assert res.success == bool(ref.success)


def test_maxiter_stops_like_scipy():
    f = lambda x: abs(x - 0.3) ** 0.5  # noqa: E731  (slow convergence)
    res = minimize_bounded(f, 0.0, 1.0, xatol=1e-14, maxiter=7)
    ref = minimize_scalar(f, bounds=(0.0, 1.0), method="bounded", options={"xatol": 1e-14, "maxiter": 7})
    assert res.nfev == ref.nfev == 7 and res.x == float(ref.x) and res.success is False is bool(ref.success)


def test_bad_bounds_are_named():
    with pytest.raises(ValueError, match="lo < hi"):
        minimize_bounded(lambda x: x, 1.0, 1.0)
    with pytest.raises(ValueError, match="finite"):
        minimize_bounded(lambda x: x, 0.0, math.inf)


def test_log_grid_and_neighbour_refinement():
    from imupipe.search import log_grid, refine_between_neighbours

    g = log_grid(0.0, 2.0, 4)
    np.testing.assert_allclose(g, 10.0 ** np.arange(9) / 10.0 ** (np.arange(9) * 0.75), rtol=1e-12)  # 10^(k/4)
    assert log_grid(1.0, 1.1, 2, min_points=3).size == 3
    # the minimum of (ln T - ln 30)^2 on the grid 1, 10, 100, 1000 s is at 10 s or 100 s; the refinement
    # between that point's neighbours finds ln 30 to its tolerance
    grid = np.array([1.0, 10.0, 100.0, 1000.0])
    f = lambda lt: (lt - math.log(30.0)) ** 2  # noqa: E731
    i = int(np.argmin([f(math.log(T)) for T in grid]))
    res = refine_between_neighbours(f, grid, i, 1e-6)
    assert abs(res.x - math.log(30.0)) < 1e-5
    assert refine_between_neighbours(f, np.array([5.0]), 0, 1e-3) is None
