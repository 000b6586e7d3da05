"""Helpers for the end-to-end workflow tests: run Snakemake on a configuration, read a dry run's job table,
write a changed tiny configuration. The shared run of tests/configs/tiny.yaml is the session fixture
`tiny_run` in conftest.py."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
TINY = ROOT / "tests" / "configs" / "tiny.yaml"
SNAKEMAKE = [sys.executable, "-m", "snakemake", "--snakefile", str(ROOT / "Snakefile"), "--cores", "2"]
# the rules downstream of the spec sheet: a change of the sheet re-runs these and nothing else
SPEC_RULES = {"bound_axis", "bound", "verify", "contract", "kf", "kalibr", "figures", "tables", "integrity",
              "summary", "report_file", "all"}
# results/{name}/ and logs/{name}/ of tests/configs/tiny.yaml
RES, LOG = "results/tiny", "logs/tiny"
# what the checkout copy needs to run (imupipe itself is installed)
CHECKOUT = ("Snakefile", "workflow", "config")
ENV = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "MPLBACKEND": "Agg"}


def snakemake(workdir, *args, config=TINY, check=True, snakefile=None, **kw):
    """Run Snakemake in `workdir` (--directory) with the repository's Snakefile, or with `snakefile` (a copy of
    the checkout, run from its own folder)."""
    base = SNAKEMAKE if snakefile is None else [*SNAKEMAKE[:3], "--snakefile", str(snakefile), *SNAKEMAKE[5:]]
    cmd = [*base, "--directory", str(workdir), "--configfile", str(config), *args]
    proc = subprocess.run(cmd, capture_output=True, text=True, env=ENV, **kw)
    if check and proc.returncode != 0:
        raise AssertionError(f"snakemake failed ({proc.returncode}):\n{proc.stdout[-3000:]}\n{proc.stderr[-5000:]}")
    return proc


def dry_run_jobs(workdir, *args, config=TINY, snakefile=None):
    """Rule -> job count from a dry run's "Job stats" table."""
    if snakefile is None and (Path(workdir) / "Snakefile").is_file():
        snakefile = Path(workdir) / "Snakefile"
    out = snakemake(workdir, "-n", *args, config=config, snakefile=snakefile).stdout
    counts = {}
    if "Job stats:" in out:
        table = out.split("Job stats:", 1)[1]
        for line in table.splitlines()[3:]:
            m = re.match(r"^(\w+)\s+(\d+)$", line.strip())
            if not m:
                break
            if m.group(1) != "total":
                counts[m.group(1)] = int(m.group(2))
    return counts


def tiny_config(tmp_path, **changes):
    cfg = yaml.safe_load(TINY.read_text())
    for key, value in changes.items():
        cfg[key] = value
    path = tmp_path / "config.yaml"
    path.write_text(yaml.safe_dump(cfg))
    return path


def copy_run(work, dest):
    """Copy a run's folder `work` to `dest`, modification times kept (so the copy is as up to date as the run) and
    symbolic links as links. Snakemake's lock files are left out: a dry run of the shared run on another pytest
    worker takes and removes them while the copy is made."""
    def locks(folder, names):
        return ["locks"] if Path(folder).name == ".snakemake" else []

    return Path(shutil.copytree(work, dest, symlinks=True, ignore=locks))


def copy_checkout(dest):
    """Copy what a run needs of the checkout (Snakefile, workflow/, config/) into `dest`."""
    dest.mkdir(parents=True, exist_ok=True)
    for name in CHECKOUT:
        (shutil.copytree if (ROOT / name).is_dir() else shutil.copy2)(ROOT / name, dest / name)
    return dest


def stage_script(name: str):
    """The workflow script workflow/scripts/<name>.py as a module, to call its `main` (its Snakemake entry point runs
    only as __main__)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(f"stage_{name}", ROOT / "workflow" / "scripts" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod
