"""End to end: bad inputs and faults in the workflow (issue 19), fewer axes, nothing stale.

Every bad dataset sits beside one good dataset in a single `--keep-going` run; each assertion is per dataset:
the run's exit code, a message naming the file and the column/row (or the config key) and what was expected,
no output of the failing dataset under results/, the good dataset's per-axis results present. Problems of
the sheet or of a record against the config stop the run at start-up (before any job), naming the line or
the config key, and leave nothing. docs/inputs.md keeps the catalogue of classes and the test of each.
"""

from __future__ import annotations

import gzip
import hashlib
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

pytest.importorskip("snakemake", reason="the workflow tests need snakemake (pip install -e '.[test]')")

from workflow_helpers import TINY, copy_checkout, snakemake  # noqa: E402

RATE_HZ = 10.0
N = 24000  # 40 min at 10 Hz: four 600 s Welch windows (psd.window_s below), 2400 decimated samples at 1 Hz
NAMES = ["t", "wx", "wy", "wz", "ax", "ay", "az"]
CHANNELS = dict(zip(["gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"], NAMES[1:]))
SHEET_COLUMNS = ["dataset", "path", "format", "rate_hz", "gyro_unit", "accel_unit", *CHANNELS, "time_column",
                 "gap_policy", "fill_max_samples"]


def _table(seed):
    """Seven columns: time (s), gyro (rad/s, white, 1e-3), accel (m/s^2, white 1e-2, gravity on z)."""
    rng = np.random.default_rng(seed)
    gyro = rng.normal(0.0, 1e-3, (N, 3))
    accel = rng.normal(0.0, 1e-2, (N, 3)) + [0.0, 0.0, -9.80665]
    return np.column_stack([np.arange(N) / RATE_HZ, gyro, accel])


def _csv(path, table, header=NAMES):
    lines = [",".join(header)] + [",".join(f"{v:.17g}" for v in row) for row in table]
    path.write_text("\n".join(lines) + "\n")
    return path


def _nc(path, table, gyro_units="rad s-1"):
    import netCDF4

    with netCDF4.Dataset(path, "w") as ds:
        ds.createDimension("time", len(table))
        for j, name in enumerate(NAMES):
            v = ds.createVariable(name, "f8", ("time",))
            v[:] = table[:, j]
            v.units = "s" if j == 0 else gyro_units if j <= 3 else "m s-2"
    return path


def _config(work, name, sheet, sensors=("gyro", "accel"), specs=("stim300",), file=None):
    cfg = yaml.safe_load(TINY.read_text())
    cfg.update(name=name, datasets=sheet, simulation=None, sensors=list(sensors), specs=list(specs))
    cfg["psd"].update(window_s=600.0, step_s=300.0)
    path = work / (file or f"{name}.yaml")
    path.write_text(yaml.safe_dump(cfg))
    return path


def _sheet(work, rows, name="datasets.tsv"):
    """A dataset sheet of `rows` (dicts; paths relative to the checkout copy, the repository root)."""
    cols = [c for c in SHEET_COLUMNS if any(c in r for r in rows)]
    lines = ["\t".join(cols)] + ["\t".join(str(r.get(c, "")) for c in cols) for r in rows]
    (work / name).write_text("\n".join(lines) + "\n")
    return name


def _row(dataset, path, **cells):
    row = {"dataset": dataset, "path": path, "rate_hz": RATE_HZ, "gyro_unit": "rad/s", "accel_unit": "m/s^2",
           "time_column": "t", **CHANNELS}
    row.update(cells)
    return {k: v for k, v in row.items() if v is not None}


def _outputs_of(work, run, dataset):
    """Files under results/{run}/ belonging to `dataset` (a path component of that name)."""
    return [p for p in (work / "results" / run).rglob("*") if p.is_file() and dataset in p.relative_to(work).parts]


# -------------------------------------------------------------------------------------------------
# the bad-input table: one run, one good dataset, one bad dataset per row
# -------------------------------------------------------------------------------------------------
def _bad_csv_value(value, column, row):
    def make(data, t):
        t = t.copy()
        t[row, column] = value
        return _csv(data / f"v{column}_{row}.csv", t).name, {}

    return make


def _subnormal(data, t):
    t = t.copy()
    t[:, 1:4] *= 1e-308
    return _csv(data / "subnormal.csv", t).name, {}


def _numeric_header(data, t):  # pandas.to_csv(index=False) of an unnamed frame; the sheet names columns
    return _csv(data / "numhead.csv", t, header=[str(i) for i in range(7)]).name, {}


def _nc_units(data, t):  # the file says deg s-1, the sheet rad/s
    return _nc(data / "degunits.nc", t, gyro_units="deg s-1").name, {"format": "netcdf", "time_column": None}


