"""Allan-domain checks of a bound and the identified upper envelope (see :mod:`imupipe.bound`)."""

from __future__ import annotations

import math

import numpy as np

from imupipe.bound.engine import (  # noqa: F401
    _EPS_BOUND,
)


def gm_bounds_gm(sigma_m: float, T_m: float, sigma: float, T: float, rtol: float = 0.0) -> bool:
    r"""Whether GM (sigma_m, T_m) bounds GM (sigma, T) in PSD at every frequency.

    With :math:`a = (2\pi f)^2`, the difference of the two PSDs over the positive common
    denominator is

    .. math::

        2(\sigma_m^2 T_m - \sigma^2 T) + 2 a\, T T_m (\sigma_m^2 T - \sigma^2 T_m),

    linear in :math:`a \ge 0`, so it is non-negative for all :math:`f` iff both coefficients are:

    .. math::

        \sigma_m^2 T_m \ge \sigma^2 T \quad (f \to 0) \qquad\text{and}\qquad
        \sigma_m^2 / T_m \ge \sigma^2 / T \quad (f \to \infty).

    Parameters
    ----------
    sigma_m, T_m : float
        Bounding GM: standard deviation (u) and time constant (s).
    sigma, T : float
        Bounded GM.
    rtol : float, optional
        Relative slack on both inequalities. Default 0.

    Returns
    -------
    bool
    """
    lo = sigma_m**2 * T_m >= sigma**2 * T * (1 - rtol)
    hi = sigma_m**2 / T_m >= sigma**2 / T * (1 - rtol)
    return bool(lo and hi)


def _gm_terms_avar(model, t):
    """Allan variance (u^2) of the sum of `model`'s Gauss-Markov terms at the averaging times `t` (s)."""
    from imupipe.models import gm_avar

    out = np.zeros_like(t)
    for s, T in model.gauss_markov:
        out = out + np.asarray(gm_avar(t, s, T), dtype=np.float64)
    return out


def _narrowband_terms_avar(model, t):
    """Allan variance (u^2) of the sum of `model`'s narrowband (line) terms at the averaging times `t` (s)."""
    from imupipe.models import narrowband_avar

    out = np.zeros_like(t)
    for s, f0, z in model.narrowband:
        out = out + np.asarray(narrowband_avar(t, s, f0, z), dtype=np.float64)
    return out


def check_allan_components(bound_model, identified_model, tau) -> dict:
    r"""Component-wise AV check: does each bound component dominate its identified counterpart?

    The paper (Gallon et al. 2021, Figure 6) verifies in the AV domain that the bound's white noise
    dominates the identified white noise, its random walk the identified random walk, and its GM
    the identified bias instability. Here, on the grid `tau`:

    * ``white``: :math:`N_b^2/\tau \ge N^2/\tau`, margin :math:`N_b^2/N^2`;
    * ``random_walk``: margin :math:`K_b^2/K^2`;
    * ``gauss_markov``: :math:`\sum_i AV_{GM}(\tau; \sigma_{b,i}, T_{b,i}) \ge
      \sum_j AV_{GM}(\tau; \sigma_j, T_j)`, margin = min over `tau` of the ratio;
    * ``flicker``: the bound's GM terms against the flicker AV :math:`(2\ln 2/\pi) B^2` over the
      taus where flicker is the identified model's largest AV term (a GM's AV vanishes as
      :math:`\tau \to 0`, so no GM covers flat flicker at every tau; elsewhere the other components
      carry the AV); ``passed = None`` if flicker never dominates. A GM with :math:`\sigma = B`
      does not cover it: its ADEV peaks at :math:`0.6174\sigma < 0.664 B` (docs/method.md, section "Slip: the flicker constant and Gauss-Markov");
    * ``bias (gauss_markov + flicker)``: the bound's GM terms against the identified GM and flicker
      together, when both are present;
    * ``quantization``, ``ramp``: not Kalman-filter states; reported with ``passed = None``.

    The check holds on the `tau` grid only (use the AV grid of the data).

    Parameters
    ----------
    bound_model, identified_model : imupipe.models.NoiseModel
        SI models.
    tau : array_like
        Averaging times, s.

    Returns
    -------
    dict
        Component -> ``{"passed": bool or None, "margin": float, "tau_at_min": float or None,
        "reason": str}``; margin is min over tau of AV_bound/AV_identified (inf if the identified
        component is absent).
    """
    from imupipe.models import FLICKER_AV

    t = np.asarray(tau, dtype=np.float64)
    t = t[np.isfinite(t) & (t > 0)]
    if t.size == 0:
        raise ValueError("tau must contain positive averaging times (s)")

    def gm_av(model):
        return _gm_terms_avar(model, t)

    def entry(av_b, av_i, what, t=t):
        if not np.any(av_i > 0):
            return {"passed": True, "margin": float("inf"), "tau_at_min": None,
                    "reason": f"no identified {what}"}
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.where(av_i > 0, av_b / av_i, np.inf)
        k = int(np.argmin(r))
        ok = bool(r[k] >= 1 - _EPS_BOUND)
        return {"passed": ok, "margin": float(r[k]), "tau_at_min": float(t[k]),
                "reason": f"bound {'dominates' if ok else 'falls below'} the identified {what} in AV "
                          f"(min ratio {r[k]:.4g} at tau = {t[k]:.4g} s)"}

    b, i = bound_model, identified_model
    out = {
        "white": entry(np.full_like(t, b.white**2) / t, np.full_like(t, i.white**2) / t, "white noise"),
        "random_walk": entry(b.random_walk**2 * t / 3, np.full_like(t, i.random_walk**2) * t / 3, "random walk"),
        "gauss_markov": entry(gm_av(b), gm_av(i), "Gauss-Markov"),
    }
    flick = np.full_like(t, FLICKER_AV * getattr(i, "flicker", 0.0) ** 2)
    # A GM's AV vanishes as tau -> 0 while flicker's is flat, so no GM covers flicker at every tau;
    # what matters is the plateau, the taus where flicker is the identified model's largest term
    # (elsewhere other components carry the AV and are checked on their own).
    parts = [np.full_like(t, i.white**2) / t, i.random_walk**2 * t / 3, gm_av(i),
             3.0 * getattr(i, "quantization", 0.0) ** 2 / t**2, getattr(i, "ramp", 0.0) ** 2 * t**2 / 2]
    window = flick > np.max(np.stack(parts), axis=0)
    if np.any(flick > 0) and not np.any(window):
        out["flicker"] = {"passed": None, "margin": None, "tau_at_min": None,
                          "reason": "identified flicker is never the largest AV term on this tau grid; covered by the "
                                    "other components' checks"}
    else:
        sel = window if np.any(window) else np.ones_like(t, dtype=bool)
        sub = t[sel]
        res = entry(gm_av(b)[sel], flick[sel], "flicker (by the bound's GM, where flicker dominates)", t=sub)
        if res["tau_at_min"] is not None and np.any(window):
            res["tau_window"] = [float(sub.min()), float(sub.max())]
        out["flicker"] = res
        if len(i.gauss_markov) and getattr(i, "flicker", 0.0) > 0 and np.any(window):
            out["gauss_markov+flicker"] = entry(gm_av(b)[sel], (gm_av(i) + flick)[sel],
                                                "GM + flicker (by the bound's GM, where flicker dominates)", t=sub)
    for name in ("quantization", "ramp"):
        v = getattr(i, name, 0.0)
        if v > 0:
            out[name] = {"passed": None, "margin": None, "tau_at_min": None,
                         "reason": f"identified {name} is not a Kalman-filter state; covered only through the PSD bound"}
    return out


