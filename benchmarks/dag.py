"""Whole-workflow benchmark: cold run and spec-sheet-only rerun of the Snakemake DAG in a scratch copy.

``python benchmarks/dag.py [--repeats 5] [--baseline 8de70ed] [--duration-h 40] [--configfile ...]
[--simulation-only]``
(``--floor-jobs N``: the wall time of a DAG of N script jobs that compute nothing, :func:`job_start_floor`)
(:func:`compare`): this checkout and the commit ``--baseline`` (checked out in a temporary git worktree, its
library run from its own ``src/`` with this checkout's compiled kernel) are run alternately, run by run, in
scratch copies on the same machine: simulation (every output and the simulated recordings removed, then
``--until simulate``), cold run (every output removed but the simulated recordings), spec-sheet
rerun (a comment appended to the spec sheet), and the critical path (the longest chain of job wall times
from the benchmark files through the job DAG, i.e. the wall time with unlimited cores); medians of
``--repeats``. Peak RSS per rule from the benchmark files against one axis's samples; ``--duration-h``
overrides the simulated record length (e.g. 40 h for the memory scaling). The config path is relative to
each tree, so each tree runs its own version of the config.

``--detail`` (:func:`run`, also used by ``benchmarks/run.py``): the single-tree report below. Steps:

1. copy ``Snakefile``, ``workflow/``, ``config/`` and ``data/`` (without ``data/simulated``) to
   ``<out>/dag_scratch`` (timestamps kept), hard-link the checkout's ``data/simulated/*`` into it when present,
   and run ``snakemake --until simulate`` there so that the input data exist (not timed as part of the cold
   run; its time is reported). The checkout's ``results/`` is never touched.
2. cold run: remove ``results/``, ``logs/`` and ``benchmarks/`` of the scratch copy, run
   ``snakemake --cores <cores> --configfile config/config.yaml`` with ``OPENBLAS_NUM_THREADS=1`` and the
   Makefile's ``SNAKEMAKE_FLAGS`` (``RUN_FLAGS``); wall time.
   While it runs, a sampler reads every job process's peak resident set (``VmHWM`` of ``/proc/<pid>/status``,
   a high-water mark, so a late sample still sees an earlier peak) every 50 ms. Snakemake's own
   ``benchmark:`` files sample memory first at 0 s and then every 0.5 s, so for sub-second jobs their
   ``max_rss`` mostly shows the launching process; both are reported.
3. spec-sheet rerun: append a comment line to ``config/specs/stim300.yaml`` (values unchanged, new mtime) and
   run again; wall time and the jobs Snakemake re-ran.
4. per rule: jobs, sum/median/max of job wall times and peak memory (benchmark files' ``max_rss`` and the
   sampler's ``VmHWM``); orchestration: a fresh interpreter's start plus each rule script's imports, times the
   jobs, against the sum of job wall times; the floor: one ``np.sum`` pass per tau per axis plus decimation and
   Welch per axis, measured on one ingested axis of the run.
"""

from __future__ import annotations

import ast
import os
import re
import shutil
import statistics
import subprocess
import sys
import threading
import time
from pathlib import Path

from timing import Timing, fmt, fmt_s, md_table, timed

SNAKEMAKE = [sys.executable, "-m", "snakemake"]
# the options `make run` adds (Makefile, SNAKEMAKE_FLAGS): the run measured is the one users get
RUN_FLAGS = ["--max-checksum-file-size", "0"]
SAMPLE_INTERVAL_S = 0.05
MB = 1e6


# ---------------------------------------------------------------------------------------------
# parsing Snakemake's output and files
# ---------------------------------------------------------------------------------------------
def parse_job_stats(text: str) -> dict:
    """First 'Job stats' table of a Snakemake log: rule -> count (and 'total')."""
    out = {}
    lines = text.splitlines()
    for i, line in enumerate(lines):
        if line.strip() == "Job stats:":
            for row in lines[i + 3:]:  # header 'job count', a rule of dashes, then rows
                parts = row.split()
                if len(parts) != 2 or not parts[1].isdigit():
                    break
                out[parts[0]] = int(parts[1])
            break
    return out


_JOB_HEAD = re.compile(r"^(?:local)?(?:rule|checkpoint) (\S+):\s*$")
_JOB_FIELD = re.compile(r"^\s{4}(\w+): (.*)$")


def parse_jobs(text: str) -> list:
    """Job blocks of a Snakemake log: [{'rule', 'jobid', 'benchmark', 'wildcards': {...}, ...}]."""
    jobs, cur = [], None
    for line in text.splitlines():
        m = _JOB_HEAD.match(line)
        if m:
            cur = {"rule": m.group(1), "wildcards": {}}
            jobs.append(cur)
            continue
        if cur is None:
            continue
        f = _JOB_FIELD.match(line)
        if f:
            key, val = f.group(1), f.group(2).strip()
            if key == "wildcards":
                cur["wildcards"] = dict(kv.split("=", 1) for kv in val.split(", ") if "=" in kv)
            else:
                cur[key] = val
        elif line.strip():
            cur = None
    return jobs


def read_benchmark_file(path: Path) -> dict:
    """One Snakemake benchmark file (tab-separated; header s, h:m:s, max_rss, ...); the first data row."""
    lines = Path(path).read_text().splitlines()
    header = lines[0].split("\t")
    row = lines[1].split("\t")
    out = {}
    for k, v in zip(header, row):
        try:
            out[k] = float(v)
        except ValueError:
            out[k] = v
    return out


