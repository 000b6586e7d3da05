r"""Record consistency: does one record (dataset) disagree with the others beyond its intervals?

Each record of a sensor type is fitted on its own (its axes pooled, :func:`imupipe.identify.fit_allan` with the
pooled selection's components), giving per parameter P (white noise N, flicker B, random walk K) an estimate
:math:`\hat p_i` and an interval :math:`[l_i, u_i]` at level c. On the log scale the interval is read as a normal
one: the half-width facing the comparison gives the standard error,
:math:`s_i^- = (\ln\hat p_i - \ln l_i)/z_c`, :math:`s_i^+ = (\ln u_i - \ln\hat p_i)/z_c`,
:math:`z_c = \Phi^{-1}((1 + c)/2)`. The other records are combined by inverse variance,
:math:`\mu_{-i} = \sum_j w_j \ln\hat p_j / \sum_j w_j`, :math:`w_j = 1/s_j^2` with :math:`s_j` the symmetric
half-width :math:`(\ln u_j - \ln l_j)/(2 z_c)`, :math:`s_{-i} = (\sum_j w_j)^{-1/2}`, and

.. math:: z_i = \frac{\ln\hat p_i - \mu_{-i}}{\sqrt{s_i^2 + s_{-i}^2}}

(:math:`s_i` the half-width of record i on the side of :math:`\mu_{-i}`). Record i is named for P when
:math:`|z_i| > z^* = \Phi^{-1}(1 - \alpha/(2 R J))`, R records and J parameters tested: when every record has
the same truth and the intervals are calibrated, each :math:`z_i` is standard normal and, by Bonferroni over the
R J tests, the probability that any record is named is at most :math:`\alpha` (the false-alarm level, per sensor
type). The test is stepped down: the record with the largest :math:`|z_i| > z^*` is named and left out of the
others' mean, and the rest are tested again against :math:`z^*` (so that one record far off does not pull the
mean of the others and get the equal records named with it); under equal truths the first step is the only way to
name any record, so the level stays :math:`\alpha`. With two records :math:`|z_1| = |z_2|`: both are named, which of
them is off cannot be told.

Not tested (said so in the row): a parameter fitted as 0 in that record or with a lower interval end of 0 (a
one-sided interval has no log-scale width on that side), and a parameter with fewer than two records holding a
two-sided interval. Intervals widened for an inadequate fit (:func:`imupipe.identify.fit_allan`) make the test
less sensitive, never more alarming.

References: R. G. Miller, "Simultaneous Statistical Inference", 2nd ed., Springer, 1981 (Bonferroni); the log-scale
standard error from a percentile or profile interval is the usual normal reading of a confidence interval
(A. C. Davison, D. V. Hinkley, "Bootstrap Methods and their Application", 1997, section 5.2).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["record_consistency", "CONSISTENCY_PARAMS"]

#: The parameters compared across records: the fit's names and how the summary labels them.
CONSISTENCY_PARAMS = {"white": "N", "flicker": "B", "random_walk": "K"}


def _log_sd(est, lo, hi, z_c):
    """(lower, upper) log-scale standard errors of an estimate with interval [lo, hi] (NaN: not two-sided)."""
    if not (np.isfinite(est) and est > 0 and np.isfinite(lo) and lo > 0 and lo <= est):
        s_lo = float("nan")
    else:
        s_lo = (math.log(est) - math.log(lo)) / z_c
    if not (np.isfinite(est) and est > 0 and np.isfinite(hi) and hi >= est):
        s_hi = float("nan")
    else:
        s_hi = (math.log(hi) - math.log(est)) / z_c
    return s_lo, s_hi


def _z_against(sd: dict, p: str, r: str, others: list):
    """(z, mu): record r's log estimate of p against the inverse-variance mean mu of `others` (module docstring)."""
    est, _, _, s_lo, s_hi = sd[r, p]
    w = np.array([1.0 / (0.5 * (sd[q, p][3] + sd[q, p][4])) ** 2 for q in others])
    mu = float(np.sum(w * np.log([sd[q, p][0] for q in others])) / np.sum(w))
    s_o = 1.0 / math.sqrt(float(np.sum(w)))
    s_i = s_lo if math.log(est) > mu else s_hi
    return (math.log(est) - mu) / math.sqrt(s_i * s_i + s_o * s_o), mu


