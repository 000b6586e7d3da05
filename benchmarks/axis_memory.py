"""Peak memory of the per-axis and per-dataset jobs against one axis's samples, at several record lengths.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/axis_memory.py [--duration-h 10 40] [--rate-hz 125]
        [--out DIR] [--keep] [--csv]

For each duration: one simulated dataset of that length at ``--rate-hz`` (the default config's truth model,
config/config.yaml otherwise), Snakemake (one core) builds the per-axis files of the gyro x axis in a
scratch working directory (``--directory``): ingest (all six channels of the dataset), allan, decimate, psd,
stationarity, lines, outliers. Per rule: the benchmark file's ``max_rss`` and the peak resident set
(``VmHWM``) a 50 ms sampler saw in the job's process (benchmarks/dag.py, ``MemorySampler``), in MB, and the
larger of the two over one axis's samples (8 bytes x n). The budget (docs/performance.md): at most 2 x one
axis plus a fixed overhead, i.e. the excess over the 10 h peak at 40 h at most 2 x the 108 MB the axis grows.
Prints a markdown table; the simulate job is listed for reference (it draws all six channels).

``--csv``: instead, ingest's reader alone on a CSV with a time column (time in s and six channels, written at
``--rate-hz`` for each duration): the rise of the peak resident set (``VmHWM``) of a fresh interpreter over its
resident set before the call (imports and first-call costs paid on a small file first) while
``imupipe.readers.read_channel`` reads gyro x with ``rate_hz`` given, in MB and over one axis.
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from dag import RUN_FLAGS, read_benchmark_file, snakemake  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
RULES = ["simulate", "ingest", "allan", "decimate", "psd", "stationarity", "lines", "outliers"]
MB = 1e6
SCRIPT_OF = {"ingest": "ingest.py", "simulate": "simulate.py", "allan": "allan.py", "decimate": "decimate.py",
             "psd": "psd.py", "stationarity": "stationarity.py", "lines": "lines.py", "outliers": "outliers.py"}


def targets(name: str) -> list:
    axis = "sim01/gyro/x"
    return [f"results/{name}/{kind}/{axis}.{ext}" for kind, ext in (
        ("allan", "nc"), ("decimated", "nc"), ("psd", "nc"), ("stationarity", "yaml"), ("lines", "yaml"),
        ("outliers", "yaml"))]


def measure(duration_h: float, rate_hz: float, work: Path) -> dict:
    """rule -> {'bench': max_rss MB, 'hwm': sampler peak MB}, and the axis size (MB) under key 'axis_mb'."""
    import yaml

    name = f"mem{duration_h:g}h"
    work.mkdir(parents=True, exist_ok=True)
    cfg = {"name": name, "simulation": {"n_datasets": 1, "duration_h": float(duration_h), "record_rate_hz": float(rate_hz)}}
    if duration_h < 10.0:  # the default Welch window (7 h, step 10 h) needs a 7 h record: scaled down with it
        cfg["psd"] = {"window_s": 0.7 * duration_h * 3600.0, "step_s": duration_h * 3600.0}
    cfgfile = work / f"{name}.yaml"
    cfgfile.write_text(yaml.safe_dump(cfg, sort_keys=False))
    args = ["--snakefile", str(ROOT / "Snakefile"), "--directory", str(work), "--cores", "1", "--configfile",
            str(ROOT / "config" / "config.yaml"), str(cfgfile), "--quiet", "rules", *RUN_FLAGS, *targets(name)]
    _, _, sampler = snakemake(ROOT, args, work / f"{name}.log", sample_memory=True)
    peaks = sampler.per_script()
    bench = work / "results" / name / "benchmarks"
    out = {"axis_mb": 8 * round(duration_h * 3600 * rate_hz) / MB}
    for rule in RULES:
        files = sorted(bench.glob(f"{rule}/**/*.tsv"))
        rss = [read_benchmark_file(f).get("max_rss") for f in files]
        rss = [r * 2**20 / MB for r in rss if isinstance(r, float)]
        hwm = peaks.get(SCRIPT_OF[rule], [])
        out[rule] = {"bench": max(rss) if rss else None, "hwm": max(hwm) if hwm else None}
    return out


_CSV_PROBE = """
import sys
from imupipe.readers import read_channel
def status(key):
    for line in open("/proc/self/status"):
        if line.startswith(key):
            return int(line.split()[1]) * 1024