# ---------------------------------------------------------------------------------------------
# identified upper envelope and the Allan-domain check against kept components
# ---------------------------------------------------------------------------------------------
def random_walk_cap(curves, confidence: float = 0.95) -> float:
    r"""The largest rate random walk K the recorded Allan variances allow, u/sqrt(s).

    A random walk K alone gives :math:`\sigma^2(\tau) = K^2\tau/3` and every other component adds to it, so a
    curve whose AV at :math:`\tau` has the upper confidence limit :math:`\hat\sigma^2 \nu / \chi^2_\nu(\alpha')`
    (:math:`\nu` its equivalent degrees of freedom) excludes every
    :math:`K > \sqrt{3\,\hat\sigma^2 \nu / (\chi^2_\nu(\alpha')\,\tau)}` at that level. Per curve the cap is the
    smallest of these over its taus (:math:`\alpha' = (1 - c)/M` over its M taus, Bonferroni); over several
    curves (the envelope must cover each) the largest per-curve cap. A model-free limit: it holds however
    badly a model fits, unlike a profile limit of an inadequate fit.

    Parameters
    ----------
    curves : sequence of (tau, avar, edf)
        Averaging times (s), Allan variances (u^2) and their equivalent degrees of freedom, per curve.
    confidence : float, optional
        Level of each curve's cap. Default 0.95.

    Returns
    -------
    float
        K cap, u/sqrt(s); inf when no curve has a finite point.
    """
    caps = [float(np.min(np.sqrt(3.0 * upper / tau))) for tau, upper in _upper_avar_limits(curves, confidence)]
    return max(caps) if caps else math.inf


def _upper_avar_limits(curves, confidence: float) -> list:
    r"""Per curve the taus (s) and the upper confidence limits (u^2) of its Allan variances, at family-wise level
    `confidence` over the curve's M finite taus (Bonferroni: each point at :math:`\alpha' = (1 - c)/M`):
    :math:`\hat\sigma^2 \nu / \chi^2_\nu(\alpha')`, :math:`\chi^2_\nu(\alpha')` the chi-squared quantile of
    probability :math:`\alpha'` with :math:`\nu` the point's equivalent degrees of freedom. Curves without a finite
    point are left out. The one rule of :func:`random_walk_cap` and :func:`gm_sigma_cap`."""
    from scipy.special import chdtri

    out = []
    for tau, avar, edf in curves:
        tau, avar, edf = (np.asarray(a, dtype=float) for a in (tau, avar, edf))
        ok = np.isfinite(tau) & np.isfinite(avar) & np.isfinite(edf) & (tau > 0) & (avar > 0) & (edf > 0)
        if not ok.any():
            continue
        a = (1.0 - confidence) / int(ok.sum())
        out.append((tau[ok], avar[ok] * edf[ok] / chdtri(edf[ok], 1.0 - a)))  # chi2 quantile at probability a
    return out


def gm_sigma_cap(curves, T_lo: float, T_hi: float | None = None, confidence: float = 0.95) -> float:
    r"""The largest Gauss-Markov sigma (u) the recorded Allan variances allow for a time constant in
    [`T_lo`, `T_hi`] (s): the GM counterpart of :func:`random_walk_cap`.

    A first-order GM (sigma, T) alone has the Allan variance :math:`\sigma^2 g(\tau, T)`,
    :math:`g(\tau, T) = (2T/\tau)[1 - (T/2\tau)(3 - 4e^{-\tau/T} + e^{-2\tau/T})]` (:func:`imupipe.models.gm_avar`
    with sigma = 1), and every other component adds to it. A curve whose AV at :math:`\tau` has the upper
    confidence limit :math:`U(\tau) = \hat\sigma^2\nu/\chi^2_\nu(\alpha')` therefore excludes every
    :math:`\sigma^2 > U(\tau)/g(\tau, T)`; over its taus

    .. math::

        \sigma_{max}(T)^2 = \min_\tau U(\tau) / g(\tau, T).

    For a range :math:`T \in [T_1, T_2]` the cap is :math:`\sup_{T}\sigma_{max}(T)`, bounded from above in closed
    form: :math:`g(\tau, T) = h(\tau/T)` with :math:`h` unimodal (it rises like :math:`2x/3`, peaks at
    :math:`x = 1.893` and falls like :math:`2/x`), so :math:`g(\tau, T) \ge \min(g(\tau, T_1), g(\tau, T_2))` on
    the range and

    .. math::

        \sup_{T_1 \le T \le T_2} \sigma_{max}(T)^2 \le \min_\tau U(\tau) / \min(g(\tau, T_1), g(\tau, T_2)),

    the value returned (a cap that is, if anything, too high: it never removes a sigma the data allow).

    **Confidence.** :math:`\alpha' = (1 - c)/M` over the M taus of each curve (Bonferroni), so each curve's upper
    limits hold at every tau at once with probability at least `confidence`; on that one event every GM of the
    truth, at every T, has :math:`\sigma \le \sigma_{max}(T)` (its AV is part of the total): the cap holds
    simultaneously for every T, every GM term and the random walk of :func:`random_walk_cap` at the same level
    (family-wise over the taus; no further correction over T or terms is needed). Over several curves (the
    envelope must cover each) the largest per-curve cap, each at level `confidence`, as in
    :func:`random_walk_cap`. Like it a model-free limit: it holds however badly a model fits.

    Parameters
    ----------
    curves : sequence of (tau, avar, edf)
        Averaging times (s), Allan variances (u^2) and their equivalent degrees of freedom, per curve.
    T_lo : float
        Time constant (s), > 0; alone: the cap at that T.
    T_hi : float, optional
        Upper end of the T range (s), >= `T_lo`; default `T_lo`. ``inf`` gives ``inf`` (a GM with T -> inf and
        :math:`\sigma^2 \propto T` has a vanishing AV at every recorded tau: nothing is excluded).
    confidence : float, optional
        Family-wise level of each curve's upper limits. Default 0.95.

    Returns
    -------
    float
        sigma cap, u; inf when no curve has a finite point.
    """
    from imupipe.models import gm_avar

    T_lo = float(T_lo)
    T_hi = T_lo if T_hi is None else float(T_hi)
    if not (T_lo > 0 and math.isfinite(T_lo) and T_hi >= T_lo):
        raise ValueError(f"gm_sigma_cap: need 0 < T_lo <= T_hi (s), got T_lo={T_lo!r}, T_hi={T_hi!r}")
    if not math.isfinite(T_hi):
        return math.inf
    caps = []
    for tau, upper in _upper_avar_limits(curves, confidence):
        g = np.minimum(gm_avar(tau, 1.0, T_lo), gm_avar(tau, 1.0, T_hi))
        with np.errstate(divide="ignore"):
            caps.append(float(np.sqrt(np.min(np.where(g > 0, upper / g, np.inf)))))
    return max(caps) if caps else math.inf


def _short_T_white_factor() -> float:
    r"""kappa = max over u >= 1 of 1/u - 2/(1 + u^2) (dimensionless, 0.13488...): the white-noise level, in units
    of :math:`\sigma^2 a`, that a GM box over [a, c] needs added to dominate every GM with T <= a (see
    :func:`gm_box_envelope`). The maximum is at the real root u >= 1 of :math:`u^4 - 4u^3 + 2u^2 + 1 = 0` (the
    derivative's zero: :math:`(1 + u^2)^2 = 4u^3`)."""
    roots = np.roots([1.0, -4.0, 2.0, 0.0, 1.0])
    u = [float(r.real) for r in roots if abs(r.imag) <= 1e-9 * abs(r) and r.real >= 1.0] + [1.0]
    return max(0.0, max(1.0 / x - 2.0 / (1.0 + x * x) for x in u))


#: :func:`_short_T_white_factor`, computed once.
SHORT_T_WHITE_FACTOR = _short_T_white_factor()


