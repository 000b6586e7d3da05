"""imupipe init: a dataset sheet and a partial config fitted to a user's records (imupipe.init, imupipe.cli)."""

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from imupipe.cli import check_config, main
from imupipe.init import MAX_UNUSED_FRACTION, PLACEHOLDER, RecordInfo, derive_settings, guess_channels, welch_unused

ROOT = Path(__file__).resolve().parents[1]
SPEC = ROOT / "config" / "specs" / "stim300.yaml"
RATE, HOURS = 10.0, 2.0


@pytest.fixture(scope="module")
def record(tmp_path_factory):
    """A static 2 h record at 10 Hz: time in s, gyro in deg/s, accel in g (1 g on z), units in the header."""
    path = tmp_path_factory.mktemp("rec") / "lab1.csv"
    n = int(RATE * HOURS * 3600)
    rng = np.random.default_rng(3)
    cols = np.column_stack([np.arange(n) / RATE, 1e-3 * rng.standard_normal((n, 6))])
    cols[:, 6] += 1.0
    header = "t [s],gx [deg/s],gy [deg/s],gz [deg/s],ax [g],ay [g],az [g]"
    np.savetxt(path, cols, delimiter=",", header=header, comments="", fmt="%.6f")
    return path


def _init(tmp_path, *args):
    return main(["init", *map(str, args), "--out", str(tmp_path / "out")])


def test_init_writes_a_sheet_and_a_config_that_validate(record, tmp_path, capsys):
    assert _init(tmp_path, record, "--spec", SPEC) == 0
    out = capsys.readouterr().out
    sheet, cfg = tmp_path / "out" / "datasets.tsv", tmp_path / "out" / "config.yaml"
    assert f"imupipe run {cfg}" in out and PLACEHOLDER not in out
    rows = [ln.split("\t") for ln in sheet.read_text().splitlines() if not ln.startswith("#")]
    row = dict(zip(rows[0], rows[1]))
    assert row["format"] == "csv" and float(row["rate_hz"]) == RATE
    assert (row["gyro_unit"], row["accel_unit"], row["time_column"], row["time_unit"]) == ("deg/s", "g", "t [s]", "s")
    assert row["gap_policy"] == "fill" and "# gap_policy fill: a gap of up to 10 missing samples" in sheet.read_text()
    assert [row[f"{s}_{a}"] for s in ("gyro", "accel") for a in "xyz"] == [
        "gx [deg/s]", "gy [deg/s]", "gz [deg/s]", "ax [g]", "ay [g]", "az [g]"]
    # the sheet has the columns of the shipped one (and the time columns)
    shipped = (ROOT / "config" / "datasets_adis16405.tsv").read_text().splitlines()[0].split("\t")
    assert set(shipped) - {"variable"} <= set(rows[0])
    lines = check_config(cfg)
    assert any("1 rows, every file present" in ln for ln in lines)
    c = yaml.safe_load(cfg.read_text())
    assert c["specs"] == ["stim300"] and c["simulation"] is None
    # the rule: 2 h at 1 Hz -> W = 1800 s, S = 900 s, outage = min(3600, W, T - fix_s) = 1800 s
    assert (c["decimate"]["rate_hz"], c["psd"]["window_s"], c["psd"]["step_s"]) == (1.0, 1800.0, 900.0)
    assert c["application"] == {"filter_rate_hz": 1.0, "outage_s": 1800.0} and "verify" not in c
    assert c["lines"] == {"scales": [1, 8, 64], "low_band_resolution_hz": 1 / 1800.0}  # 1 / psd.window_s
    n = int(HOURS * 3600 * c["decimate"]["rate_hz"])
    assert welch_unused(n, 1800, 900) <= MAX_UNUSED_FRACTION * n
    for key in ("window_s", "step_s", "scales"):  # every derived value carries its rule as a comment
        text = cfg.read_text().split(f"  {key}:")[0].splitlines()[-1]
        assert text.lstrip().startswith("#")


