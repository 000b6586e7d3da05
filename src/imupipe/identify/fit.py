r"""The Allan-variance fit: :func:`fit_allan` (weighted NNLS over the components of :mod:`imupipe.identify.basis`,
the GM time constants profiled) with bootstrap and profile-likelihood intervals and a goodness-of-fit verdict;
its result :class:`AllanFit`. SI units.

The fit
-------
For fixed GM time constants :math:`T_i` the AV is linear in
:math:`\theta = (N^2, \sigma_i^2, K^2, B^2, Q^2, R^2) \ge 0` (:func:`imupipe.identify.av_basis`,
:math:`\sigma^2(\tau) = A(\tau; T)\,\theta`). An AV estimate with :math:`\nu` equivalent
degrees of freedom is approximately :math:`m\,\chi^2_\nu/\nu`, i.e. variance
:math:`2 m^2/\nu` (NIST SP 1065, section 5.2), so :math:`\theta` solves

.. math::

    \min_{\theta \ge 0} \sum_k \frac{\nu_k}{2}
    \left(\frac{y_k - A_k \theta}{m_k}\right)^2, \qquad m = A\theta ,

by non-negative least squares with the weights re-evaluated on the model until :math:`m` stops changing
(quasi-likelihood of gamma-distributed data [4]; weights from the data alone would bias the fit low).
:math:`T` is profiled on a log grid and refined by a bounded scalar search (Nelder-Mead in :math:`\log T` for
several GM terms).

Intervals
---------
Parametric bootstrap, refitting each replicate (T profile included); intervals are percentiles at
`confidence`. Overlapping AV estimates at neighbouring taus share data and are strongly correlated; the
replicate generator must keep that:

* ``"correlated"`` (default): the exact covariance of the overlapping estimates under the
  fitted model (:func:`imupipe.avcov.avar_covariance`, records of `n_samples` at `record_rate_hz`), drawn
  with chi-squared marginals through a Gaussian copula
  (:func:`imupipe.avcov.correlated_replicates`). Milliseconds per replicate.
* ``"series"``: whole records simulated from the fitted model and their AV recomputed (the
  same distribution up to the copula approximation; one record per replicate and curve).
* ``"chi2"``: :math:`y^*_k = m_k \chi^2_{\nu_k}/\nu_k` independently per point. It ignores the
  correlation, and its intervals are too narrow (docs/performance.md); kept for comparison only.

The random walk K needs more: a K > 0 that the GM absorbs is fitted near 0, and replicates drawn
from that fit rarely reach the truth (its percentile interval under-covered: docs/performance.md). Its upper
end is therefore also taken from the profile of the fit statistic (test inversion): with :math:`\chi^2(k)` the
fit with :math:`K = k` held and everything else refitted, :math:`\Delta(k) = \chi^2(k) - \chi^2_{free}`, the
limit is the largest :math:`k \ge \hat K` with :math:`\Delta(k) \le c`, where `c` is the `confidence` quantile
of :math:`\Delta` over the bootstrap replicates evaluated at the K they were drawn with (so the correlation of the
AV points and the boundary K >= 0 are in the calibration, not a chi-squared assumption). The reported upper end
is the larger of the two.

A single GM's time constant gets the same construction on both sides (its percentile interval under-covered
with GM and random walk trading off): :math:`\Delta(T) = \chi^2(T) - \chi^2_{free}` with T held and every
coefficient refitted, evaluated on the fit's T grid and bisected at the ends
(:func:`imupipe.identify.intervals._gm_T_profile_limits`), threshold the `confidence` quantile of :math:`\Delta`
of the replicates at the T they were drawn with (one extra fixed-T solve per replicate); the reported interval
is the hull of the percentile and the profile interval, and an end the profile leaves open at the end of the
search is 0 or inf, labelled one-sided in ``interval_kind``. With two GM terms T has the percentile interval
only.

The white noise N gets it too (its percentile interval under-covered where a short GM and quantization trade
off against it): :math:`\Delta(n) = \chi^2(N = n) - \chi^2_{free}` with N held at n, every other coefficient
refitted and the GM time constants held at the free fit's optimum, the same statistic on every replicate (N
held at the N it was drawn with, T at the replicate's own optimum), so the calibration matches the statistic;
both ends bisected to 1e-4 N (:func:`imupipe.identify.intervals._profile_interval`, one extra fixed-T solve per
replicate), the reported interval the hull of the percentile and the profile interval (``white_profile``).

A single GM's sigma gets the profile interval alone (``gm_sigma_profile``): with
:math:`\chi^2_\sigma(s) = \min_{T,\,\theta' \ge 0} \chi^2` of the fit with :math:`\sigma^2 g(\tau; T)` held
at :math:`s^2 g(\tau; T)` (a fixed part of the model) and T and every other coefficient :math:`\theta'`
refitted (:func:`imupipe.identify.intervals._gm_sigma_held`: the fit's T grid, then Brent's method in
:math:`\ln T`), :math:`\Delta(s) = \chi^2_\sigma(s) - \chi^2_{free}`, the interval is
:math:`\{s \ge 0 : \Delta(s) \le c\}`, both ends bisected to 1e-3 sigma; a lower end 0 (:math:`\Delta(0) \le c`:
the data do not exclude the GM's absence) is labelled one-sided. Profiling T (and with it K) is the point:
sigma, T and K trade off along a ridge of the fit statistic (the GM's AV plateau :math:`\approx \sigma^2`
against the random walk's rise), and the percentile interval, drawn around the fitted point of that ridge,
missed on the side the estimate had moved to. The threshold is

.. math::

    c = \max\bigl(q_c(\Delta^* \mid \hat\theta),\; q_c(\Delta^* \mid \tilde\theta_{K_u})\bigr),

:math:`q_c` the `confidence` quantile of the same statistic over bootstrap replicates, each held at the sigma it
was drawn with (T searched within a factor 4 of the replicate's own optimum: a better T missed only enlarges c),
the replicates drawn once from the fitted model :math:`\hat\theta` and once, as many, from
:math:`\tilde\theta_{K_u}`, the fit with K held at its profile upper limit :math:`K_u` (the
``random_walk_profile`` upper end) and everything else refitted
(:func:`imupipe.identify.intervals._sigma_deltas_at_k`; skipped without a random walk or when
:math:`K_u \le \hat K`). Why two: :math:`\Delta(\sigma_{true})` is not pivotal, its distribution depends on the
nuisance K (how much of a wrong sigma T and K can absorb depends on the random walk's rise across the GM's
plateau), and a K fitted below the truth (the GM absorbing part of the random walk) gives thresholds below the
quantile at the truth, where the interval misses (docs/performance.md). Taking the larger quantile over the K
the data allow (the fitted one and the upper end of its interval) is conservative over that nuisance range: the
usual treatment of a nuisance parameter in bootstrap test inversion, calibrating at the least favourable value
within its confidence set (Berger & Boos [8] maximise over the whole set; here two points of it, the estimate
and K's upper end; Davison & Hinkley [7], chapters 4 and 5). The second bootstrap repeats the replicates' free
fits and sigma's held fit (not the other held fits). Its replicates come from a generator spawned from `rng`, so
the draws `rng` makes afterwards are unchanged. Profile-likelihood intervals: Venzon & Moolgavkar [6]; their
calibration by the bootstrap: Davison & Hinkley [7], chapter 5. The percentile ends are kept in
``gm_sigma_profile``.

The coverage of these intervals on simulated records (tests/test_coverage.py), the seeds used for development
and for verification, and the cost of each profile are in docs/performance.md. With one record of a few hours
GM and rate random walk are confounded (docs/method.md, section "Identification"): K is often fitted as 0 and
the GM parameters spread widely; the result's `notes` say so when the bootstrap shows it.

Adequacy and boundaries
-----------------------
The Pearson statistic is calibrated on the bootstrap replicates (drawn with the exact correlation of the
overlapping AV estimates, refitted the same way), so neither the correlation nor the fitted parameters need a
chi-squared approximation; without a bootstrap, the generalised statistic with the exact AV covariance is
referred to chi2(dof) (:func:`imupipe.identify.bootstrap._adequacy`). When the fit is inadequate
(p <= `adequacy_level`) the notes say so and every interval is widened on the log scale by
:math:`\sqrt{\phi}`, :math:`\phi` the over-dispersion (observed statistic over its bootstrap mean;
quasi-likelihood, McCullagh & Nelder 1989, section 4.5): a 0.15 % interval on a fit with
chi2/dof = 5000 becomes about 10 %, and it is still labelled indicative.

A GM time constant on the first or last value of the search (the data want a shorter or longer T than is
identifiable) is flagged ``on_boundary``; its interval is one-sided ((0, upper] or [lower, inf)), never
collapsed on the grid value. A coefficient fitted as 0 is flagged too (interval [0, upper]).

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

import math
from dataclasses import dataclass, field, replace

import numpy as np

from imupipe.identify.basis import (COMPONENTS, _check_components, _default_T_grid, _near_grid, _params_to_model,
                                    _per_curve, _plus, _pool, _profile, _solution_to_params, _solve_fixed)
from imupipe.identify.bootstrap import _adequacy, _child_rng, _chi2_covariance, _replicates
from imupipe.identify.intervals import (_gm_sigma_held, _gm_T_profile_limits, _hull, _profile_interval,
                                        _random_walk_upper, _sigma_deltas_at_k)

__all__ = ["AllanFit", "fit_allan"]


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
    #: the known AV of every pooled point (u^2; spectral lines, `known_avar` of :func:`fit_allan`), a fixed part of
    #: every fit; empty when none was given. `model` holds the fitted components only: the fit's total AV is
    #: ``model.avar(tau) + known``.
    known: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))

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
    record_rate_hz: float | None = None,
    n_samples=None,
    adequacy_level: float = 0.01,
    T_min_samples: float | None = None,
    known_avar=None,
) -> AllanFit:
    r"""Fit noise components to one or several (pooled) Allan-variance curves: weighted NNLS of the squared
    coefficients with the GM time constants profiled, bootstrap and profile intervals, the adequacy verdict
    (the method: module docstring).

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
    n_boot : int, optional
        Bootstrap replicates (0 for none). Default 200.
    confidence : float, optional
        Level of the intervals. Default 0.95.
    rng : numpy.random.Generator or int, optional
        Random generator (or seed) for the bootstrap. Default ``numpy.random.default_rng()``.
    dt : float, optional
        Sample interval, s, stored in the returned model (needed by quantization's PSD).
    bootstrap : {"correlated", "series", "chi2"}, optional
        Replicate generator (module docstring). Default ``"correlated"``.
    record_rate_hz : float or sequence of float, optional
        Sampling rate of the records the AVs come from, Hz, one for all curves or one per pooled curve
        (records of different rates pool: each curve's averaging factors are tau * its rate); needed by
        ``correlated`` and ``series`` and by the covariance adequacy statistic.
    n_samples : int or sequence of int, optional
        Record length(s) in samples, one per pooled curve (``correlated`` and ``series``).
    adequacy_level : float, optional
        Level of the goodness-of-fit test (``adequacy``). Default 0.01; 0 turns the verdict off.
    T_min_samples : float, optional
        With the default grid: its shortest T is at least ``T_min_samples * dt`` s (a GM of T a few sample
        intervals acts as white noise; config identify.fit_tau_min_samples). Needs `dt`. Default None (tau_min).
    known_avar : array_like or sequence of array_like, optional
        A known part of each AV point, u^2, shaped as `avar` (one array per curve): the Allan variance of the
        curve's spectral lines (:func:`imupipe.lines.line_avar`). It is a fixed offset :math:`o` of the model,
        :math:`m = o + A\theta`, in the free fit, in every profile and held fit, and in the bootstrap (each
        replicate is :math:`o` plus a draw of the fitted components, :func:`imupipe.identify.bootstrap._replicates`),
        so neither the fit nor its intervals absorb it. The returned ``model`` holds the fitted components only.
        Default None (no known part: the arithmetic of a fit without it).

    Returns
    -------
    AllanFit
        Model, parameters, intervals, chi2 and notes; ``adequacy`` (``chi2``, ``dof``, ``chi2_per_dof``,
        ``p_value``, ``adequate``, ``method``, ``overdispersion``, ``widening``, ``chi2_covariance``),
        ``on_boundary`` and ``interval_kind`` per parameter.

    Raises
    ------
    ValueError
        Mismatched inputs, fewer than 2 usable points, unknown components.
    """
    if known_avar is None:
        t, y, e, cid = _pool(tau, avar, edf, return_curve=True)
        known = None
    else:
        t, y, e, cid, known = _pool(tau, avar, edf, return_curve=True, known=known_avar)
    comps = _check_components(components, n_gm)
    records = _records(cid, bootstrap, n_boot, record_rate_hz, n_samples)
    n_gm = int(n_gm) if "gauss_markov" in comps else 0
    grid = _T_search(t, comps, T_grid, T_min_samples, dt)
    best, profile = _profile(t, y, e, comps, n_gm, grid, offset=known)
    pb = _Problem(t, y, e, cid, comps, n_gm, grid, best, known)
    params = _solution_to_params(best, comps, n_gm)
    model = _params_to_model(params, dt)
    names = list(params)
    c = float(confidence)
    if not 0.0 < c < 1.0:
        raise ValueError(f"confidence must lie in (0, 1), got {confidence!r}")
    rng = np.random.default_rng(rng)
    rep = _bootstrap_statistics(pb, params, model, int(n_boot), bootstrap, records, rng)
    intervals, p_zero = _percentile_intervals(rep.params, names, c)
    random_walk_profile = _random_walk_limit(pb, params, rep, intervals, c)
    white_profile = _white_limits(pb, params, rep, intervals, c)
    gm_sigma_profile = _gm_sigma_limits(pb, params, rep, intervals, c, random_walk_profile, rng, bootstrap, dt)
    gm_T_profile, T_open = _gm_T_limits(pb, profile, rep, intervals, c)
    notes = _confounding_notes(params, intervals, p_zero, comps, n_gm, int(n_boot))
    n_free = int(np.count_nonzero(best.p)) + n_gm
    dof = int(t.size - n_free)
    adequacy = _adequacy(best.chi2, dof, rep.chi2 if bootstrap != "chi2" else np.zeros(0),
                         _chi2_of_covariance(pb, model, records), float(adequacy_level))
    on_boundary, interval_kind = _T_on_search_ends(params, intervals, names, grid, n_gm, notes)
    _mark_one_sided(params, intervals, names, grid, c, T_open, gm_sigma_profile, p_zero, comps, n_gm, int(n_boot),
                    on_boundary, interval_kind, notes)
    intervals_statistical = dict(intervals)
    if not adequacy["adequate"]:
        _widen(intervals, params, adequacy, adequacy_level, notes)
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
        bootstrap=rep.params,
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
        known=np.zeros(0) if known is None else known,
    )


# ---------------------------------------------------------------------------------------------
# the steps of fit_allan
# ---------------------------------------------------------------------------------------------
@dataclass
class _Problem:
    """The pooled data of :func:`fit_allan` and its free fit: taus (s), AVs (u^2), edf and curve index of every
    point, the components and GM count, the T search grid (s) and the best solution on it."""

    t: np.ndarray
    y: np.ndarray
    e: np.ndarray
    cid: np.ndarray
    comps: tuple
    n_gm: int
    grid: np.ndarray
    best: object
    known: np.ndarray | None = None


@dataclass
class _Replicated:
    """What :func:`_bootstrap_statistics` returns: the replicates' parameters (n_boot, n_params) and Pearson
    statistics, and each profile statistic at the value the replicate was drawn with (None where that profile is
    not run); `bgrid` the replicates' T grid (s), `per_curve` (averaging factors, lengths, rates) of the draws."""

    params: np.ndarray
    chi2: np.ndarray
    k_deltas: np.ndarray | None = None
    t_deltas: np.ndarray | None = None
    n_deltas: np.ndarray | None = None
    s_deltas: np.ndarray | None = None
    bgrid: np.ndarray | None = None
    per_curve: tuple = (None, None, None)


def _records(cid, bootstrap: str, n_boot: int, record_rate_hz, n_samples):
    """(lengths in samples, rates in Hz) of the pooled curves, one each, or None when `record_rate_hz` or
    `n_samples` is not given; checks `bootstrap` and that the correlated and series bootstraps have positive rates and lengths."""
    if bootstrap not in ("correlated", "chi2", "series"):
        raise ValueError(f"bootstrap must be 'correlated', 'chi2' or 'series', got {bootstrap!r}")
    needed = bootstrap in ("correlated", "series") and n_boot > 0
    if needed and (record_rate_hz is None or n_samples is None):
        raise ValueError(
            f"the {bootstrap} bootstrap needs the records' rate (Hz) and n_samples (per curve): pass "
            "record_rate_hz= and n_samples= (allan_variance(...).attrs 'rate_hz' and 'n_samples'), or n_boot=0"
        )
    if record_rate_hz is None or n_samples is None:
        return None
    n_curves = int(cid.max()) + 1
    lengths = _per_curve(n_samples, n_curves, "n_samples", np.int64)
    rates = _per_curve(record_rate_hz, n_curves, "record_rate_hz", np.float64)
    if needed and (np.any(~np.isfinite(rates) | (rates <= 0)) or np.any(lengths < 2)):
        raise ValueError(f"record_rate_hz (Hz) must be positive and n_samples >= 2 per curve, got {rates}, {lengths}")
    return lengths, rates


def _T_search(t, comps, T_grid, T_min_samples, dt):
    """The GM time constants searched, s: `T_grid`, or the default grid from the taus `t` (its shortest T at least
    `T_min_samples` * `dt`)."""
    if T_min_samples is not None and dt is None:
        raise ValueError("T_min_samples needs dt (s, the decimated series' sample interval)")
    T_min_s = None if T_min_samples is None else float(T_min_samples) * float(dt)
    grid = _default_T_grid(t, T_min_s=T_min_s) if T_grid is None else np.asarray(T_grid, dtype=np.float64)
    if "gauss_markov" in comps and (grid.size == 0 or np.any(grid <= 0)):
        raise ValueError("T_grid must hold positive time constants (s)")
    return grid


def _bootstrap_statistics(pb: _Problem, params: dict, model, n_boot: int, bootstrap: str, records, rng):
    """The bootstrap of :func:`fit_allan`: `n_boot` replicates drawn from `model` (mean: the free fit's AV), each
    refitted (T on a grid of at most 30 points over the fit's span) and, for each profile interval that applies,
    refitted with that parameter held at the value the replicate was drawn with (K, a single GM's T, N, a single
    GM's sigma): the statistics :math:`\\max(\\chi^2_{held} - \\chi^2_{free}, 0)` the thresholds are quantiles of."""
    t, e, comps, n_gm, grid = pb.t, pb.e, pb.comps, pb.n_gm, pb.grid
    names = list(params)
    rep = _Replicated(np.full((n_boot, len(names)), np.nan), np.full(n_boot, np.nan))
    # the random walk's profile interval (module docstring): the statistic at the bootstrap's own K
    rep.k_deltas = np.full(n_boot, np.nan) if n_boot > 0 and "random_walk" in comps else None
    rest = tuple(comp for comp in comps if comp != "random_walk")
    k2_hat = params.get("random_walk", 0.0) ** 2
    # the single GM time constant's profile interval: the statistic at the fitted T
    T_hat = params.get("gm_T_1", float("nan")) if n_gm == 1 else float("nan")
    rep.t_deltas = np.full(n_boot, np.nan) if n_boot > 0 and np.isfinite(T_hat) and grid.size >= 2 else None
    # the white noise's profile interval: the statistic at the fitted N, the GM time constants held at each fit's
    # own optimum (the same statistic on the data and on every replicate)
    n_hat = params.get("white", float("nan"))
    rep.n_deltas = np.full(n_boot, np.nan) if n_boot > 0 and "white" in comps and n_hat > 0 else None
    no_white = tuple(comp for comp in comps if comp != "white")
    # the single GM variance's profile interval: the statistic at the fitted sigma, T and every other coefficient
    # refitted (the same statistic on the data and on every replicate)
    s_hat = params.get("gm_sigma_1", float("nan")) if n_gm == 1 else float("nan")
    rep.s_deltas = np.full(n_boot, np.nan) if n_boot > 0 and s_hat > 0 and grid.size >= 2 else None
    no_gm = tuple(comp for comp in comps if comp != "gauss_markov")
    if n_boot <= 0:
        return rep
    # bootstrap grid: a little coarser than the fit's, same span
    bgrid = grid if grid.size <= 30 else np.logspace(math.log10(grid[0]), math.log10(grid[-1]), 30)
    rep.bgrid = bgrid
    # per curve, for the correlated and series bootstraps: averaging factors, lengths (samples), rates (Hz)
    if bootstrap != "chi2":
        lengths, rates = records
        rep.per_curve = (np.rint(t * rates[pb.cid]).astype(np.int64), lengths, rates)
    known = pb.known
    for b, ystar in enumerate(_replicates(bootstrap, model, pb.best.m, e, pb.cid, *rep.per_curve, n_boot, rng,
                                          known=known)):
        sol, _ = _profile(t, ystar, e, comps, n_gm, bgrid, offset=known)
        rep.chi2[b] = sol.chi2
        pb_params = _solution_to_params(sol, comps, n_gm)
        rep.params[b] = [pb_params[k] for k in names]
        if rep.k_deltas is not None:
            # the replicate's fit with K held at the value it was drawn with; T searched near the
            # replicate's own optimum (a better T missed only enlarges the threshold: conservative)
            local = _near_grid(bgrid, sol.T[0]) if n_gm == 1 else bgrid
            held = _profile(t, ystar, e, rest, n_gm, local, offset=_plus(known, k2_hat * t / 3.0))[0]
            rep.k_deltas[b] = max(held.chi2 - sol.chi2, 0.0)
        if rep.t_deltas is not None:
            # the replicate's fit with T held at the value it was drawn with
            held_T = _solve_fixed(t, ystar, e, comps, (T_hat,), m0=sol.m, offset=known)
            rep.t_deltas[b] = max(held_T.chi2 - sol.chi2, 0.0)
        if rep.n_deltas is not None:
            held_N = _solve_fixed(t, ystar, e, no_white, sol.T, m0=sol.m, offset=_plus(known, n_hat * n_hat / t))
            rep.n_deltas[b] = max(held_N.chi2 - sol.chi2, 0.0)
        if rep.s_deltas is not None:
            # the replicate's fit with sigma held at the value it was drawn with, T searched near the
            # replicate's own optimum (a better T missed only enlarges the threshold: conservative)
            local = _near_grid(bgrid, sol.T[0]) if sol.T and np.isfinite(sol.T[0]) else bgrid
            held_s = _gm_sigma_held(t, ystar, e, no_gm, s_hat * s_hat, local, m0=sol.m, known=known)
            rep.s_deltas[b] = max(held_s.chi2 - sol.chi2, 0.0)
    return rep


def _percentile_intervals(boots, names, c: float):
    """Percentile intervals at level `c` of the bootstrap parameters `boots` (NaN where fewer than 5 or half the
    replicates are finite) and each parameter's share of replicates at zero (a GM time constant: vanished)."""
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
    return intervals, p_zero


def _random_walk_limit(pb: _Problem, params: dict, rep: _Replicated, intervals: dict, c: float) -> dict:
    """The random walk's profile upper limit (module docstring); `intervals["random_walk"]`'s upper end raised to
    it in place. Returns ``random_walk_profile`` (empty without its statistic)."""
    k_deltas = rep.k_deltas
    if k_deltas is None or not np.isfinite(k_deltas).any():
        return {}
    threshold = float(np.quantile(k_deltas[np.isfinite(k_deltas)], c))
    rest = tuple(comp for comp in pb.comps if comp != "random_walk")
    k_hat = math.sqrt(params.get("random_walk", 0.0) ** 2)
    k_up = _random_walk_upper(pb.t, pb.y, pb.e, rest, pb.n_gm, pb.grid, pb.best.chi2, k_hat, threshold,
                              known=pb.known)
    lo_k, hi_k = intervals["random_walk"]
    intervals["random_walk"] = (lo_k, max(hi_k, k_up) if np.isfinite(hi_k) else k_up)
    return {"threshold": threshold, "upper": k_up, "percentile_upper": hi_k}


def _white_limits(pb: _Problem, params: dict, rep: _Replicated, intervals: dict, c: float) -> dict:
    """The white noise's profile interval (module docstring); `intervals["white"]` becomes its hull with the
    percentile interval, in place. Returns ``white_profile`` (empty without its statistic)."""
    n_deltas = rep.n_deltas
    if n_deltas is None or not np.isfinite(n_deltas).any():
        return {}
    t, y, e, best = pb.t, pb.y, pb.e, pb.best
    n_hat = params.get("white", float("nan"))
    no_white = tuple(comp for comp in pb.comps if comp != "white")
    threshold = float(np.quantile(n_deltas[np.isfinite(n_deltas)], c))
    lo_p, hi_p = intervals["white"]

    def delta_n(x):
        return (_solve_fixed(t, y, e, no_white, best.T, m0=best.m, offset=_plus(pb.known, x * x / t)).chi2
                - best.chi2)

    step = (hi_p - n_hat) if np.isfinite(hi_p) and hi_p > n_hat else 1e-3 * n_hat
    n_lo, n_up = _profile_interval(delta_n, n_hat, threshold, step)
    intervals["white"] = _hull((lo_p, hi_p), (n_lo, n_up))
    return {"threshold": threshold, "lower": n_lo, "upper": n_up, "percentile_lower": lo_p, "percentile_upper": hi_p}


def _gm_sigma_limits(pb: _Problem, params: dict, rep: _Replicated, intervals: dict, c: float,
                     random_walk_profile: dict, rng, bootstrap: str, dt) -> dict:
    """A single GM's sigma profile interval (module docstring: the threshold the larger of the calibrations under
    the fitted model and under the fit with K at its profile upper limit); `intervals["gm_sigma_1"]` becomes it,
    in place. Returns ``gm_sigma_profile`` (empty without its statistic)."""
    s_deltas = rep.s_deltas
    if s_deltas is None or not np.isfinite(s_deltas).any() or "gm_sigma_1" not in intervals:
        return {}
    t, y, e, comps, n_gm, grid, best = pb.t, pb.y, pb.e, pb.comps, pb.n_gm, pb.grid, pb.best
    s_hat = params.get("gm_sigma_1", float("nan")) if n_gm == 1 else float("nan")
    rest = tuple(comp for comp in comps if comp != "random_walk")
    no_gm = tuple(comp for comp in comps if comp != "gauss_markov")
    threshold_fitted = float(np.quantile(s_deltas[np.isfinite(s_deltas)], c))
    # the same statistic calibrated under the fit with K at its profile upper limit (the statistic's distribution
    # depends on K), the larger threshold kept
    k_up = random_walk_profile.get("upper", float("nan"))
    threshold_k_upper, k_cal = float("nan"), float("nan")
    if np.isfinite(k_up) and k_up > math.sqrt(params.get("random_walk", 0.0) ** 2):
        k_cal = float(k_up)
        k_deltas_up = _sigma_deltas_at_k(t, y, e, comps, rest, no_gm, n_gm, grid, rep.bgrid, k_cal,
                                         rep.params.shape[0], _child_rng(rng), bootstrap, dt, pb.cid, *rep.per_curve,
                                         known=pb.known)
        if np.isfinite(k_deltas_up).any():
            threshold_k_upper = float(np.quantile(k_deltas_up[np.isfinite(k_deltas_up)], c))
    threshold = max(threshold_fitted, threshold_k_upper) if np.isfinite(threshold_k_upper) else threshold_fitted
    lo_p, hi_p = intervals["gm_sigma_1"]

    def delta_s(x):
        return _gm_sigma_held(t, y, e, no_gm, x * x, grid, m0=best.m, known=pb.known).chi2 - best.chi2

    step = (hi_p - s_hat) if np.isfinite(hi_p) and hi_p > s_hat else 1e-2 * s_hat
    s_lo, s_up = _profile_interval(delta_s, s_hat, threshold, step, rtol=1e-3)
    # the profile interval alone, not its hull with the percentile one (which over-covered: docs/performance.md,
    # the GM sigma profile interval)
    intervals["gm_sigma_1"] = (float(s_lo), float(s_up))
    return {"threshold": threshold, "lower": s_lo, "upper": s_up, "percentile_lower": lo_p, "percentile_upper": hi_p,
            "threshold_fitted": threshold_fitted, "threshold_k_upper": threshold_k_upper, "k_calibration": k_cal}


def _gm_T_limits(pb: _Problem, profile, rep: _Replicated, intervals: dict, c: float):
    """A single GM's T profile interval (module docstring) on the fit's T profile `profile` (grid s, chi2);
    `intervals["gm_T_1"]` becomes its hull with the percentile interval, in place. Returns (``gm_T_profile``,
    (lower end open, upper end open))."""
    t_deltas = rep.t_deltas
    if t_deltas is None or not np.isfinite(t_deltas).any() or profile[1].size != profile[0].size:
        return {}, (False, False)
    threshold = float(np.quantile(t_deltas[np.isfinite(t_deltas)], c))
    T_lo, T_up, lo_open, up_open = _gm_T_profile_limits(pb.t, pb.y, pb.e, pb.comps, profile[0], profile[1],
                                                        pb.best.chi2, threshold, m0=pb.best.m, known=pb.known)
    lo_p, hi_p = intervals.get("gm_T_1", (np.nan, np.nan))
    if not (np.isfinite(T_lo) or T_lo == 0.0):
        return {}, (False, False)
    intervals["gm_T_1"] = _hull((lo_p, hi_p), (T_lo, T_up))
    return ({"threshold": threshold, "lower": T_lo, "upper": T_up, "percentile_lower": lo_p,
             "percentile_upper": hi_p}, (lo_open, up_open))


def _confounding_notes(params: dict, intervals: dict, p_zero: dict, comps, n_gm: int, n_boot: int) -> list:
    """Notes on what the bootstrap shows poorly identified: a random walk fitted as 0 in more than a fifth of the
    replicates, a GM sigma interval spanning more than a factor 3."""
    notes = []
    if n_boot <= 0:
        return notes
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
    return notes


def _chi2_of_covariance(pb: _Problem, model, records):
    """The generalised statistic of the free fit with the exact AV covariance
    (:func:`imupipe.identify.bootstrap._chi2_covariance`), None without the records' rates and lengths or when the
    averaging factors fall outside a record (inconsistent n_samples)."""
    if records is None:
        return None
    lengths, rates = records
    ms_all = np.rint(pb.t * rates[pb.cid]).astype(np.int64)
    cov_model = model if model.dt is not None else replace(model, dt=1.0 / float(rates[0]))
    try:
        return _chi2_covariance(pb.y, pb.best.m, cov_model, ms_all, pb.cid, lengths, rates)
    except ValueError:  # averaging factors outside the record (inconsistent n_samples): no statistic
        return None


def _T_on_search_ends(params: dict, intervals: dict, names, grid, n_gm: int, notes: list):
    """``on_boundary`` and ``interval_kind`` of every parameter, a GM time constant on the first or last value of
    the search flagged and its interval made one-sided ((0, upper] or [lower, inf)), in place; notes appended."""
    on_boundary, interval_kind = {}, {}
    for k in names:
        on_boundary[k], interval_kind[k] = False, "two-sided"
    if not (n_gm and grid.size >= 2):
        return on_boundary, interval_kind
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
    return on_boundary, interval_kind


def _mark_one_sided(params, intervals, names, grid, c, T_open, gm_sigma_profile, p_zero, comps, n_gm, n_boot,
                    on_boundary, interval_kind, notes) -> None:
    """The other one-sided intervals, in place: a T profile interval open at an end of the search, a GM sigma
    whose T sits on an end of the search (its percentile interval reported instead of the profile), a sigma
    profile reaching 0, coefficients fitted as 0 ([0, upper]), a random walk confounded with the GM."""
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


def _widen(intervals: dict, params: dict, adequacy: dict, adequacy_level: float, notes: list) -> None:
    """Every interval of an inadequate fit widened about its estimate by the over-dispersion factor, on the log
    scale (module docstring), in place; a note says so."""
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