def gm_box_envelope(sigma_up: float, T: float, T_lo: float, T_hi: float, T_search=None,
                    span_s: float | None = None) -> tuple:
    r"""A single GM plus a white-noise addition that dominate, in PSD, every GM of the box
    :math:`\sigma \le \sigma_{up}`, :math:`T_{lo} \le T' \le T_{hi}`, including a box left open at either end.

    PSDs are two-sided (:mod:`imupipe.models`): a GM (sigma, T) has
    :math:`S(f) = 2\sigma^2 T / (1 + \omega^2 T^2)`, :math:`\omega = 2\pi f` (its integral over all f is
    :math:`\sigma^2`), white noise N has :math:`N^2`. The PSD is increasing in sigma, so only
    :math:`\sigma = \sigma_{up}` (written s) matters.

    **Closed box** :math:`[a, c]` (:math:`0 < a \le c < \infty`): the single GM :math:`T_m = \sqrt{ac}`,
    :math:`\sigma_m^2 = s^2\sqrt{c/a}`, the tightest single GM above every GM of the box (a GM dominates another
    iff :math:`\sigma_m^2 T_m \ge \sigma^2 T` and :math:`\sigma_m^2/T_m \ge \sigma^2/T`,
    :func:`gm_bounds_gm`; here :math:`\sigma_m^2 T_m = s^2 c`, :math:`\sigma_m^2/T_m = s^2/a`). Its PSD is
    :math:`S_{box}(\omega) = 2 s^2 c / (1 + \omega^2 a c)`.

    **Open upper end** (:math:`T_{hi} = \infty`: the data do not bound T above within the search). No finite
    model dominates every such GM at every frequency (at a fixed f the supremum over T is
    :math:`s^2/\omega`, reached at :math:`T = 1/\omega`). The box is closed at
    :math:`c = \max(T, T_{search,max}, h/(2\pi))`, h = `span_s`: for :math:`T' > c` and
    :math:`\omega \ge 1/c`, :math:`\partial S/\partial T' = 2 s^2 (1 - \omega^2 T'^2)/(1 + \omega^2 T'^2)^2 < 0`
    (:math:`\omega T' > \omega c \ge 1`), so :math:`S(\omega; T') \le S(\omega; c) \le S_{box}(\omega)`.
    With :math:`c \ge h/(2\pi)` that holds for every :math:`f \ge 1/h`, the slowest frequency a filter run
    over h seconds resolves; below 1/h nothing is claimed (:math:`c = h` would only give it from
    :math:`1/(2\pi h)` on, at :math:`2\pi` times the low-frequency level). Without `span_s`,
    :math:`c = \max(T, T_{search,max})` and the envelope dominates for :math:`f \ge 1/(2\pi c)` only.

    **Open lower end** (:math:`T_{lo} = 0`: the data do not bound T below). Split at
    :math:`a = \min(T, T_{search,min})` (any :math:`a > 0` is valid; the shortest T searched is the natural
    one). The box over :math:`[a, c]` dominates every T' >= a. For :math:`T' \le a`:
    :math:`S(\omega; T') \le S(\omega; a) \le S_{box}(\omega)` where :math:`\omega a \le 1` (S increasing in T'
    for :math:`\omega T' < 1`), and :math:`S(\omega; T') \le s^2/\omega` (:math:`1 + x^2 \ge 2x`) where
    :math:`\omega a > 1`. With :math:`u = \omega a \ge 1` and :math:`r = c/a \ge 1`, the shortfall of the box
    there is :math:`s^2 a\,[1/u - 2r/(1 + r u^2)] \le s^2 a\,[1/u - 2/(1 + u^2)]` (the box term increases with
    r), at most :math:`\kappa s^2 a`, :math:`\kappa` = :data:`SHORT_T_WHITE_FACTOR` = 0.1349
    (:func:`_short_T_white_factor`). So white noise :math:`W = \kappa s^2 a` added to the envelope's covers the
    rest. The cruder :math:`W = 2 s^2 a` (the GM's PSD at f = 0, :math:`2 s^2 T' \le 2 s^2 a`, a white noise
    alone above every such GM) is 14.8 times larger; on the ADIS16405 accelerometer (s = 0.0224 m/s^2,
    a = 0.01 s) it raised the envelope's N by 40 % against 3 %
    (docs/method.md, section "The upper envelope").

    Parameters
    ----------
    sigma_up : float
        Upper end of sigma (u).
    T : float
        Estimate of T (s), > 0.
    T_lo, T_hi : float
        Ends of the T interval (s): ``T_lo = 0`` an open lower end, ``T_hi = inf`` an open upper end; NaN: no
        interval on that side (the estimate is used, the box is then closed there at T).
    T_search : tuple of float, optional
        (shortest, longest) time constant the fit searched (s).
    span_s : float, optional
        Horizon h (s) from which on (f >= 1/h) an open upper end is covered.

    Returns
    -------
    tuple
        ``(sigma_m (u), T_m (s), W (u^2/Hz, two-sided white-noise addition), lower_open, upper_open)``.
    """
    s = float(sigma_up)
    a, c, w, lower_open, upper_open = _gm_box_ends(T, T_lo, T_hi, T_search, span_s)
    return s * (c / a) ** 0.25, math.sqrt(a * c), w * s * s, lower_open, upper_open


def _gm_box_ends(T, T_lo, T_hi, T_search=None, span_s=None) -> tuple:
    """The closed box [a, c] (s) of :func:`gm_box_envelope` (an open end closed as its docstring derives), the
    white-noise addition per unit sigma_up^2 that covers the T below an open lower end (kappa a, s; 0 when closed)
    and whether each end was open: ``(a, c, w, lower_open, upper_open)``."""
    T = float(T)
    if not (T > 0 and math.isfinite(T)):
        raise ValueError(f"gm_box_envelope: T must be a positive finite time constant (s), got {T!r}")
    if span_s is not None and not (float(span_s) > 0 and math.isfinite(float(span_s))):
        raise ValueError(f"gm_box_envelope: span_s must be a positive number of seconds, got {span_s!r}")
    t_min, t_max = (T, T) if T_search is None else (min(float(T_search[0]), T), max(float(T_search[1]), T))
    lower_open, upper_open = T_lo == 0.0, T_hi == math.inf
    if lower_open:
        a = t_min
    else:
        a = min(T, float(T_lo)) if math.isfinite(T_lo) and T_lo > 0 else T
    if upper_open:
        c = max(t_max, float(span_s) / (2.0 * math.pi) if span_s is not None else 0.0)
    else:
        c = max(T, float(T_hi)) if math.isfinite(T_hi) and T_hi > 0 else T
    return a, max(c, a), SHORT_T_WHITE_FACTOR * a if lower_open else 0.0, lower_open, upper_open


#: Largest ratio T_hi/T_lo of one GM term of the upper envelope: a wider box is split into sub-boxes of at most
#: this ratio (:func:`split_gm_box`).
BOX_SPLIT_RATIO = 10.0


class BankError(RuntimeError):
    """The linear programme of :func:`gm_bank_envelope` found no weights (the solver's status is in the message);
    :func:`upper_envelope` then covers the box by :func:`split_gm_box`'s sub-box terms, which dominate it without
    the cap."""


def split_gm_box(sigma_up: float, a: float, c: float, max_ratio: float = BOX_SPLIT_RATIO) -> tuple:
    r"""GM terms whose sum dominates, in PSD, every GM of the box :math:`\sigma \le \sigma_{up}`,
    :math:`T \in [a, c]` (s): the single box GM of :func:`gm_box_envelope` (:math:`T_m = \sqrt{ac}`,
    :math:`\sigma_m^2 = \sigma_{up}^2\sqrt{c/a}`) when :math:`c/a \le` `max_ratio`, else one such GM per
    sub-box of k sub-boxes of equal ratio :math:`r = (c/a)^{1/k} \le` `max_ratio`: term j has
    :math:`T_j = a r^{j + 1/2}`, :math:`\sigma_j^2 = \sigma_{up}^2 \sqrt r`. Each term dominates every GM of its
    sub-box (the closed-box rule), the sub-boxes cover [a, c] and every term is >= 0, so the sum dominates every GM
    of the box at every frequency. Where c/a is large the single GM is far above the box's supremum in between (at
    :math:`\omega = 1/\sqrt{ac}` it is :math:`\sigma_{up}^2 c`, the supremum :math:`\sigma_{up}^2\sqrt{ac}`);
    the sum exceeds it there by a factor of order :math:`\sqrt r`, and by at most :math:`r/(r-1)` against the
    single GM as f -> 0 and f -> inf (1.11 for r = 10).

    Returns
    -------
    tuple of (sigma u, T s)
        The terms, by increasing T.
    """
    if not (max_ratio > 1.0):
        raise ValueError(f"split_gm_box: max_ratio must exceed 1, got {max_ratio!r}")
    s, a, c = float(sigma_up), float(a), float(c)
    ratio = c / a
    k = 1 if ratio <= max_ratio * (1.0 + 1e-12) else math.ceil(math.log(ratio) / math.log(max_ratio) - 1e-12)
    r = ratio ** (1.0 / k)
    return tuple((s * r**0.25, a * r ** (j + 0.5)) for j in range(k))


