r"""Which Gauss-Markov (GM) time constants the records resolve, and what a GM they do not resolve acts as.

**The search range** (:func:`gm_T_range`). A GM of variance :math:`\sigma^2` and time constant :math:`T` has the
Allan variance (AV) :math:`\sigma^2 g(x)`, :math:`x = \tau/T`,

.. math::

    g(x) = \frac{2}{x}\Big(1 - \frac{3 - 4e^{-x} + e^{-2x}}{2x}\Big)

(IEEE Std 952 Annex C; :func:`imupipe.models.gm_avar`). Far below the averaging time it is the white noise of
the same low-frequency PSD, :math:`N^2 = 2\sigma^2 T` (AV :math:`2\sigma^2 T/\tau`); far above it the random
walk of the same high-frequency PSD, :math:`K^2 = 2\sigma^2/T` (AV :math:`2\sigma^2\tau/(3T)`). Both limits
bound the GM's PSD :math:`2\sigma^2T/(1+(2\pi fT)^2)` at every frequency. The relative departures of the GM's AV
from them,

.. math::

    r_w(x) = 1 - \frac{x\,g(x)}{2} = \frac{3 - 4e^{-x} + e^{-2x}}{2x}, \qquad
    r_k(x) = 1 - \frac{3\,g(x)}{2x},

are what the AV can see of T. An AV estimate with :math:`\nu` equivalent degrees of freedom has the relative
standard error :math:`\sqrt{2/\nu}` (a scaled :math:`\chi^2_\nu`). A GM is told from its white-noise limit if at
some AV point :math:`r_w(\tau_k/T) > z\sqrt{2/\nu_k}`, and from its random-walk limit if
:math:`r_k(\tau_k/T) > z\sqrt{2/\nu_k}`, :math:`z = z_{(1+c)/2}` at the confidence :math:`c`. The shortest T
resolved is the smallest T passing the first test, the longest the largest passing the second (a fraction of
the longest tau: at the few-dof long taus :math:`r_k` must come close to 1, which needs :math:`T` well below
:math:`\tau`). Long records have AV points of so many degrees of freedom at the shortest tau that the first test
alone passes T below one sample; the AV's shape sets the floor there: the GM's AV peaks at :math:`\tau = 1.89 T`
and falls like white noise's above it, so a T whose peak lies below the second AV point
(:math:`T < \tau_2/1.89`, :math:`\tau_2` the second-shortest tau) leaves at most one AV point on the rising side
of the GM and its T is not resolved from the AV's falling -1/2 slope; the shortest T is the larger of the two.

**The re-assignment** (:func:`reassign_unresolved_gm`). A fitted GM whose T interval reaches an end of the search
range, or whose T (or its interval's lower end) lies within a factor 2 (one octave of the AV's taus) of the
range's shortest T, is not kept as
a GM: it is reported as what it acts as, the white noise :math:`N^2 + 2\sigma^2 T` (fast side) or the random walk
:math:`K^2 + 2\sigma^2/T` (slow side), with the interval of that sum from the same bootstrap replicates (each
replicate's own :math:`\sigma, T`): the low-frequency level :math:`2\sigma^2T` (or the drift :math:`2\sigma^2/T`)
is what the data pin down even where T is not. The fit itself keeps the GM column (so the refit still describes
the short or long taus); only the reported and bounded model changes, and the replacement's PSD is above the
GM's at every frequency (see above).

References: IEEE Std 952-1997 Annex C; W. J. Riley, NIST SP 1065, 2008, section 5 (AV confidence: chi-squared
with the equivalent degrees of freedom); Gallon, Joerger, Pervan, ION GNSS+ 2021. SI units: T and tau in s.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

__all__ = ["gm_T_range", "reassign_unresolved_gm", "PEAK_TAU_OVER_T"]

#: tau / T at the peak of a GM's Allan variance (the maximum of g(x)/1, x = tau/T: 1.8926).
PEAK_TAU_OVER_T = 1.8926


def _g(x):
    """AV of a unit-variance GM at x = tau/T (dimensionless; series for small x, where the closed form cancels)."""
    x = np.asarray(x, dtype=np.float64)
    out = np.empty_like(x)
    small = x < 1e-3
    xs = x[small]
    out[small] = 2.0 * xs / 3.0 - xs * xs / 2.0
    xl = x[~small]
    out[~small] = (2.0 / xl) * (1.0 - (3.0 - 4.0 * np.exp(-xl) + np.exp(-2.0 * xl)) / (2.0 * xl))
    return out


def departure_from_white(x):
    r""":math:`r_w(x) = 1 - x g(x)/2`: relative departure of a GM's AV from its white-noise limit (module
    docstring), x = tau/T; decreases from 1 (x -> 0) like 3/(2x)."""
    return 1.0 - np.asarray(x, dtype=np.float64) * _g(x) / 2.0


def departure_from_random_walk(x):
    r""":math:`r_k(x) = 1 - 3 g(x)/(2x)`: relative departure of a GM's AV from its random-walk limit (module
    docstring), x = tau/T; increases from 0 (x -> 0, like 3x/4) to 1."""
    x = np.asarray(x, dtype=np.float64)
    return 1.0 - 1.5 * _g(x) / x


def gm_T_range(tau, edf, confidence: float = 0.95) -> dict:
    r"""The GM time constants the AV points resolve (module docstring), s.

    Parameters
    ----------
    tau : array_like
        Averaging times of every AV point used (pooled curves concatenated), s.
    edf : array_like
        Their equivalent degrees of freedom.
    confidence : float
        Level c of the departure test (z = z_{(1+c)/2}).

    Returns
    -------
    dict
        ``T_min_s``, ``T_max_s`` (s; ``T_max_s <= T_min_s``: no GM resolvable), ``T_min_statistical_s`` (the
        departure test alone), ``T_min_peak_s`` (the AV-peak floor tau_2/1.89), ``tau_min_s``, ``tau_max_s``,
        ``T_min_samples_of_tau_min`` (T_min over the shortest tau) and ``T_max_fraction_of_tau_max``, ``z``,
        ``rule`` (a sentence).
    """
    from scipy.special import ndtri

    t = np.asarray(tau, dtype=np.float64).ravel()
    e = np.asarray(edf, dtype=np.float64).ravel()
    ok = np.isfinite(t) & np.isfinite(e) & (t > 0) & (e > 0)
    t, e = t[ok], e[ok]
    if t.size < 2:
        raise ValueError("gm_T_range: fewer than 2 usable AV points (finite positive tau and edf)")
    c = float(confidence)
    if not 0.0 < c < 1.0:
        raise ValueError(f"gm_T_range: confidence must lie in (0, 1), got {confidence!r}")
    z = float(ndtri((1.0 + c) / 2.0))
    thr = z * np.sqrt(2.0 / e)  # the departure an AV point resolves (relative)
    tmin, tmax = float(t.min()), float(t.max())
    # candidate T: 64 per decade over a range that brackets both answers
    T = np.logspace(math.log10(tmin) - 6.0, math.log10(tmax) + 2.0, int(round(64 * (8 + math.log10(tmax / tmin)))))
    x = t[None, :] / T[:, None]
    white_ok = np.any(departure_from_white(x) > thr[None, :], axis=1)   # true for T above some value
    rw_ok = np.any(departure_from_random_walk(x) > thr[None, :], axis=1)  # true for T below some value
    T_stat = float(T[np.argmax(white_ok)]) if white_ok.any() else float("inf")
    T_max = float(T[len(T) - 1 - np.argmax(rw_ok[::-1])]) if rw_ok.any() else 0.0
    taus = np.unique(t)
    T_peak = float(taus[1] / PEAK_TAU_OVER_T)
    T_min = max(T_stat, T_peak)
    return {
        "T_min_s": T_min,
        "T_max_s": T_max,
        "T_min_statistical_s": T_stat,
        "T_min_peak_s": T_peak,
        "tau_min_s": tmin,
        "tau_max_s": tmax,
        "T_min_samples_of_tau_min": T_min / tmin,
        "T_max_fraction_of_tau_max": T_max / tmax,
        "z": z,
        "rule": ("shortest T: the larger of the smallest T whose AV departs from its white-noise limit "
                 "(N^2 = 2 sigma^2 T) by more than z relative standard errors sqrt(2/edf) at some AV point, and "
                 "the second-shortest tau / 1.89 (the GM's AV peak at 1.89 T above the shortest AV point); longest "
                 "T: the largest T whose AV departs from its random-walk limit (K^2 = 2 sigma^2 / T) by more than "
                 f"z relative standard errors at some AV point; z = {z:.3g} (confidence {c:g})"),
    }


def _replicate_column(fit, name):
    names = list(getattr(fit, "param_names", []) or [])
    b = np.asarray(getattr(fit, "bootstrap", np.zeros((0, 0))))
    if name in names and b.ndim == 2 and b.shape[0] > 0:
        return b[:, names.index(name)]
    return None


def reassign_unresolved_gm(fit, kept, T_range: dict):
    r"""The fit with every GM term it does not resolve re-assigned to what it acts as (module docstring).

    A GM term i is unresolved when its T interval (``fit.intervals``, also the statistical one) reaches
    ``T_range["T_min_s"]`` or ``T_range["T_max_s"]`` (within 0.1 %), is open (0, inf or NaN), or its T or its
    interval's lower end is below 2 ``T_min_s`` (within one octave of the AV's taus above the shortest T
    resolved: the "few sample intervals"). Fast side (the low end reached, by the interval or within the first
    octave, and not the high end; both reached: T at or below the range's geometric middle): white noise :math:`N'^2 = N^2 + 2\sigma^2 T`; slow side: random walk
    :math:`K'^2 = K^2 + 2\sigma^2/T`. The new parameter's interval is the percentile interval of the same
    quantity over the fit's bootstrap replicates (each with its own N or K, sigma and T), widened by the fit's
    over-dispersion factor where it is inadequate, and always containing the point value; without replicates,
    the point value with a NaN interval.

    Parameters
    ----------
    fit : imupipe.identify.AllanFit
        The selected refit.
    kept : sequence of str
        The selection's kept components.
    T_range : dict
        :func:`gm_T_range`'s result.

    Returns
    -------
    (AllanFit, list of str, list of dict)
        The fit (a copy when anything changed: model, params, intervals, boundary flags, notes), the kept
        components after the re-assignment, and one record per re-assigned term (``term``, ``sigma``, ``T_s``,
        ``T_interval_s``, ``acts_as``, ``why``, ``T_open_above`` (the statistical T interval reaches the longest T
        or is open: the data do not close the GM's box above), the new ``value`` and ``interval``; SI).
    """
    from imupipe.models import NoiseModel

    kept = list(kept)
    if "gauss_markov" not in kept or not fit.model.gauss_markov:
        return fit, kept, []
    T_lo_range, T_hi_range = float(T_range["T_min_s"]), float(T_range["T_max_s"])
    params, intervals = dict(fit.params), dict(fit.intervals)
    stat = dict(fit.intervals_statistical or fit.intervals)
    on_boundary, kind, notes = dict(fit.on_boundary), dict(fit.interval_kind), list(fit.notes)
    c = float(fit.confidence)
    lo_q, hi_q = 100 * (1 - c) / 2, 100 * (1 + c) / 2
    widening = float(fit.adequacy.get("widening") or 1.0) if not fit.adequacy.get("adequate", True) else 1.0
    records = []
    remaining = []
    i = 1
    while f"gm_sigma_{i}" in params:
        s, T = float(params[f"gm_sigma_{i}"]), float(params.get(f"gm_T_{i}", float("nan")))
        if not (s > 0 and np.isfinite(T)):
            i += 1
            continue
        ends = [v for iv in (intervals.get(f"gm_T_{i}"), stat.get(f"gm_T_{i}")) if iv is not None for v in iv]
        finite = [v for v in ends if np.isfinite(v)]
        reaches_lo = (any(v <= T_lo_range * (1 + 1e-3) for v in finite) or any(v == 0.0 for v in ends)
                      or any(np.isnan(v) for v in ends))
        reaches_hi = any(v >= T_hi_range * (1 - 1e-3) for v in finite) or any(v == np.inf for v in ends)
        lower_ends = [iv[0] for iv in (intervals.get(f"gm_T_{i}"), stat.get(f"gm_T_{i}"))
                      if iv is not None and np.isfinite(iv[0])]
        few = T < 2.0 * T_lo_range or any(v < 2.0 * T_lo_range for v in lower_ends)
        if not (reaches_lo or reaches_hi or few):
            remaining.append((s, T))
            i += 1
            continue
        low_side = few or reaches_lo
        if low_side and not reaches_hi:
            fast = True
        elif reaches_hi and not low_side:
            fast = False
        else:  # both ends reached: the side its estimate is nearer (log scale)
            fast = T <= math.sqrt(T_lo_range * max(T_hi_range, T_lo_range))
        near = ([f"T below twice the shortest T the records resolve ({T_lo_range:.3g} s)"]
                if T < 2.0 * T_lo_range else
                [f"its T interval's lower end ({_seconds(min(lower_ends), T_lo_range)}) below twice the shortest T "
                 f"the records resolve ({T_lo_range:.3g} s)"] if few else [])
        if reaches_lo and reaches_hi:  # one statement, not three that read as contradicting each other
            why = (f"its T interval spans every T the records resolve ({T_lo_range:.3g} to {T_hi_range:.3g} s): "
                   "the records do not fix T")
        else:
            why = "; ".join(
                near
                + (["its T interval reaches the shortest T the records resolve"] if reaches_lo else [])
                + (["its T interval reaches the longest T the records resolve"] if reaches_hi else []))
        # what the statistical interval (the one the upper envelope reads) leaves open above: there the envelope
        # of the GM box is kept (stages.identify.selected_and_envelope), the data do not close it
        st = stat.get(f"gm_T_{i}")
        open_above = st is None or not np.isfinite(st[1]) or st[1] >= T_hi_range * (1 - 1e-3)
        target = "white" if fast else "random_walk"
        base = float(params.get(target, 0.0) or 0.0)
        add = 2.0 * s * s * T if fast else 2.0 * s * s / T
        value = math.sqrt(base * base + add)
        cs, cT = _replicate_column(fit, f"gm_sigma_{i}"), _replicate_column(fit, f"gm_T_{i}")
        cb = _replicate_column(fit, target)
        iv_new = (float("nan"), float("nan"))
        if cs is not None and cT is not None:
            cs = np.nan_to_num(cs, nan=0.0)
            gm_part = np.where(np.isfinite(cT) & (cs > 0) & (cT > 0),
                               2.0 * cs * cs * (cT if fast else 1.0 / np.where(cT > 0, cT, 1.0)), 0.0)
            b2 = np.nan_to_num(cb, nan=0.0) ** 2 if cb is not None else 0.0
            rep = np.sqrt(b2 + gm_part)
            fin = rep[np.isfinite(rep)]
            if fin.size >= 5:
                iv_new = (min(float(np.percentile(fin, lo_q)), value), max(float(np.percentile(fin, hi_q)), value))
        # the old interval of the target (e.g. the random walk's profile limit) still counts: the new upper end
        # is at least its upper end
        old = stat.get(target)
        if old is not None and np.isfinite(old[1]) and np.isfinite(iv_new[1]):
            iv_new = (iv_new[0], max(iv_new[1], math.sqrt(old[1] ** 2 + add)))
        stat[target] = iv_new
        if widening != 1.0 and all(np.isfinite(iv_new)) and iv_new[0] > 0:
            # the quasi-likelihood widening of an inadequate fit (fit._widen), about the new value, log scale
            intervals[target] = (value * (iv_new[0] / value) ** widening, value * (iv_new[1] / value) ** widening)
        else:
            intervals[target] = iv_new
        params[target] = value
        on_boundary[target] = False
        kind[target] = (f"two-sided (percentile of {target}^2 + 2 sigma^2 {'T' if fast else '/ T'} over the "
                        "bootstrap replicates: a re-assigned GM term)")
        # the GM term is gone from the reported model
        params[f"gm_sigma_{i}"], params[f"gm_T_{i}"] = 0.0, float("nan")
        for k in (f"gm_sigma_{i}", f"gm_T_{i}"):
            intervals.pop(k, None)
            stat.pop(k, None)
            on_boundary.pop(k, None)
            kind[k] = "re-assigned (not a GM the data resolve)"
        T_iv = intervals.get(f"gm_T_{i}") or fit.intervals.get(f"gm_T_{i}")
        rec = {"term": i, "sigma": s, "T_s": T, "T_interval_s": [float(v) for v in T_iv] if T_iv else None,
               "T_resolved_s": [T_lo_range, T_hi_range],
               "acts_as": target, "why": why, "T_open_above": bool(open_above), "value": value, "interval": [float(v) for v in intervals[target]]}
        records.append(rec)
        unit = "u/sqrt(Hz)" if fast else "u/sqrt(s)"
        formula = "N^2 = N_fit^2 + 2 sigma^2 T" if fast else "K^2 = K_fit^2 + 2 sigma^2 / T"
        notes.append(f"GM term {i} (sigma = {s:.3g} u, T = {T:.3g} s) is not a GM the records resolve ({why}; "
                     f"resolved range {T_lo_range:.3g}-{T_hi_range:.3g} s): re-assigned to the "
                     f"{'white noise' if fast else 'random walk'} it acts as, {formula} = {value:.3g} {unit}")
        i += 1
    if not records:
        return fit, kept, []
    kept_new = [k for k in kept if k != "gauss_markov" or remaining]
    for r in records:
        if r["acts_as"] not in kept_new:
            kept_new.append(r["acts_as"])
    from imupipe.identify.basis import COMPONENTS

    kept_new = [k for k in COMPONENTS if k in kept_new]
    m = fit.model
    model = NoiseModel(white=params.get("white", 0.0), random_walk=params.get("random_walk", 0.0),
                       flicker=m.flicker, quantization=m.quantization, ramp=m.ramp,
                       gauss_markov=tuple(remaining), dt=m.dt)
    out = replace(fit, model=model, params=params, intervals=intervals, intervals_statistical=stat,
                  on_boundary=on_boundary, interval_kind=kind, notes=notes)
    return out, kept_new, records


def _seconds(t: float, scale: float) -> str:
    """`t` s as text, 0 where it is below 1e-6 of `scale` s (an interval's end fitted at 0 comes out as 1e-166 s)."""
    return "0 s" if t < 1e-6 * scale else f"{t:.3g} s"
