"""What each workflow job imports and costs: per rule, the jobs, their CPU (median, range, sum) and the heavy
modules they load with the library line that imported each first.

    OPENBLAS_NUM_THREADS=1 nice .venv/bin/python benchmarks/job_imports.py [--config tests/configs/tiny.yaml]
        [--workdir DIR] [--until RULE] [--probe-dir DIR]

Copies ``Snakefile``, ``workflow/``, ``config/`` and ``data/`` into `--workdir` (a new temporary folder by
default; an existing one is re-used, so a copy whose simulation is done measures a cold run without it), runs
``snakemake --cores 2 --max-checksum-file-size 0`` there with a ``sitecustomize`` module first on
``PYTHONPATH``, and prints the table. The probe records, in every Python process of the run, the user + system
CPU of the whole process (``getrusage``: interpreter, Snakemake's script preamble, imports, numerics, writing;
a job's benchmark file samples its CPU and misses most of a sub-second job) and which of ``HEAVY`` it loaded.
``--probe-dir`` only prints the table of an earlier run's probe files. The library is the one the
interpreter imports (this checkout's with ``make env``, another tree's with ``PYTHONPATH=<tree>/src``).
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("xarray", "pandas", "matplotlib", "scipy.special", "scipy.stats", "scipy.linalg", "scipy.optimize",
         "scipy.signal", "highspy")

PROBE = '''\
import atexit, json, os, resource, sys, traceback
_OUT = os.environ.get("IMUPIPE_IMPORT_PROBE")
_HEAVY = %r
_first = {}


class _Probe:
    def find_spec(self, name, path=None, target=None):
        if name in _HEAVY and name not in _first:
            stack = traceback.extract_stack()[:-1]
            frames = [f"{os.path.basename(f.filename)}:{f.lineno}:{f.name}" for f in stack
                      if "imupipe" in f.filename or "scripts" in f.filename]
            _first[name] = frames[-1] if frames else ""
        return None


if _OUT:
    sys.meta_path.insert(0, _Probe())

    def _dump():
        r = resource.getrusage(resource.RUSAGE_SELF)
        rec = {"argv0": sys.argv[0] if sys.argv else "", "cpu_s": r.ru_utime + r.ru_stime,
               "loaded": [m for m in _HEAVY if m in sys.modules], "first": _first}
        with open(os.path.join(_OUT, f"{os.getpid()}.json"), "w") as fh:
            json.dump(rec, fh)

    atexit.register(_dump)
''' % (HEAVY,)


def run(config: str, workdir: Path, until: str | None, probe_dir: Path) -> None:
    """The workflow in `workdir` (a copy of this checkout's workflow) with the probe on."""
    workdir.mkdir(parents=True, exist_ok=True)
    for name in ("Snakefile", "workflow", "config", "data"):
        if not (workdir / name).exists():
            (shutil.copytree if (ROOT / name).is_dir() else shutil.copy2)(ROOT / name, workdir / name)
    cfg = Path(config)
    if not (workdir / cfg).exists():
        (workdir / cfg).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / cfg, workdir / cfg)
    site = Path(tempfile.mkdtemp(prefix="probe-"))
    (site / "sitecustomize.py").write_text(PROBE)
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", IMUPIPE_IMPORT_PROBE=str(probe_dir),
               PYTHONPATH=os.pathsep.join([str(site), *filter(None, [os.environ.get("PYTHONPATH")])]))
    cmd = [sys.executable, "-m", "snakemake", "--cores", "2", "--configfile", str(cfg),
           "--max-checksum-file-size", "0", "--quiet", "rules", "host", "reason"]
    subprocess.run(cmd + (["--until", until] if until else []), cwd=workdir, env=env, check=True)


def table(probe_dir: Path) -> list[dict]:
    """Rows per rule (the job's script name ``tmpXXXX.<rule>.py``; the Snakemake process itself as
    ``snakemake``), costliest first."""
    by_rule = collections.defaultdict(list)
    for p in probe_dir.glob("*.json"):
        rec = json.loads(p.read_text())
        m = re.search(r"tmp\w+\.(\w+)\.py$", rec["argv0"])
        rule = m.group(1) if m else ("snakemake" if "snakemake" in rec["argv0"] else None)
        if rule:
            by_rule[rule].append(rec)
    rows = []
    for rule, recs in by_rule.items():
        cpu = sorted(r["cpu_s"] for r in recs)
        loaded = collections.Counter(m for r in recs for m in r["loaded"])
        first = {m: next((r["first"][m] for r in recs if r["first"].get(m)), "") for m in loaded}
        rows.append({"rule": rule, "jobs": len(recs), "median": statistics.median(cpu), "min": cpu[0],
                     "max": cpu[-1], "sum": sum(cpu),
                     "heavy": [f"{m} ({loaded[m]}/{len(recs)}; {first[m]})" for m in HEAVY if m in loaded]})
    return sorted(rows, key=lambda r: -r["sum"])


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default="config/config.yaml", help="config file, relative to the checkout")
    ap.add_argument("--workdir", help="folder of the copy (default: a new temporary folder)")
    ap.add_argument("--until", help="stop after this rule (snakemake --until)")
    ap.add_argument("--probe-dir", help="print the table of an earlier run's probe files; run nothing")
    args = ap.parse_args(argv)
    if args.probe_dir:
        probe = Path(args.probe_dir)
    else:
        workdir = Path(args.workdir) if args.workdir else Path(tempfile.mkdtemp(prefix="imupipe-jobs-"))
        probe = Path(tempfile.mkdtemp(prefix="probe-out-"))
        run(args.config, workdir, args.until, probe)
        print(f"workdir {workdir}, probe files {probe}")
    print("| rule | jobs | CPU per job, median [min-max] | CPU, all jobs "
          "| heavy modules (jobs; first importer) |")
    print("|---|---|---|---|---|")
    for r in table(probe):
        print(f"| {r['rule']} | {r['jobs']} | {r['median']:.2f} s [{r['min']:.2f}-{r['max']:.2f}] "
              f"| {r['sum']:.1f} s | "
              f"{'; '.join(r['heavy']) or 'none'} |")


if __name__ == "__main__":
    main()