def cap_gm_terms(terms, sigma_up: float, a: float, c: float, upper_open: bool, gm_cap, estimate=None,
                 record: list | None = None) -> tuple:
    r"""The GM terms of :func:`split_gm_box` over the box :math:`\sigma \le \sigma_{up}`, :math:`T \in [a, c]`
    (s), each reduced to cover its sub-box only at the sigma the recorded Allan variances allow there.

    Term j (:math:`T_j = a r^{j+1/2}`, sub-box :math:`[T_j/\sqrt r, T_j\sqrt r]`) dominates every GM of its
    sub-box with :math:`\sigma \le \sigma_{eff}` when :math:`\sigma_j^2 = \sigma_{eff}^2\sqrt r` (the closed-box
    rule of :func:`gm_box_envelope`). With the cap :math:`C(T_1, T_2)` of `gm_cap` (:func:`gm_sigma_cap`: on the
    event that the recorded AV upper limits hold, no GM of the truth with T in the sub-box has a larger sigma):
    :math:`\sigma_{eff} = \min(\sigma_{up}, C(T_1, T_2))`, and at least the fit's `estimate` sigma in the sub-box
    that holds its T (the envelope stays above the fitted model).

    **Open upper end.** The top term also covers every T' > c for :math:`\omega \ge 1/c` (:func:`gm_box_envelope`).
    Its cap extends there: :math:`T\,g(\tau, T)` is non-decreasing in T (the AV is a positive-kernel integral of
    the PSD, and :math:`T \cdot 2T/(1 + \omega^2T^2)` increases with T at every :math:`\omega`), so
    :math:`\sigma_{max}(T')^2 \le (T'/c)\,\sigma_{max}(c)^2` and such a GM's PSD is at most
    :math:`2T'\sigma_{max}(T')^2/(\omega^2T'^2) \le 2\sigma_{max}(c)^2/(c\,\omega^2)`; a GM
    :math:`(\sqrt 2\,\sigma_{max}(c), c)` is above that for :math:`\omega c \ge 1`. The top term's
    :math:`\sigma_{eff}^2 = \min(\sigma_{up}^2, \max(C(T_1, c)^2, 2\sigma_{max}(c)^2))`.

    Parameters
    ----------
    terms : sequence of (sigma u, T s)
        :func:`split_gm_box` (`sigma_up`, `a`, `c`), by increasing T.
    sigma_up : float
        The box's sigma (u).
    a, c : float
        The box's ends (s), as closed by :func:`gm_box_envelope`.
    upper_open : bool
        Whether the box stands for a T interval open above.
    gm_cap : callable
        ``gm_cap(T_lo_s, T_hi_s)`` -> sigma (u); ``gm_cap(T, T)`` the pointwise cap.
    estimate : tuple of (sigma u, T s), optional
        The fit's GM estimate.
    record : list, optional
        One dict per term is appended: ``T_range_s``, ``sigma_box``, ``sigma_cap``, ``sigma_used`` (u).

    Returns
    -------
    tuple of (sigma u, T s)
    """
    k = len(terms)
    if k == 0:
        return tuple(terms)
    r = (float(c) / float(a)) ** (1.0 / k)
    s_up = float(sigma_up)
    sig_hat, T_hat = estimate if estimate is not None else (0.0, float("nan"))
    out = []
    for j, (_, T_j) in enumerate(terms):
        lo, hi = T_j / math.sqrt(r), T_j * math.sqrt(r)
        cap = float(gm_cap(lo, hi))
        top_open = upper_open and j == k - 1
        if top_open:
            cap = max(cap, math.sqrt(2.0) * float(gm_cap(hi, hi)))
        eff = min(s_up, cap)
        holds_estimate = lo * (1 - 1e-12) <= T_hat and (top_open or T_hat <= hi * (1 + 1e-12))
        if holds_estimate:
            eff = max(eff, min(s_up, float(sig_hat)))
        out.append((eff * r**0.25, T_j))
        if record is not None:
            record.append({"T_range_s": [float(lo), float("inf") if top_open else float(hi)],
                           "sigma_box": s_up, "sigma_cap": cap, "sigma_used": eff,
                           "term": {"sigma": eff * r**0.25, "T": float(T_j)}})
    return tuple(out)


#: Time constants per decade of the GM bank of :func:`gm_bank_envelope`, and frequency nodes per decade of its LP.
BANK_PER_DECADE, BANK_NODES_PER_DECADE = 2, 40


