"""Interrupt and resume (imupipe.cli._call): SIGINT to a real `imupipe run` gives one line and exit 130, and the
same command run again finishes with the outputs of an uninterrupted run."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from imupipe.cli import INTERRUPTED_EXIT, INTERRUPTED_MESSAGE

ROOT = Path(__file__).resolve().parents[1]
TINY = ROOT / "tests" / "configs" / "tiny.yaml"
ENV = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "MPLBACKEND": "Agg"}
#: the run's result kinds compared with the uninterrupted run (numbers the workflow computes; logs, benchmarks,
#: the report and figures carry times or renderer bytes)
COMPARED = ("identify", "bound", "contract", "kf", "verify", "stationarity", "psd", "allan")


def _files(results: Path) -> dict:
    return {p.relative_to(results): p for kind in COMPARED for p in sorted((results / kind).rglob("*"))
            if p.is_file() and p.suffix in (".yaml", ".nc")}


def _same(a: Path, b: Path) -> bool:
    if a.suffix == ".yaml":
        import yaml

        return yaml.safe_load(a.read_text()) == yaml.safe_load(b.read_text())
    import netCDF4
    import numpy as np

    with netCDF4.Dataset(a) as da, netCDF4.Dataset(b) as db:
        if {k: str(da.getncattr(k)) for k in da.ncattrs()} != {k: str(db.getncattr(k)) for k in db.ncattrs()}:
            return False
        return set(da.variables) == set(db.variables) and all(_equal(da[v][:], db[v][:]) for v in da.variables)


def _equal(x, y) -> bool:
    """Arrays equal element by element, NaN equal to NaN where the dtype holds NaN (a label variable of strings
    cannot: np.array_equal(equal_nan=True) raises on it)."""
    import numpy as np

    x, y = np.asarray(x), np.asarray(y)
    floats = x.dtype.kind in "fc" and y.dtype.kind in "fc"
    return bool(np.array_equal(x, y, equal_nan=floats))


def _config(tmp_path: Path) -> Path:
    import shutil

    import yaml

    shutil.copytree(ROOT / "config" / "specs", tmp_path / "specs")
    cfg = yaml.safe_load(TINY.read_text())
    cfg["spec_dir"] = str(tmp_path / "specs")
    config = tmp_path / "config.yaml"
    config.write_text(yaml.safe_dump(cfg))
    return config


@pytest.mark.slow
def test_sigint_then_rerun_equals_an_uninterrupted_run(tmp_path, tiny_run):
    pytest.importorskip("snakemake")
    config = _config(tmp_path)
    work = tmp_path / "work"
    work.mkdir()
    cmd = [sys.executable, "-m", "imupipe", "run", str(config), "--cores", "2", "--directory", str(work)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV)
    deadline = time.monotonic() + 600
    # interrupt mid-run: once the first per-axis PSDs exist (jobs of later stages are still to come or running)
    while time.monotonic() < deadline and proc.poll() is None:
        if any((work / "results" / "tiny" / "psd").rglob("*.nc")):
            break
        time.sleep(0.5)
    assert proc.poll() is None, "the run ended before it could be interrupted"
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == INTERRUPTED_EXIT, err[-3000:]
    assert INTERRUPTED_MESSAGE in err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err
    assert not (work / "results" / "tiny" / "summary.md").exists()  # it did stop before the end
    # the same command again: resumes (no extra flag), exit 0
    again = subprocess.run(cmd, capture_output=True, text=True, env=ENV, timeout=1200)
    assert again.returncode == 0, again.stderr[-3000:]
    assert "IncompleteFilesException" not in again.stderr
    mine, ref = _files(work / "results" / "tiny"), _files(tiny_run[0] / "results" / "tiny")
    assert mine.keys() == ref.keys() and mine
    differ = [str(k) for k in mine if not _same(mine[k], ref[k])]
    assert not differ, differ
