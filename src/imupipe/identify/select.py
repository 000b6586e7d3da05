r"""Model selection: keep only the components the data show and the application needs
(:func:`select_components`), then refit the kept ones (:func:`refit_selected`). SI units.

References: Gallon, Joerger, Pervan, ION GNSS+ 2021, eqs. 17 and 19 (the filter models with and without the
random-walk state); docs/method.md, section "Identification".
"""

from __future__ import annotations

import math

import numpy as np

from imupipe.identify.basis import (COMPONENTS, _default_T_grid, _params_to_model, _pool, _profile,
                                    _solution_to_params)
from imupipe.identify.fit import AllanFit, fit_allan

__all__ = ["select_components", "refit_selected"]

#: Components removed together with the tested one in the refit test of select_components: a rate
#: ramp (tau^2) absorbs a random walk's rise at the longest taus, and is not a filter state. A flicker floor is
#: tested against a null without the random walk and the ramp either (with the GM time constants capped as for the
#: random walk): over the few decades of tau a record gives, a random walk with a GM (or with the white noise's
#: bowl) passes for a flat floor, and the one-at-a-time test then drops the flicker whichever of them is true
#: (measured: white + flicker + GM, and white + flicker + random walk, 3 h at 10 Hz: the flicker dropped, K twice
#: the truth). The random walk is then tested with the flicker in its null, so it is kept only where the data rise
#: beyond the floor.
_SUBSTITUTES = {"random_walk": ("ramp",), "white": ("quantization",), "flicker": ("random_walk", "ramp")}


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


def _tested(fit: AllanFit) -> list:
    """The components :func:`select_components` tests: those of ``fit.model`` that are non-zero, and two the fit set to
    zero that a substitute took. A white noise the full fit gave to quantization and a GM at the shortest T: the
    selected model must not lose it (n_gm = 2 did in most records). A random walk fitted 0 beside a ramp that took the
    rise (its null drops the ramp too and caps the GM time constants): the ramp is no filter state, and with the random
    walk dropped untested the selected model lost the rise (a held-out consumer-grade truth, K 5e-6: the selected refit
    at chi2/dof 9.8)."""
    present = _present(fit.model)
    extra = {"white"} | ({"random_walk"} if "ramp" in present else set())
    return [c for c in COMPONENTS if c in present or (c in extra and c in fit.components)]


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
    filter_rate_hz: float | None = None,
    outage_s: float | None = None,
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
    :math:`(1/\text{outage}, \text{filter rate}/2)` from the filter rate and the outage; without either, every
    component is taken as relevant.

    Decision: keep = data test and band test, except the random walk, which is kept whenever the data
    show it: the paper's reduced model without the random-walk state (Gallon et al. 2021, eq. 19) is
    allowed only when the AV shows no random walk. With `lr_test`, the components the data tests dropped are then
    tested together (:func:`_jointly_needed`): while the data reject dropping them all, the one whose return lowers
    the refit's chi-squared most is kept.

    Parameters
    ----------
    fit : AllanFit
        Result of :func:`fit_allan` on the same data.
    tau, avar, edf : array_like or sequences
        The AV data of the fit (pooled the same way), s, u^2, 1.
    band_hz : tuple of float, optional
        (f_lo, f_hi) of the application, Hz.
    filter_rate_hz : float, optional
        The filter's update rate, Hz (f_hi = filter_rate_hz/2) when `band_hz` is not given.
    outage_s : float, optional
        The outage (longest interval the filter must propagate without aiding), s (f_lo = 1/outage_s).
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
    from scipy.special import ndtri

    t, y, e = _pool(tau, avar, edf)
    model = fit.model
    # the fit's known AV (spectral lines, fit_allan's known_avar): a fixed part of the full fit and of every null
    known = fit.known if getattr(fit, "known", np.zeros(0)).size == t.size else None
    m = np.asarray(model.avar(t), dtype=np.float64) + (0.0 if known is None else known)
    sd = m * np.sqrt(2.0 / e)
    present = _tested(fit)
    n_tested = max(1, len(present))
    # Bonferroni over the AV points and over the components tested
    zcrit = float(-ndtri(significance / (t.size * n_tested)))

    f_lo, f_hi = _band_of(band_hz, filter_rate_hz, outage_s, t)
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
        m_null, d_chi2, chi2_crit, lr_shows = _null_fit(fit, c, t, y, e, m, lr_test, significance, n_tested, known)
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
        keep, reason = _decision(c, data, relevant, relevance)
        (kept if keep else dropped).append(c)
        reasons[c] = f"{reason}; {why}"
    if lr_test:
        _keep_jointly_needed(fit, t, y, e, (kept, dropped, reasons, details), significance, known)
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


