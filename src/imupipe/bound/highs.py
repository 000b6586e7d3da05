"""The bounding LP's solver: HiGHS through highspy, one instance per process, silent on stdout
(:func:`highs_min`, used by :mod:`imupipe.bound.engine`)."""

from __future__ import annotations

import numpy as np

__all__ = ["highs_min", "quiet_highs"]

_HIGHS = None  # one solver instance per process, reused (each LP replaces the previous model)


def quiet_highs(highspy):
    """A Highs instance created with file descriptor 1 redirected: the constructor prints a banner on
    stdout before any option can be set, and a workflow script's stdout is its output."""
    import os
    import sys

    sys.stdout.flush()
    saved = os.dup(1)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 1)
            h = highspy.Highs()
            h.setOptionValue("output_flag", False)
            h.setOptionValue("log_to_console", False)
    finally:
        os.dup2(saved, 1)
        os.close(saved)
    return h


def highs_min(c, A, b=None):
    """argmin of c @ u subject to A u >= 1, u >= 0, by HiGHS (highspy; one thread, no output).

    The bounding LPs have 2-4 columns and a few dozen rows after the dominance reduction: HiGHS solves
    one in ~0.2 ms, and ``scipy.optimize.linprog`` spends ~1 ms around the same solve (input checks,
    option validation), which summed to half of a bound job.
    """
    global _HIGHS
    import highspy

    if _HIGHS is None:
        _HIGHS = quiet_highs(highspy)
        _HIGHS.setOptionValue("output_flag", False)
        _HIGHS.setOptionValue("threads", 1)
    m, n = A.shape
    lp = highspy.HighsLp()
    lp.num_col_, lp.num_row_ = n, m
    lp.col_cost_ = np.ascontiguousarray(c, dtype=np.float64)
    lp.col_lower_ = np.zeros(n)
    lp.col_upper_ = np.full(n, highspy.kHighsInf)
    lp.row_lower_ = np.ones(m) if b is None else np.ascontiguousarray(b, dtype=np.float64)
    lp.row_upper_ = np.full(m, highspy.kHighsInf)
    lp.a_matrix_.format_ = highspy.MatrixFormat.kColwise
    lp.a_matrix_.start_ = np.arange(0, m * n + 1, m, dtype=np.int32)
    lp.a_matrix_.index_ = np.tile(np.arange(m, dtype=np.int32), n)
    lp.a_matrix_.value_ = np.ascontiguousarray(A.T, dtype=np.float64).ravel()
    _HIGHS.passModel(lp)
    _HIGHS.run()
    status = _HIGHS.getModelStatus()
    if status != highspy.HighsModelStatus.kOptimal:
        raise RuntimeError(f"HiGHS failed on the bounding LP: {_HIGHS.modelStatusToString(status)}")
    return np.array(_HIGHS.getSolution().col_value, dtype=np.float64)