def rule_scripts(repo: Path) -> dict:
    """rule name -> script path, from ``script:`` directives in the Snakefile and workflow/rules/*.smk."""
    files = [repo / "Snakefile"] + sorted((repo / "workflow" / "rules").glob("*.smk"))
    out = {}
    for f in files:
        if not f.is_file():
            continue
        rule = None
        lines = f.read_text().splitlines()
        for i, line in enumerate(lines):
            m = re.match(r"^(?:rule|checkpoint)\s+(\w+)\s*:", line)
            if m:
                rule = m.group(1)
                continue
            s = re.match(r"^\s+script:\s*(.*)$", line)
            if s and rule:
                arg = s.group(1).strip() or (lines[i + 1].strip() if i + 1 < len(lines) else "")
                q = re.search(r"[\"']([^\"']+)[\"']", arg)
                if q:
                    out[rule] = (f.parent / q.group(1)).resolve()
    return out


def script_imports(path: Path) -> list:
    """Top-level module names a script imports anywhere in its body (snakemake excluded)."""
    tree = ast.parse(Path(path).read_text())
    mods = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [node.module]
        else:
            continue
        for n in names:
            if not n.startswith("snakemake") and n not in mods and n != "__future__":
                mods.append(n)
    return mods


# ---------------------------------------------------------------------------------------------
# peak memory of job processes
# ---------------------------------------------------------------------------------------------
def _vmhwm_kb(pid: int):
    try:
        with open(f"/proc/{pid}/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


class MemorySampler(threading.Thread):
    """Samples VmHWM of every descendant process of `root_pid` running a Snakemake script."""

    def __init__(self, root_pid: int, interval: float = SAMPLE_INTERVAL_S):
        super().__init__(daemon=True)
        self.root_pid, self.interval = root_pid, interval
        self.peaks = {}  # (pid, create_time) -> {"script": name, "kb": peak}
        self._halt = threading.Event()

    def stop(self):
        self._halt.set()
        self.join()

    def run(self):
        try:
            import psutil
        except ImportError:
            return
        try:
            root = psutil.Process(self.root_pid)
        except psutil.Error:
            return
        names = {}
        while not self._halt.is_set():
            try:
                children = root.children(recursive=True)
            except psutil.Error:
                break
            for p in children:
                key = (p.pid, getattr(p, "_create_time", None))
                if key not in names:
                    try:
                        cmd = p.cmdline()
                    except psutil.Error:
                        continue
                    script = next((os.path.basename(c) for c in cmd if ".snakemake/scripts/" in c), None)
                    names[key] = script
                if names[key] is None:
                    continue
                kb = _vmhwm_kb(p.pid)
                if kb is not None:
                    ent = self.peaks.setdefault(key, {"script": names[key], "kb": 0})
                    ent["kb"] = max(ent["kb"], kb)
            self._halt.wait(self.interval)

    def per_script(self) -> dict:
        """script file name (tmpXXXX.<name>.py -> <name>.py) -> list of peak RSS per process, MB."""
        out = {}
        for ent in self.peaks.values():
            name = ent["script"].split(".", 1)[1] if ent["script"].startswith("tmp") else ent["script"]
            out.setdefault(name, []).append(ent["kb"] * 1024 / MB)
        return out


# ---------------------------------------------------------------------------------------------
# running Snakemake
# ---------------------------------------------------------------------------------------------
def _env():
    env = dict(os.environ)
    env["OPENBLAS_NUM_THREADS"] = "1"
    return env


def snakemake(workdir: Path, args: list, log: Path, sample_memory: bool = False):
    """Run Snakemake in `workdir`; returns (wall s, combined output text, MemorySampler or None)."""
    cmd = SNAKEMAKE + args
    with open(log, "w") as fh:
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, cwd=workdir, stdout=fh, stderr=subprocess.STDOUT, env=_env())
        sampler = MemorySampler(proc.pid) if sample_memory else None
        if sampler:
            sampler.start()
        rc = proc.wait()
        wall = time.perf_counter() - t0
        if sampler:
            sampler.stop()
    text = log.read_text()
    if rc != 0:
        tail = "\n".join(text.splitlines()[-30:])
        raise RuntimeError(f"snakemake {' '.join(args)} failed (exit {rc}) in the scratch copy; log {log}:\n{tail}")
    return wall, text, sampler


def make_scratch(repo: Path, scratch: Path) -> Path:
    """Copy the workflow (not results/) to `scratch`; hard-link the checkout's simulated data if present."""
    if scratch.exists():
        shutil.rmtree(scratch)
    scratch.mkdir(parents=True)
    shutil.copy2(repo / "Snakefile", scratch / "Snakefile")
    for d in ("workflow", "config", "tests/configs"):
        if (repo / d).is_dir():
            shutil.copytree(repo / d, scratch / d, ignore=shutil.ignore_patterns("__pycache__"))
    if (repo / "data").is_dir():
        shutil.copytree(repo / "data", scratch / "data", ignore=shutil.ignore_patterns("simulated", "__pycache__"))
    sim = repo / "data" / "simulated"
    if sim.is_dir():
        (scratch / "data" / "simulated").mkdir(parents=True, exist_ok=True)
        for f in sim.iterdir():
            if f.is_file():
                try:
                    os.link(f, scratch / "data" / "simulated" / f.name)
                except OSError:
                    shutil.copy2(f, scratch / "data" / "simulated" / f.name)
    return scratch


def results_root(scratch: Path) -> Path:
    """The folder holding series/, allan/, ...: results/ (layout before per-run folders) or results/{name}/."""
    res = scratch / "results"
    if (res / "series").is_dir() or not res.is_dir():
        return res
    named = sorted(p for p in res.iterdir() if (p / "series").is_dir())
    return named[0] if named else res


def clean_outputs(scratch: Path) -> None:
    """Remove every output but the simulated recordings (data/simulated/ or results/{name}/simulated/)."""
    keep = scratch / ".keep_simulated"
    kept = []
    for sim in sorted((scratch / "results").glob("*/simulated")) if (scratch / "results").is_dir() else []:
        dest = keep / sim.parent.name
        dest.parent.mkdir(parents=True, exist_ok=True)
        sim.rename(dest)
        kept.append((dest, sim))
    for d in ("results", "logs", "benchmarks"):
        if (scratch / d).exists():
            shutil.rmtree(scratch / d)
    for dest, sim in kept:
        sim.parent.mkdir(parents=True, exist_ok=True)
        dest.rename(sim)
    if keep.exists():
        shutil.rmtree(keep)


def clean_all(scratch: Path) -> None:
    """Remove every output, the simulated recordings included (data/simulated/ and results/, logs/, benchmarks/)."""
    for d in ("results", "logs", "benchmarks", "data/simulated"):
        if (scratch / d).exists():
            shutil.rmtree(scratch / d)


def spec_file(scratch: Path):
    specs = scratch / "config" / "specs"
    if (specs / "stim300.yaml").is_file():
        return specs / "stim300.yaml"
    found = sorted(specs.glob("*.yaml")) if specs.is_dir() else []
    return found[0] if found else None


# ---------------------------------------------------------------------------------------------
# measurements derived from a finished run
# ---------------------------------------------------------------------------------------------
def collect_jobs(scratch: Path, text: str) -> list:
    """Jobs of a run with their benchmark-file numbers (when the rule has a benchmark: directive)."""
    jobs = parse_jobs(text)
    for j in jobs:
        b = j.get("benchmark")
        if b and (scratch / b).is_file():
            j["bench"] = read_benchmark_file(scratch / b)
    return jobs


def per_rule_summary(jobs: list, sampler_runs: list, scripts: dict) -> dict:
    """rule -> jobs, wall sum/median/max (s), max_rss (MB, benchmark files), VmHWM peak (MB, sampler)."""
    by_rule = {}
    for j in jobs:
        by_rule.setdefault(j["rule"], []).append(j)
    hwm = {}
    for s in sampler_runs:
        for name, vals in s.per_script().items():
            hwm.setdefault(name, []).extend(vals)
    out = {}
    for rule, js in by_rule.items():
        walls = [j["bench"]["s"] for j in js if "bench" in j]
        rss = [j["bench"]["max_rss"] * 2**20 / MB for j in js if "bench" in j and isinstance(j["bench"].get("max_rss"), float)]
        script = scripts.get(rule)
        peaks = hwm.get(script.name, []) if script else []
        out[rule] = {
            "jobs": len(js),
            # jobs that hold full-rate axis samples (one axis at a time in `reduce`)
            "axis_rule": rule in FULL_RATE_RULES or any("axis" in j.get("wildcards", {}) for j in js),
            "benchmarked_jobs": len(walls),
            "sum_s": sum(walls) if walls else float("nan"),
            "median_s": statistics.median(walls) if walls else float("nan"),
            "max_s": max(walls) if walls else float("nan"),
            "bench_max_rss_mb": max(rss) if rss else None,
            "peak_rss_mb": max(peaks) if peaks else None,
            "script": script.name if script else None,
        }
    return out


def import_costs(scripts: dict, repeats: int = 3) -> dict:
    """Fresh-interpreter start (s) and, per rule script, the time to import what it imports (s)."""
    t_start, _ = timed(lambda: subprocess.run([sys.executable, "-c", "pass"], env=_env(), check=True),
                       max(3, repeats))
    out = {"_python_start": t_start.median}
    for rule, path in scripts.items():
        if not path.is_file():
            continue
        mods = script_imports(path)
        code = ("import time\nt = time.perf_counter()\n" + "".join(f"import {m}\n" for m in mods)
                + "print(time.perf_counter() - t)")
        vals = []
        for _ in range(repeats):
            r = subprocess.run([sys.executable, "-c", code], env=_env(), capture_output=True, text=True, check=False)
            if r.returncode != 0:
                break
            vals.append(float(r.stdout.strip().splitlines()[-1]))
        out[rule] = {"modules": mods, "import_s": statistics.median(vals) if vals else None}
    return out


_NOOP_SNAKEFILE = """
rule all:
    input:
        expand("out/{i}.txt", i=range(NJOBS)),

rule noop:
    output:
        "out/{i}.txt",
    benchmark:
        "bench/{i}.tsv"
    script:
        "noop.py"
"""


def script_job_overhead(workdir: Path, n_jobs: int = 6) -> dict:
    """Wall time of a Snakemake ``script:`` job whose script only touches its output (one core, no contention):
    interpreter start, Snakemake's preamble (unpickling the ``snakemake`` object) and job bookkeeping."""
    if workdir.exists():
        shutil.rmtree(workdir)
    workdir.mkdir(parents=True)
    (workdir / "Snakefile").write_text(_NOOP_SNAKEFILE.replace("NJOBS", str(n_jobs)))
    (workdir / "noop.py").write_text('open(snakemake.output[0], "w").close()\n')
    wall, _, _ = snakemake(workdir, ["--cores", "1"], workdir / "noop.log")
    walls = [read_benchmark_file(f)["s"] for f in sorted((workdir / "bench").glob("*.tsv"))]
    shutil.rmtree(workdir)
    return {"median_job_s": statistics.median(walls) if walls else float("nan"), "jobs": len(walls),
            "wall_s": wall}


