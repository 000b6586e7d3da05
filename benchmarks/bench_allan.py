"""Speed and agreement of imupipe's overlapping Allan variance against allantools.oadev.

Run: ``python benchmarks/bench_allan.py [--repeat 5] [--quick]``. Prints the machine, then tables of
the median (min/max) wall time of each method over ``--repeat`` runs on the same input and the same
averaging factors, with ratios to allantools and the largest relative difference between results:

1. 4.5e6 samples (10 h at 125 Hz), 100 log-spaced averaging factors 1 .. n/4 (unique: 92);
2. the same record, octave factors;
3. every averaging factor 1 .. n/2 - 1 of a 1 Hz record (36 000 points = 10 h; the FFT method), and a size
   sweep 9k/18k/36k/72k showing how each method scales.

Inputs are white rate noise plus a small rate random walk (fixed seed). BLAS is limited to one thread
before NumPy is imported (the kernels do not use BLAS; this keeps the comparison single-threaded).
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse
import platform
import statistics
import time

import numpy as np

from imupipe import allan

try:
    import allantools
except ImportError:  # pragma: no cover
    allantools = None


def machine() -> str:
    model = platform.processor() or "unknown CPU"
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    model = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    kern = "not built" if allan._kernels is None else (
        f"built (BLOCK={allan._kernels.BLOCK}, SMALL_LAG={allan._kernels.SMALL_LAG})"
    )
    at = getattr(allantools, "__version__", "absent") if allantools else "absent"
    return (
        f"CPU: {model}; logical cores: {os.cpu_count()}; Python {platform.python_version()}; "
        f"NumPy {np.__version__}; allantools {at}; imupipe._kernels {kern}"
    )


def timed(fn, repeat):
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return out, times


def fmt(times):
    return f"{statistics.median(times):8.4f} ({min(times):.4f}/{max(times):.4f})"


def table(title, rows, ref_name="allantools.oadev"):
    """rows: list of (name, times, avar). Ratios are allantools median / method median."""
    print(f"\n{title}")
    ref = next((r for r in rows if r[0] == ref_name), None)
    print(f"| {'method':34s} | {'median (min/max) s':28s} | {'x faster':>8s} | {'max rel diff':>12s} |")
    print(f"|{'-' * 36}|{'-' * 30}|{'-' * 10}|{'-' * 14}|")
    for name, times, av in rows:
        if ref is not None and name != ref_name:
            ratio = f"{statistics.median(ref[1]) / statistics.median(times):8.1f}"
            diff = f"{np.max(np.abs(av / ref[2] - 1)):12.1e}"
        else:
            ratio, diff = f"{'1.0' if name == ref_name else '-':>8s}", f"{'-':>12s}"
        print(f"| {name:34s} | {fmt(times):28s} | {ratio} | {diff} |")


def oadev_allantools(x, rate, m):
    taus, adev, _, _ = allantools.oadev(x, rate=rate, data_type="freq", taus=m / rate)
    got = np.rint(np.asarray(taus) * rate).astype(np.int64)
    if not np.array_equal(got, m):
        raise RuntimeError("allantools used other averaging factors")
    return np.asarray(adev) ** 2


def record(n, rate, seed):
    rng = np.random.default_rng(seed)
    return 0.003 * rng.standard_normal(n) + 2e-6 / np.sqrt(rate) * np.cumsum(rng.standard_normal(n))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=5, help="runs per method (>= 5 for the report)")
    ap.add_argument("--quick", action="store_true", help="smaller inputs (a smoke test, not a benchmark)")
    args = ap.parse_args()
    print(machine())
    rep = args.repeat
    have_c = allan._kernels is not None

    # --- 1, 2: paper-scale record -------------------------------------------------------------
    rate = 125.0
    n = 450_000 if args.quick else 4_500_000
    x = record(n, rate, 1)
    grids = {
        "100 log-spaced factors": np.unique(np.rint(np.logspace(0, np.log10(n // 4), 100)).astype(np.int64)),
        "octave factors": allan.tau_grid(n, rate, "octave").m,
    }
    for label, m in grids.items():
        rows = []
        if allantools:
            av, t = timed(lambda m=m: oadev_allantools(x, rate, m), rep)
            rows.append(("allantools.oadev", t, av))
        if have_c:
            av, t = timed(lambda m=m: allan.overlapping_avar(x, rate, m, backend="c"), rep)
            rows.append(("imupipe overlapping_avar, C kernel", t, av))
        av, t = timed(lambda m=m: allan.overlapping_avar(x, rate, m, backend="numpy"), rep)
        rows.append(("imupipe overlapping_avar, NumPy", t, av))
        _, t = timed(lambda m=m: allan.allan_variance(x, rate, taus=m / rate), rep)
        rows.append(("imupipe allan_variance (+EDF, CI)", t, rows[-1][2]))
        table(f"{n} samples at {rate:g} Hz, {label} ({m.size} unique, m = {m[0]}..{m[-1]})", rows)
        if have_c:
            c = next(r[2] for r in rows if "C kernel" in r[0])
            p = next(r[2] for r in rows if "NumPy" in r[0])
            print(f"C kernel vs NumPy path: max rel diff {np.max(np.abs(c / p - 1)):.1e}")

    # --- 3: every averaging factor, 1 Hz ---------------------------------------------------------
    sizes = [9_000, 18_000] if args.quick else [9_000, 18_000, 36_000, 72_000]
    sweep = []
    for n1 in sizes:
        x1 = record(n1, 1.0, 2)
        m1 = np.arange(1, n1 // 2)  # allantools stops one short of n/2 (a single term)
        rows = []
        if allantools:
            av, t = timed(lambda x1=x1, m1=m1: oadev_allantools(x1, 1.0, m1), rep)
            rows.append(("allantools.oadev", t, av))
        av, t = timed(lambda x1=x1, m1=m1: allan.overlapping_avar(x1, 1.0, m1, method="fft"), rep)
        rows.append(("imupipe FFT method (O(N log^2 N))", t, av))
        if have_c:
            av, t = timed(lambda x1=x1, m1=m1: allan.overlapping_avar(x1, 1.0, m1, method="direct", backend="c"),
                          rep)
            rows.append(("imupipe direct, C kernel (O(N^2))", t, av))
        _, t = timed(lambda x1=x1, m1=m1: allan.allan_variance(x1, 1.0, taus=m1 / 1.0), rep)
        rows.append(("imupipe allan_variance (+EDF, CI)", t, rows[1][2]))
        th, _ = allan._integrate(x1)
        _, recomputed, _ = allan._oavar_sums_all(th, int(m1[-1]))
        if n1 == 36_000 or args.quick and n1 == sizes[-1]:
            table(f"{n1} points at 1 Hz, every averaging factor 1..{m1[-1]} "
                  f"(FFT path recomputed {int(recomputed.sum())} factors directly)", rows)
        sweep.append((n1, {r[0]: statistics.median(r[1]) for r in rows}))

    names = list(sweep[0][1])
    print("\nsize sweep, every averaging factor 1..n/2-1, median seconds (growth factor per doubling)")
    print("| n      | " + " | ".join(f"{nm:34s}" for nm in names) + " |")
    print("|--------|" + "|".join("-" * 36 for _ in names) + "|")
    for i, (n1, med) in enumerate(sweep):
        cells = []
        for nm in names:
            g = f" (x{med[nm] / sweep[i - 1][1][nm]:.1f})" if i else ""
            cells.append(f"{med[nm]:10.4f}{g:8s}".ljust(34))
        print(f"| {n1:6d} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
