"""The workflow through a real SLURM cluster gives the results of a local run.

A one-node cluster on localhost (munged, slurmctld, slurmd; tests/slurm/start_cluster.sh) runs
tests/configs/tiny.yaml through ``--profile workflow/profiles/slurm`` with snakemake-executor-plugin-slurm:
every job is an sbatch job. The same config runs once locally (``--cores 2``), each run in a
``--directory`` of its own. Every .nc and .yaml file the two runs write must be present in both and equal:
netCDF files by variables, coordinates, values (bit for bit: same code, same machine, one BLAS thread, seeded
simulation, so any difference is the executor's doing) and attributes; YAML files by their parsed content,
with wall-clock fields left out. Nothing here names a rule or a result path: the comparison walks the trees.

Run it with ``make test-slurm`` (installs Debian's slurm-wlm and munge when missing, needs root) or
``pytest -m slurm tests/test_slurm.py`` where the daemons are installed. It skips with the reason where the
plugin, the SLURM commands or munge are missing, or where the daemons do not start; the daemons it started
are stopped afterwards, also when the test fails.
"""

from __future__ import annotations

import importlib.util
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
TINY = ROOT / "tests" / "configs" / "tiny.yaml"
PROFILE = "workflow/profiles/slurm"  # relative to ROOT, as a user types it
START = ROOT / "tests" / "slurm" / "start_cluster.sh"
STOP = ROOT / "tests" / "slurm" / "stop_cluster.sh"
# the daemons are in /usr/sbin on Debian, which a non-login PATH may lack
SEARCH_PATH = os.pathsep.join([os.environ.get("PATH", ""), "/usr/sbin", "/usr/local/sbin"])
COMMANDS = ("munged", "slurmctld", "slurmd", "sbatch", "squeue", "scontrol", "sinfo", "srun")
# directories of a run that hold Snakemake's bookkeeping and job logs, not results
NOT_RESULTS = {".snakemake", "logs", "benchmarks"}
# YAML keys / netCDF attributes that hold wall-clock readings, not results: the LP's solve_time_s today, and
# the usual names of such fields so that adding one does not break the comparison. Explicit names, not any
# "*time*": a correlation time is a result.
TIMING = re.compile(r"^(solve_time|wall_time|cpu_time|elapsed|runtime|timestamp|created|date_created|history)"
                    r"(_s|_seconds)?$")
# one job's budget: the tiny run takes ~12 s locally; through SLURM each of ~18 jobs adds a submission and a
# status poll, so minutes, not hours
TIMEOUT_S = 900


def _missing() -> str | None:
    if importlib.util.find_spec("snakemake") is None:
        return "snakemake not installed (pip install -e '.[test]')"
    if importlib.util.find_spec("snakemake_executor_plugin_slurm") is None:
        return "snakemake-executor-plugin-slurm not installed (pip install -e '.[test]')"
    absent = [c for c in COMMANDS if shutil.which(c, path=SEARCH_PATH) is None]
    if absent:
        return (f"SLURM/munge commands not found: {', '.join(absent)} "
                "(apt-get install slurm-wlm munge, or make test-slurm)")
    return None


MISSING = _missing()


@pytest.fixture(scope="module")
def cluster():
    """A running one-node cluster: the environment (SLURM_CONF, PATH) that reaches it."""
    if MISSING:
        pytest.skip(MISSING)
    # a short path: munge's socket path must fit in a Unix socket address (108 bytes)
    home = Path(tempfile.mkdtemp(prefix="imupipe-slurm-"))
    env = {**os.environ, "PATH": SEARCH_PATH}
    try:
        started = subprocess.run(["bash", str(START), str(home)], capture_output=True, text=True, env=env,
                                 timeout=120)
        if started.returncode != 0:
            pytest.skip(f"the one-node SLURM cluster did not start (start_cluster.sh exit "
                        f"{started.returncode}):\n{started.stderr[-3000:]}")
        yield {**env, "SLURM_CONF": str(home / "slurm.conf")}
    finally:
        subprocess.run(["bash", str(STOP), str(home)], capture_output=True, text=True, env=env, timeout=120)
        shutil.rmtree(home, ignore_errors=True)