def job_start_floor(workdir: Path, n_jobs: int, cores: int, repeats: int = 3) -> dict:
    """Wall time (s, median of `repeats`) of a DAG of `n_jobs` independent ``script:`` jobs on `cores` cores,
    whose scripts do nothing but touch their output ("empty"), and whose scripts first import numpy and netCDF4
    ("numpy + netCDF4", what any job reading or writing the workflow's netCDF files needs): the least a DAG of
    that many script jobs costs, whatever the jobs compute. Alternating, in `workdir` (removed afterwards)."""
    out = {"n_jobs": n_jobs, "cores": cores}
    scripts = {"empty": 'open(snakemake.output[0], "w").close()\n',
               "numpy + netCDF4": 'import numpy, netCDF4\nopen(snakemake.output[0], "w").close()\n'}
    walls = {k: [] for k in scripts}
    for _ in range(repeats):
        for kind, text in scripts.items():
            if workdir.exists():
                shutil.rmtree(workdir)
            workdir.mkdir(parents=True)
            (workdir / "Snakefile").write_text(_NOOP_SNAKEFILE.replace("NJOBS", str(n_jobs)))
            (workdir / "noop.py").write_text(text)
            wall, _, _ = snakemake(workdir, ["--cores", str(cores), "--quiet", "all"], workdir.parent / "floor.log")
            walls[kind].append(wall)
    shutil.rmtree(workdir, ignore_errors=True)
    out.update({k: {"median_s": statistics.median(v), "min_s": min(v), "max_s": max(v)} for k, v in walls.items()})
    rows = [[k, fmt_s(v["median_s"]), f"{fmt_s(v['min_s'])}-{fmt_s(v['max_s'])}"]
            for k, v in out.items() if isinstance(v, dict)]
    out["markdown"] = (f"Floor of a DAG of {n_jobs} independent script jobs on {cores} cores (median of {repeats}):\n\n"
                       + md_table(["jobs' scripts", "wall", "min-max"], rows))
    return out


def _netcdf_dims(path: Path) -> dict:
    import netCDF4

    with netCDF4.Dataset(path) as nc:
        return {k: len(v) for k, v in nc.dimensions.items()}


FULL_RATE_RULES = {"reduce", "ingest"}  # jobs holding full-rate samples without an axis wildcard


def floor_estimate(scratch: Path, n_axes: int, repeats: int) -> dict:
    """Floor = axes x (taus x one np.sum pass + decimation + Welch), measured on an ingested axis of the run."""
    import numpy as np

    from imupipe.spectra import decimate, psd

    root = results_root(scratch)
    series = sorted((root / "series").glob("**/*.nc"))
    allan = sorted(p for p in (root / "allan").glob("*/*/*.nc"))
    if not series or not allan:
        return {"formula": "not measured: no results/series or results/allan/<dataset>/<sensor>/<axis>.nc"}
    import xarray as xr

    with xr.open_dataset(series[0]) as ds:
        name = next(v for v in ds.data_vars if ds[v].ndim == 1 and ds[v].size > 1000)
        x = np.asarray(ds[name].values, dtype=np.float64)
        rate = float(ds.attrs.get("rate_hz", 0) or 0)
        if not rate and "time" in ds.coords:
            rate = 1.0 / float(np.median(np.diff(ds["time"].values[:1000].astype(np.float64))))
    n_taus = _netcdf_dims(allan[0]).get("tau")
    t_sum, _ = timed(lambda: np.sum(x), max(21, repeats))
    low = 1.0 if rate >= 1.0 and abs(rate - round(rate)) < 1e-9 else rate
    t_dec, (x1, _) = timed(lambda: decimate(x, rate, low), max(11, repeats))
    window = min(25200.0, 0.7 * x1.size / low)
    t_psd, _ = timed(lambda: psd(x1, low, window_s=window, step_s=max(window, 36000.0 * window / 25200.0)),
                     max(11, repeats))
    per_axis = n_taus * t_sum.median + t_dec.median + t_psd.median
    total = n_axes * per_axis
    return {
        "n_axes": n_axes, "n_taus": n_taus, "n_samples": int(x.size), "rate_hz": rate,
        "sum_pass_s": t_sum.median, "decimate_s": t_dec.median, "psd_s": t_psd.median, "total_s": total,
        "raw_mb": x.size * 8 / MB,
        "formula": (f"{n_axes} axes x ({n_taus} taus x {fmt_s(t_sum.median)} np.sum pass + {fmt_s(t_dec.median)} "
                    f"decimation to {fmt(low)} Hz + {fmt_s(t_psd.median)} Welch) = {fmt_s(total)} "
                    f"(one core; axis of {x.size} samples)"),
    }


