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
import math
import os
import re
import shutil
import signal
import subprocess
import threading
import time
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
                 "time_unit", "topic", "gap_policy", "fill_max_samples"]
X_ONLY = {"gyro_y": None, "gyro_z": None, "accel_y": None, "accel_z": None}  # a row naming gyro_x and accel_x


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


def _accel_in_g(data, t):  # issue 19: accel stored in g, the sheet says m/s^2 (valid, but 9.8x too small)
    t = t.copy()
    t[:, 4:7] /= 9.80665
    return _csv(data / "accel_g.csv", t).name, {}


# dataset, maker, message regex (the file and its column/row or line, what was expected)
BAD = [
    ("gyro_huge", _bad_csv_value(1e300, 2, 17),
     r"v2_17\.csv: gyro_y \(column 'wy'\) has a sample of 1e\+300 rad/s at row 17 \(0-based\), line 19 .*\|x\| <= 1000 rad/s"),
    ("gyro_inf", _bad_csv_value(np.inf, 1, 5), r"v1_5\.csv: gyro_x \(column 'wx'\) has a non-finite sample \(inf\) at row 5"),
    ("subnormal", _subnormal, r"subnormal\.csv: gyro_x \(column 'wx'\): the largest sample is .*expected a channel scale >= 1e-150"),
    ("numhead", _numeric_header, r"numhead\.csv: gyro_x column 'wx' not found; available: '0', '1'"),
    ("degunits", _nc_units, r"degunits\.nc: gyro_unit = 'rad/s' in the sheet but 'wx' states 'deg s-1'"),
    ("fifo", _fifo, r"fifo\.npy: is a FIFO \(named pipe\), not a regular file; refused"),
    ("symloop", _loop, r"loop_a\.csv: symbolic link loop"),
    ("gzipped", _gzip, r"packed\.csv: is gzip-compressed, not a text file"),
    ("absent", _missing, r"absent\.csv"),
    ("truncated", _truncated, r"truncated\.csv.*line 102"),
    # |mean| = 1 m/s^2 (gravity 9.80665 m/s^2 stored in g) +- the mean of the 1e-2 m/s^2 / g0 noise: 4 digits
    ("accel_in_g", _accel_in_g,
     r"accel_g\.csv \(dataset 'accel_in_g'\): accel_unit = 'm/s\^2' gives the mean specific force of the three "
     r"accel axes a magnitude of 1 m/s\^2 = 0\.102 g; .*accel_unit = 'g' would make it 1 g\..*gravity_removed: yes"),
]


DROPS = [1000, 5000, 9000, 13000, 17000]  # 0-based rows dropped from the drops.csv record
EPOCH_S = 1_700_000_000.0  # a phone's clock: Unix time (s)


def _jittered_stamps(n, rate_hz, seed, sigma_s=1e-3):
    """Unix-time stamps (s) of a `rate_hz` clock read with a jitter of `sigma_s` (clipped at 3 sigma, so that
    every interval stays within (0.94, 1.06) periods at 10 Hz: sample steps, no gap)."""
    rng = np.random.default_rng(seed)
    return EPOCH_S + np.arange(n) / rate_hz + np.clip(rng.normal(0.0, sigma_s, n), -3 * sigma_s, 3 * sigma_s)


def _ms_clock(rate_hz, duration_s, seed):
    """Three columns (t in integer ms, wx rad/s, ax m/s^2) of a `rate_hz` record whose clock counts whole
    milliseconds: t = floor(i * 1000 / rate), so that the intervals alternate (7, 8 ms at 128 Hz; 3, 4 ms at
    300 Hz) and their median is not the rate, their mean is (within 1 ms over the record)."""
    n = int(rate_hz * duration_s)
    rng = np.random.default_rng(seed)
    return np.column_stack([np.floor(np.arange(n) * 1000.0 / rate_hz), rng.normal(0.0, 1e-3, n),
                            rng.normal(0.0, 1e-2, n)])