def test_an_outage_shorter_than_the_default_is_said_and_a_longer_one_can_be_asked_for(record, tmp_path, capsys):
    """An outside evaluation: init wrote application.outage_s 600 s for a 40 min record and only the config's
    comment said so. The 2 h record: the rule's 1800 s is said on stdout; --outage-s 3600 is taken (one fix period of
    600 s plus 3600 s fit in 7200 s: the comment says it was asked); --outage-s 7000 is refused naming the longest
    outage the record holds (7200 - 600 = 6600 s), and nothing is written."""
    assert _init(tmp_path, record, "--spec", SPEC) == 0
    out = capsys.readouterr().out
    # the note says what set the default and the longest outage --outage-s takes (a second evaluation: "allow no
    # longer" read as a limit that --outage-s 3600 then passed)
    assert ("note: application.outage_s = 1800 s, shorter than the default 3600 s: by default the outage is at most "
            "the PSD window (1800 s)") in out and "imupipe init --outage-s asks for it, up to 6600 s" in out
    assert main(["init", str(record), "--spec", str(SPEC), "--out", str(tmp_path / "o2"), "--outage-s", "3600"]) == 0
    assert "note: application.outage_s" not in capsys.readouterr().out
    text = (tmp_path / "o2" / "config.yaml").read_text()
    assert yaml.safe_load(text)["application"]["outage_s"] == 3600.0 and "as asked (imupipe init --outage-s)" in text
    # 1/3600 Hz lies below the PSD's 1/1800 Hz: the comment says where the band's bottom is covered from (an outside
    # evaluation read "inside the decimated spectra's [1/W, f/2]" there)
    assert "1/outage_s lies below the lowest PSD" in text and "inside the decimated spectra's" not in text
    assert check_config(tmp_path / "o2" / "config.yaml")  # the start-up checks take it
    assert main(["init", str(record), "--spec", str(SPEC), "--out", str(tmp_path / "o3"), "--outage-s", "7000"]) == 1
    err = capsys.readouterr().err
    assert "--outage-s 7000: the shortest record" in err and "an outage of at most 6600 s" in err
    assert not (tmp_path / "o3" / "config.yaml").exists()