# ---------------------------------------------------------------------------------------------
def run(repo: Path, out: Path, cores: int = 2, repeats: int = 3, keep_scratch: bool = False,
        configfile: str = "config/config.yaml", spec_name: str | None = None) -> dict:
    """The DAG section of the benchmark; returns numbers and a markdown block under 'markdown'."""
    repo, out = Path(repo), Path(out)
    res = {}
    missing = [p for p in ("Snakefile", configfile) if not (repo / p).is_file()]
    if missing:
        res["skipped"] = f"not measured: {', '.join(missing)} not in the tree yet (workflow not written)"
        res["markdown"] = res["skipped"]
        return res
    scratch = make_scratch(repo, out / "dag_scratch")
    # as `make run` does (Makefile, BYTECODE): the package's bytecode compiled, whatever PYTHONDONTWRITEBYTECODE
    subprocess.run([sys.executable, "-m", "compileall", "-q", str(repo / "src" / "imupipe")], check=False)
    logs = out / "dag_logs"
    logs.mkdir(parents=True, exist_ok=True)
    base = ["--cores", str(cores), "--configfile", configfile, *RUN_FLAGS]
    res["scratch"] = "benchmarks/results/dag_scratch (copy of Snakefile, workflow/, config/, data/)"
    try:
        t_prep, text, _ = snakemake(scratch, base + ["--until", "simulate"], logs / "prepare.log")
        res["prepare_s"] = t_prep
        res["prepare_jobs"] = parse_job_stats(text).get("total", 0)
        spec = scratch / "config" / "specs" / spec_name if spec_name else spec_file(scratch)
        res["spec_file"] = str(spec.relative_to(scratch)) if spec else None
        cold, rerun = Timing(), Timing()
        all_jobs, samplers, rerun_stats, cold_stats = [], [], [], []
        floor = None
        for i in range(repeats):
            clean_outputs(scratch)
            wall, text, sampler = snakemake(scratch, base, logs / f"cold_{i}.log", sample_memory=True)
            cold.values.append(wall)
            cold_stats.append(parse_job_stats(text))
            jobs = collect_jobs(scratch, text)
            all_jobs.append(jobs)
            samplers.append(sampler)
            if floor is None:
                n_axes = len(list((results_root(scratch) / "allan").glob("*/*/*.nc")))
                floor = floor_estimate(scratch, n_axes, 5) if n_axes else {"formula": "no per-axis AV files found"}
            if spec is not None:
                with open(spec, "a") as fh:
                    fh.write(f"\n# benchmark: spec-sheet rerun {i} (values unchanged)\n")
                wall, text, _ = snakemake(scratch, base, logs / f"spec_rerun_{i}.log")
                rerun.values.append(wall)
                rerun_stats.append(parse_job_stats(text))
        t_dry, _ = timed(lambda: snakemake(scratch, base + ["-n"], logs / "dry_run.log"), min(3, repeats))
        scripts = rule_scripts(scratch)
        costs = import_costs(scripts, repeats=min(3, repeats))
        noop = script_job_overhead(out / "dag_noop")
    except RuntimeError as exc:
        res["skipped"] = f"not measured: {exc}"
        res["markdown"] = "Not measured: the workflow failed in the scratch copy.\n\n```\n" + str(exc) + "\n```"
        return res
    finally:
        if not keep_scratch and scratch.exists() and "skipped" not in res:
            shutil.rmtree(scratch)

    # aggregate: per rule over the cold runs (the job set is the same in every cold run)
    flat_jobs = [j for jobs in all_jobs for j in jobs]
    per_rule = per_rule_summary(flat_jobs, samplers, scripts)
    for r in per_rule.values():  # sums per run, not over all runs
        r["sum_s"] /= max(1, len(all_jobs))
        r["jobs"] //= max(1, len(all_jobs))
    res.update(cold=cold.to_dict(), spec_rerun=rerun.to_dict() if rerun.values else None,
               jobs_cold=cold_stats[0], jobs_rerun=rerun_stats[0] if rerun_stats else {}, per_rule=per_rule,
               dry_run=t_dry.to_dict(), floor=floor, imports=costs)
    res["spec_rerun_jobs"] = res["jobs_rerun"].get("total", 0)

    # orchestration: an empty script job (start, preamble) + the script's imports, per job, against the sum of
    # job wall times
    start = noop["median_job_s"]
    res["noop_script_job"] = noop
    orch, work = 0.0, 0.0
    orch_rows = []
    for rule, r in per_rule.items():
        imp = (costs.get(rule) or {}).get("import_s")
        if r["benchmarked_jobs"] == 0 or r["sum_s"] != r["sum_s"]:
            continue
        per_job = start + (imp or 0.0) if rule in scripts else None
        if per_job is not None:
            orch += per_job * r["jobs"]
        work += r["sum_s"]
        orch_rows.append([rule, r["jobs"], fmt_s(r["median_s"]), fmt_s(per_job) if per_job is not None else "n/a (no script)",
                          ", ".join((costs.get(rule) or {}).get("modules", [])[:6])])
    res["orchestration"] = {"empty_script_job_s": start, "start_plus_imports_s": orch, "sum_job_wall_s": work,
                            "fraction": orch / work if work else float("nan"),
                            "outside_jobs_core_s": cold.median * cores - work}

    # axis jobs: peak memory against the raw data size
    raw_mb = (floor or {}).get("raw_mb")
    axis_rules = {k: v for k, v in per_rule.items() if v["axis_rule"]}
    src, peak, prule = None, None, None
    for rule, v in axis_rules.items():
        val = v["peak_rss_mb"]
        if val is not None and (peak is None or val > peak):
            peak, prule = val, rule
    if peak is not None:
        src = f"sampled VmHWM (every {SAMPLE_INTERVAL_S * 1e3:.0f} ms) of the job's script process"
    else:
        for rule, v in axis_rules.items():
            val = v["bench_max_rss_mb"]
            if val is not None and (peak is None or val > peak):
                peak, prule = val, rule
        src = "Snakemake benchmark max_rss (sampled at 0 s then every 0.5 s)"
    if peak is not None and raw_mb:
        res["axis_memory"] = {"peak_rss_mb": peak, "raw_mb": raw_mb, "rule": prule, "source": src}

    # markdown
    lines = []
    fl = floor or {}
    lines.append(f"Scratch copy of the workflow; input data prepared by `snakemake --until simulate` "
                 f"({fmt_s(res['prepare_s'])}, {res['prepare_jobs']} jobs; not part of the cold run). "
                 f"`snakemake --cores {cores} --configfile {configfile} {' '.join(RUN_FLAGS)}` (as `make run`), "
                 f"OPENBLAS_NUM_THREADS=1, {repeats} runs each.")
    lines.append("")
    lines.append(md_table(
        ["run", "wall time", "jobs", "note"],
        [["cold (results empty, data present)", cold.cell(), res["jobs_cold"].get("total", "?"),
          f"floor {fmt_s(fl.get('total_s'))}: {fl.get('formula', '')}"],
         ["spec-sheet rerun", rerun.cell() if rerun.values else "n/a", res["spec_rerun_jobs"],
          f"after appending a comment to {res['spec_file']}; rules: "
          + ", ".join(f"{k} {v}" for k, v in res["jobs_rerun"].items() if k != "total")],
         ["dry run, nothing to do", t_dry.cell(), 0, "DAG build + up-to-date check"]],
    ))
    lines.append("")
    lines.append("Per rule (cold run; times from the `benchmark:` files, medians over jobs; memory: max over jobs "
                 "and runs):")
    lines.append("")
    lines.append(md_table(
        ["rule", "jobs", "sum of job walls", "median job", "max job", "peak RSS (VmHWM sampler)",
         "max_rss (benchmark file)", "axis job"],
        [[k, v["jobs"], fmt_s(v["sum_s"]), fmt_s(v["median_s"]), fmt_s(v["max_s"]),
          f"{fmt(v['peak_rss_mb'], 3)} MB" if v["peak_rss_mb"] else "n/a",
          f"{fmt(v['bench_max_rss_mb'], 3)} MB" if v["bench_max_rss_mb"] else "n/a (no benchmark:)",
          "yes" if v["axis_rule"] else ""]
         for k, v in sorted(per_rule.items(), key=lambda kv: -(kv[1]["sum_s"] if kv[1]["sum_s"] == kv[1]["sum_s"] else 0))],
    ))
    o = res["orchestration"]
    lines.append("")
    lines.append(
        f"Orchestration: a Snakemake `script:` job whose script does nothing takes {fmt_s(start)} "
        f"(median of {noop['jobs']} jobs, one core; a bare interpreter starts in {fmt_s(costs['_python_start'])}); "
        f"that plus the script's imports (measured in a fresh process per rule), per job, sums to "
        f"{fmt_s(o['start_plus_imports_s'])} over the jobs, "
        f"{fmt(100 * o['fraction'], 3)} % of the {fmt_s(o['sum_job_wall_s'])} sum of job wall times. "
        f"Core-seconds of the cold run outside any job (DAG build, scheduling, idle cores): "
        f"{fmt_s(o['outside_jobs_core_s'])} of {fmt_s(cold.median * cores)}.")
    lines.append("")
    lines.append(md_table(["rule", "jobs", "median job wall", "empty job + imports, per job", "script imports"],
                          orch_rows))
    res["markdown"] = "\n".join(lines)
    return res


