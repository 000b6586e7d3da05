"""The default config's simulation, this checkout against a baseline commit: wall and CPU, medians of several runs.

``python benchmarks/simulate_cost.py [--baseline main [388c12b ...]] [--repeats 3] [--cores 2] [--job-only] [--keep DIR]``

Two measurements per tree, the trees alternating run by run on the same machine (``nice`` both):

1. ``--until simulate`` from nothing: a scratch copy of ``Snakefile``, ``workflow/``, ``config/`` and an empty
   ``data/`` per tree, ``OPENBLAS_NUM_THREADS=1 snakemake --cores <cores> --configfile config/config.yaml
   --max-checksum-file-size 0 --until simulate`` with ``PYTHONPATH`` at the tree's ``src/`` (the simulated
   records removed before each run). Wall time, and the CPU time (user + system) of Snakemake and every job it
   ran (the children's resource usage, as ``/usr/bin/time`` reports it).
2. one ``simulate`` job alone (``imupipe.stages.simulate.simulate_stage`` of the default config's first record:
   10 h at 125 Hz, 6 channels) in a fresh interpreter, imports included: wall and CPU (trees older than that
   module: not measured, ``nan``).

The baseline's files are taken with ``git archive`` (no worktree is added); its library runs from its own
``src/`` with this checkout's compiled kernel copied in (the baseline calls only the kernels it has). On a shared
machine the CPU column is the one to compare; the wall column depends on the load.
"""

from __future__ import annotations

import argparse
import io
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
COPIED = ("Snakefile", "workflow", "config")
JOB = (
    "import sys, yaml\n"
    "from imupipe.stages.simulate import simulate_stage\n"
    "cfg = yaml.safe_load(open('config/config.yaml'))['simulation']\n"
    "simulate_stage(truth=cfg['truth'], seed=int(cfg['seed']), duration_s=float(cfg['duration_h']) * 3600.0,\n"
    "               rate_hz=float(cfg['record_rate_hz']), gravity_axis=cfg.get('gravity_axis', 'z'),\n"
    "               path_out=sys.argv[1], name='job')\n"
)


def _tree_from_commit(commit: str, where: Path) -> Path:
    """`commit`'s src/, Snakefile, workflow/ and config/ extracted into `where` (git archive), with this checkout's
    compiled kernel copied into its src/imupipe."""
    blob = subprocess.run(["git", "-C", str(REPO), "archive", "--format=tar", commit, "src", *COPIED],
                          check=True, capture_output=True).stdout
    where.mkdir(parents=True)
    with tarfile.open(fileobj=io.BytesIO(blob)) as tar:
        tar.extractall(where, filter="data")
    for so in (REPO / "src" / "imupipe").glob("_kernels*.so"):
        shutil.copy2(so, where / "src" / "imupipe" / so.name)
    return where


def _scratch(tree: Path, where: Path) -> Path:
    """Snakefile, workflow/, config/ of `tree` and an empty data/ in `where`."""
    where.mkdir(parents=True)
    for name in COPIED:
        src = tree / name
        (shutil.copytree if src.is_dir() else shutil.copy2)(src, where / name)
    (where / "data").mkdir()
    return where


def _clean(scratch: Path) -> None:
    for name in ("data", "results", "logs", "benchmarks", ".snakemake"):
        shutil.rmtree(scratch / name, ignore_errors=True)
    (scratch / "data").mkdir()


def _timed(cmd: list, cwd: Path, env: dict, log: Path) -> tuple[float, float]:
    """Run `cmd` (niced) in `cwd`: (wall s, CPU s of it and all its waited-for descendants)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    with open(log, "w") as fh:
        proc = subprocess.run(["nice", *cmd], cwd=cwd, env=env, stdout=fh, stderr=subprocess.STDOUT)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed in {cwd} (exit {proc.returncode}); log: {log}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--baseline", nargs="+", default=["main"], help="commits to compare against (default: main)")
    ap.add_argument("--repeats", type=int, default=3, help="runs per tree and measurement (default 3)")
    ap.add_argument("--cores", type=int, default=2, help="snakemake --cores (default 2)")
    ap.add_argument("--job-only", action="store_true", help="only the single-job measurement")
    ap.add_argument("--keep", type=Path, default=None, help="keep the scratch trees and logs in this folder")
    args = ap.parse_args(argv)

    tmp = Path(tempfile.mkdtemp(prefix="simulate_cost_")) if args.keep is None else args.keep.resolve()
    tmp.mkdir(parents=True, exist_ok=True)
    snakemake = str(Path(sys.executable).with_name("snakemake"))
    try:
        trees = {"this checkout": REPO}
        for i, commit in enumerate(args.baseline):
            trees[f"commit {commit}"] = _tree_from_commit(commit, tmp / f"baseline_{i}")
        runs = {}
        for i, (label, tree) in enumerate(trees.items()):
            env = dict(os.environ, OPENBLAS_NUM_THREADS="1", PYTHONPATH=str(tree / "src"))
            runs[label] = {"scratch": _scratch(tree, tmp / f"scratch_{i}"), "env": env, "dag": [], "job": [],
                           "stage": (tree / "src" / "imupipe" / "stages" / "simulate.py").exists()}
        for r in range(args.repeats):
            for label, st in runs.items():  # alternate the trees run by run
                scratch, env = st["scratch"], st["env"]
                if not args.job_only:
                    _clean(scratch)
                    st["dag"].append(_timed(
                        [snakemake, "--cores", str(args.cores), "--configfile", "config/config.yaml",
                         "--max-checksum-file-size", "0", "--until", "simulate", "--quiet", "all"],
                        scratch, env, scratch / f"dag_{r}.log"))
                if st["stage"]:  # trees before imupipe.stages.simulate: the DAG measurement only
                    out = scratch / "job.nc"
                    st["job"].append(_timed([sys.executable, "-c", JOB, str(out)], scratch, env,
                                            scratch / f"job_{r}.log"))
                    out.unlink(missing_ok=True)
                print(f"run {r + 1}/{args.repeats} {label}: until simulate {st['dag'][-1] if st['dag'] else '-'}, "
                      f"one job {st['job'][-1] if st['job'] else '-'} (wall s, CPU s)", file=sys.stderr, flush=True)

        def med(values, k):
            return statistics.median(v[k] for v in values) if values else float("nan")

        print(f"\nmedians of {args.repeats} runs, trees alternating; --cores {args.cores}; nice; OPENBLAS_NUM_THREADS=1\n")
        print("| tree | until simulate: wall (s) | until simulate: CPU (s) | one job: wall (s) | one job: CPU (s) |")
        print("|---|---|---|---|---|")
        for label, st in runs.items():
            print(f"| {label} | {med(st['dag'], 0):.1f} | {med(st['dag'], 1):.1f} | {med(st['job'], 0):.2f} "
                  f"| {med(st['job'], 1):.2f} |")
        this = runs["this checkout"]
        for commit in args.baseline:
            base = runs[f"commit {commit}"]
            print(f"| this checkout / {commit} | {med(this['dag'], 0) / med(base['dag'], 0):.2f} "
                  f"| {med(this['dag'], 1) / med(base['dag'], 1):.2f} "
                  f"| {med(this['job'], 0) / med(base['job'], 0):.2f} | {med(this['job'], 1) / med(base['job'], 1):.2f} |")
    finally:
        if args.keep is None:
            shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