def test_imupipe_check_with_a_dry_run_accepts_the_config(record, tmp_path):
    """The workflow's own start-up checks (schema, records against the config) and DAG, as a user runs them."""
    assert _init(tmp_path, record, "--spec", SPEC) == 0
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    proc = subprocess.run([sys.executable, "-m", "imupipe", "check", str(tmp_path / "out" / "config.yaml")],
                          capture_output=True, text=True, env=env, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "snakemake dry run: the workflow's DAG builds" in proc.stdout


def test_headerless_record_gets_placeholders_and_says_so(tmp_path, capsys):
    path = tmp_path / "raw.txt"
    np.savetxt(path, np.random.default_rng(0).standard_normal((4000, 6)), fmt="%.5f")
    assert main(["init", str(path), "--spec", str(SPEC), "--rate-hz", "1", "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert "FILL_ME" in out and "gyro_unit" in out and "gyro_x" in out
    sheet = (tmp_path / "o" / "datasets.tsv").read_text()
    assert "# replace every FILL_ME" in sheet and sheet.count(PLACEHOLDER) >= 8
    assert "gap_policy fill" not in sheet  # no stamps: no gaps to see
    # an outside evaluation: `imupipe check` said "ok" on a sheet still holding placeholders; it now refuses it
    # naming the sheet, the line and the cells (and so does `imupipe run`, whose start-up check it is)
    assert main(["check", str(tmp_path / "o" / "config.yaml")]) == 1
    err = capsys.readouterr().err
    # the line as an editor shows it: after init's comment lines and the header
    line = 1 + next(i for i, ln in enumerate(sheet.splitlines()) if ln.startswith("raw\t"))
    assert f"datasets.tsv, line {line} (dataset 'raw'): column(s) gyro_unit, accel_unit, gyro_x" in err
    assert line > 2 and "still hold the placeholder FILL_ME: fill them in" in err


def test_a_header_unit_init_cannot_read_is_named_in_the_placeholder_note(tmp_path, capsys):
    """An outside evaluation: `gx [degs]` gave `gyro_unit FILL_ME` with only "the unit as stored"; the note now names
    the header's unit that was not read; the accelerometer's readable `[g]` is taken."""
    path = tmp_path / "rec.csv"
    x = np.random.default_rng(1).standard_normal((4000, 6)) * 0.01 + [0, 0, 0, 0, 0, 1]
    header = "gx [degs],gy [degs],gz [degs],ax [g],ay [g],az [g]"
    np.savetxt(path, x, fmt="%.5f", delimiter=",", header=header, comments="")
    assert main(["init", str(path), "--spec", str(SPEC), "--rate-hz", "1", "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert "gyro_unit" in out and "the header's 'degs' was not read as a rate unit" in out
    assert "accel_unit (" not in out


def test_a_record_with_a_few_drops_runs_from_the_sheet_init_writes(tmp_path):
    # an outside evaluation: init wrote no gap_policy, so a record with a few dropped samples stopped at the ingest
    from imupipe.init import inspect_record
    from imupipe.readers import read_dataset_row

    n = 20000
    t = np.delete(np.arange(n + 3) / 10.0, [5000, 9000, 9001])
    x = np.random.default_rng(4).standard_normal((n, 6)) * 1e-3
    x[:, 5] += 9.80665
    path = tmp_path / "drops.csv"
    np.savetxt(path, np.column_stack([t, x]), delimiter=",", fmt="%.10g", comments="",
               header="t [s],gx [rad/s],gy [rad/s],gz [rad/s],ax [m/s^2],ay [m/s^2],az [m/s^2]")
    info = inspect_record(path, "drops")
    assert info.row["gap_policy"] == "fill"
    rec = read_dataset_row(info.row)
    assert rec.n_filled == 3 and rec.n_samples == n + 3 and [g.row for g in rec.filled] == [4999, 8998]


def test_guess_channels():
    ch, units, t, tu = guess_channels(["time_ms", "Gyro. X", "Gyro. Y", "Gyro. Z", "acc_x (m/s^2)", "acc_y (m/s^2)"])
    assert ch == {"gyro_x": "Gyro. X", "gyro_y": "Gyro. Y", "gyro_z": "Gyro. Z", "accel_x": "acc_x (m/s^2)",
                  "accel_y": "acc_y (m/s^2)"}
    assert units == {"accel": "m/s^2"} and (t, tu) == ("time_ms", "ms")
    assert guess_channels(["wx [g]", "wy [g]", "wz [g]"])[1] == {}  # g is no gyro unit: not guessed


@pytest.mark.parametrize("hours", [0.5, 2.0, 10.0, 27.9, 29.0, 31.4, 50.0, 300.0])
def test_psd_step_leaves_at_most_ten_percent_unused(hours):
    """Also past 4 x 7 h, where the window is capped and S = W/2 alone would leave up to 1/8 of the record."""
    n = int(hours * 3600 * 100)
    rec = RecordInfo("r", Path("r.csv"), "csv", 100.0, "sheet", n, n / 100.0, {})
    s = derive_settings([rec])
    nd = n // 100
    nw, ns = round(s.window_s), round(s.step_s)
    assert ns <= nw / 2 and welch_unused(nd, nw, ns) <= MAX_UNUSED_FRACTION * nd
    assert s.outage_s <= min(3600.0, s.window_s, nd - 600.0)
    assert math.isclose(s.unused["r"], welch_unused(nd, nw, ns) / nd)


def test_decimation_divides_every_rate():
    recs = [RecordInfo(f"r{i}", Path("r"), "csv", f, "sheet", int(f * 7200), 7200.0, {}) for i, f in
            enumerate((12.5, 100.0))]
    assert derive_settings(recs).decimate_rate_hz == 0.5  # gcd(12.5, 100, 1) Hz


def test_bad_inputs_refused_by_name_and_nothing_written(record, tmp_path, capsys):
    out = tmp_path / "out"
    assert _init(tmp_path, tmp_path / "nope.csv", "--spec", SPEC) == 1
    assert "nope.csv: record not found" in capsys.readouterr().err
    odd = tmp_path / "rec.xyz"
    odd.write_text("1,2\n")
    assert _init(tmp_path, odd, "--spec", SPEC) == 1
    assert "rec.xyz" in capsys.readouterr().err
    assert _init(tmp_path, record, "--spec", tmp_path / "none.yaml") == 1
    assert "none.yaml: spec sheet not found" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        _init(tmp_path, record)
    assert exc.value.code != 0 and "--spec" in capsys.readouterr().err
    assert not out.exists() or not any(out.iterdir())


def test_existing_files_kept_unless_force(record, tmp_path, capsys):
    assert _init(tmp_path, record, "--spec", SPEC) == 0
    cfg = tmp_path / "out" / "config.yaml"
    cfg.write_text("# mine\n")
    assert _init(tmp_path, record, "--spec", SPEC) == 1
    assert "not overwritten (--force" in capsys.readouterr().err and cfg.read_text() == "# mine\n"
    assert _init(tmp_path, record, "--spec", SPEC, "--force") == 0
    assert "window_s" in cfg.read_text()


def test_r_file_columns_guessed_units_left_to_fill(tmp_path, capsys):
    """An ADIS16405-like .rda (column names 'Gyro. X' ..., rate in the freq attribute, no units in the file)."""
    from test_readers import write_r_matrix

    names = [f"{s}. {a}" for s in ("Gyro", "Accel") for a in "XYZ"]
    matrix = 1e-3 * np.random.default_rng(5).standard_normal((4000, 6))
    path = write_r_matrix(tmp_path / "imu.rda", matrix, names, freq=2.0)
    assert main(["init", str(path), "--spec", str(SPEC), "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert "imu: gyro_unit" in out and "imu: accel_unit" in out and "gyro_x (column" not in out
    rows = [ln.split("\t") for ln in (tmp_path / "o" / "datasets.tsv").read_text().splitlines() if ln[0] != "#"]
    row = dict(zip(rows[0], rows[1]))
    assert (row["format"], row["rate_hz"], row["gyro_x"], row["accel_z"]) == ("rdata", "2", "Gyro. X", "Accel. Z")
    c = yaml.safe_load((tmp_path / "o" / "config.yaml").read_text())
    assert c["psd"]["window_s"] == 500.0 and c["application"]["outage_s"] == 500.0  # 2000 s: T/4, T/4


def test_ros_bag_and_netcdf_rows(tmp_path, capsys):
    """A ROS 1 bag (sensor_msgs/Imu: SI, fields by default, rate from the stamps) and a netCDF file whose
    variables carry their units (``from_file``), 1200 s at 2 Hz each."""
    pytest.importorskip("rosbags")
    from test_readers import TestRosbag
    from test_readers_faults import write_nc

    n, rate = 2400, 2.0
    rng = np.random.default_rng(9)
    data = {(s, a): 1e-3 * rng.standard_normal(n) + (9.81 if (s, a) == ("accel", "z") else 0.0)
            for s in ("gyro", "accel") for a in "xyz"}
    bag = TestRosbag.write(tmp_path / "bench.bag", data, 10**18 + np.arange(n) * 500_000_000, "ros1")
    table = np.column_stack([np.arange(n) / rate] + [data[(s, a)] for s in ("gyro", "accel") for a in "xyz"])
    nc = write_nc(tmp_path / "lab.nc", table, units={"gyro": "rad/s", "accel": "m/s^2"})
    assert main(["init", str(bag), str(nc), "--spec", str(SPEC), "--out", str(tmp_path / "o")]) == 0
    assert "FILL_ME" not in capsys.readouterr().out
    rows = [ln.split("\t") for ln in (tmp_path / "o" / "datasets.tsv").read_text().splitlines() if ln[0] != "#"]
    bag_row, nc_row = (dict(zip(rows[0], r)) for r in rows[1:])
    assert (bag_row["format"], bag_row["rate_hz"], bag_row["gyro_unit"], bag_row["gyro_x"]) == ("rosbag", "2",
                                                                                                "rad/s", "")
    assert (nc_row["format"], nc_row["rate_hz"], nc_row["gyro_unit"], nc_row["gyro_x"], nc_row["time_column"]) == (
        "netcdf", "2", "from_file", "wx", "t")
    c = yaml.safe_load((tmp_path / "o" / "config.yaml").read_text())
    assert (c["psd"]["window_s"], c["psd"]["step_s"], c["application"]["outage_s"]) == (300.0, 150.0, 300.0)
    # 1 / 300 s is not finer than the line search's 0.002 Hz: no low band (the start-up check would refuse it)
    assert c["lines"]["low_band_resolution_hz"] is None
    assert check_config(tmp_path / "o" / "config.yaml")


def test_ambiguous_time_unit_refused_then_given(tmp_path, capsys):
    """Stamps 0.5 apart are 2 Hz in s or 2 kHz in ms: refused naming --time-unit, accepted with it."""
    path = tmp_path / "slow.csv"
    n = 2400
    table = np.column_stack([np.arange(n) * 0.5, 1e-3 * np.random.default_rng(2).standard_normal((n, 3))])
    np.savetxt(path, table, delimiter=",", header="t,wx,wy,wz", comments="", fmt="%.6f")
    assert main(["init", str(path), "--spec", str(SPEC), "--out", str(tmp_path / "o")]) == 1
    assert "--time-unit" in capsys.readouterr().err and not (tmp_path / "o").exists()
    assert main(["init", str(path), "--spec", str(SPEC), "--out", str(tmp_path / "o"), "--time-unit", "s"]) == 0
    text = (tmp_path / "o" / "datasets.tsv").read_text()
    out = capsys.readouterr().out
    assert "\t2\t" in text and "gyro_unit" in out and "no accel column recognised" in out
    assert "accel_x (column" not in out  # left out, not a cell to fill
    assert yaml.safe_load((tmp_path / "o" / "config.yaml").read_text())["sensors"] == ["gyro"]


def test_a_record_with_a_gap_gets_the_rate_of_its_spacing_and_a_note(tmp_path, capsys):
    # an outside evaluation: a 10 Hz record with one 60 s gap; init took the span's mean rate (9.89 Hz), which the
    # ingest then refused as contradicting the stamps without naming the gap. The head's median spacing gives the
    # clock's rate; the note says how much is missing, and the ingest names the gap
    from imupipe.init import inspect_record

    t = np.arange(20000) / 10.0
    t[10000:] += 60.0
    x = np.random.default_rng(1).standard_normal((t.size, 6)) * 1e-3
    x[:, 5] += 9.80665
    path = tmp_path / "gap.csv"
    np.savetxt(path, np.column_stack([t, x]), delimiter=",", fmt="%.10g", comments="",
               header="t [s],gx [rad/s],gy [rad/s],gz [rad/s],ax [m/s^2],ay [m/s^2],az [m/s^2]")
    info = inspect_record(path, "gap")
    assert info.rate_hz == 10.0 and info.row["rate_hz"] == "10"
    (note,) = [n for n in info.notes if "missing" in n]
    assert "the timestamps' span gives 9.7 Hz but their spacing 10 Hz: about 62 s" in note, note  # the span's
    # rate is the probe's, rounded to 1e-3 (readers.snap_rate): the missing time to +- 2 s here (60.1 s)
    # a record without gaps: its span's rate, no note
    path2 = tmp_path / "nogap.csv"
    np.savetxt(path2, np.column_stack([np.arange(20000) / 10.0, x]), delimiter=",", fmt="%.10g", comments="",
               header="t [s],gx [rad/s],gy [rad/s],gz [rad/s],ax [m/s^2],ay [m/s^2],az [m/s^2]")
    info = inspect_record(path2, "nogap")
    assert info.rate_hz == 10.0 and not [n for n in info.notes if "missing" in n]
    # stamps jittered by +-40 ms (uniform), nothing missing: the span's rate, no note (a second outside evaluation:
    # the median spacing of 2000 stamps gave 9.9 Hz and "about -36 s missing")
    jit = np.arange(20000) / 10.0 + np.random.default_rng(2).uniform(-0.04, 0.04, 20000)
    path3 = tmp_path / "jitter.csv"
    np.savetxt(path3, np.column_stack([jit, x]), delimiter=",", fmt="%.10g", comments="",
               header="t [s],gx [rad/s],gy [rad/s],gz [rad/s],ax [m/s^2],ay [m/s^2],az [m/s^2]")
    info = inspect_record(path3, "jitter")
    assert info.rate_hz == 10.0 and not [n for n in info.notes if "missing" in n], info.notes