def gm_bank_envelope(sigma_up: float, a: float, c: float, lower_open: bool, upper_open: bool, gm_cap=None,
                     estimate=None, f_min_hz: float | None = None, fine_ratio: float = 1.05) -> tuple:
    r"""A bank of GM terms whose summed PSD lies above every GM the data allow in a box left open by the data:
    :math:`\sigma \le \sigma(T') = \min(\sigma_{up}, \sigma_{max}(T'))`, :math:`T' \in [a, c]` (s), and beyond an
    open end as :func:`gm_box_envelope` covers it; the weights by a linear programme, not by sub-box over-cover.

    **Target.** :math:`F(\omega)` (two-sided PSD, u^2/Hz, :math:`\omega = 2\pi f`), an upper bound of the
    supremum over the allowed GMs: [a, c] split into fine sub-boxes :math:`[T_1, T_2]` of ratio <= `fine_ratio`,
    each at :math:`\sigma_k = \min(\sigma_{up}, C(T_1, T_2))` (:func:`gm_sigma_cap`'s range bound via `gm_cap`;
    :math:`\sigma_{up}` without it), whose supremum is :math:`2\sigma_k^2 t/(1 + \omega^2 t^2)`,
    :math:`t = \mathrm{clip}(1/\omega, T_1, T_2)` (the GM's PSD is increasing in T below :math:`T = 1/\omega`,
    decreasing above); with an open lower end also the GM :math:`(\sigma_{up}, a)` (the white noise
    :math:`\kappa\sigma_{up}^2 a` the caller adds covers the rest of every shorter T, :func:`gm_box_envelope`);
    with an open upper end, for :math:`\omega \ge 2\pi f_{min}` (:math:`\ge 1/c`), every T' > c:
    :math:`\min(2\sigma_{up}^2 c/(1 + \omega^2c^2), 2\sigma_{max}(c)^2/(c\omega^2))` (:func:`cap_gm_terms`); the
    fit's `estimate` GM at every frequency.

    **Bank.** Terms at :data:`BANK_PER_DECADE` time constants per decade over [a, c], weights
    :math:`w_j = \sigma_j^2 \ge 0` minimising the summed relative overshoot over the nodes. Both the bank's PSD
    :math:`S_b` and F decrease with :math:`\omega`, so on nodes :math:`\omega_0 < \dots < \omega_N`
    (:data:`BANK_NODES_PER_DECADE` per decade) the constraints :math:`S_b(\omega_{i+1}) \ge F(\omega_i)` give
    :math:`S_b \ge F` on every :math:`[\omega_i, \omega_{i+1}]` exactly; below :math:`\omega_0`
    :math:`S_b(\omega_0) \ge \sup F` (closed part: :math:`F(0)`); above :math:`\omega_N`,
    :math:`\omega^2 S_b(\omega)` is increasing and :math:`\omega^2 F(\omega) \le \max 2\sigma^2/T`, so
    :math:`\omega_N^2 S_b(\omega_N) \ge \max 2\sigma^2/T` ends it. After the LP the constraints are evaluated again
    and the weights scaled up by any shortfall (the LP's tolerance), so the bank dominates F at every
    :math:`\omega` (open upper end: the tail from :math:`f_{min}` on, as before).

    An equal-weight bank of ratio :math:`\rho` over a flat :math:`\sigma` needs only
    :math:`w \approx \sigma^2 \ln\rho/\pi` (its sum is :math:`w\pi/(\omega\ln\rho)` against the supremum
    :math:`\sigma^2/\omega`), where the sub-box rule of :func:`split_gm_box` gives :math:`\sigma^2\sqrt r` per term.

    Parameters
    ----------
    sigma_up : float
        The box's sigma (u).
    a, c : float
        The box's ends (s), closed as :func:`gm_box_envelope` closes an open end.
    lower_open, upper_open : bool
        Whether the T interval was open below / above.
    gm_cap : callable, optional
        ``gm_cap(T_lo_s, T_hi_s)`` -> sigma (u) (:func:`gm_sigma_cap` of the curves). Default: no cap.
    estimate : tuple of (sigma u, T s), optional
        The fit's GM, dominated at every frequency.
    f_min_hz : float, optional
        Lowest frequency (Hz) from which on an open upper end is covered: 1/h (h the horizon). Default 1/(2 pi c).
    fine_ratio : float, optional
        Largest T ratio of the target's fine sub-boxes. Default 1.05.

    Returns
    -------
    tuple of (sigma u, T s)
        The bank's terms of non-zero weight, by increasing T.
    """
    from scipy.optimize import linprog

    s_up, a, c = float(sigma_up), float(a), float(c)
    c = max(c, a)
    cap = gm_cap if gm_cap is not None else (lambda lo, hi: math.inf)
    n_f = max(1, math.ceil(math.log(c / a) / math.log(fine_ratio) - 1e-12)) if c > a else 1
    edges = a * (c / a) ** (np.arange(n_f + 1) / n_f) if c > a else np.array([a, a])
    t1, t2 = edges[:-1], edges[1:]
    sig2 = np.array([min(s_up, float(cap(lo, hi))) ** 2 for lo, hi in zip(t1, t2)])
    w_h = 2.0 * math.pi * float(f_min_hz) if f_min_hz is not None else 1.0 / c
    w_h = max(w_h, 1.0 / c)
    s_tail2 = min(s_up, float(cap(c, c))) ** 2 if upper_open else 0.0
    sig_hat, T_hat = estimate if estimate is not None else (0.0, a)

    def target(w):
        w = np.atleast_1d(np.asarray(w, dtype=float))
        t = np.clip(1.0 / w[:, None], t1[None, :], t2[None, :])
        out = np.max(2.0 * sig2[None, :] * t / (1.0 + (w[:, None] * t) ** 2), axis=1)
        if lower_open:
            out = np.maximum(out, 2.0 * s_up**2 * a / (1.0 + (w * a) ** 2))
        out = np.maximum(out, 2.0 * sig_hat**2 * T_hat / (1.0 + (w * T_hat) ** 2))
        if upper_open:
            tail = np.minimum(2.0 * s_up**2 * c / (1.0 + (w * c) ** 2), 2.0 * s_tail2 / (c * w**2))
            out = np.maximum(out, np.where(w >= w_h * (1 - 1e-12), tail, 0.0))
        return out

    q = 10.0 ** (1.0 / BANK_NODES_PER_DECADE)
    lo_w, hi_w = min(w_h, 0.1 / c), 10.0 / a
    i0, i1 = math.ceil(math.log(w_h / lo_w) / math.log(q)), math.ceil(math.log(hi_w / w_h) / math.log(q))
    nodes = w_h * q ** np.arange(-i0, i1 + 1)  # w_h itself a node: the tail starts there
    n_T = max(2, math.ceil(BANK_PER_DECADE * math.log10(c / a)) + 1) if c > a else 1
    T = a * (c / a) ** (np.arange(n_T) / max(n_T - 1, 1)) if c > a else np.array([a])

    def bank(w, Tj):
        return 2.0 * Tj[None, :] / (1.0 + (w[:, None] * Tj[None, :]) ** 2)

    F = target(nodes)
    # rows: S_b(w_{i+1}) >= F(w_i); S_b(w_0) >= F(0) (closed part, the estimate, the open lower end's GM);
    # w_N^2 S_b(w_N) >= sup w^2 F
    f0 = max(float(np.max(2.0 * sig2 * t2)), 2.0 * sig_hat**2 * T_hat, 2.0 * s_up**2 * a if lower_open else 0.0)
    top = max(float(np.max(2.0 * sig2 / t1)), 2.0 * sig_hat**2 / T_hat if sig_hat > 0 else 0.0,
              2.0 * s_up**2 / a if lower_open else 0.0, 2.0 * min(s_up**2, s_tail2) / c if upper_open else 0.0)
    # a row whose target is 0 constrains nothing (a sub-box the cap closes, below the open tail's start): left out,
    # as are the objective's terms there (division by 0 would make the programme ill-posed)
    rows = [bank(nodes[1:], T)[F[:-1] > 0] / F[:-1][F[:-1] > 0, None]]
    if f0 > 0:
        rows.append(bank(nodes[:1], T) / f0)
    if top > 0:
        rows.append(nodes[-1] ** 2 * bank(nodes[-1:], T) / top)
    A = np.vstack(rows)
    if A.shape[0] == 0:  # nothing to cover: every GM of the box is capped at 0
        return ()
    scale = s_up**2
    pos = F > 0
    cost = np.sum(bank(nodes[pos], T) / F[pos, None], axis=0)
    # the cost's scale (1/F: up to 5e8 on the ADIS16405 imu2 gyro z box) does not move the optimum; unscaled, the
    # HiGHS simplex stopped there with "Status 0: Not Set" (tests/test_gm_cap.py, slow)
    res = linprog(cost / np.max(cost), A_ub=-A * scale, b_ub=-np.ones(A.shape[0]), bounds=(0, None), method="highs")
    if res.status != 0 or res.x is None or not np.all(np.isfinite(res.x)):
        raise BankError(f"gm_bank_envelope: the bank's linear programme failed ({res.message})")
    w = np.maximum(res.x, 0.0) * scale
    short = float(np.min(A @ w))  # >= 1 - the LP's tolerance; scale up by any shortfall
    if short < 1.0:
        w = w / short * (1.0 + 1e-12)
    keep = w > 1e-12 * float(np.max(w))
    return tuple((math.sqrt(float(v)), float(t)) for v, t in zip(w[keep], T[keep]))


def ramp_random_walk(ramp: float, span_s: float | None) -> float:
    r"""The random walk that stands in for a fitted rate ramp R (u/s) over a filter's window h = `span_s` (s):
    :math:`K_R = R \sqrt{1.5\,h}` (u/sqrt(s)); 0 without a ramp or a window.

    A ramp is no filter state, and over a record of a few hours a random walk's path often looks like one: the fit
    then gives the rise of the long-tau Allan variance to the ramp and the random walk's upper limit falls with it
    (a 2 h gyro record whose random walk was fitted as zero beside a ramp: the envelope's K 0.74x the truth's, and a
    per-axis model on it under-stated its axis's error 2.03x over an 1800 s outage). The envelope carries the ramp's
    power as a random walk instead: :math:`K_R^2 \tau/3 \ge R^2 \tau^2/2` (the ramp's Allan variance) for every
    :math:`\tau \le h`, and over an outage t <= h its angle (velocity) error variance :math:`K_R^2 t^3/3` is at
    least twice the ramp's :math:`(R t^2/2)^2`. Added in quadrature to the envelope's K (:func:`upper_envelope`)."""
    if not (ramp > 0 and span_s and math.isfinite(float(span_s)) and span_s > 0):
        return 0.0
    return float(ramp) * math.sqrt(1.5 * float(span_s))