def record_consistency(records: dict, confidence: float, alpha: float = 0.01, params=None) -> dict:
    r"""Compare each record's parameters with the other records' (module docstring).

    Parameters
    ----------
    records : dict
        Record name -> {parameter -> (estimate, lower, upper)} (SI, the fit's ``params`` and ``intervals``).
    confidence : float
        Level c of the intervals (e.g. 0.95).
    alpha : float
        Family-wise false-alarm level over records and parameters (default 0.01).
    params : sequence of str, optional
        Parameters to compare (default: those of :data:`CONSISTENCY_PARAMS` present in any record).

    Returns
    -------
    dict
        ``z_crit`` (the critical |z|), ``alpha``, ``n_tests`` (R J), ``rows`` (record -> parameter -> {``estimate``,
        ``lower``, ``upper``, ``z`` (None when not tested), ``flagged``, ``note``}), ``flagged`` (list of
        (record, parameter, z, estimate, others' estimate exp(mu))), ``method``.
    """
    from scipy.special import ndtri

    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must lie in (0, 1), got {confidence!r}")
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"alpha must lie in (0, 1), got {alpha!r}")
    z_c = float(ndtri(0.5 * (1.0 + confidence)))
    names = list(records)
    if params is None:
        params = [p for p in CONSISTENCY_PARAMS if any(p in records[r] for r in names)]
    sd = {}
    for r in names:
        for p in params:
            est, lo, hi = records[r].get(p, (float("nan"),) * 3)
            sd[r, p] = (float(est), float(lo), float(hi), *_log_sd(float(est), float(lo), float(hi), z_c))
    # the tests actually made: a two-sided interval in this record and at least one other
    testable = {p: [r for r in names if np.isfinite(sd[r, p][3]) and np.isfinite(sd[r, p][4])] for p in params}
    n_tests = sum(len(v) for v in testable.values() if len(v) >= 2)
    z_crit = float(-ndtri(alpha / (2.0 * max(n_tests, 1))))
    rows, flagged = {}, []
    for r in names:
        rows[r] = {}
        for p in params:
            est, lo, hi = sd[r, p][:3]
            rows[r][p] = {"estimate": est, "lower": lo, "upper": hi, "z": None, "flagged": False,
                          "note": ("not tested: fitted as 0 or a one-sided interval" if np.isfinite(est) and
                                   r not in testable[p] else "" if np.isfinite(est) else "not in this record's model")}
    for p in params:
        active = list(testable[p])
        while len(active) >= 2:
            zs = {r: _z_against(sd, p, r, [q for q in active if q != r]) for r in active}
            for r, (z, mu) in zs.items():
                rows[r][p].update(z=float(z), others=float(math.exp(mu)))
            worst = max(active, key=lambda r: abs(zs[r][0]))
            if abs(zs[worst][0]) <= z_crit:
                break
            # two records left: which one is off cannot be told, both are named
            named = list(active) if len(active) == 2 else [worst]
            for r in named:
                rows[r][p].update(flagged=True, note=("disagrees with the other record" if len(active) == 2 else
                                                      "disagrees with the other records"))
                # the statistic that named it: the worst record's (with two records both are named by it)
                flagged.append((r, p, float(zs[worst][0]), sd[r, p][0], float(math.exp(zs[r][1]))))
                active.remove(r)
    for r in names:
        for p in params:
            if rows[r][p]["z"] is None and not rows[r][p]["note"]:
                rows[r][p]["note"] = "not tested: no other record with a two-sided interval"
    return {"z_crit": z_crit, "alpha": float(alpha), "confidence": float(confidence), "n_tests": int(n_tests),
            "rows": rows, "flagged": flagged,
            "method": ("per parameter, each record's log estimate against the inverse-variance mean of the other "
                       "records', standard errors from the intervals' half-widths on the log scale; named when "
                       f"|z| > {z_crit:.3g} (Bonferroni over {n_tests} tests at family-wise level {alpha:g})")}
