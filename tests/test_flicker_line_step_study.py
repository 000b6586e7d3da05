"""A reduced run of benchmarks/flicker_line_step_study.py (issue 28): simulated records with a known flicker floor, a
0.5 Hz line with +-0.1 Hz sidebands and a mean step, through events, split, lines, Allan and identification.

Derived ranges: each interval is a 95 % one, so over n independent records the count that covers the truth is
Binomial(n, 0.95) when the level holds; its central 95 % range for n = 10 is 8-10 (P(X < 8) = 1.2 %). The same count
for K: the split record's K (0 where no random walk is kept) inside the 95 % K interval of the same record without
the step is, with the step handled, the coverage of that interval (truth K = 0). The step's time: the least-squares
change point has sd sqrt(26) N^2 / delta^2 = 0.2 s at this step, but the 0.5 Hz line and the flicker put 2 of 60
simulated records beyond 1 s (docs/performance.md): at most one of 10 beyond 1 s (P(X >= 2) = 4 % at 2/60). The
carrier's amplitude error: largest 4.6 % over 35 records, the issue's 10 % on every record.
"""
import os
import sys
from pathlib import Path

import numpy as np
import pytest

BENCH = Path(__file__).resolve().parents[1] / "benchmarks"
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


@pytest.mark.slow
def test_reduced_study_meets_the_issue_ranges():
    sys.path.insert(0, str(BENCH))
    try:
        import flicker_line_step_study as study
    finally:
        sys.path.remove(str(BENCH))
    n = 10
    rows = study.main(["--records", str(n), "--seed", "303", "--n-boot", "100"])
    lo, hi = study.binomial_range(n, 0.95)
    assert (lo, hi) == (8, 10)
    for key, truth in (("B", study.FLICKER), ("N", study.WHITE)):
        covered = sum(study.inside(o[key], truth) for o in rows)
        assert lo <= covered <= hi, (key, covered)
    within = sum(bool(np.isfinite(o["dt_step_s"]) and abs(o["dt_step_s"]) <= 1.0) for o in rows)
    assert within >= n - 1, [o["dt_step_s"] for o in rows]
    assert all(abs(o["amp_err"]) <= 0.1 for o in rows)
    assert lo <= sum(study.inside(o["K0"], o["K"][0]) for o in rows) <= hi
