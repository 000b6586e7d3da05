"""`imupipe plan`'s auto columns for the truths of benchmarks/bound_modes.py: the predicted mean P/MSE of the auto bound
(imupipe.plan.auto_prediction: the run's identification of the expected curves, the joint envelope, against the model
over the reference scenario) for 10 h records at 10 Hz, one axis, 1 and 5 records, to set beside the measured auto
conservatism of bound_modes.py (docs/performance.md). Prints a Markdown table.

    OPENBLAS_NUM_THREADS=1 python benchmarks/plan_auto.py
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bound_modes import TRUTHS  # noqa: E402
from imupipe.plan import auto_prediction  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--truth", nargs="+", default=sorted(TRUTHS), choices=sorted(TRUTHS))
    ap.add_argument("--records", nargs="+", type=int, default=[1, 5])
    ap.add_argument("--hours", type=float, default=10.0)
    ap.add_argument("--rate", type=float, default=10.0)
    a = ap.parse_args(argv)
    print("| truth | sensor | records | predicted auto P/MSE | predicted worst MSE/P | in-band inflation |")
    print("|---|---|---|---|---|---|")
    for tn in a.truth:
        for sensor in ("accel", "gyro"):
            for r in a.records:
                p = auto_prediction(TRUTHS[tn], a.hours, r, 1, a.rate, sensor)
                print(f"| {tn} | {sensor} | {r} | {p['conservatism']:.2f} | {p['worst']:.3f} | {p['inflation']:.2f} |",
                      flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