def upper_envelope(fit, kept=None, intervals: str = "statistical", random_walk_cap: float | None = None,
                   span_s: float | None = None, max_box_ratio: float = BOX_SPLIT_RATIO, gm_cap=None,
                   cap_record: list | None = None):
    r"""The identified model's upper confidence envelope, for the all-frequency rows of :func:`bound_psd`.

    Each KEPT component at the upper end of its interval (``fit.intervals``, level ``fit.confidence``;
    the point estimate where the interval is NaN): white :math:`N_{up}`, flicker :math:`B_{up}`, each GM
    term as the tightest single GM dominating every GM of the box :math:`\sigma \le \sigma_{up}`,
    :math:`T_{lo} \le T \le T_{hi}`: :math:`T_m = \sqrt{T_{lo} T_{hi}}`,
    :math:`\sigma_m^2 = \sigma_{up}^2 \sqrt{T_{hi}/T_{lo}}` (a GM dominates another iff
    :math:`\sigma_m^2 T_m \ge \sigma^2 T` and :math:`\sigma_m^2/T_m \ge \sigma^2/T`). A T interval left open
    by the data (``T_lo = 0`` or ``T_hi = inf``, ``interval_kind`` "one-sided") is not replaced by the
    estimate: an open upper end is closed at :math:`\max(T_{search,max}, h/(2\pi))` (h = `span_s`), which
    dominates every longer T for :math:`f \ge 1/h`; an open lower end is closed at the shortest T searched
    and every shorter T is covered by white noise :math:`0.1349\,\sigma_{up}^2 T_{search,min}` added to
    :math:`N_{up}^2` (:func:`gm_box_envelope`, with the proofs). A box wider than `max_box_ratio` in T is
    represented by a sum of GM terms over narrower sub-boxes (:func:`split_gm_box`): still above every GM of
    the box, and far below the single GM in between.
    The random walk at its upper limit **whether or not it was kept**: a random walk the data cannot
    exclude at the stated confidence is an integrity risk below the lowest bin (the profile limit
    ``random_walk_profile["upper"]`` exists when K was fitted as zero); a ramp the fit gives power to (estimate
    above 0) adds its stand-in :func:`ramp_random_walk` at the ramp's upper limit, in quadrature, over `span_s`.

    Parameters
    ----------
    fit : imupipe.identify.AllanFit
        Or an object with its ``params``, ``intervals`` (and optionally ``intervals_statistical``,
        ``random_walk_profile``, ``T_grid``: the time constants searched, s).
    kept : sequence of str or dict, optional
        Components kept by model selection (names or a ``select_components`` result). Default: all of
        the fit's components with a non-zero estimate.
    random_walk_cap : float, optional
        A model-free upper limit of K from the recorded Allan variances (:func:`random_walk_cap`, u/sqrt(s)):
        the envelope's K is then at most the cap (and at least the fit's estimate). Default: no cap.
    intervals : {"statistical", "widened"}, optional
        Which upper ends: ``"statistical"`` (default) the fitted model's own confidence limits
        (``fit.intervals_statistical`` where the fit carries them), ``"widened"`` the intervals after the
        over-dispersion widening of an inadequate fit (``fit.intervals``). On real records whose fit the
        data reject (chi2/dof in the thousands) the widened ends are factors of 10^3-10^14 above the
        estimates and would turn the bound into a useless one; the statistical ends are limits
        conditional on the fitted model. The bound file flags an inadequate fit in either case, and the
        replay of the records in the verification stage is the model-free check over the horizon.
    span_s : float, optional
        The window a filter must be right over, s (fix period plus outage): a GM whose T
        interval is open above is dominated for f >= 1/span_s. Default: only for f >= 1/(2 pi T_max), T_max
        the longest T searched.
    max_box_ratio : float, optional
        Largest T_hi/T_lo of one envelope GM term (:func:`split_gm_box`). Default :data:`BOX_SPLIT_RATIO` (10).
    gm_cap : callable, optional
        ``gm_cap(T_lo_s, T_hi_s)``: the largest GM sigma (u) the recorded Allan variances allow for a T in the
        range (:func:`gm_sigma_cap` of the curves). Each GM term of a box then covers its sub-box at
        :math:`\min(\sigma_{up}, \text{cap})` instead of :math:`\sigma_{up}` (:func:`cap_gm_terms`, never below
        the fit's estimate in the sub-box that holds it). Default: no cap.
    cap_record : list, optional
        With `gm_cap`: one dict per GM term is appended (its T range s, the box's sigma, the cap, the sigma used, u).

    Returns
    -------
    imupipe.models.NoiseModel
        SI.
    """
    from imupipe.models import NoiseModel

    if isinstance(kept, dict):
        kept = kept.get("kept", [])
    if intervals not in ("statistical", "widened"):
        raise ValueError(f"upper_envelope: intervals must be 'statistical' or 'widened', got {intervals!r}")
    p, iv = fit.params, fit.intervals
    if intervals == "statistical" and getattr(fit, "intervals_statistical", None):
        iv = fit.intervals_statistical
    grid = np.asarray(getattr(fit, "T_grid", None) if getattr(fit, "T_grid", None) is not None else [], dtype=float)
    grid = grid[np.isfinite(grid) & (grid > 0)]
    T_search = (float(grid.min()), float(grid.max())) if grid.size else None

    def up(name):
        v = float(p.get(name, 0.0) or 0.0)
        lo_hi = iv.get(name)
        if lo_hi is not None and math.isfinite(lo_hi[1]):
            v = max(v, float(lo_hi[1]))
        return v if math.isfinite(v) else 0.0

    def is_kept(name):
        if kept is None:
            return name in p and float(p.get(name) or 0.0) > 0
        return name in kept

    gm, white_add = [], 0.0
    if is_kept("gauss_markov") or (kept is None):
        i = 1
        while f"gm_sigma_{i}" in p:
            s, T = up(f"gm_sigma_{i}"), float(p.get(f"gm_T_{i}", float("nan")))
            if s > 0 and math.isfinite(T) and T > 0:
                T_lo, T_hi = (float(v) for v in iv.get(f"gm_T_{i}", (float("nan"), float("nan"))))
                # the GM box sigma <= s, T in [T_lo, T_hi], an open end included (docs/method.md, section
                # "The upper envelope")
                a, c, w, lower_open, upper_open = _gm_box_ends(T, T_lo, T_hi, T_search, span_s)
                # a box wider than max_box_ratio in T as a sum of narrower boxes (split_gm_box): the single GM
                # over a box of several decades is far above every GM of it in between
                terms = split_gm_box(s, a, c, max_box_ratio)
                if gm_cap is not None and (lower_open or upper_open):
                    # a box the data leave open: a bank whose weights a linear programme sets against every GM the
                    # recorded Allan variances allow in it (docs/method.md, section "The upper envelope")
                    try:
                        terms = gm_bank_envelope(s, a, c, lower_open, upper_open, gm_cap,
                                                 estimate=(float(p.get(f"gm_sigma_{i}", 0.0) or 0.0), T),
                                                 f_min_hz=1.0 / float(span_s) if span_s else None)
                        failed = None
                    except BankError as exc:  # terms stay the uncapped sub-box terms: looser, never lower
                        failed = str(exc)
                    if cap_record is not None:
                        box = {"T_range_s": [float(a), float("inf") if upper_open else float(c)], "sigma_box": s}
                        listed = [{"sigma": float(v), "T": float(t)} for v, t in terms]
                        if failed is not None:
                            box.update(sigma_cap=float("nan"), sigma_used=s, bank_failed=failed, sub_boxes=listed)
                        else:
                            least = min((float(gm_cap(t, t)) for _, t in terms), default=0.0)
                            box.update(sigma_cap=least, sigma_used=min(s, least), bank=listed)
                        cap_record.append(box)
                elif gm_cap is not None:
                    # each term at most what the recorded Allan variances allow over its sub-box (docs/method.md,
                    # section "The upper envelope")
                    terms = cap_gm_terms(terms, s, a, c, upper_open, gm_cap,
                                         estimate=(float(p.get(f"gm_sigma_{i}", 0.0) or 0.0), T),
                                         record=cap_record)
                gm.extend(terms)
                white_add += w * s * s
            i += 1
    k = up("random_walk")
    prof = getattr(fit, "random_walk_profile", {}) or {}
    if math.isfinite(prof.get("upper", float("nan")) or float("nan")):
        k = max(k, float(prof["upper"]))
    if random_walk_cap is not None and math.isfinite(random_walk_cap):
        k = max(min(k, float(random_walk_cap)), float(p.get("random_walk", 0.0) or 0.0))
    k = math.sqrt(k * k + ramp_random_walk(up("ramp") if float(p.get("ramp", 0.0) or 0.0) > 0 else 0.0, span_s) ** 2)
    white = up("white") if is_kept("white") else 0.0
    return NoiseModel(white=math.sqrt(white**2 + white_add), gauss_markov=tuple(gm), random_walk=k,
                      flicker=up("flicker") if is_kept("flicker") else 0.0)