def _fifo(data, t):
    os.mkfifo(data / "fifo.npy")
    return "fifo.npy", {"format": "npy", "time_column": None, **{k: i for i, k in enumerate(CHANNELS)}}


def _loop(data, t):
    (data / "loop_a.csv").symlink_to(data / "loop_b.csv")
    (data / "loop_b.csv").symlink_to(data / "loop_a.csv")
    return "loop_a.csv", {}


def _gzip(data, t):
    raw = _csv(data / "plain_tmp.csv", t).read_bytes()
    (data / "packed.csv").write_bytes(gzip.compress(raw))
    (data / "plain_tmp.csv").unlink()
    return "packed.csv", {}


def _missing(data, t):
    return "absent.csv", {}


def _truncated(data, t):
    path = _csv(data / "truncated.csv", t)
    text = path.read_text().splitlines()
    text[101] = ",".join(text[101].split(",")[:4])  # row 100 (0-based) loses its last three cells
    path.write_text("\n".join(text) + "\n")
    return path.name, {}


# dataset, maker, message regex (the file and its column/row or line, what was expected)
BAD = [
    ("gyro_huge", _bad_csv_value(1e300, 2, 17),
     r"v2_17\.csv: gyro_y \(column 'wy'\) has a sample of 1e\+300 rad/s at row 17 \(0-based\), line 19 .*\|x\| <= 1000 rad/s"),
    ("gyro_inf", _bad_csv_value(np.inf, 1, 5), r"v1_5\.csv: gyro_x \(column 'wx'\) has a non-finite sample \(inf\) at row 5"),
    ("subnormal", _subnormal, r"subnormal\.csv: gyro_x \(column 'wx'\): the largest sample is .*expected a channel scale >= 1e-150"),
    ("numhead", _numeric_header, r"numhead\.csv: gyro_x column 'wx' not found; available: '0', '1'"),
    ("degunits", _nc_units, r"degunits\.nc: gyro_unit = 'rad/s' in the sheet but variable 'wx' has units 'deg s-1'"),
    ("fifo", _fifo, r"fifo\.npy: is a FIFO \(named pipe\), not a regular file; refused"),
    ("symloop", _loop, r"loop_a\.csv: symbolic link loop"),
    ("gzipped", _gzip, r"packed\.csv: is gzip-compressed, not a text file"),
    ("absent", _missing, r"absent\.csv"),
    ("truncated", _truncated, r"truncated\.csv.*line 102"),
]


DROPS = [1000, 5000, 9000, 13000, 17000]  # 0-based rows dropped from the drops.csv record


@pytest.fixture(scope="module")
def fault_run(tmp_path_factory):
    """One --keep-going run: the good dataset (netCDF, read one channel at a time) and every BAD row."""
    work = copy_checkout(tmp_path_factory.mktemp("faults") / "checkout")
    data = work / "data_faults"
    data.mkdir()
    good = _table(1)
    _nc(data / "good.nc", good)
    # a second good dataset: a text log with five single-sample drops, filled (gap_policy fill)
    _csv(data / "drops.csv", np.delete(_table(8), DROPS, axis=0))
    rows = [_row("good", "data_faults/good.nc", format="netcdf", time_column=None),
            _row("drops+1.v2", "data_faults/drops.csv", gap_policy="fill", fill_max_samples=1)]
    for name, make, _ in BAD:
        path, cells = make(data, good)
        rows.append(_row(name, f"data_faults/{path}", **cells))
    config = _config(work, "faults", _sheet(work, rows))
    proc = snakemake(work, "--keep-going", config=config, snakefile=work / "Snakefile", check=False, timeout=600)
    return work, proc


def test_fault_run_fails(fault_run):
    _, proc = fault_run
    assert proc.returncode == 1, proc.stderr[-3000:]


@pytest.mark.parametrize("dataset, message", [(b[0], b[2]) for b in BAD], ids=[b[0] for b in BAD])
def test_bad_dataset_fails_alone_naming_the_culprit(fault_run, dataset, message):
    import re

    work, proc = fault_run
    log = work / "logs" / "faults" / "ingest" / f"{dataset}.log"
    assert log.is_file(), f"no ingest log for {dataset}"
    text = log.read_text()
    assert re.search(message, text), text[-2000:]
    assert re.search(message, proc.stdout + proc.stderr)  # and on the terminal
    assert _outputs_of(work, "faults", dataset) == []