def _bag(data, n, seed):
    """A ROS 2 MCAP file of sensor_msgs/Imu on /imu at 10 Hz (and a /status topic), written with rosbags'
    writer (tests/test_readers.py); the bare .mcap file, without its rosbag2 metadata.yaml."""
    pytest.importorskip("rosbags")
    import test_readers  # the module, not its classes: nothing of it is collected here

    table = _table(seed)[:n]  # the columns of CHANNELS: gyro x y z, accel x y z
    values = {(s, a): table[:, 1 + 3 * i + j] for i, s in enumerate(("gyro", "accel")) for j, a in enumerate("xyz")}
    stamps = int(EPOCH_S) * 10**9 + np.arange(n) * 100_000_000
    folder = test_readers.TestRosbag.write(data / "imu_bag", values, stamps, kind="mcap", topic="/imu")
    return next(folder.glob("*.mcap"))


class _RewriteWhileRead(threading.Thread):
    """Rewrites a file (a shorter record, as a logger restarting its file would) while the workflow's ingest
    job has it open: polls /proc/<pid>/fd of the processes running the ingest script until one holds the file,
    stops that process (SIGSTOP), checks that the file is still open, rewrites it, and resumes the process
    (SIGCONT). The process is stopped while its descriptor is open, so the rewrite happens mid-read whatever
    the timing; `rewritten_in` records the process (None: the file was never seen open)."""

    def __init__(self, path, text, timeout_s):
        super().__init__(daemon=True)
        self.path, self.text, self.deadline = os.path.realpath(path), text, time.monotonic() + timeout_s
        self.rewritten_in = None
        self.finish = threading.Event()

    def _holds(self, pid):
        try:
            return any(os.readlink(f"/proc/{pid}/fd/{fd}") == self.path for fd in os.listdir(f"/proc/{pid}/fd"))
        except OSError:  # gone, or a descriptor closed while listed
            return False

    def _ingest_jobs(self):
        for pid in filter(str.isdigit, os.listdir("/proc")):
            try:
                with open(f"/proc/{pid}/cmdline", "rb") as fh:
                    if b"ingest.py" not in fh.read():  # Snakemake runs the script as .snakemake/scripts/tmp*.ingest.py
                        continue
            except OSError:
                continue
            yield int(pid)

    @staticmethod
    def _stopped(pid):
        """Whether the process has stopped (T, t), or ended (Z, X: it will not stop; its files are closed)."""
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] in ("T", "t", "Z", "X")

    def run(self):
        while not self.finish.is_set() and time.monotonic() < self.deadline:
            for pid in self._ingest_jobs():
                if not self._holds(pid):
                    continue
                try:
                    os.kill(pid, signal.SIGSTOP)
                except ProcessLookupError:
                    continue
                try:
                    while not self._stopped(pid):
                        time.sleep(0.001)
                    if self._holds(pid):
                        with open(self.path, "w") as fh:  # same file (inode), shorter content
                            fh.write(self.text)
                        self.rewritten_in = pid
                except OSError:  # the process ended meanwhile
                    pass
                finally:
                    try:
                        os.kill(pid, signal.SIGCONT)
                    except ProcessLookupError:
                        pass
                if self.rewritten_in is not None:
                    return
            time.sleep(0.02)  # the parse of N_REWRITTEN rows holds the file ~0.5 s or more: 25 polls


N_REWRITTEN = 200_000  # 5.6 h at 10 Hz, ~30 MB: its parse holds the file open ~0.5 s (the watcher needs one poll)
N_BAG = 7200  # 720 s at 10 Hz: one 600 s PSD window
TMPFS_BYTES = 16384  # the full disk: 4 pages, less than one channel's 192 kB


