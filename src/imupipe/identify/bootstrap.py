r"""Bootstrap replicates of pooled Allan-variance curves and the goodness of fit of an AV fit.

Overlapping AV estimates at neighbouring taus share data and are strongly correlated; the replicates keep that
correlation (the exact covariance of the estimates under the fitted model, :func:`imupipe.avcov.avar_covariance`,
drawn with chi-squared marginals, :func:`imupipe.avcov.correlated_replicates`), or simulate whole records
(``series``), or draw each point independently (``chi2``, for comparison). SI units; AVs in u^2.

References: A. C. Davison, D. V. Hinkley, "Bootstrap Methods and their Application", Cambridge University Press,
1997, section 4.2 (parametric bootstrap tests); P. McCullagh, J. A. Nelder, "Generalized Linear Models", 2nd ed.,
1989, section 4.5 (over-dispersion).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

__all__: list[str] = []


def _child_rng(rng):
    """An independent generator spawned from `rng` without advancing its stream (so the draws `rng` makes
    afterwards, e.g. a caller's next simulated record, are the same with or without the extra calibration);
    `rng` itself when it has no seed sequence to spawn from."""
    try:
        return rng.spawn(1)[0]
    except (AttributeError, TypeError, ValueError):
        return rng


def _replicates(bootstrap, model, mean, e, cid, ms, lengths, rates, n_boot, rng, known=None):
    """The bootstrap's replicate Allan variances, one array per replicate (floored at 1e-300), drawn from `model`
    (SI; its ``dt`` the first curve's sample interval when unset) with the estimator's mean `mean`: ``correlated``
    (every replicate at once, with the exact correlation of the overlapping AV estimates, :func:`_correlated_draws`),
    ``series`` (a simulated record per curve and replicate, its overlapping AV at the averaging factors `ms`), else
    independent scaled chi-squared draws of `e` degrees of freedom. `cid` the curve of each point, `lengths` and
    `rates` per curve (samples, Hz). One generator for the main bootstrap and the second calibration of a GM sigma's
    profile in :func:`fit_allan`, so both draw alike from `rng`.

    `known` (u^2 per point, optional): a known, deterministic part of the AV (the spectral lines' Allan variance,
    :func:`imupipe.lines.line_avar`), included in `mean`: each replicate is `known` plus a draw of the rest
    (mean `mean` - `known`, the covariance of `model`, which holds the broadband components only), i.e. the
    lines are a fixed offset of every replicate, as of the fit."""
    if known is not None:
        mean = np.maximum(mean - known, 1e-300)
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
        yield np.maximum(ystar if known is None else ystar + known, 1e-300)


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
    from imupipe.spectra import chi2_sf as chdtrc  # closed form for integer dof: no scipy.special import

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