def check_allan(bound_model, identified_model, tau, kept=None, sample_avar=None, sample_edf=None, labels=None,
                span_s: float | None = None, confidence: float = 0.95, tau_min_s: float | None = None) -> dict:
    r"""Allan-domain check that distinguishes a real shortfall from a component without counterpart.

    1. Component against component, **kept components only** (`kept`, e.g. the ``select_components``
       result; default: every component of `identified_model`): white against white, random walk
       against random walk, the identified GM terms against the bound's GM terms, and the identified
       flicker against the bound's GM terms **plus** its white noise (the bound represents flicker
       that way; GM + white + random walk when GM + white alone falls short and the bound has a random
       walk, which then carries the long-tau end of the plateau; likewise an identified GM against the bound's
       GM, then GM + white, then GM + white + random walk) over the taus where flicker is the
       largest identified term; over the application band of item 2 (a ratio outside it is reported
       under the component's ``outside_band`` and fails nothing). A bound component with
       no kept identified counterpart is reported as ``no counterpart`` (not a failure), and so is an
       identified component that the bound represents by another one.
    2. Total AV against every sample AV: the bound's total AV :math:`\sigma^2_b(\tau)` must reach the
       lower confidence limit of each sample AV, :math:`\hat\sigma^2 \nu/\chi^2_\nu(1-\alpha/M)` (level
       `confidence`, Bonferroni over the M curves x taus compared), over the application band
       `tau_min_s` :math:`\le \tau \le` `span_s` (`tau_min_s` = 1/application.filter_rate_hz: the filter never
       averages over less than one step, and a model is not claimed for what it does not use).
       A sample AV below the bound's by chance is not a shortfall; one whose lower limit is above it is.
       Ratios outside the band are reported (``outside_band``: the worst one, with its curve and tau) but
       fail nothing; a shortfall inside the band always fails the check.

    Returns
    -------
    dict
        ``components``: name -> {status: ``ok`` | ``shortfall`` | ``no counterpart`` | ``not a state``,
        margin, tau_s, reason}; ``total``: {passed, worst_ratio, curve, tau_s, n_compared, shortfalls:
        [{curve, tau_s, ratio}], tau_band_s: [lo, hi], outside_band: {n_compared, worst_ratio, curve, tau_s}};
        ``passed``: no shortfall anywhere in the band.
    """
    t = np.asarray(tau, dtype=np.float64)
    good = np.isfinite(t) & (t > 0)
    t = t[good]
    if t.size == 0:
        raise ValueError("check_allan: tau must contain positive averaging times (s)")
    if isinstance(kept, dict):
        kept = kept.get("kept", [])
    i = identified_model
    present = {"white": i.white > 0, "random_walk": i.random_walk > 0, "gauss_markov": len(i.gauss_markov) > 0,
               "flicker": getattr(i, "flicker", 0.0) > 0}
    kept = [c for c, v in present.items() if v] if kept is None else [c for c in kept if present.get(c, False)]
    b = bound_model

    t_lo = float(tau_min_s) if tau_min_s is not None else 0.0
    t_hi = float(span_s) if span_s is not None else math.inf
    if not (t_lo >= 0 and t_hi > t_lo):
        raise ValueError(f"check_allan: the tau band needs 0 <= tau_min_s < span_s, got [{tau_min_s}, {span_s}] s")
    band = (t >= t_lo * (1 - 1e-12)) & (t <= t_hi)  # 1e-12: a tau of exactly one filter step is in the band

    comps = _component_checks(b, i, kept, t, band)
    total = _total_check(b, t, good, band, (t_lo, t_hi), sample_avar, sample_edf, labels, confidence)
    passed = all(v["status"] != "shortfall" for v in comps.values()) and total["passed"] is not False
    return {"components": comps, "total": total, "passed": bool(passed), "confidence": float(confidence),
            "units": "tau s; ratios of Allan variances (dimensionless)"}


def _compare(t, band, av_b, av_i, what, sel=None):
    """Worst AV ratio bound/identified over the application band `band` (a mask of the taus `t`, s; `sel`
    narrows it further) for :func:`check_allan`; the worst ratio outside the band is reported with it and fails
    nothing, as for the total check."""
    sel = np.ones_like(t, dtype=bool) if sel is None else sel
    with np.errstate(divide="ignore", invalid="ignore"):
        r_all = np.where(sel & (av_i > 0), av_b / av_i, np.inf)
    r = np.where(band, r_all, np.inf)
    k = int(np.argmin(r))
    if not np.isfinite(r[k]):
        out = {"status": "ok", "margin": None, "tau_s": None,
               "reason": f"bound {what}: no tau of the application band to compare"}
    else:
        ok = bool(r[k] >= 1 - _EPS_BOUND)
        out = {"status": "ok" if ok else "shortfall", "margin": float(r[k]), "tau_s": float(t[k]),
               "reason": f"bound {what}: min AV ratio {r[k]:.4g} at tau = {t[k]:.4g} s"}
    r_out = np.where(band, np.inf, r_all)
    j = int(np.argmin(r_out))
    if np.isfinite(r_out[j]) and r_out[j] < 1 - _EPS_BOUND:
        out["outside_band"] = {"margin": float(r_out[j]), "tau_s": float(t[j]),
                               "note": "tau outside the application band: reported, not a failure"}
        out["reason"] += f"; outside the band {r_out[j]:.4g} at tau = {t[j]:.4g} s (not a failure)"
    return out


