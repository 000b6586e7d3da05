"""The words of a verification check that passed only by its sampling tolerance, of an initial bias that rests
on an assumption nobody stated, of stationarity failures against what chance gives (and the verdict's
qualifier for them), and of the confidence a ``bounded`` verdict is stated at.

One home for those sentences: the verification writes it into the verify and contract files
(:mod:`imupipe.verify`), the run summary prints it as a FLAG (:mod:`imupipe.summary`), so the wording is the same
wherever a user reads the verdict. Plain dicts in, a string out: no numerics here.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

__all__ = ["BOUNDED_TOLERANCE", "NONSTATIONARY_VERDICT", "STRETCH_VERDICT", "beyond_chance", "chance_failures",
           "confidence_lines", "confidence_statement", "failure_tail", "nonstationary_qualifier", "stretch_note",
           "taken_in_why", "unstated_t_max", "within_tolerance"]

#: A margin (model over target, dimensionless) of at least 1 - BOUNDED_TOLERANCE counts as bounded: the linear
#: programme's solution touches its constraints up to round-off. The one tolerance of the bound, the contract and
#: the summary's verdict lines.
BOUNDED_TOLERANCE = 1e-9


def within_tolerance(check) -> str | None:
    r"""The statement of a check that passed only by its sampling tolerance, else None.

    A Monte Carlo or replay check estimates the true MSE from a finite sample and passes while the worst ratio
    MSE/P is at most 1 + ``tolerance`` (:func:`replay`: ``tolerance`` = z sqrt(2/n_eff)). A worst ratio above 1 that
    passes is not a confirmation: the sample shows the filter under-stating its error and is too small to say that
    this is not chance. Every place a verdict is read (the verify and contract files, the run summary's FLAG lines)
    carries this sentence so that it is never only a number in a nested field.

    Parameters
    ----------
    check : mapping
        A check as :meth:`Verification.to_dict` writes it: ``worst_ratio``, ``tolerance`` (the allowance on the
        ratio, dimensionless), ``passed``, optionally ``method`` (an ``exact`` analysis has no sampling tolerance),
        ``n_eff``, ``relative_standard_error`` and ``worst_t_s`` (s).

    Returns
    -------
    str or None
        ``"passes within the replay's sampling tolerance (ratio X, tolerance 1 + t = Y ...)"`` with t the check's
        ``tolerance`` and Y the largest ratio it accepts; None when the check failed, has no tolerance or its
        worst ratio is <= 1.
    """
    try:
        worst, tol = float(check.get("worst_ratio")), float(check.get("tolerance") or 0.0)
    except (TypeError, ValueError):
        return None
    method = str(check.get("method") or "")
    if not check.get("passed") or not tol > 0 or not worst > 1.0 or "exact" in method:
        return None  # an exact analysis's tolerance is a rounding allowance (1e-6), not a sampling one
    what = "the replay's" if "replay" in method else "the Monte Carlo's" if method else "its"
    n_eff, rse = check.get("n_eff"), check.get("relative_standard_error")
    how = (f"; t = {tol / float(rse):.3g} sqrt(2/n_eff), n_eff {float(n_eff):.3g} independent windows"
           if n_eff is not None and rse else "")
    at = f" at {float(check['worst_t_s']):.4g} s" if check.get("worst_t_s") is not None else ""
    if check.get("worst_outage_ratio") is not None and check.get("worst_t_s") is not None and \
            check.get("worst_outage_t_s") is not None and float(check["worst_t_s"]) != float(check["worst_outage_t_s"]):
        at += f", in the fixes; the outage's worst {float(check['worst_outage_ratio']):.3g}"
    shown = f"{worst:.3g}" if float(f"{worst:.3g}") > 1.0 else f"{worst:.6g}"  # 1.0004 is not shown as 1
    return (f"passes within {what} sampling tolerance (ratio {shown}{at}, tolerance 1 + {tol:.3g} = {1.0 + tol:.3g}"
            f"{how}): the "
            "records' squared error reaches that ratio to the filter's variance; with this few independent windows "
            "chance alone gives such a ratio, and so would a filter that under-states its error by up to that much: "
            "it neither confirms nor excludes an under-statement. The verdict bounded rests on the exact checks "
            "and the data check; to settle this one, record more or longer (the tolerance falls as 1/sqrt(n_eff): "
            "four times the windows halve it)")


def unstated_t_max(bias, std_text: str | None = None) -> str | None:
    """The sentence for a user when an exported initial bias variance (a ``bias_initialisation`` dict as the
    contract and the KF file carry it, :meth:`imupipe.biasinit.BiasInitialisation.to_dict` with ``required_std``)
    rests on a longest bias time constant T_max the user did not state: the default assumption
    (:data:`imupipe.biasinit.RECORD_FACTOR` x the longest record, :func:`imupipe.biasinit.max_bias_time`), beyond
    what the records can check. A slow drift extrapolated to T_max, or a spec sheet's random walk (K^2 T_max / 2),
    then sets the P0 by that assumption; a user who knows the sensor states T_max (``identify.max_bias_time_s``).
    The same holds when T_max is the spec sheet's longest GM time constant: a sheet's GM states the correlation
    time of its bias instability, not that no bias persists longer, and the records cannot check it either.
    `std_text`: the P0's standard deviation as the caller shows it (e.g. in the spec sheet's unit and SI); default
    its ``required_std`` with its unit. None when the P0 rests on the model's own GM states (T_max plays no part),
    when the records check it, or when the user stated T_max (``identify.max_bias_time_s``)."""
    if not isinstance(bias, dict) or bias.get("checked_by_records") or bias.get("rests_on") == "model":
        return None
    src = str(bias.get("T_max_source") or "")
    if not src or src.startswith("config"):
        return None

    def num(v):
        return "-" if v is None else f"{float(v):.3g}"

    std = std_text or f"{num(bias.get('required_std'))} {(bias.get('units') or {}).get('required_std', '')}".rstrip()
    what = "the records' slow drift" if bias.get("rests_on") == "records" else "the spec sheet's bias"
    rec = f"; the longest record, {num(bias.get('record_s'))} s, cannot check it" if bias.get("record_s") else ""
    return (f"the exported initial bias (std {std}: every bias state together, the p state's initial sd and any GM's "
            f"sigma, which the values to paste give apart) rests on {what} extrapolated "
            f"to T_max = {num(bias.get('T_max_s'))} s ({src}{rec}): state the longest time a bias persists "
            "(identify.max_bias_time_s, s) if it is known, and the spec sheet's turn_on_bias (the spread of the bias "
            "from one switch-on to the next, which records with their mean removed cannot show)")


def failure_tail(n_failed: int, n_tests: int, alpha) -> float | None:
    r""":math:`P(X \ge k)` for X ~ Binomial(`n_tests`, `alpha`) and k = `n_failed` (:func:`chance_failures`), or
    None without failures or a level in (0, 1)."""
    k, n = int(n_failed), int(n_tests)
    if k <= 0 or n <= 0 or not (alpha and 0.0 < float(alpha) < 1.0):
        return None
    a = float(alpha)
    return min(1.0, sum(math.comb(n, j) * a**j * (1.0 - a) ** (n - j) for j in range(k, n + 1)))


def beyond_chance(n_failed: int, n_tests: int, alpha) -> bool:
    """Whether `n_failed` of `n_tests` tests at level `alpha` failing is more than chance gives (the tail
    :func:`failure_tail` below `alpha`; :func:`chance_failures` words it)."""
    tail = failure_tail(n_failed, n_tests, alpha)
    return tail is not None and tail < float(alpha)


def chance_failures(n_failed: int, n_tests: int, alpha: float, outcome: str = "failed", by_chance: str = "fail",
                    null: str = "every axis stationary", beyond: str | None = None) -> str | None:
    r"""How `n_failed` failures among `n_tests` independent tests, each at level `alpha`, compare with chance: with
    every null true the count is Binomial(`n_tests`, `alpha`), mean `n_tests` x `alpha`, and
    :math:`P(X \ge k) = \sum_{j \ge k} \binom{n}{j}\alpha^j(1-\alpha)^{n-j}`. A tail probability of at least
    `alpha` is worded as consistent with chance, a smaller one as more than chance gives. None without failures or a
    level. Used for the stationarity tests of a sensor's axes (one per axis, each at the configured level) and for
    the event scan (`outcome` "show an event", `by_chance` "show one", `null` "no event in any record"). The count
    says what chance explains of how many, not how strong one is: `beyond`, a clause saying that one finding is
    beyond the level over every test on its own (a line far above the threshold of every series searched), makes the
    verdict "more than chance gives" whatever the count."""
    tail = failure_tail(n_failed, n_tests, alpha)
    if tail is None:
        return None
    k, n, a = int(n_failed), int(n_tests), float(alpha)
    verdict = ("consistent with chance" if tail >= a and not beyond else
               "more than chance gives: look at the records named")
    return (f"{k} of {n} axes {outcome} at level {a:g} each; with {null} {n * a:.2g} {by_chance} by chance on "
            f"average and P(>= {k}) = {tail:.2g}" + (f"; {beyond}" if beyond else "") + f": {verdict}")


#: The verdict's qualifier where the bound covers the noisiest stretch of records that fail the stationarity test
#: (:func:`nonstationary_qualifier`).
STRETCH_VERDICT = " with the noisiest stretch of its {n} non-stationary curve{s} (FLAGs below)"
#: ... and where more of a sensor's axes fail than chance gives and the bound keeps them without a stretch scan (records
#: too short for it): it covers their average PSD; a filter meeting their noisiest stretch may under-state its error
#: there (an outside evaluation: white noise 2.5x over the last third of a record, MSE/P up to 1.5 in that stretch).
NONSTATIONARY_VERDICT = " for the records' average noise (they are not stationary: FLAGs below)"


def nonstationary_qualifier(stat: Mapping) -> str:
    """What a sensor's verdict adds for its non-stationary records (its stationarity summary `stat`):
    :data:`STRETCH_VERDICT` where curves carry a ``noisiest_stretch``, else :data:`NONSTATIONARY_VERDICT` where
    the failures are beyond chance (:func:`beyond_chance`) and kept; empty otherwise."""
    n = sum(1 for c in stat.get("curves") or () if isinstance(c, Mapping) and c.get("noisiest_stretch"))
    if n:
        return STRETCH_VERDICT.format(n=n, s="" if n == 1 else "s")
    kept = stat.get("on_fail") == "warn"
    return NONSTATIONARY_VERDICT if kept and beyond_chance(stat.get("n_non_stationary") or 0, stat.get("n_curves") or 0,
                                                           stat.get("alpha")) else ""


def stretch_note(scan) -> str:
    """``"; with its noisiest stretch ..."``: what a stationarity FLAG adds where the bound took in the curve's
    noisiest stretch (`scan`: the stationarity summary's ``noisiest_stretch``, :meth:`imupipe.stretches.StretchLevels
    .to_dict`); empty otherwise."""
    if not isinstance(scan, Mapping) or not scan.get("bands"):
        return ""
    top = max(scan["bands"], key=lambda b: float(b.get("ratio", 0.0)))
    return (f" with its noisiest stretch: its PSD raised up to {float(scan.get('max_gain', 1.0)):.3g}x (the "
            f"{float(top.get('stretch_s', scan['stretch_s'])):.6g} s from {float(top.get('start_s', 0.0)):.6g} s, "
            f"{float(top['f_lo_hz']):.3g}-{float(top['f_hi_hz']):.3g} Hz)")


def taken_in_why(curve: Mapping, stat: Mapping) -> str:
    """Why a failing curve's noisiest stretch is in the bound where the sensor's failures alone are consistent with
    chance: the rule the stationarity summary `stat` recorded for its `curve` (``taken_in_by``,
    :func:`imupipe.stages.stationarity.summary_stage`), its own p-value or its stretch test's below alpha / n
    (family-wise). Empty where the failures beyond chance took it in, or no stretch was taken in."""
    n, alpha, by = stat.get("n_curves") or 0, stat.get("alpha"), curve.get("taken_in_by")
    if not curve.get("noisiest_stretch") or not alpha or by not in ("own p-value", "stretch test"):
        return ""
    level = f"alpha / {n} = {float(alpha) / max(n, 1):.2g}"
    if by == "own p-value":
        return f" (taken in: its own p-value is below {level})"
    p = float(curve.get("stretch_test_p", float("nan")))
    return f" (taken in: its stretch test, p = {p:.2g}, is below {level})"


def confidence_statement(bound: Mapping) -> dict | None:
    """The confidence a ``bounded`` verdict is stated at, from a bound file's dict `bound` (or a candidate's): its
    ``identification_intervals`` (the identification's level c, ``identify.confidence``), ``upper_envelope_kind``
    and each per-axis model's ``identification_level`` (:func:`imupipe.stages.identify.axis_level`). Every check
    behind ``bounded`` is exact given the identified upper envelope (the model covers it in the reference filter,
    and every sample PSD or its confidence limits in band); the envelope is the one statistical statement: the
    noise the records allow at level c (docs/method.md, "What bounded rests on"). Returns ``level`` (c),
    ``envelope``, ``per_axis_level`` (None where no axis has its own model), ``statement`` (one paragraph) and
    ``short`` (its first sentence, for the summary's first screen), or None where the bound records no
    identification level."""
    ident = bound.get("identification_intervals")
    if not isinstance(ident, Mapping) or ident.get("confidence") is None:
        return None
    c, kind = float(ident["confidence"]), str(bound.get("upper_envelope_kind") or "marginal")
    if kind == "joint":
        env = (f"the simultaneous band of the fit's bootstrap at confidence {c:g}, family-wise over its frequencies, "
               f"and that model below them")
    else:
        env = (f"every kept component at its upper confidence limit at once, each at {c:g}; together at least "
               f"1 - k (1 - {c:g}) for k components by Bonferroni, the level below measured in simulation: the "
               f"envelope covered the truth's PSD in 97 of 100 records of two held-out truths")
    text = (f"the identified upper envelope ({env}) is the one statistical statement behind it: the truth's noise "
            f"lies under it with confidence {c:g}; in the other {1.0 - c:.2g} of runs a noise above it can be "
            f"under-stated by a filter on the exported model. The other checks are computations on the records and "
            f"that envelope: they can fail a bound, not lower this level. The level assumes noise that decorrelates "
            f"within the records (the fit's white, GM, random-walk and flicker terms): a process coherent over a "
            f"whole record, e.g. a slow narrow oscillation, shows one random amplitude per record and is not covered "
            f"at it (docs/method.md, \"What bounded rests on\").")
    short = (f"the identified upper envelope at confidence {c:g} ({kind}) is the one statistical statement: in the "
             f"other {1.0 - c:.2g} of runs a filter on the exported model can under-state its error; it assumes noise "
             f"that decorrelates within the records")
    axes = {str(lab).rsplit("/", 1)[-1] for lab in bound.get("curves") or () if "/" in str(lab)}
    if ident.get("model_adequate") is False:
        short += ", and here a model the data reject (FLAG below: the replay is the model-free check)"
        text += (" The selected model does not describe the records' Allan variances (the adequacy test: FLAG below):"
                 " the envelope is then that of a model the data reject, and its level holds only as far as the model"
                 " does; the verification's replay of the records is the model-free check.")
    k = len(bound.get("axis_upper_envelopes") or {})
    if k:
        short += (f"; the model is also checked on each axis's own envelope, all {k} together at least "
                  f"{max(0.0, 1.0 - k * (1.0 - c)):.2g}")
        text += (f" The axes are pooled (the pooling test accepts one model for them), and the model is also verified "
                 f"against each axis's own envelope (each at {c:g}, all {k} together at least "
                 f"{max(0.0, 1.0 - k * (1.0 - c)):.2g}): a difference between axes the test does not detect.")
    elif len(axes) > 1 and not bound.get("per_axis_models"):
        text += " The axes are pooled: the statement is for the one model the pooling test accepts for them."
    per = [pa.get("identification_level") for pa in (bound.get("per_axis_models") or {}).values()
           if isinstance(pa, Mapping)]
    level = next((v for v in per if isinstance(v, Mapping) and v.get("confidence") is not None), None)
    c_a = float(level["confidence"]) if level else c
    if per:
        text += (f" Each axis's own model (the KF file's per_axis) rests on its axis's envelope at {c_a:.4g}"
                 + (f" ({level['rule']})." if level and level.get("family_confidence") else "."))
    return {"level": c, "envelope": kind, "per_axis_level": c_a if per else None, "statement": text,
            "short": short + " (in full: the details, \"What BOUNDED rests on\")."}


def confidence_lines(contracts: Mapping, key: str = "statement") -> list[str]:
    """The run summary's lines of what BOUNDED rests on: per distinct statement of the contracts' ``confidence``
    (`contracts`: sensor -> contract dict, :func:`confidence_statement`), the sensors it holds for and the
    statement (`key`: ``"statement"``, the paragraph of the details, or ``"short"``, the first screen's sentence,
    the paragraph where a contract has none); a blank line after. Empty where no contract states one."""
    by: dict = {}
    for sensor, contract in contracts.items():
        st = (contract or {}).get("confidence") if isinstance(contract, Mapping) else None
        if isinstance(st, Mapping) and st.get("statement"):
            by.setdefault(str(st.get(key) or st["statement"]), []).append(str(sensor))
    return [line for text, sensors in by.items() for line in (f"What BOUNDED rests on ({', '.join(sensors)}): {text}",
                                                                "")]
