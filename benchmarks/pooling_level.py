"""False-alarm rate of the pooling test (imupipe.identify.pooling.pooling_test) by simulation: records of one truth
(benchmarks/bound_modes.py's TRUTHS), so every rejection is a false alarm; per set of records the test's p-value
(99 bootstrap replicates, the workflow's), and the counts at 0.01 (its level) and 0.05.

    OPENBLAS_NUM_THREADS=1 python benchmarks/pooling_level.py --truth nav_grade --sets 160 --seed 9100
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bound_modes import TRUTHS  # noqa: E402


def main(argv=None) -> int:
    from imupipe.allan import allan_variance
    from imupipe.identify.pooling import pooling_test
    from imupipe.simulate import simulate

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--truth", default="nav_grade", choices=sorted(TRUTHS))
    ap.add_argument("--sets", type=int, default=160)
    ap.add_argument("--records", type=int, default=5)
    ap.add_argument("--hours", type=float, default=10.0)
    ap.add_argument("--rate", type=float, default=10.0)
    ap.add_argument("--seed", type=int, default=9100)
    a = ap.parse_args(argv)
    truth, n = TRUTHS[a.truth], int(a.hours * 3600 * a.rate)
    ps = []
    for r in range(a.sets):
        X = simulate(truth, n, a.rate, rng=np.random.default_rng(a.seed + r), n_records=a.records)
        T, A, E = [], [], []
        for x in X:
            av = allan_variance(x, a.rate, taus="octave", confidence=0.683)
            v, e = av["avar"].values, av["edf"].values
            ok = np.isfinite(v) & np.isfinite(e)
            T.append(av["tau"].values[ok]), A.append(v[ok]), E.append(e[ok])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = pooling_test(T, A, E, components=["white", "gauss_markov", "random_walk"], n_gm=1,
                               record_rate_hz=a.rate, n_samples=n, n_boot=99, level=0.01, rng=a.seed + 1000 + r)
        ps.append(res["p_value"])
    ps = np.array(ps)
    print(f"| truth | sets of {a.records} x {a.hours:g} h | rejected at 0.01 (expected) | at 0.05 (expected) |")
    print("|---|---|---|---|")
    print(f"| {a.truth} | {a.sets} | {int(np.sum(ps <= 0.01))} ({0.01 * a.sets:.1f}) | "
          f"{int(np.sum(ps <= 0.05))} ({0.05 * a.sets:.1f}) |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