def _n_params(fit: AllanFit, comps) -> int:
    """Parameters of the components `comps` in `fit` (a GM term two: sigma and T)."""
    return sum(2 * fit.n_gm if c == "gauss_markov" else 1 for c in comps if c in fit.components)


def _keep_jointly_needed(fit: AllanFit, t, y, e, decided, significance: float, known=None) -> None:
    """Move the components :func:`_jointly_needed` returns from dropped to kept in `decided` = (kept, dropped,
    reasons, details) of :func:`select_components`, in place: their reason and ``jointly_needed`` detail say why."""
    kept, dropped, reasons, details = decided
    for c, why in _jointly_needed(fit, t, y, e, kept, details, significance, known):
        dropped.remove(c)
        kept.append(c)
        details[c]["jointly_needed"] = True
        reasons[c] = why + "; " + reasons[c].split("; ", 1)[1]
    kept.sort(key=COMPONENTS.index)


def _jointly_needed(fit: AllanFit, t, y, e, kept, details, significance: float, known=None) -> list:
    r"""The components the data tests dropped one at a time that the data need together (helper of
    :func:`select_components`): ``[(component, reason), ...]`` to keep.

    Each component's test refits without it alone, so components that stand in for each other (a random walk, a
    flicker and a GM of T near the record each raise the long end) pass it one by one and are dropped together. A
    held-out 4 h record with a 600 s GM kept the white noise alone that way (chi2/dof 261 against the full fit's
    2.5). The set is tested at once: the refit with the components the data show (kept, or shown and dropped for
    the band) against the full fit, :math:`\Delta\chi^2 > \chi^2_d(1-\alpha)` (d the parameters dropped for the
    data); while it is rejected, the dropped component whose return lowers the refit's :math:`\chi^2` most is kept.
    """
    from scipy.special import chdtri

    shown = [c for c in fit.components if c in details and details[c].get("delta_chi2") is not None
             and (c in kept or details[c]["shown_by_z"] or details[c]["shown_by_chi2"])]
    candidates = [c for c in fit.components if c in details and "z_crit" in details[c] and c not in shown]
    grid = fit.T_grid if fit.T_grid.size else _default_T_grid(t)

    def chi2_of(comps):
        comps = tuple(c for c in fit.components if c in comps)
        return float(_profile(t, y, e, comps, fit.n_gm, grid, offset=known)[0].chi2) if comps else math.inf

    out = []
    while candidates and shown:
        d_chi2 = chi2_of(shown) - float(fit.chi2)
        n = _n_params(fit, candidates)
        crit = float(chdtri(n, significance))
        if not d_chi2 > crit:
            break
        best = min(candidates, key=lambda c: chi2_of(shown + [c]))
        out.append((best, f"kept: not needed alone, but the data reject dropping {', '.join(candidates)} together "
                          f"(refit without them: delta chi2 = {d_chi2:.3g}, critical {crit:.3g} at {n} parameters); "
                          "of them it lowers that refit's chi2 most"))
        shown.append(best)
        candidates.remove(best)
    return out


def _band_of(band_hz, filter_rate_hz, outage_s, t):
    """(f_lo, f_hi) of the application band, Hz (helper of :func:`select_components`): `band_hz`, or from the
    filter rate (f_hi = filter_rate_hz/2; default the shortest tau's 1/(2 tau)) and the outage (f_lo = 1/outage_s;
    default the longest tau's 1/(2 tau)); (None, None) without any of them."""
    if band_hz is not None:
        f_lo, f_hi = (float(band_hz[0]), float(band_hz[1]))
    elif filter_rate_hz is not None or outage_s is not None:
        f_hi = float(filter_rate_hz) / 2.0 if filter_rate_hz is not None else 0.5 / float(t.min())
        f_lo = 1.0 / float(outage_s) if outage_s is not None else 0.5 / float(t.max())
    else:
        f_lo = f_hi = None
    if f_lo is not None and not (0 < f_lo < f_hi):
        raise ValueError(f"band must satisfy 0 < f_lo < f_hi, got ({f_lo}, {f_hi})")
    return f_lo, f_hi