def _component_checks(b, i, kept, t, band) -> dict:
    """Item 1 of :func:`check_allan`: each kept component of the identified model `i` against its
    representation in the bound `b` over the taus `t` (s) of the band mask `band`, and the bound's components
    without a counterpart."""
    from imupipe.models import FLICKER_AV

    comps = {}
    if "white" in kept:
        comps["white"] = _compare(t, band, np.full_like(t, b.white**2) / t, np.full_like(t, i.white**2) / t,
                                  "white vs white")
    if "random_walk" in kept:
        comps["random_walk"] = _compare(t, band, b.random_walk**2 * t / 3, i.random_walk**2 * t / 3,
                                        "random walk vs random walk")
    if "gauss_markov" in kept:
        comps["gauss_markov"] = _compare(t, band, _gm_terms_avar(b, t), _gm_terms_avar(i, t), "GM vs GM")
        if comps["gauss_markov"]["status"] == "shortfall":
            # a short-T identified GM (T below the bound's resolution) is white noise to the bound: its
            # representation there is GM + white, as for flicker
            alt = _compare(t, band, _gm_terms_avar(b, t) + b.white**2 / t, _gm_terms_avar(i, t), "GM + white vs GM")
            if alt["status"] == "ok":
                alt["reason"] += (" (the bound's GM alone falls short at short tau, where the identified GM "
                                  "acts as white noise and the bound's white noise represents it)")
                comps["gauss_markov"] = alt
            elif b.random_walk > 0:
                # a long-T identified GM rises like a random walk for tau < T: a random walk with
                # K^2 >= 2 sigma^2 / T dominates that GM's PSD at every frequency (docs/method.md, section
                # "Allan-domain check"), so the bound may carry it by its random walk
                alt = _compare(t, band, _gm_terms_avar(b, t) + b.white**2 / t + b.random_walk**2 * t / 3,
                               _gm_terms_avar(i, t),
                              "GM + white + random walk vs GM")
                if alt["status"] == "ok":
                    alt["reason"] += (" (the bound's GM alone falls short where the identified GM's AV still "
                                      "rises like a random walk, and the bound's random walk represents it)")
                    comps["gauss_markov"] = alt
        if comps["gauss_markov"]["status"] == "shortfall" and b.narrowband:
            # the fit takes each line's Allan variance as known at its estimate, and line power beyond it comes back
            # as a GM bump (an outside evaluation: lines at 0.06 and 0.09 Hz, a GM of T 1.7 s fitted beside them,
            # its white equivalent above the records' floor); the bound carries that power in its line states
            alt = _compare(t, band, _gm_terms_avar(b, t) + b.white**2 / t + b.random_walk**2 * t / 3
                           + _narrowband_terms_avar(b, t), _gm_terms_avar(i, t),
                           "GM + white + random walk + lines vs GM")
            if alt["status"] == "ok":
                alt["reason"] += (" (the identified GM lies where the bound's spectral lines are, whose states "
                                  "represent it)")
                comps["gauss_markov"] = alt
    if "flicker" in kept:
        fl = np.full_like(t, FLICKER_AV * i.flicker**2)
        others = [np.full_like(t, i.white**2) / t, i.random_walk**2 * t / 3, _gm_terms_avar(i, t)]
        sel = fl > np.max(np.stack(others), axis=0)
        if not np.any(sel):
            comps["flicker"] = {"status": "no counterpart", "margin": None, "tau_s": None,
                                "reason": "identified flicker is never the largest AV term: covered by the others"}
        else:
            comps["flicker"] = _compare(t, band, _gm_terms_avar(b, t) + b.white**2 / t, fl, "GM + white vs flicker", sel)
            if comps["flicker"]["status"] == "shortfall" and b.random_walk > 0:
                # the LP may represent the long-tau end of a flicker plateau by its random walk (both rise
                # above the GM's decay there): the representation is then GM + white + random walk
                alt = _compare(t, band, _gm_terms_avar(b, t) + b.white**2 / t + b.random_walk**2 * t / 3, fl,
                              "GM + white + random walk vs flicker", sel)
                if alt["status"] == "ok":
                    alt["reason"] += (" (GM + white alone falls short at long tau, where the bound's random "
                                      "walk represents the flicker)")
                    comps["flicker"] = alt
    for c, has in (("white", b.white > 0), ("random_walk", b.random_walk > 0),
                   ("gauss_markov", len(b.gauss_markov) > 0)):
        if has and c not in comps and not (c == "gauss_markov" and "flicker" in comps):
            comps[c] = {"status": "no counterpart", "margin": None, "tau_s": None,
                        "reason": f"bound {c} has no kept identified counterpart (covers the spec or the PSD)"}
    for c in ("quantization", "ramp"):
        if getattr(i, c, 0.0) > 0:
            comps[c] = {"status": "not a state", "margin": None, "tau_s": None,
                        "reason": f"{c} is not a Kalman-filter state; its AV is covered by the total check"}
    return comps


def _total_check(b, t, good, band, tau_band, sample_avar, sample_edf, labels, confidence) -> dict:
    """Item 2 of :func:`check_allan`: the bound `b`'s total AV against the lower confidence limit of every
    sample AV (columns `good` of the tau grid; `t` the good taus, s) inside the band mask `band`, Bonferroni
    over the points compared; the worst ratio outside the band reported."""
    t_lo, t_hi = tau_band
    total = {"passed": None, "worst_ratio": None, "curve": None, "tau_s": None, "n_compared": 0, "shortfalls": [],
             "tau_band_s": [t_lo, t_hi], "outside_band": None}
    if sample_avar is not None:
        from scipy.special import chdtri  # chi2 upper-tail quantile; scipy.stats would add ~1 s of import

        av = np.atleast_2d(np.asarray(sample_avar, dtype=np.float64))[:, good]
        nu = np.broadcast_to(np.asarray(2.0 if sample_edf is None else sample_edf, dtype=np.float64),
                             np.atleast_2d(np.asarray(sample_avar)).shape)[:, good]
        lab = labels if labels is not None else [f"curve {j}" for j in range(av.shape[0])]
        valid = np.isfinite(av) & (av > 0) & np.isfinite(nu) & (nu > 0)
        ok = valid & band[None, :]
        M = int(ok.sum())
        total["n_compared"] = M
        mb = np.asarray(b.avar(t), dtype=np.float64)

        def ratios(sel, m):
            alpha = (1.0 - confidence) / m
            lower = np.where(sel, av * nu / chdtri(np.where(sel, nu, 1.0), alpha), 0.0)
            with np.errstate(divide="ignore", invalid="ignore"):
                return np.where(sel & (lower > 0), mb[None, :] / lower, np.inf)

        if M:
            r = ratios(ok, M)
            c, k = np.unravel_index(int(np.argmin(r)), r.shape)
            total.update(worst_ratio=float(r[c, k]), curve=str(lab[c]), tau_s=float(t[k]),
                         passed=bool(r[c, k] >= 1 - _EPS_BOUND))
            for cc, kk in zip(*np.nonzero(r < 1 - _EPS_BOUND)):
                total["shortfalls"].append({"curve": str(lab[cc]), "tau_s": float(t[kk]), "ratio": float(r[cc, kk])})
        out_sel = valid & ~band[None, :]
        if out_sel.any():  # reported, never failed: outside what the application uses
            r = ratios(out_sel, int(out_sel.sum()))
            c, k = np.unravel_index(int(np.argmin(r)), r.shape)
            total["outside_band"] = {"n_compared": int(out_sel.sum()), "worst_ratio": float(r[c, k]),
                                     "curve": str(lab[c]), "tau_s": float(t[k]),
                                     "note": "taus outside the application band: reported, not a failure"}
    return total


def upper_envelope_from_identification(identified: dict, span_s: float | None = None):
    """The identified upper confidence envelope (SI :class:`imupipe.models.NoiseModel`) of an identify file.

    Parameters
    ----------
    identified : dict
        The content of ``results/<name>/identify/{sensor}.yaml``: its ``upper_envelope_model`` (a
        :meth:`NoiseModel.to_dict`) when present, else the selected refit ``fit.selected`` (else the ``fit``
        itself: ``params``, ``intervals``, ``intervals_statistical``, ``random_walk_profile``, ``T_search_s``, as
        :meth:`imupipe.identify.AllanFit.to_dict` writes them, None for NaN or an open end) and
        ``selection.kept``, from which :func:`upper_envelope` rebuilds the envelope with the same rule as the
        identification (open T ends included; without the curves, no :func:`random_walk_cap`).
    span_s : float, optional
        For the rebuild: the span of :func:`upper_envelope` (s); default the file's ``upper_envelope_horizon_s``.

    Raises
    ------
    ValueError
        Neither an ``upper_envelope_model`` nor a ``fit`` with ``params``.
    """
    from types import SimpleNamespace

    from imupipe.models import NoiseModel

    if identified.get("upper_envelope_model"):
        return NoiseModel.from_dict(identified["upper_envelope_model"])
    fit = identified.get("fit") or {}
    fit = fit.get("selected") or fit  # the envelope is the selected refit's (identify stage)
    if "params" not in fit:
        raise ValueError("identify file: no 'upper_envelope_model' and no 'fit.params' to rebuild the upper envelope")

    def num(v):
        return float("nan") if v is None else float(v)

    def interval(name, v):
        lo, hi = num(v[0]), num(v[1])
        if name.startswith("gm_T_") and v[1] is None and math.isfinite(lo):
            hi = math.inf  # YAML writes an open upper end (inf) as null; a missing interval has both ends null
        return lo, hi

    view = SimpleNamespace(
        params={k: num(v) for k, v in (fit.get("params") or {}).items()},
        intervals={k: interval(k, v) for k, v in (fit.get("intervals") or {}).items()},
        intervals_statistical={k: interval(k, v) for k, v in (fit.get("intervals_statistical") or {}).items()},
        random_walk_profile={k: num(v) for k, v in (fit.get("random_walk_profile") or {}).items()},
        T_grid=np.asarray(fit.get("T_search_s") or [], dtype=float),
    )
    if span_s is None:
        span_s = identified.get("upper_envelope_horizon_s")
    return upper_envelope(view, (identified.get("selection") or {}).get("kept"), span_s=span_s)