def _snakemake(workdir: Path, *args: str, env: dict) -> tuple[subprocess.CompletedProcess, float]:
    """Run the workflow on tests/configs/tiny.yaml in WORKDIR from the project root: (process, wall s)."""
    cmd = [sys.executable, "-m", "snakemake", "--snakefile", str(ROOT / "Snakefile"),
           "--directory", str(workdir), "--configfile", str(TINY), *args]
    start = time.perf_counter()
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, env=env, timeout=TIMEOUT_S)
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        logs = ""
        for log in sorted((workdir / "logs").rglob("*.log"))[-5:]:
            logs += f"\n---- {log.relative_to(workdir)}\n{log.read_text()[-1500:]}"
        raise AssertionError(f"snakemake {' '.join(args)} failed ({proc.returncode}):\n"
                             f"{proc.stdout[-3000:]}\n{proc.stderr[-5000:]}{logs}")
    return proc, wall


def result_files(workdir: Path) -> set[Path]:
    """Every .nc and .yaml file a run wrote under WORKDIR, relative to it (bookkeeping and logs left out)."""
    out = set()
    for path in workdir.rglob("*"):
        rel = path.relative_to(workdir)
        if path.suffix in (".nc", ".yaml") and path.is_file() and rel.parts[0] not in NOT_RESULTS:
            out.add(rel)
    return out


def _drop_timing(value):
    """VALUE (parsed YAML) without the mapping entries whose key names a wall-clock reading (TIMING)."""
    if isinstance(value, dict):
        return {k: _drop_timing(v) for k, v in value.items() if not (isinstance(k, str) and TIMING.search(k))}
    if isinstance(value, list):
        return [_drop_timing(v) for v in value]
    return value


def yaml_differences(a, b, where: str = "") -> list[str]:
    """Where two parsed YAML documents differ: exact equality, NaN equal to NaN (a NaN is a result too)."""
    if isinstance(a, dict) and isinstance(b, dict):
        diffs = [f"{where}/{k}: only in one run" for k in set(a) ^ set(b)]
        for k in set(a) & set(b):
            diffs += yaml_differences(a[k], b[k], f"{where}/{k}")
        return diffs
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{where}: {len(a)} against {len(b)} items"]
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in yaml_differences(x, y, f"{where}[{i}]")]
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return []
    return [] if type(a) is type(b) and a == b else [f"{where}: {a!r} != {b!r}"]


def _attrs(attrs: dict) -> dict:
    return {k: v for k, v in attrs.items() if not TIMING.search(k)}


def netcdf_differences(path_a: Path, path_b: Path) -> list[str]:
    """Where two netCDF files differ: variable and coordinate names, dims, dtypes, values (bit for bit, NaN
    equal to NaN) and attributes of the file and of every variable."""
    import xarray as xr

    with xr.open_dataset(path_a) as a, xr.open_dataset(path_b) as b:
        diffs = []
        if _attrs(a.attrs).keys() != _attrs(b.attrs).keys() or yaml_differences(
            {k: np.asarray(v).tolist() for k, v in _attrs(a.attrs).items()},
            {k: np.asarray(v).tolist() for k, v in _attrs(b.attrs).items()},
        ):
            diffs.append(f"file attributes: {a.attrs} != {b.attrs}")
        names_a, names_b = set(a.variables), set(b.variables)
        if names_a != names_b:
            diffs.append(f"variables only in one run: {sorted(names_a ^ names_b)}")
        for name in sorted(names_a & names_b):
            va, vb = a[name], b[name]
            if va.dims != vb.dims or va.dtype != vb.dtype:
                diffs.append(f"{name}: dims/dtype {va.dims} {va.dtype} != {vb.dims} {vb.dtype}")
                continue
            if not np.array_equal(va.values, vb.values, equal_nan=va.dtype.kind in "fc"):
                diffs.append(f"{name}: values differ")
            if yaml_differences({k: np.asarray(v).tolist() for k, v in _attrs(va.attrs).items()},
                                {k: np.asarray(v).tolist() for k, v in _attrs(vb.attrs).items()}):
                diffs.append(f"{name}: attributes {va.attrs} != {vb.attrs}")
        return diffs


def compare_runs(local: Path, other: Path) -> list[str]:
    """Every difference between the .nc and .yaml results of two runs (empty: the runs agree)."""
    files_local, files_other = result_files(local), result_files(other)
    diffs = [f"{f}: only in the local run" for f in sorted(files_local - files_other)]
    diffs += [f"{f}: only in the SLURM run" for f in sorted(files_other - files_local)]
    for rel in sorted(files_local & files_other):
        if rel.suffix == ".nc":
            found = netcdf_differences(local / rel, other / rel)
        else:
            found = yaml_differences(_drop_timing(yaml.safe_load((local / rel).read_text())),
                                     _drop_timing(yaml.safe_load((other / rel).read_text())))
        diffs += [f"{rel}: {d}" for d in found]
    return diffs


