"""How the reader reads jittered timestamps with dropped samples (imupipe.readers, docs/inputs.md "Timestamps"), by
simulation: records of `--hours` at `--rate` Hz whose stamps jitter about their sample grid (Gaussian, sd in
periods), with `--drops` single samples removed from each, read through the public `read_dataset` under
``gap_policy: split``. Prints a Markdown table per jitter: stamps stepping back per record, records refused, rates
read, the gaps found (segment boundaries at a drop or one row beside it, over the records read) and the false
ones.

    OPENBLAS_NUM_THREADS=1 python benchmarks/timestamps.py --jitter 0.15 0.2 0.25 --records 20
"""

from __future__ import annotations

import argparse
import tempfile
import warnings
from pathlib import Path

import numpy as np

from imupipe.readers import DataError, read_dataset

CHANNELS = {"gyro_x": 1}  # one channel: the stamps are what is read
UNITS = {"gyro": "rad/s"}


def read_one(folder: Path, rng, hours: float, rate: float, jitter: float, drops: int):
    """(steps back, refused, rate read, gaps found, false gaps, gaps) of one simulated record (two neighbouring
    drops are one gap)."""
    n = int(hours * 3600 * rate) + drops
    t = (np.arange(n) + rng.normal(0.0, jitter, n)) / rate
    keep = np.delete(np.arange(n), rng.choice(np.arange(100, n - 100), drops, replace=False))
    table = np.column_stack([t[keep], rng.normal(0.0, 1e-3, keep.size)])
    path = folder / "record.npy"
    np.save(path, table)
    back = int(np.count_nonzero(np.diff(table[:, 0]) <= 0))
    true = set((np.flatnonzero(np.diff(keep) > 1) + 1).tolist())  # rows that follow a drop
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            rec = read_dataset(path, "npy", None, CHANNELS, UNITS, time_column=0, gap_policy="split")
        except DataError:
            return back, True, None, 0, 0, len(true)
    found = {s.start for s in rec.segments[1:]}
    # a gap placed one row off (the long interval beside the drop's: jitter) is that gap
    near = {f for f in found if {f - 1, f, f + 1} & true}
    return back, False, rec.rate_hz, len(near), len(found - near), len(true)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--jitter", type=float, nargs="+", default=[0.15, 0.2, 0.25], help="stamp jitter sd (periods)")
    ap.add_argument("--records", type=int, default=20)
    ap.add_argument("--hours", type=float, default=10.0)
    ap.add_argument("--rate", type=float, default=10.0, help="Hz")
    ap.add_argument("--drops", type=int, default=20, help="single samples removed per record")
    ap.add_argument("--seed", type=int, default=9000)
    args = ap.parse_args(argv)
    print(f"{args.records} records of {args.hours:g} h at {args.rate:g} Hz, {args.drops} single drops each, "
          "gap_policy split, rate_hz empty\n")
    print("| stamp jitter (periods) | steps back per record | refused | rates read (Hz) | gaps found | false gaps |")
    print("|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for jitter in args.jitter:
            rows = [read_one(Path(tmp), np.random.default_rng([args.seed, r]), args.hours, args.rate, jitter,
                             args.drops) for r in range(args.records)]
            rates = sorted({f"{r[2]:g}" for r in rows if r[2] is not None}) or ["-"]
            read = [r for r in rows if not r[1]]
            print(f"| {jitter:g} | {np.mean([r[0] for r in rows]):.1f} | {sum(r[1] for r in rows)} of {len(rows)} | "
                  f"{', '.join(rates)} | {sum(r[3] for r in read)} of {sum(r[5] for r in read)} | "
                  f"{sum(r[4] for r in read)} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
