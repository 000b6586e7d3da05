"""The words of a verification check that passed only by its sampling tolerance.

One home for that sentence: the verification writes it into the verify and contract files
(:mod:`imupipe.verify`), the run summary prints it as a FLAG (:mod:`imupipe.summary`), so the wording is the same
wherever a user reads the verdict. Plain dicts in, a string out: no numerics here.
"""

from __future__ import annotations

__all__ = ["within_tolerance"]


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
            "few independent windows: neither evidence of an under-statement nor a confirmation")