def test_good_dataset_results_present(fault_run):
    import netCDF4

    work, _ = fault_run
    res = work / "results" / "faults"
    for s, a in [(s, a) for s in ("gyro", "accel") for a in "xyz"]:
        for folder, ext in (("series", "nc"), ("allan", "nc"), ("decimated", "nc"), ("psd", "nc"), ("stationarity", "yaml")):
            assert (res / folder / "good" / s / f"{a}.{ext}").is_file(), (folder, s, a)
    with netCDF4.Dataset(res / "series" / "good" / "gyro" / "x.nc") as nc:
        assert nc.getncattr("n_filled") == 0 and nc.variables["signal"].units == "rad/s"
    with netCDF4.Dataset(res / "series" / "drops+1.v2" / "accel" / "z.nc") as nc:
        # five gaps filled, each after the file row before the dropped one (rows shift by one per earlier drop)
        assert nc.getncattr("n_filled") == 5 and nc.dimensions["sample"].size == N
        assert nc.getncattr("filled_rows") == ",".join(str(r - 1 - i) for i, r in enumerate(DROPS))
    assert (res / "psd" / "drops+1.v2" / "gyro" / "z.nc").is_file()
    # the per-sensor merges need every dataset: none is left looking complete
    assert not (res / "stack").exists() and not list(res.glob("spectra/*.nc"))


# -------------------------------------------------------------------------------------------------
# refused at start-up: the sheet, the dataset names, the records against the config (no job runs)
# -------------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def startup_work(tmp_path_factory):
    work = copy_checkout(tmp_path_factory.mktemp("startup") / "checkout")
    (work / "data_faults").mkdir()
    _csv(work / "data_faults" / "good.csv", _table(2))
    _csv(work / "data_faults" / "short.csv", _table(3)[:3000])  # 300 s < psd.window_s = 600 s
    return work


def _startup(work, name, sheet_text=None, rows=None, **cfg_changes):
    sheet = "sheet_" + name + ".tsv"
    if sheet_text is not None:
        (work / sheet).write_text(sheet_text)
    else:
        _sheet(work, rows, name=sheet)
    config = _config(work, name, sheet)
    if cfg_changes:
        cfg = yaml.safe_load(config.read_text())
        for key, value in cfg_changes.items():
            section, _, sub = key.partition("__")
            cfg[section][sub] = value
        config.write_text(yaml.safe_dump(cfg))
    proc = snakemake(work, config=config, snakefile=work / "Snakefile", check=False, timeout=300)
    return proc, proc.stdout + proc.stderr


GOOD = _row("good", "data_faults/good.csv")