# ---------------------------------------------------------------------------------------------
# critical path and the comparison with an earlier commit
# ---------------------------------------------------------------------------------------------
def _files(field: str) -> list:
    return [f.strip() for f in field.split(",") if f.strip()] if field else []


def critical_path(jobs: list) -> dict:
    """Longest chain of job wall times (benchmark files' s) through the job DAG of a run: the wall time of the
    run with unlimited cores (scheduling and job start outside the jobs not counted). Edges: a job's input
    files that another job of the run wrote. Jobs without a benchmark file count 0 s."""
    producer = {}
    for i, j in enumerate(jobs):
        for f in _files(j.get("output", "")):
            producer[f] = i
    finish, before = {}, {}

    def end(i):  # earliest finish of job i with unlimited cores
        if i not in finish:
            deps = {producer[f] for f in _files(jobs[i].get("input", "")) if f in producer} - {i}
            start, prev = 0.0, None
            for d in deps:
                if end(d) > start:
                    start, prev = end(d), d
            finish[i] = start + float(jobs[i].get("bench", {}).get("s", 0.0) or 0.0)
            before[i] = prev
        return finish[i]

    if not jobs:
        return {"s": 0.0, "chain": []}
    last = max(range(len(jobs)), key=lambda i: (end(i), i))  # ties: the later job (the target)
    chain, i = [], last
    while i is not None:
        chain.append(jobs[i]["rule"])
        i = before[i]
    return {"s": finish[last], "chain": chain[::-1]}


def _benchmark_config(scratch: Path, configfile: str, duration_h) -> str:
    """`configfile`, or a copy with simulation.duration_h replaced (written into the scratch copy)."""
    if duration_h is None:
        return configfile
    import yaml

    cfg = yaml.safe_load((scratch / configfile).read_text())
    if not cfg.get("simulation"):
        raise RuntimeError(f"{configfile}: --duration-h needs a simulated configuration")
    cfg["simulation"]["duration_h"] = float(duration_h)
    path = scratch / "config" / f"bench_{duration_h:g}h.yaml"
    path.write_text(yaml.safe_dump(cfg, sort_keys=False))
    return str(path.relative_to(scratch))


def _tree_env(tree_src) -> dict:
    env = _env()
    if tree_src is not None:  # the baseline's library first on the path
        env["PYTHONPATH"] = os.pathsep.join([str(tree_src)] + [p for p in [env.get("PYTHONPATH")] if p])
    return env


