"""Small helpers of the benchmark harness: repeated timing, the machine description, markdown tables.

Kept free of imupipe imports so that ``benchmarks/run.py`` and ``benchmarks/dag.py`` can share them and the
smoke test can import them on their own.
"""

from __future__ import annotations

import math
import os
import platform
import statistics
import sys
import time
from dataclasses import dataclass, field


@dataclass
class Timing:
    """Wall times (s) of repeated runs of one callable: median, min, max and the raw values."""

    values: list = field(default_factory=list)

    @property
    def n(self) -> int:
        return len(self.values)

    @property
    def median(self) -> float:
        return statistics.median(self.values) if self.values else math.nan

    @property
    def min(self) -> float:
        return min(self.values) if self.values else math.nan

    @property
    def max(self) -> float:
        return max(self.values) if self.values else math.nan

    def cell(self) -> str:
        """``median [min-max]`` in seconds, 3 significant digits."""
        if not self.values:
            return "n/a"
        if self.n == 1:
            return f"{fmt_s(self.median)} (n=1)"
        return f"{fmt_s(self.median)} [{fmt_s(self.min)}-{fmt_s(self.max)}]"

    def to_dict(self) -> dict:
        return {"median_s": self.median, "min_s": self.min, "max_s": self.max, "n": self.n, "values_s": self.values}


def timed(fn, repeats: int, slow_s: float = 20.0, very_slow_s: float = 60.0):
    """Run ``fn()`` `repeats` times and return (Timing, last result).

    Long settings are not run `repeats` times: a run slower than `slow_s` seconds caps the count at 3 (a median
    still exists), one slower than `very_slow_s` at the runs already done (the cell then says n=1).
    """
    t = Timing()
    result = None
    target = max(1, int(repeats))
    while t.n < target:
        t0 = time.perf_counter()
        result = fn()
        t.values.append(time.perf_counter() - t0)
        if t.values[-1] > very_slow_s:
            target = t.n
        elif t.values[-1] > slow_s:
            target = min(target, 3)
    return t, result


def fmt_s(seconds: float) -> str:
    """Seconds with 3 significant digits and a unit that keeps them readable (ms below 1 s)."""
    if seconds is None or not math.isfinite(seconds):
        return "n/a"
    if seconds < 1e-3:
        return f"{seconds * 1e6:.3g} us"
    if seconds < 1.0:
        return f"{seconds * 1e3:.3g} ms"
    return f"{seconds:.3g} s"


def fmt(x, digits: int = 3) -> str:
    """Number with `digits` significant digits; n/a for None/NaN."""
    if x is None:
        return "n/a"
    if isinstance(x, str):
        return x
    x = float(x)
    if not math.isfinite(x):
        return "n/a" if math.isnan(x) else ("inf" if x > 0 else "-inf")
    return f"{x:.{digits}g}"


def pct(x, digits: int = 2) -> str:
    """Relative value as a percentage (0.0123 -> '1.2 %')."""
    if x is None or not math.isfinite(float(x)):
        return "n/a"
    v = 100.0 * float(x)
    return f"{v:.{digits}g} %" if abs(v) < 10 ** digits else f"{v:.0f} %"


def md_table(headers, rows) -> str:
    """A GitHub-markdown table; cells are converted with str()."""
    lines = ["| " + " | ".join(str(h) for h in headers) + " |", "|" + "|".join("---" for _ in headers) + "|"]
    for r in rows:
        lines.append("| " + " | ".join(str(c).replace("|", "/") for c in r) + " |")
    return "\n".join(lines)


def cpu_model() -> str:
    """CPU model name from /proc/cpuinfo (Linux), else platform.processor()."""
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.lower().startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine_info() -> dict:
    """What the numbers depend on: CPU, cores, Python and library versions, BLAS threads."""
    import numpy

    info = {
        "cpu": cpu_model(),
        "cores (os.cpu_count)": os.cpu_count(),
        "usable cores (affinity)": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None,
        "python": platform.python_version(),
        "numpy": numpy.__version__,
        "OPENBLAS_NUM_THREADS": os.environ.get("OPENBLAS_NUM_THREADS", "unset"),
        "platform": f"{platform.system()} {platform.machine()}",
    }
    from importlib.metadata import PackageNotFoundError, version

    for mod in ("scipy", "allantools", "snakemake", "xarray"):
        try:
            info[mod] = version(mod)
        except PackageNotFoundError:  # not installed: say so rather than fail
            info[mod] = "not installed"
    try:
        import imupipe.allan as _allan

        info["imupipe C kernel"] = "loaded" if getattr(_allan, "_kernels", None) is not None else "NumPy fallback"
    except ImportError:
        info["imupipe C kernel"] = "imupipe.allan missing"
    info["executable"] = os.path.basename(sys.executable)
    return info