kw = dict(time_column="time", time_unit="s", rate_hz=float(sys.argv[3]), units={"gyro": "rad/s", "accel": "m/s^2"})
read_channel(("gyro", "x"), sys.argv[2], **kw)
before = status("VmRSS")
x = read_channel(("gyro", "x"), sys.argv[1], **kw)["gyro", "x"]
print(status("VmHWM") - before, x.size)
"""


def write_csv(path: Path, duration_h: float, rate_hz: float) -> int:
    """A static record as CSV: time (s) and gyro (rad/s, white noise) and accel (m/s^2, gravity on z) x, y, z,
    written in blocks of 2^18 rows; returns the number of rows."""
    import numpy as np

    n = int(round(duration_h * 3600 * rate_hz))
    rng = np.random.default_rng(1)
    with open(path, "w") as fh:
        fh.write("time,gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z\n")
        for a in range(0, n, 1 << 18):
            b = min(n, a + (1 << 18))
            block = np.column_stack([np.arange(a, b) / rate_hz, 1e-3 * rng.standard_normal((b - a, 3)),
                                     [0.0, 0.0, 9.80665] + 1e-2 * rng.standard_normal((b - a, 3))])
            np.savetxt(fh, block, fmt=["%.6f"] + ["%.9e"] * 6, delimiter=",")
    return n


def measure_csv(duration_h: float, rate_hz: float, work: Path) -> dict:
    """{'rise_mb': VmHWM rise of read_channel (MB), 'axis_mb': one axis (MB)} for a CSV of `duration_h`."""
    import subprocess

    work.mkdir(parents=True, exist_ok=True)
    big, small = work / "imu.csv", work / "small.csv"
    n = write_csv(big, duration_h, rate_hz)
    write_csv(small, 1000 / rate_hz / 3600, rate_hz)
    out = subprocess.run([sys.executable, "-c", _CSV_PROBE, str(big), str(small), str(rate_hz)], check=True,
                         capture_output=True, text=True, env={**os.environ, "OPENBLAS_NUM_THREADS": "1"})
    rise, size = map(int, out.stdout.split())
    assert size == n, (size, n)
    return {"rise_mb": rise / MB, "axis_mb": 8 * n / MB}


def csv_table(results: dict) -> str:
    rows = ["| duration | one axis (MB) | read_channel peak rise (MB) | x axis |", "|---|---|---|---|"]
    rows += [f"| {h:g} h | {r['axis_mb']:.0f} | {r['rise_mb']:.0f} | {r['rise_mb'] / r['axis_mb']:.2f} |"
             for h, r in results.items()]
    return "\n".join(rows) + "\n"


def table(results: dict) -> str:
    hours = list(results)
    head = "| rule | " + " | ".join(f"{h:g} h: max_rss / VmHWM (MB) | x axis" for h in hours) + " |"
    lines = [head, "|---|" + "---|---|" * len(hours)]
    for rule in RULES:
        cells = []
        for h in hours:
            r, axis = results[h][rule], results[h]["axis_mb"]
            peak = max(v for v in (r["bench"], r["hwm"]) if v is not None) if any((r["bench"], r["hwm"])) else None
            txt = " / ".join("n/a" if v is None else f"{v:.0f}" for v in (r["bench"], r["hwm"]))
            cells += [txt, "n/a" if peak is None else f"{peak / axis:.2f}"]
        lines.append(f"| {rule} | " + " | ".join(cells) + " |")
    axes = ", ".join(f"{results[h]['axis_mb']:.0f} MB at {h:g} h" for h in hours)
    return "\n".join(lines) + f"\n\none axis: {axes}\n"


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--duration-h", type=float, nargs="+", default=[10.0, 40.0])
    p.add_argument("--rate-hz", type=float, default=125.0)
    p.add_argument("--out", type=Path, default=None, help="scratch folder (default: a temporary one)")
    p.add_argument("--keep", action="store_true", help="keep the scratch folder")
    p.add_argument("--csv", action="store_true",
                   help="only ingest's reader on a CSV with a time column (module docstring)")
    a = p.parse_args(argv)
    work = a.out or Path(tempfile.mkdtemp(prefix="axis_memory_"))
    run = measure_csv if a.csv else measure
    try:
        results = {h: run(h, a.rate_hz, work / f"{h:g}h") for h in a.duration_h}
    finally:
        if not a.keep:
            shutil.rmtree(work, ignore_errors=True)
    print(csv_table(results) if a.csv else table(results))


if __name__ == "__main__":
    main()