def _run_in(workdir: Path, args: list, log: Path, env: dict):
    with open(log, "w") as fh:
        t0 = time.perf_counter()
        rc = subprocess.run(SNAKEMAKE + args, cwd=workdir, stdout=fh, stderr=subprocess.STDOUT, env=env).returncode
        wall = time.perf_counter() - t0
    text = log.read_text()
    if rc != 0:
        raise RuntimeError(f"snakemake {' '.join(args)} failed (exit {rc}) in {workdir}; log {log}:\n"
                           + "\n".join(text.splitlines()[-30:]))
    return wall, text


def _baseline_tree(repo: Path, commit: str, where: Path) -> Path:
    """`commit` checked out in a temporary worktree at `where`, with this checkout's compiled kernel copied in
    (the baseline's library runs from its own src/ through PYTHONPATH)."""
    subprocess.run(["git", "-C", str(repo), "worktree", "add", "--detach", str(where), commit], check=True,
                   capture_output=True)
    for so in (repo / "src" / "imupipe").glob("_kernels*.so"):
        shutil.copy2(so, where / "src" / "imupipe" / so.name)
    return where


def _job_cpu(jobs: list) -> float:
    """Sum of the benchmark files' ``cpu_time`` (s) over `jobs` (:func:`collect_jobs`); jobs without one count 0."""
    total = 0.0
    for j in jobs:
        c = j.get("bench", {}).get("cpu_time")
        if isinstance(c, float) and c == c:
            total += c
    return total


def compare(repo: Path, out: Path, cores: int = 2, repeats: int = 5, baseline: str | None = "8de70ed",
            configfile: str = "config/config.yaml", duration_h=None, spec_name: str = "stim300.yaml",
            simulation_only: bool = False) -> dict:
    """Cold run, spec-sheet rerun and critical path of this checkout and (unless `baseline` is None) of the
    commit `baseline` in a temporary worktree, alternating run by run on the same machine; medians of
    `repeats` (`simulation_only`: the simulation alone, the other columns n/a). Per rule: peak RSS (benchmark files' max_rss, max over jobs and runs) against one axis's
    samples (8 bytes x samples of an ingested axis)."""
    import tempfile

    repo, out = Path(repo).resolve(), Path(out)
    out.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix="dag_compare_"))
    trees = {"this checkout": (repo, None)}
    try:
        if baseline:
            wt = _baseline_tree(repo, baseline, tmp / "baseline")
            trees[f"commit {baseline}"] = (wt, wt / "src")
        state = {}
        for label, (tree, src) in trees.items():
            scratch = make_scratch(tree, tmp / f"scratch_{len(state)}")
            cfg = _benchmark_config(scratch, configfile, duration_h)
            env = _tree_env(src)
            base = ["--cores", str(cores), "--configfile", cfg, *RUN_FLAGS]
            logs = out / "dag_logs" / f"tree_{len(state)}"
            logs.mkdir(parents=True, exist_ok=True)
            _run_in(scratch, base + ["--until", "simulate"], logs / "prepare.log", env)
            state[label] = {"scratch": scratch, "env": env, "base": base, "logs": logs, "cold": Timing(),
                            "simulation": Timing(),
                            "rerun": Timing(), "cold_cpu": Timing(), "rerun_cpu": Timing(), "sim_cpu": Timing(),
                            "critical": [], "rss": {}, "jobs": {}, "rerun_jobs": {}}
        for i in range(repeats):
            for label, st in state.items():  # alternate the trees run by run
                scratch = st["scratch"]
                clean_all(scratch)  # the simulation alone: `--until simulate` from nothing
                wall, text = _run_in(scratch, st["base"] + ["--until", "simulate"], st["logs"] / f"simulate_{i}.log",
                                     st["env"])
                st["simulation"].values.append(wall)
                st["sim_cpu"].values.append(_job_cpu(collect_jobs(scratch, text)))
                if simulation_only:
                    continue
                clean_outputs(scratch)
                wall, text = _run_in(scratch, st["base"], st["logs"] / f"cold_{i}.log", st["env"])
                st["cold"].values.append(wall)
                st["jobs"] = parse_job_stats(text)
                jobs = collect_jobs(scratch, text)
                st["critical"].append(critical_path(jobs))
                st["cold_cpu"].values.append(_job_cpu(jobs))
                for j in jobs:
                    rss = j.get("bench", {}).get("max_rss")
                    if isinstance(rss, float):
                        st["rss"][j["rule"]] = max(st["rss"].get(j["rule"], 0.0), rss * 2**20 / MB)
                if "axis_mb" not in st:
                    series = sorted((results_root(scratch) / "series").glob("*/*/*.nc"))
                    st["axis_mb"] = 8 * _netcdf_dims(series[0]).get("sample", 0) / MB if series else None
                spec = scratch / "config" / "specs" / spec_name
                with open(spec, "a") as fh:
                    fh.write(f"\n# benchmark: spec-sheet rerun {i} (values unchanged)\n")
                wall, text = _run_in(scratch, st["base"], st["logs"] / f"spec_rerun_{i}.log", st["env"])
                st["rerun"].values.append(wall)
                st["rerun_jobs"] = parse_job_stats(text)
                st["rerun_cpu"].values.append(_job_cpu(collect_jobs(scratch, text)))
    finally:
        if baseline and (tmp / "baseline").exists():
            subprocess.run(["git", "-C", str(repo), "worktree", "remove", "--force", str(tmp / "baseline")],
                           check=False, capture_output=True)
        shutil.rmtree(tmp, ignore_errors=True)

    res = {"cores": cores, "repeats": repeats, "configfile": configfile, "duration_h": duration_h, "trees": {}}
    rows, mem_rows = [], []
    for label, st in state.items():
        crit = Timing([c["s"] for c in st["critical"]])
        st.setdefault("axis_mb", None)
        chain = max(st["critical"], key=lambda c: c["s"])["chain"] if st["critical"] else []
        res["trees"][label] = {"cold": st["cold"].to_dict(), "spec_rerun": st["rerun"].to_dict(),
                               "simulation": st["simulation"].to_dict(),
                               "simulation_job_cpu": st["sim_cpu"].to_dict(), "cold_job_cpu": st["cold_cpu"].to_dict(),
                               "spec_rerun_job_cpu": st["rerun_cpu"].to_dict(),
                               "critical_path": crit.to_dict(), "critical_chain": chain, "jobs_cold": st["jobs"],
                               "jobs_rerun": st["rerun_jobs"], "peak_rss_mb": st["rss"], "axis_mb": st["axis_mb"]}
        rows.append([label, st["simulation"].cell(), st["cold"].cell(), st["rerun"].cell(), crit.cell(),
                     fmt(crit.median / st["cold"].median, 3) if st["critical"] else "n/a", st["sim_cpu"].cell(),
                     st["cold_cpu"].cell(),
                     st["rerun_cpu"].cell(),
                     st["jobs"].get("total", "?"),
                     " -> ".join(dict.fromkeys(chain))])
        for rule, mb in sorted(st["rss"].items()):
            ax = st["axis_mb"]
            mem_rows.append([label, rule, f"{fmt(mb, 3)} MB", fmt(ax, 3) if ax else "n/a",
                             fmt(mb / ax, 3) if ax else "n/a"])
    dur = f", simulation.duration_h = {duration_h:g}" if duration_h is not None else ""
    lines = [f"`snakemake --cores {cores} --configfile {configfile}{dur} {' '.join(RUN_FLAGS)}` in scratch copies, "
             f"simulation: `--until simulate` from nothing; cold run: with the simulated recordings present; "
             f"{repeats} runs per tree, alternating; medians "
             "[min-max]. Critical path: longest chain of job wall times (benchmark files) = wall time with unlimited "
             "cores. Job CPU: the sum of the benchmark files' cpu_time over the run's jobs (steadier than wall time "
             "on a shared machine).", "",
             md_table(["tree", "simulation", "cold run", "spec-sheet rerun", "critical path", "critical / cold",
                       "simulation job CPU", "cold job CPU", "rerun job CPU", "jobs", "chain"],
                      rows), "",
             "Peak RSS per rule (benchmark files' max_rss, max over jobs and runs; sampled at 0 s then every 0.5 s, so "
             "sub-second jobs may show less than their peak) against one axis's samples:", "",
             md_table(["tree", "rule", "peak RSS", "one axis (MB)", "peak / axis"], mem_rows)]
    res["markdown"] = "\n".join(lines)
    return res