# ---- the comparison itself must be able to fail (no cluster needed) ----

def _write_pair(tmp_path: Path, change) -> tuple[Path, Path]:
    import xarray as xr

    a, b = tmp_path / "a", tmp_path / "b"
    for run in (a, b):
        (run / "results" / "x").mkdir(parents=True)
        (run / ".snakemake").mkdir()
        (run / ".snakemake" / "noise.yaml").write_text(f"run: {run.name}\n")  # bookkeeping: not compared
    ds = xr.Dataset({"psd": ("frequency", np.array([1.0, np.nan, 3.0]), {"units": "(rad/s)^2/Hz"})},
                    coords={"frequency": ("frequency", [0.1, 0.2, 0.3], {"units": "Hz"})},
                    attrs={"sidedness": "two-sided"})
    doc = {"bounded": True, "margin": 1.25, "solve_time_s": 0.03, "correlation_time_s": 300.0,
           "curve": [1.0, float("nan")]}
    ds.to_netcdf(a / "results" / "x" / "s.nc")
    (a / "results" / "x" / "b.yaml").write_text(yaml.safe_dump(doc))
    ds, doc = change(ds.copy(deep=True), dict(doc))
    ds.to_netcdf(b / "results" / "x" / "s.nc")
    (b / "results" / "x" / "b.yaml").write_text(yaml.safe_dump(doc))
    return a, b


def test_comparison_accepts_equal_runs_and_timing_fields(tmp_path):
    def only_timing(ds, doc):
        doc["solve_time_s"] = 99.0
        return ds, doc

    assert compare_runs(*_write_pair(tmp_path, only_timing)) == []


@pytest.mark.parametrize(
    "what", ["value", "nc_attr", "yaml_number", "yaml_key", "yaml_result_time", "missing_file"]
)
def test_comparison_finds_each_kind_of_difference(tmp_path, what):
    def change(ds, doc):
        if what == "value":
            ds["psd"].values[0] = np.nextafter(1.0, 2.0)  # one ulp
        elif what == "nc_attr":
            ds["psd"].attrs["units"] = "(rad/s)^2"
        elif what == "yaml_number":
            doc["margin"] = 1.2500000001
        elif what == "yaml_key":
            doc["extra"] = 1
        elif what == "yaml_result_time":  # a time that is a result is compared
            doc["correlation_time_s"] = 301.0
        return ds, doc

    a, b = _write_pair(tmp_path, change)
    if what == "missing_file":
        (b / "results" / "x" / "s.nc").unlink()
    assert compare_runs(a, b), what


# ---- the real thing ----

@pytest.mark.slurm
@pytest.mark.slow  # minutes and daemons: not in the default suite; `make test-slurm` selects it by -m slurm
def test_slurm_run_equals_local_run(cluster, tmp_path):
    env = {**cluster, "OPENBLAS_NUM_THREADS": "1", "MPLBACKEND": "Agg"}
    local, slurm = tmp_path / "local", tmp_path / "slurm"
    _, wall_local = _snakemake(local, "--cores", "2", env=env)
    proc, wall_slurm = _snakemake(
        slurm,
        "--profile", PROFILE,
        # settings of this test cluster, not of the profile: no accounting database, so no account to look
        # up (sacctmgr) and job states from squeue, which keeps finished jobs for MinJobAge = 1 h
        "--slurm-no-account",
        "--slurm-status-command", "squeue",
        # first status poll 2 s after submission instead of 40 s (the jobs take seconds)
        "--slurm-init-seconds-before-status-checks", "2",
        "--latency-wait", "5",
        env=env,
    )
    print(f"wall time: local {wall_local:.1f} s, SLURM {wall_slurm:.1f} s")
    out = proc.stdout + proc.stderr
    # the jobs really went through sbatch (the plugin logs the SLURM job id of every submission)
    submitted = re.findall(r"has been submitted with SLURM jobid (\d+)", out)
    assert submitted, out[-3000:]
    files = result_files(local)
    assert any(f.suffix == ".nc" for f in files) and any(f.suffix == ".yaml" for f in files), sorted(files)
    diffs = compare_runs(local, slurm)
    assert not diffs, "\n".join(diffs[:50])