def _mount_tiny_tmpfs(folder):
    """Mount a tmpfs of TMPFS_BYTES on `folder`; None when done, else why it could not be (the test skips)."""
    if os.geteuid() != 0 or shutil.which("mount") is None:
        return "mounting a tiny tmpfs needs root and mount(8)"
    folder.mkdir(parents=True)
    proc = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={TMPFS_BYTES}", "tmpfs", str(folder)],
                          capture_output=True, text=True)
    if proc.returncode != 0:
        folder.rmdir()
        return f"mount -t tmpfs failed: {proc.stderr.strip()}"
    return None


@pytest.fixture(scope="module")
def fault_run(tmp_path_factory):
    """One --keep-going run: the good dataset (netCDF, read one channel at a time), inputs wrongly refused
    before (a phone log: jittered stamps, no rate, five drops; integer-millisecond clocks; a ROS 2 bag named
    by its topic), every BAD row, a CSV rewritten while its ingest job reads it, and a dataset whose
    series folder is a full file system (a tiny tmpfs; left out where it cannot be mounted)."""
    work = copy_checkout(tmp_path_factory.mktemp("faults") / "checkout")
    data = work / "data_faults"
    data.mkdir()
    good = _table(1)
    _nc(data / "good.nc", good)
    # a phone-like text log: Unix-time stamps with 1 ms jitter, rate_hz left empty, five single-sample
    # drops, filled (gap_policy fill)
    phone = _table(8)
    phone[:, 0] = _jittered_stamps(N, RATE_HZ, 18)
    _csv(data / "drops.csv", np.delete(phone, DROPS, axis=0))
    # integer-millisecond clocks at 128 Hz (rate given) and 300 Hz (rate_hz left empty)
    _csv(data / "ms128.csv", _ms_clock(128.0, 720.0, 10), header=["t", "wx", "ax"])
    _csv(data / "ms300.csv", _ms_clock(300.0, 720.0, 11), header=["t", "wx", "ax"])
    bag = _bag(data, N_BAG, 12)
    nothing = {k: None for k in ("rate_hz", "gyro_unit", "accel_unit", "time_column", *CHANNELS)}
    rows = [_row("good", "data_faults/good.nc", format="netcdf", time_column=None),
            _row("drops+1.v2", "data_faults/drops.csv", rate_hz=None, gap_policy="fill", fill_max_samples=1),
            _row("ms128", "data_faults/ms128.csv", rate_hz=128.0, time_unit="ms", **X_ONLY),
            _row("ms300", "data_faults/ms300.csv", rate_hz=None, time_unit="ms", **X_ONLY),
            _row("bag", f"data_faults/{bag.relative_to(data)}", topic="/imu", **nothing)]
    for name, make, _ in BAD:
        path, cells = make(data, good)
        rows.append(_row(name, f"data_faults/{path}", **cells))
    watcher = None
    rewrite_skip = None if os.path.isdir("/proc/self/fd") else "watching a job's open files needs /proc/<pid>/fd (Linux)"
    if rewrite_skip is None:
        big = np.column_stack([np.arange(N_REWRITTEN) / RATE_HZ,
                               np.random.default_rng(13).normal(0.0, 1e-3, (N_REWRITTEN, 6))])
        big[:, 6] -= 9.80665
        rewritten = _csv(data / "rewritten.csv", big)
        lines = rewritten.read_text().splitlines(keepends=True)
        rows.append(_row("rewritten", "data_faults/rewritten.csv"))
        watcher = _RewriteWhileRead(rewritten, "".join(lines[: len(lines) // 2]), timeout_s=900)
    full_folder = work / "results" / "faults" / "series" / "full"
    full_skip = _mount_tiny_tmpfs(full_folder)
    if full_skip is None:
        _nc(data / "full.nc", _table(14))
        rows.append(_row("full", "data_faults/full.nc", format="netcdf", time_column=None))
    # the tiny config's stationarity test (calibrated, 39 draws): the verdicts are not under test here, only made
    config = _config(work, "faults", _sheet(work, rows))
    if watcher is not None:
        watcher.start()
    try:
        # the DAG up to the per-sensor merges (`--until stack`): ingest and the per-axis allan, decimate, psd and
        # stationarity jobs the tests below read, and the merges, which must not run on a partial set of datasets;
        # not the outliers and lines jobs, which no test here reads
        proc = snakemake(work, "--keep-going", "--until", "stack", config=config, snakefile=work / "Snakefile",
                         check=False, timeout=900)
        if watcher is not None:
            watcher.finish.set()
            watcher.join()
        yield work, proc, {"rewritten_in": watcher.rewritten_in if watcher is not None else None,
                           "rewrite_skip": rewrite_skip, "full_skip": full_skip, "full_folder": full_folder}
    finally:
        if watcher is not None:
            watcher.finish.set()
        if full_skip is None:
            subprocess.run(["umount", str(full_folder)], check=False)


def test_fault_run_fails(fault_run):
    _, proc, _ = fault_run
    assert proc.returncode == 1, proc.stderr[-3000:]


@pytest.mark.parametrize("dataset, message", [(b[0], b[2]) for b in BAD], ids=[b[0] for b in BAD])
def test_bad_dataset_fails_alone_naming_the_culprit(fault_run, dataset, message):
    import re

    work, proc, _ = fault_run
    log = work / "logs" / "faults" / "ingest" / f"{dataset}.log"
    assert log.is_file(), f"no ingest log for {dataset}"
    text = log.read_text()
    assert re.search(message, text), text[-2000:]
    assert re.search(message, proc.stdout + proc.stderr)  # and on the terminal
    assert _outputs_of(work, "faults", dataset) == []


def test_good_dataset_results_present(fault_run):
    import netCDF4

    work, _, _ = fault_run
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
    # the PSD file carries the fill to the summary (imupipe.stages.summary.psd_usage -> summary.filled_lines)
    from imupipe.stages.summary import psd_usage
    from imupipe.summary import filled_lines

    usage = psd_usage(str(res / "psd" / "drops+1.v2" / "gyro" / "z.nc"))
    assert usage["n_filled"] == 5 and usage["filled_rows"] == ",".join(str(r - 1 - i) for i, r in enumerate(DROPS))
    assert filled_lines([usage, psd_usage(str(res / "psd" / "good" / "gyro" / "z.nc"))]) == [
        "- samples made up by linear interpolation (gap_policy fill): drops+1.v2 5 samples in 5 gap(s) (after file "
        f"rows {', '.join(str(r - 1 - i) for i, r in enumerate(DROPS))})"]
    with netCDF4.Dataset(res / "series" / "drops+1.v2" / "gyro" / "x.nc") as nc:
        assert nc.rate_hz == RATE_HZ  # rate_hz left empty: the mean interval of the jittered stamps, snapped
    with netCDF4.Dataset(res / "allan" / "drops+1.v2" / "gyro" / "x.nc") as nc:  # the AV carries the fill
        assert nc.getncattr("n_filled") == 5
    # the per-sensor merges need every dataset: none is left looking complete
    assert not (res / "stack").exists() and not list(res.glob("spectra/*.nc"))


# wrongly refused before, now run end to end (ingest and every per-axis stage): dataset, rate of the series
# (Hz, exact), the channels its sheet row gives (None: all six, a bag's sensor_msgs/Imu fields)
ACCEPTED = [
    # (jittered stamps with rate_hz empty: the phone log drops+1.v2, test_good_dataset_results_present)
    ("ms128", 128.0, [("gyro", "x"), ("accel", "x")]),  # integer-ms clock, rate_hz 128
    ("ms300", 300.0, [("gyro", "x"), ("accel", "x")]),  # integer-ms clock, rate_hz empty
    ("bag", 10.0, [(s, a) for s in ("gyro", "accel") for a in "xyz"]),  # ROS 2 MCAP, the row gives the topic
]


@pytest.mark.parametrize("dataset, rate, channels", ACCEPTED, ids=[a[0] for a in ACCEPTED])
def test_accepted_inputs_run_every_per_axis_stage(fault_run, dataset, rate, channels):
    import netCDF4

    work, _, _ = fault_run
    res = work / "results" / "faults"
    log = (work / "logs" / "faults" / "ingest" / f"{dataset}.log").read_text()
    assert "imupipe error" not in log, log[-2000:]
    made = sorted((p.parent.name, p.stem) for p in (res / "series" / dataset).rglob("*.nc"))
    assert made == sorted(channels)
    for s, a in channels:
        for folder, ext in (("allan", "nc"), ("decimated", "nc"), ("psd", "nc"), ("stationarity", "yaml")):
            assert (res / folder / dataset / s / f"{a}.{ext}").is_file(), (folder, s, a)
        with netCDF4.Dataset(res / "series" / dataset / s / f"{a}.nc") as nc:
            assert nc.rate_hz == rate and nc.getncattr("n_filled") == 0
        with netCDF4.Dataset(res / "decimated" / dataset / s / f"{a}.nc") as nc:
            assert nc.rate_hz == 1.0  # the config's decimate.rate_hz: the ratio is an integer
    if dataset == "bag":  # the samples of topic /imu, in SI as sensor_msgs/Imu states them
        table = _table(12)[:N_BAG]
        with netCDF4.Dataset(res / "series" / "bag" / "gyro" / "y.nc") as nc:
            np.testing.assert_array_equal(nc.variables["signal"][:], table[:, 2])
            assert nc.variables["signal"].units == "rad/s"
        with netCDF4.Dataset(res / "series" / "bag" / "accel" / "z.nc") as nc:
            np.testing.assert_array_equal(nc.variables["signal"][:], table[:, 6])


def test_csv_rewritten_while_ingested_fails_naming_the_file(fault_run):
    """The watcher rewrote rewritten.csv (half its rows) while the ingest job held it open: that dataset fails
    with a message naming the file and the change; nothing of it is left; the good datasets' results are
    there (test_good_dataset_results_present, same run)."""
    work, proc, info = fault_run
    if info["rewrite_skip"]:
        pytest.skip(info["rewrite_skip"])
    assert info["rewritten_in"] is not None, "the ingest job was never seen with rewritten.csv open"
    text = (work / "logs" / "faults" / "ingest" / "rewritten.log").read_text()
    message = r"imupipe error: data_faults/rewritten\.csv: changed while it was read \(size (\d+) -> (\d+) bytes"
    m = re.search(message, text)
    assert m, text[-2000:]
    assert int(m.group(2)) < int(m.group(1))  # shortened
    assert re.search(message, proc.stdout + proc.stderr)
    assert _outputs_of(work, "faults", "rewritten") == []
    assert (work / "results" / "faults" / "psd" / "good" / "gyro" / "x.nc").is_file()


def test_full_disk_names_the_output_and_leaves_nothing(fault_run):
    """The `full` dataset's series folder is a 16 kB tmpfs: writing its first channel fails with ENOSPC (netCDF:
    "HDF error"); the job's log and the terminal say the disk is full and name the output; no file (neither
    an output nor a temporary) is left on that file system."""
    work, proc, info = fault_run
    if info["full_skip"]:
        pytest.skip(info["full_skip"])
    text = (work / "logs" / "faults" / "ingest" / "full.log").read_text()
    message = r"imupipe error: disk full: no space left on the device writing results/faults/series/full/gyro/x\.nc"
    assert re.search(message, text), text[-2000:]
    assert re.search(message, proc.stdout + proc.stderr)
    assert [p for p in info["full_folder"].rglob("*") if not p.is_dir()] == []
    assert _outputs_of(work, "faults", "full") == []
    assert (work / "results" / "faults" / "psd" / "good" / "gyro" / "x.nc").is_file()


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
            cfg.setdefault(section, {})[sub] = value  # a section the config leaves out takes the defaults
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


@pytest.mark.parametrize("tag, sep, extra, message", [
    ("commasheet", ",", "", "sheet_commasheet.tsv', line 1: not tab-separated (found commas"),
    ("notescol", "\t", "notes", "sheet_notescol.tsv', line 1: unknown column 'notes' (column 13); allowed columns: "
                                "dataset, path,"),
])
def test_first_hour_sheet_refused_naming_the_culprit(startup_work, tag, sep, extra, message):
    # before: "no 'path' column" (commas) and "Error validating config file." (an extra notes column)
    cols = [c for c in SHEET_COLUMNS if c in GOOD] + ([extra] if extra else [])
    cells = [str(GOOD[c]) for c in cols if c in GOOD] + (["bench 2"] if extra else [])
    proc, out = _startup(startup_work, tag, sheet_text=sep.join(cols) + "\n" + sep.join(cells) + "\n")
    assert proc.returncode == 1
    assert message in out, out[-2000:]
    assert not (startup_work / "results" / tag).exists()


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
                         decimate__rate_hz=0.1, application__filter_rate_hz=0.1)
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
    """sha256 of every .nc and .yaml under `root` (relative path -> digest), whole files: wall-clock readings
    (the LP's solve time) go to the job logs, not into the results."""
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.suffix in (".nc", ".yaml") and p.is_file()}


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

    # a second config (another name, dataset and spec sheet) run in the same folder: its own results/other/,
    # nothing of results/one/ touched (the per-sensor files of two configs do not overwrite each other)
    _csv(work / "data_faults" / "other.csv", _table(7))
    shutil.copy2(work / "config" / "specs" / "stim300.yaml", work / "config" / "specs" / "stim300c.yaml")
    cfg_o = _config(work, "other", _sheet(work, [{**one, "dataset": "one", "path": "data_faults/other.csv"}],
                                          name="o.tsv"), sensors=["gyro"], specs=["stim300c"])
    snakemake(work, config=cfg_o, snakefile=work / "Snakefile", timeout=600)
    other = _hashes(work / "results" / "other")
    assert "bound/stim300c/gyro.yaml" in other and "identify/gyro.yaml" in other
    assert _hashes(res) == first

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

    # the first config again, every job re-made: only its own outputs, identical bytes; the temporary file a
    # job killed by SIGKILL leaves beside its output (imupipe.io.atomic_path's name) is removed
    killed = res / "psd" / "one" / "gyro" / ".tmp-x.nc-k1ll3d.nc"
    killed.parent.mkdir(parents=True, exist_ok=True)
    killed.write_bytes(b"half a netCDF file")
    proc = snakemake(work, "--forceall", config=cfg_a, snakefile=work / "Snakefile", timeout=600)
    assert not killed.exists()
    assert not (res / "bound" / "stim300b").exists()
    assert _outputs_of(work, "one", "bad") == [] and _outputs_of(work, "one", "two") == []
    assert not list((work / "logs" / "one").rglob("bad*")) and not list((work / "logs" / "one").rglob("two*"))
    assert "imupipe: removed" in proc.stdout + proc.stderr
    again = _hashes(res)
    assert again.keys() == first.keys()
    differ = [k for k in first if first[k] != again[k]]
    assert not differ, f"not byte-identical between identical runs: {differ}"
    assert _hashes(work / "results" / "other") == other  # the other config's results: untouched by all this
    assert not list(work.rglob(".tmp-*"))


@pytest.mark.slow  # a complete run: minutes on a loaded machine
def test_rate_from_timestamps_reaches_the_bound_and_kalibr(tmp_path):
    """Two records whose sheet rows give no rate_hz (the phone log with five fills, the MCAP bag named by its
    topic) run to the bound, the filters and the Kalibr file, whose update_rate is the rate the timestamps
    gave (10 Hz) and whose topic is the sheet's."""
    work = copy_checkout(tmp_path / "checkout")
    data = work / "data_faults"
    data.mkdir()
    phone = _table(8)
    phone[:, 0] = _jittered_stamps(N, RATE_HZ, 18)
    _csv(data / "drops.csv", np.delete(phone, DROPS, axis=0))
    bag = _bag(data, N_BAG, 12)
    nothing = {k: None for k in ("rate_hz", "gyro_unit", "accel_unit", "time_column", *CHANNELS)}
    rows = [_row("phone", "data_faults/drops.csv", rate_hz=None, gap_policy="fill", fill_max_samples=1),
            _row("bag", f"data_faults/{bag.relative_to(data)}", topic="/imu", **nothing)]
    config = _config(work, "norate", _sheet(work, rows))
    snakemake(work, config=config, snakefile=work / "Snakefile", timeout=1800)
    res = work / "results" / "norate"
    for sensor in ("gyro", "accel"):
        ident = yaml.safe_load((res / "identify" / f"{sensor}.yaml").read_text())
        assert set(ident["rate_hz"].values()) == {RATE_HZ}
        assert (res / "bound" / "stim300" / f"{sensor}.yaml").is_file()
        assert (res / "kf" / "stim300" / f"{sensor}.yaml").is_file()
    kalibr = yaml.safe_load((res / "kf" / "stim300" / "kalibr_imu.yaml").read_text())
    assert not kalibr.get("refused"), kalibr  # white-noise records (seeded): no line, one rate
    assert kalibr["update_rate"] == RATE_HZ and kalibr["rostopic"] == "/imu"
    assert (res / "summary.md").is_file()


def test_first_hour_deg_s_declared_rad_s_is_flagged_in_the_summary(tmp_path):
    """The issue's case end to end: a one-axis gyro record at the STIM-300's white noise (0.15 deg/sqrt(h)),
    stored in deg/s but declared rad/s: every value 57.3x too large. The run stays BOUNDED (a valid unit) and its
    summary FLAGs the white noise far above the spec sheet, naming the sheet column and the dataset."""
    work = copy_checkout(tmp_path / "checkout")
    (work / "data_faults").mkdir()
    sigma_deg_s = 0.15 / 60.0 * math.sqrt(RATE_HZ)  # N (deg/s/sqrt(Hz)) * sqrt(rate): the sample sigma, deg/s
    t = _table(8)
    t[:, 1] = np.random.default_rng(8).normal(0.0, sigma_deg_s, N)
    _csv(work / "data_faults" / "degs.csv", t)
    row = {"dataset": "degs", "path": "data_faults/degs.csv", "rate_hz": RATE_HZ, "gyro_unit": "rad/s",
           "time_column": "t", "gyro_x": "wx"}
    cfg = _config(work, "degs", _sheet(work, [row], name="degs.tsv"), sensors=["gyro"])
    # up to the summary (every file it reads); not the figures, tables and report copies, which do not enter it
    snakemake(work, "--until", "summary", config=cfg, snakefile=work / "Snakefile", timeout=900)
    text = (work / "results" / "degs" / "summary.md").read_text()
    flag = [ln for ln in text.splitlines() if "FLAG data far above the spec sheet [degs]" in ln]
    assert len(flag) == 1, text
    assert "check the unit of gyro (dataset sheet column gyro_unit of degs)" in flag[0]
    ratio = float(flag[0].split("data/spec ")[1].split("x")[0])
    assert 40.0 < ratio < 120.0  # 57.3x the data's N, within the envelope's statistical width
    # the same record declared in its own unit: no such flag
    cfg = _config(work, "degs_ok", _sheet(work, [{**row, "gyro_unit": "deg/s"}], name="degs_ok.tsv"), sensors=["gyro"])
    snakemake(work, "--until", "summary", config=cfg, snakefile=work / "Snakefile", timeout=900)
    assert "far above the spec sheet" not in (work / "results" / "degs_ok" / "summary.md").read_text()