def main(argv=None) -> int:
    """Command line: ``python benchmarks/dag.py [--repo .] [--out benchmarks/results] [--cores 2] [--repeats 5]
    [--baseline 8de70ed | --baseline none] [--duration-h H] [--detail]``."""
    import argparse
    import json

    here = Path(__file__).resolve().parent
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("--repo", type=Path, default=here.parent, help="checkout holding Snakefile (default: this one)")
    ap.add_argument("--out", type=Path, default=here / "results", help="output folder (default benchmarks/results)")
    ap.add_argument("--cores", type=int, default=2, help="snakemake --cores (default 2)")
    ap.add_argument("--repeats", type=int, default=5, help="cold runs and spec reruns per tree (default 5)")
    ap.add_argument("--baseline", default="8de70ed",
                    help="git commit run alternately in a temporary worktree (default 8de70ed; 'none': this tree only)")
    ap.add_argument("--duration-h", type=float, default=None,
                    help="override simulation.duration_h (h) of the config, e.g. 40 for the memory scaling")
    ap.add_argument("--detail", action="store_true",
                    help="the former single-tree report instead (per-rule walls, memory sampler, import costs)")
    ap.add_argument("--configfile", default="config/config.yaml", help="relative to the repo")
    ap.add_argument("--spec", default=None, help="spec sheet under config/specs/ to touch (default: found)")
    ap.add_argument("--keep-scratch", action="store_true", help="keep <out>/dag_scratch")
    ap.add_argument("--simulation-only", action="store_true",
                    help="time the simulation alone (`--until simulate` from nothing), no cold run or rerun")
    ap.add_argument("--floor-jobs", type=int, default=None, metavar="N",
                    help="instead: the wall time of N empty script jobs, and of N importing numpy and netCDF4, on "
                         "--cores (job_start_floor; --repeats runs each)")
    args = ap.parse_args(argv)
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    args.out.mkdir(parents=True, exist_ok=True)
    if args.floor_jobs:
        res = job_start_floor(args.out / "dag_floor", args.floor_jobs, args.cores, args.repeats)
        print(res["markdown"])
        return 0
    if args.detail:
        res = run(args.repo, args.out, cores=args.cores, repeats=args.repeats, keep_scratch=args.keep_scratch,
                  configfile=args.configfile, spec_name=args.spec)
    else:
        baseline = None if str(args.baseline).lower() == "none" else args.baseline
        res = compare(args.repo, args.out, cores=args.cores, repeats=args.repeats, baseline=baseline,
                      configfile=args.configfile, duration_h=args.duration_h,
                      spec_name=args.spec or "stim300.yaml", simulation_only=args.simulation_only)
    print(res["markdown"])
    (args.out / "dag.md").write_text(res["markdown"] + "\n")
    (args.out / "dag.json").write_text(json.dumps(res, indent=1, default=str))
    return 1 if "skipped" in res and "not in the tree" not in res["skipped"] else 0


if __name__ == "__main__":
    sys.exit(main())
