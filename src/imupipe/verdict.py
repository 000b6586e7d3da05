"""The words of a verification check that passed only by its sampling tolerance, and of an initial bias that rests
on an assumption nobody stated.

One home for those sentences: the verification writes it into the verify and contract files
(:mod:`imupipe.verify`), the run summary prints it as a FLAG (:mod:`imupipe.summary`), so the wording is the same
wherever a user reads the verdict. Plain dicts in, a string out: no numerics here.
"""

from __future__ import annotations

__all__ = ["unstated_t_max", "within_tolerance"]


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
            "records' squared error reaches that ratio to the filter's variance, within what chance gives with this "
            "few independent windows: neither evidence of an under-statement nor a confirmation (more or longer "
            "records narrow the tolerance)")


def unstated_t_max(bias, std_text: str | None = None) -> str | None:
    """The sentence for a user when an exported initial bias variance (a ``bias_initialisation`` dict as the
    contract and the KF file carry it, :meth:`imupipe.biasinit.BiasInitialisation.to_dict` with ``required_std``)
    rests on a longest bias time constant T_max nobody stated: the default assumption
    (:data:`imupipe.biasinit.RECORD_FACTOR` x the longest record, :func:`imupipe.biasinit.max_bias_time`), beyond
    what the records can check. A slow drift extrapolated to T_max, or a spec sheet's random walk (K^2 T_max / 2),
    then sets the P0 by that assumption; a user who knows the sensor states T_max (``identify.max_bias_time_s``).
    `std_text`: the P0's standard deviation as the caller shows it (e.g. in the spec sheet's unit and SI); default
    its ``required_std`` with its unit. None when the P0 rests on the model's own GM states (T_max plays no part),
    when the records check it, or when T_max was stated (config or spec sheet)."""
    if not isinstance(bias, dict) or bias.get("checked_by_records") or bias.get("rests_on") == "model":
        return None
    src = str(bias.get("T_max_source") or "")
    if not src.startswith("assumption"):
        return None

    def num(v):
        return "-" if v is None else f"{float(v):.3g}"

    std = std_text or f"{num(bias.get('required_std'))} {(bias.get('units') or {}).get('required_std', '')}".rstrip()
    what = "the records' slow drift" if bias.get("rests_on") == "records" else "the spec sheet's bias"
    rec = f"; the longest record, {num(bias.get('record_s'))} s, cannot check it" if bias.get("record_s") else ""
    return (f"the exported initial bias (std {std}) rests on {what} extrapolated "
            f"to T_max = {num(bias.get('T_max_s'))} s ({src}{rec}): state the longest time a bias persists "
            "(identify.max_bias_time_s, s) if it is known")
