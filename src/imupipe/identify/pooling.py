r"""Are several Allan-variance curves (axes, units of one sensor type) consistent with one model?
:func:`pooling_test`: the drop of the fit statistic from one pooled fit to one fit per curve, calibrated by a
parametric bootstrap with the exact correlation of the overlapping AV estimates. SI units."""

from __future__ import annotations

import numpy as np

from imupipe.identify.basis import (_check_components, _default_T_grid, _params_to_model, _per_curve, _pool,
                                    _profile, _solution_to_params)
from imupipe.identify.bootstrap import _adequacy, _chi2_covariance, _correlated_draws

__all__ = ["pooling_test"]


def pooling_test(
    tau,
    avar,
    edf,
    components=("white", "gauss_markov", "random_walk"),
    n_gm: int = 1,
    record_rate_hz=None,
    n_samples=None,
    labels=None,
    n_boot: int = 99,
    level: float = 0.01,
    T_grid=None,
    rng=None,
    known_avar=None,
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
    record_rate_hz : float or sequence of float
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
    known_avar : array_like or sequence of array_like, optional
        A known part of each AV point, u^2, shaped as `avar` (the lines' Allan variance): a fixed offset of the pooled
        and every per-curve fit and of every replicate, as in :func:`imupipe.identify.fit_allan`.

    Returns
    -------
    dict
        ``consistent``, ``statistic`` (F), ``p_value``, ``p_value_resolution``, ``level``, ``d1``, ``d2`` (sum of
        the per-curve dof),
        ``chi2_pooled``, ``method``, ``pooled`` (parameters of the pooled fit), ``per_curve`` (list of
        ``{label, params, chi2, dof, chi2_per_dof, p_value, adequate}`` with the covariance adequacy of each
        curve's own fit, SI parameters as :attr:`AllanFit.params`), ``note``.
    """
    # known_avar (u^2 per point, as avar): a known part of every fit and replicate (the lines, fit_allan's)
    t, y, e, cid, *kn = _pool(tau, avar, edf, return_curve=True, known=known_avar)
    kn = kn[0] if kn else None
    n_curves = int(cid.max()) + 1
    if record_rate_hz is None or n_samples is None:
        raise ValueError("pooling_test needs record_rate_hz= (Hz) and n_samples= per curve (the bootstrap draws each "
                         "curve with its own record length and rate)")
    rates = _per_curve(record_rate_hz, n_curves, "record_rate_hz", np.float64)
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
        pooled, _ = _profile(t, yy, e, comps, ngm, grid, offset=kn)
        per = [_profile(t[s], yy[s], e[s], comps, ngm, grid, offset=None if kn is None else kn[s])[0] for s in sels]
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
        mean = pooled.m if kn is None else np.maximum(pooled.m - kn, 1e-300)
        draws = _correlated_draws(model, mean, ms, cid, lengths, rates, int(n_boot), rng)
        draws = draws if kn is None else draws + kn
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