def _null_fit(fit: AllanFit, c: str, t, y, e, m, lr_test: bool, significance: float, n_tested: int, known=None):
    r"""The refit without component `c` (and what substitutes for it, :data:`_SUBSTITUTES`) of
    :func:`select_components`: its AV at `t` (u^2; zero when nothing is left) and, with `lr_test`, its chi-squared
    rise over `fit` against :math:`\chi^2_{d}(1-\alpha/J)`. Returns (m_null, delta_chi2, critical, shows)."""
    from scipy.special import chdtri

    removed = (c,) + _SUBSTITUTES.get(c, ())
    comps = tuple(x for x in fit.components if x not in removed)
    d_chi2 = chi2_crit = None
    lr_shows = False
    if comps:
        n_removed = sum(fit.n_gm * 2 if x == "gauss_markov" else 1 for x in removed if x in fit.components)
        grid = fit.T_grid if fit.T_grid.size else _default_T_grid(t)
        if c in ("random_walk", "flicker"):
            # the null must not rise (random walk) nor hold a floor (flicker) at the long end: its GM peak
            # (1.89 T) stays two octaves below the longest tau, so a +1/2 slope or a flat floor there counts
            # as evidence
            grid = grid[grid <= t.max() / 8.0]
            if grid.size == 0:
                comps = tuple(x for x in comps if x != "gauss_markov")
        elif c == "white":
            # nor mimic white noise at the short end: a GM with T well below tau has AV 2 sigma^2 T/tau,
            # a -1/2 slope; its T stays three octaves above the shortest tau
            grid = grid[grid >= 8.0 * t.min()]
            if grid.size == 0:
                comps = tuple(x for x in comps if x != "gauss_markov")
        alt, _ = _profile(t, y, e, comps, fit.n_gm, grid, offset=known)
        m_null = np.asarray(_refit_model(alt, comps, fit.n_gm).avar(t), dtype=np.float64)
        if known is not None:
            m_null = m_null + known
        if lr_test:
            d_chi2 = float(alt.chi2 - fit.chi2)
            chi2_crit = float(chdtri(n_removed, significance / n_tested))
            lr_shows = bool(d_chi2 > chi2_crit)
    else:
        m_null = np.zeros_like(m) if known is None else known.copy()
    return m_null, d_chi2, chi2_crit, lr_shows


def _decision(c: str, data: bool, relevant: bool, relevance: float):
    """(keep, reason) of component `c` given the data tests (`data`) and the band test (`relevant`): white noise
    and the random walk on the data alone (:data:`_DATA_ONLY`), the others on both."""
    if c in _DATA_ONLY:
        keep, reason = data, _DATA_ONLY[c][0 if data else 1]
    elif data and relevant:
        keep, reason = True, "kept: significant in the AV and relevant in the band"
    elif not data:
        keep, reason = False, "dropped: not significant against the AV confidence"
    else:
        keep, reason = False, f"dropped: below {relevance:g} of the model AV inside the band"
    return keep, reason


def refit_selected(fit: AllanFit, selection: dict, tau, avar, edf, **fit_kwargs) -> AllanFit:
    r"""The selected model refitted: :func:`fit_allan` on the same data with only the components
    :func:`select_components` kept, attached to `fit` as ``fit.selected`` (an :class:`AllanFit`) and returned.

    The parameters to report and bound are this refit's, not the full fit's: in the full fit quantization
    and a short-T GM absorb part of the white noise (N biased low, intervals that under-cover: docs/performance.md);
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
        Passed to :func:`fit_allan` (``n_boot``, ``confidence``, ``rng``, ``record_rate_hz``, ``n_samples``, ``dt``,
        ``T_grid``, ...); ``components`` and ``n_gm`` are set here. Default ``confidence`` that of `fit`.

    A random walk the selection dropped (the data do not show it) is not thereby absent: with a bootstrap,
    the refit also carries ``random_walk`` = 0 with the interval [0, upper], the upper limit of the fit with
    the random walk (its profile limit), flagged ``on_boundary``: the integrity side for the bound (a small K
    under two GMs is dropped in most records of a few hours: docs/performance.md).

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
    (docs/performance.md). The fit with the random walk contains both models (K >= 0), so:

    * a single GM's time constant and sigma, whose intervals there are (or include) profile intervals (test
      inversion in the larger model, calibrated whichever model holds), are taken from the fit with the random
      walk (with the random walk dropped the refit's own sigma interval, and less often its hull with the larger
      fit's percentile interval, missed the truth above it; that fit's profile interval did not);
    * a percentile-only interval (the GM intervals of two GM terms) is the hull of the two: the percentile
      interval of the larger model is centred on an estimate the random walk pulls low when the truth has none,
      the refit's on one pushed high when it has one (the coverage of each: docs/performance.md).
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
