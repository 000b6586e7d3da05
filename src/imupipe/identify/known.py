r"""The scale of each curve's known Allan variance (its spectral lines), calibrated in the Allan domain.

Why. A line's power comes from the PSD (:mod:`imupipe.lines`): an estimate :math:`\hat P` with :math:`\nu`
degrees of freedom, :math:`\hat P \sim P\,\chi^2_\nu/\nu`. For a slow or damped line the looks are few (a 0.04 Hz
line of damping 5e-3 in a 4 h record at the low band's 1/3600 Hz: :math:`\nu \approx 11`, a standard error of
about 40 %), and the sum over the detection bins leaves out part of a resolved line's Lorentzian tails. The Allan
fit takes the lines' AV as a fixed part of the model (``known_avar`` of :func:`imupipe.identify.fit_allan`); at the
taus where the line dominates, the AV estimates carry hundreds of degrees of freedom, so a known term 25 % low
leaves a residual that the broadband columns can only fill with a Gauss-Markov or random walk far above the data
at the long taus (the quasi-likelihood charges a model above a point at most nu/2, one below it without limit). The
fit is then rejected and the bound's random walk inflated hundreds of times (measured: docs/performance.md).

What. Per curve, the scale s of its known term that minimises the Pearson statistic of the curve's own free fit,
:math:`\chi^2(s)` (the components and GM time constants of the identification, T profiled as in the fit), over the
interval the lines' power allows: :math:`s \in [\max_\ell \nu_\ell/\chi^2_{\nu_\ell}(c),\
\min_\ell \nu_\ell/\chi^2_{\nu_\ell}(1-c)]` at the identification's confidence c, one-sided at each end (the upper
end is where :func:`imupipe.lines.line_power_upper` holds the line in the upper envelope, so the envelope keeps
every line at least at its calibrated power). The scale is kept at 1 unless :math:`\chi^2(1) - \chi^2(s)` exceeds
the :math:`\chi^2_1` quantile at `level` (a likelihood-ratio test of one added parameter, Wilks 1938): a line whose
AV the data do not see (a weak line, most lines above the decimated Nyquist frequency) keeps its PSD estimate.
"""

from __future__ import annotations

import math

import numpy as np

from imupipe.identify.basis import _check_components, _pool, _profile
from imupipe.identify.fit import _T_search

#: points of the coarse log grid of s before Brent's refinement between the best point's neighbours
SCALE_GRID_POINTS = 25


def scale_interval(dofs, confidence: float) -> tuple[float, float]:
    """[s_lo, s_hi] of a curve's lines (module docstring): the common scale of their powers that every line's
    one-sided `confidence` limits allow (:func:`imupipe.lines.line_power_lower` and
    :func:`~imupipe.lines.line_power_upper` of a unit power), from each line's degrees of freedom
    (:attr:`imupipe.lines.Line.dof`); (1, 1) where a line has no degrees of freedom (its power is not a chi-square
    estimate)."""
    from imupipe.lines import line_power_lower, line_power_upper

    lo, hi = 0.0, math.inf
    for nu in dofs:
        if nu is None or not float(nu) > 0:
            return 1.0, 1.0
        lo = max(lo, line_power_lower(1.0, nu, confidence))
        hi = min(hi, line_power_upper(1.0, nu, confidence))
    return (lo, hi) if np.isfinite(hi) else (1.0, 1.0)


def calibrated_known(tau, avar, edf, known, dofs, *, components, n_gm: int, T_grid, confidence: float,
                     level: float = 0.01) -> tuple[list, list]:
    """Each curve's known AV times its calibrated scale (module docstring), and one record per curve.

    Parameters
    ----------
    tau, avar, edf : sequence of array_like
        Per curve: taus (s), Allan variances (u^2), equivalent degrees of freedom, as :func:`fit_allan` takes them.
    known : sequence of array_like
        Per curve: the known AV (u^2 at its taus; :func:`imupipe.lines.line_avar` of its lines), zeros for none.
    dofs : sequence of sequence of float
        Per curve: the degrees of freedom of each of its lines' powers.
    components, n_gm, T_grid :
        The identification's components, GM count and GM time constants searched (s), as for :func:`fit_allan`.
    confidence : float
        The identification's confidence c (the interval of s, module docstring).
    level : float
        Level of the test that keeps s = 1 (module docstring).

    Returns
    -------
    known : list of numpy.ndarray
        Per curve, ``s * known`` (u^2).
    records : list of dict
        Per curve: ``scale`` (1), ``interval`` [s_lo, s_hi] (1), ``chi2_unscaled``, ``chi2_scaled`` (the free
        fit's Pearson statistic at s = 1 and at the best s), ``threshold`` (the chi2_1 quantile), ``calibrated``
        (bool), ``at_interval_end`` (the applied scale at an end of its interval: the Allan variance asks for more
        than the lines' power allows, the fit's residual is then another process's); None for a curve without
        known AV.
    """
    from scipy.special import chdtri

    comps = _check_components(components, n_gm)
    n_gm = int(n_gm) if "gauss_markov" in comps else 0
    threshold = float(chdtri(1.0, float(level)))
    out, records = [], []
    for t_c, y_c, e_c, k_c, d_c in zip(tau, avar, edf, known, dofs):
        k_c = np.asarray(k_c, dtype=np.float64)
        if not np.any(k_c > 0):
            out.append(k_c)
            records.append(None)
            continue
        t, y, e, _, k = _pool([t_c], [y_c], [e_c], return_curve=True, known=[k_c])
        grid = _T_search(t, comps, T_grid, None, None)

        def chi2(s, t=t, y=y, e=e, k=k, grid=grid):
            return float(_profile(t, y, e, comps, n_gm, grid, offset=s * k)[0].chi2)

        lo, hi = scale_interval(d_c, confidence)
        c1 = chi2(1.0)
        s_best, c_best = 1.0, c1
        if hi > lo:
            s_best, c_best = _minimise_log(chi2, lo, hi, s_best, c_best)
        calibrated = c1 - c_best > threshold
        s = s_best if calibrated else 1.0
        out.append(s * k_c)
        edge = calibrated and (s <= lo * (1.0 + 1e-3) or s >= hi * (1.0 - 1e-3))
        records.append({"scale": float(s), "interval": [float(lo), float(hi)], "chi2_unscaled": c1,
                        "chi2_scaled": float(c_best), "threshold": threshold, "calibrated": bool(calibrated),
                        "at_interval_end": bool(edge)})
    return out, records


def _minimise_log(fun, lo: float, hi: float, s0: float, f0: float) -> tuple[float, float]:
    """The smallest of `fun` over a log grid of [lo, hi] refined by Brent's method between the best grid point's
    neighbours (:func:`imupipe.search.refine_between_neighbours`), and (s0, f0) already evaluated: (s, fun(s))."""
    from imupipe.search import refine_between_neighbours

    grid = np.exp(np.linspace(math.log(lo), math.log(hi), SCALE_GRID_POINTS))
    vals = np.array([fun(float(s)) for s in grid])
    i = int(np.argmin(vals))
    best = (float(grid[i]), float(vals[i]))
    res = refine_between_neighbours(lambda ls: fun(math.exp(ls)), grid, i, 1e-4)
    if res is not None and res.fun < best[1]:
        best = (math.exp(res.x), float(res.fun))
    return best if best[1] < f0 else (s0, f0)