def test_duplicated_sheet_column_refused(startup_work):
    header = "\t".join(["dataset", "path", "gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "gyro_x"])
    proc, out = _startup(startup_work, "dupcol", sheet_text=header + "\ngood\tdata_faults/good.csv\twx\twy\twz\tax\tay\taz\n")
    assert proc.returncode == 1
    assert "sheet_dupcol.tsv', line 1: duplicated column header 'gyro_x' in columns 3, 8" in out
    assert not (startup_work / "results" / "dupcol").exists()


@pytest.mark.parametrize("name", ["..", "a/b", "-x"])
def test_bad_dataset_name_refused(startup_work, name):
    tag = "name" + hashlib.md5(name.encode()).hexdigest()[:6]
    proc, out = _startup(startup_work, tag, rows=[GOOD, {**GOOD, "dataset": name}])
    assert proc.returncode == 1
    assert f"sheet_{tag}.tsv, line 3: dataset name {name!r}" in out
    assert not (startup_work / "results" / tag).exists()


def test_record_too_short_names_psd_window_s(startup_work):
    proc, out = _startup(startup_work, "short", rows=[GOOD, _row("short", "data_faults/short.csv")])
    assert proc.returncode == 1
    assert "dataset 'short' lasts 300 s" in out and "config key psd.window_s = 600 s" in out
    assert not (startup_work / "results" / "short").exists()


def test_decimation_ratio_and_segments_name_their_keys(startup_work):
    proc, out = _startup(startup_work, "ratio", rows=[GOOD], decimate__rate_hz=3.0)
    assert proc.returncode == 1
    assert "config key decimate.rate_hz = 3 Hz does not divide the rate of dataset 'good' (10 Hz" in out
    # 700 s decimated to 0.1 Hz: 70 samples, fewer than 3 per segment for 100 segments (the schema's maximum)
    _csv(startup_work / "data_faults" / "s700.csv", _table(7)[:7000])
    proc, out = _startup(startup_work, "segs", rows=[_row("s700", "data_faults/s700.csv")], stationarity__n_segments=100,
                         decimate__rate_hz=0.1)
    assert proc.returncode == 1
    assert "dataset 's700': 70 decimated samples" in out
    assert "for config key stationarity.n_segments = 100 (need >= 3 per segment" in out
    assert not (startup_work / "results" / "segs").exists()


def test_rate_cell_not_a_number(startup_work):
    proc, out = _startup(startup_work, "ratecell", rows=[{**GOOD, "rate_hz": "ten"}])
    assert proc.returncode == 1
    assert "sheet_ratecell.tsv, line 2: rate_hz = 'ten' is not a number (Hz)" in out


# -------------------------------------------------------------------------------------------------
# one axis, nothing stale, byte-identical reruns
# -------------------------------------------------------------------------------------------------
def _hashes(root):
    """sha256 of every .nc and .yaml under `root` (relative path -> digest). The bound YAML still holds the
    solver's wall time (`solve_time_s`, to move to the logs): that line alone is left out of the digest."""
    out = {}
    for p in sorted(root.rglob("*")):
        if p.suffix in (".nc", ".yaml") and p.is_file():
            data = p.read_bytes()
            if p.suffix == ".yaml":
                data = b"\n".join(ln for ln in data.split(b"\n") if not ln.lstrip().startswith(b"solve_time_s:"))
            out[str(p.relative_to(root))] = hashlib.sha256(data).hexdigest()
    return out


def test_one_axis_gyro_then_failed_rerun_then_identical_rerun(tmp_path):
    """A one-axis gyro dataset runs end to end; a failed rerun (another spec sheet and a bad dataset) leaves
    nothing of its config once the first config is run again; that rerun (--forceall) is byte-identical."""
    work = copy_checkout(tmp_path / "checkout")
    (work / "data_faults").mkdir()
    _csv(work / "data_faults" / "one.csv", _table(4))
    one = {"dataset": "one", "path": "data_faults/one.csv", "rate_hz": RATE_HZ, "gyro_unit": "rad/s",
           "time_column": "t", "gyro_x": "wx"}
    cfg_a = _config(work, "one", _sheet(work, [one], name="a.tsv"), sensors=["gyro"])
    snakemake(work, config=cfg_a, snakefile=work / "Snakefile", timeout=600)
    res = work / "results" / "one"
    assert sorted(p.name for p in (res / "series" / "one" / "gyro").iterdir()) == ["x.nc"]
    assert (res / "bound" / "stim300" / "gyro.yaml").is_file()
    bound = yaml.safe_load((res / "bound" / "stim300" / "gyro.yaml").read_text())
    assert len(bound["per_axis"]) == 1
    first = _hashes(res)
    assert len(first) > 10  # series, allan, decimated, psd, stationarity, stack, identify, bound, kf files

    # failed rerun: a second spec sheet, a second good dataset and a bad one (an inf at row 100: the
    # start-up probe passes, the ingest job fails)
    shutil.copy2(work / "config" / "specs" / "stim300.yaml", work / "config" / "specs" / "stim300b.yaml")
    _csv(work / "data_faults" / "two.csv", _table(5))
    t = _table(6)
    t[100, 1] = np.inf
    _csv(work / "data_faults" / "bad.csv", t)
    rows = [one, {**one, "dataset": "two", "path": "data_faults/two.csv"}, {**one, "dataset": "bad", "path": "data_faults/bad.csv"}]
    cfg_b = _config(work, "one", _sheet(work, rows, name="b.tsv"), sensors=["gyro"], specs=["stim300", "stim300b"],
                    file="one_b.yaml")
    proc = snakemake(work, "--keep-going", config=cfg_b, snakefile=work / "Snakefile", check=False, timeout=600)
    assert proc.returncode == 1
    assert (res / "psd" / "two" / "gyro" / "x.nc").is_file()  # the failed config's own outputs
    # downstream of the failed dataset nothing looks complete: the global bound was removed at start
    assert not (res / "bound" / "stim300" / "gyro.yaml").exists()
    assert not (res / "identify" / "gyro.yaml").exists()

    # the first config again, every job re-made: only its own outputs, identical bytes
    proc = snakemake(work, "--forceall", config=cfg_a, snakefile=work / "Snakefile", timeout=600)
    assert not (res / "bound" / "stim300b").exists()
    assert _outputs_of(work, "one", "bad") == [] and _outputs_of(work, "one", "two") == []
    assert not list((work / "logs" / "one").rglob("bad*")) and not list((work / "logs" / "one").rglob("two*"))
    assert "imupipe: removed" in proc.stdout + proc.stderr
    again = _hashes(res)
    assert again.keys() == first.keys()
    differ = [k for k in first if first[k] != again[k]]
    assert not differ, f"not byte-identical between identical runs: {differ}"
    assert not list(work.rglob(".tmp-*"))
