"""The imupipe command (imupipe.cli): run, allan, check; exit codes and error messages naming the file."""

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from imupipe.cli import check_config, main

ROOT = Path(__file__).resolve().parents[1]
TINY = ROOT / "tests" / "configs" / "tiny.yaml"


@pytest.fixture
def white_csv(tmp_path):
    """A CSV of white gyro noise, density N = 0.01 deg/s/sqrt(Hz) at 50 Hz (column gx in deg/s)."""
    rate, n, N = 50.0, 200_000, 0.01
    rng = np.random.default_rng(11)
    x = N * math.sqrt(rate) * rng.standard_normal(n)
    path = tmp_path / "rec.csv"
    np.savetxt(path, x[:, None], header="gx", comments="", fmt="%.9e")
    return path, rate, N


def test_allan_table_of_a_csv(white_csv, capsys):
    path, rate, N = white_csv
    assert main(["allan", str(path), "--rate-hz", str(rate), "--channel", "gyro_x=gx", "--units", "gyro=deg/s"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith(f"# {path}") and "50 Hz" in out[0]
    assert out[1] == "tau_s\tgyro_x [rad/s]"
    rows = np.array([[float(v) for v in ln.split("\t")] for ln in out[2:]])
    tau, adev = rows[:, 0], rows[:, 1]
    # octave taus from 1/rate: 0.02 * 2^k s
    np.testing.assert_allclose(tau[:3], [0.02, 0.04, 0.08], rtol=1e-12)
    # white noise: ADEV = N / sqrt(tau) (N in rad/s/sqrt(Hz)); at tau = 1.28 s the record holds 4000 s / 1.28 s
    # = 3125 independent averages -> relative s.e. of the ADEV <= 1/sqrt(2 * 3125) = 1.3 % (the overlapping
    # estimate does better); 5 s.e. = 6.3 %
    i = int(np.argmin(abs(tau - 1.28)))
    np.testing.assert_allclose(adev[i] * math.sqrt(tau[i]), math.radians(N), rtol=0.063)


@pytest.mark.parametrize("suffix", [".svg", ".pdf"])
def test_allan_plot_written_in_the_format_of_its_name(white_csv, tmp_path, suffix, capsys):
    path, rate, _ = white_csv
    out = tmp_path / f"adev{suffix}"
    assert main(["allan", str(path), "--rate-hz", str(rate), "--channel", "gyro_x=gx", "--units", "gyro=deg/s",
                 "--plot", str(out)]) == 0
    head = out.read_bytes()[:200]
    assert (b"<svg" in head or b"<?xml" in head) if suffix == ".svg" else head.startswith(b"%PDF")


def test_allan_bad_file_is_named(tmp_path, capsys):
    missing = tmp_path / "nope.csv"
    assert main(["allan", str(missing), "--rate-hz", "10"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("imupipe: error:") and "nope.csv" in err


def test_check_tiny_config_passes(capsys):
    lines = check_config(TINY)
    assert any("spec sheet stim300.yaml" in ln for ln in lines)
    assert any("datasets: simulated" in ln for ln in lines)


def test_check_names_a_missing_spec_sheet(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text(TINY.read_text().replace("specs: [stim300]", "specs: [no_such_imu]"))
    assert main(["check", str(bad), "--no-dry-run"]) == 1
    err = capsys.readouterr().err
    assert "no_such_imu" in err and "does not exist" in err


def test_check_names_a_missing_dataset_file(tmp_path, capsys):
    sheet = tmp_path / "sheet.tsv"
    sheet.write_text("dataset\tpath\tformat\trate_hz\tgyro_unit\nlab1\t/nonexistent/lab1.csv\tcsv\t100\tdeg/s\n")
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(TINY.read_text().replace("datasets: null", f"datasets: {sheet}"))
    assert main(["check", str(cfg), "--no-dry-run"]) == 1
    err = capsys.readouterr().err
    assert "line 2" in err and "lab1" in err and "/nonexistent/lab1.csv: file not found" in err


def test_check_read_reads_every_record_and_names_the_bad_one(tmp_path, capsys):
    # two 1 h CSV records at 20 Hz; "in_g" stores accel in g but its row declares m/s^2: only reading the
    # samples shows it (the gravity check of ingest), which check without --read does not do
    rng = np.random.default_rng(3)
    n = 72_000
    for name, g in (("good", 9.80665), ("in_g", 1.0)):
        x = np.column_stack([0.01 * rng.standard_normal((n, 5)), g + 1e-3 * rng.standard_normal(n)])
        np.savetxt(tmp_path / f"{name}.csv", x, delimiter=",", comments="", fmt="%.6e",
                   header="gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z")
    sheet = tmp_path / "sheet.tsv"
    rows = "".join(f"{d}\t{tmp_path / f'{d}.csv'}\tcsv\t20\tdeg/s\tm/s^2\n" for d in ("good", "in_g"))
    sheet.write_text("dataset\tpath\tformat\trate_hz\tgyro_unit\taccel_unit\n" + rows)
    cfg = tmp_path / "cfg.yaml"
    text = TINY.read_text().replace("datasets: null", f"datasets: {sheet}")
    cfg.write_text(text[: text.index("simulation:")] + "simulation: null\n" + text[text.index("sensors:"):])
    assert main(["check", str(cfg), "--no-dry-run"]) == 0  # the sheet and the files are there
    capsys.readouterr()
    assert main(["check", str(cfg), "--no-dry-run", "--read"]) == 1
    err = capsys.readouterr().err
    assert f"{tmp_path / 'in_g.csv'} (dataset 'in_g')" in err and "accel_unit = 'g' would make it 1 g" in err
    assert "read well: good: 72000 samples at 20 Hz" in err and "read well: in_g" not in err
    sheet.write_text(sheet.read_text().replace("in_g\t", "#in_g\t"))  # a comment line is no record
    assert main(["check", str(cfg), "--no-dry-run", "--read"]) == 0
    out = capsys.readouterr().out
    assert "1 rows" in out and f"ok  read good: 72000 samples at 20 Hz (1.00 h) from {tmp_path / 'good.csv'}" in out
    # a record shorter than one Welch window stops the workflow before any job: its message, not an empty one
    short = cfg.read_text().replace("window_s: 1800.0", "window_s: 7200.0")
    cfg.write_text(short)
    assert main(["check", str(cfg), "--no-dry-run", "--read"]) == 1
    err = capsys.readouterr().err
    assert "dataset 'good' lasts 3600 s (72000 samples at 20 Hz, the sheet's rate_hz)" in err and "Error in file" not in err
    assert "psd.window_s = 7200 s" in err and "or correct rate_hz if it is not the record's rate" in err


def test_check_read_refuses_a_split_record_shorter_than_the_psd_window(tmp_path, capsys):
    # an outside evaluation: `gap_policy: split` kept 1500 s of a 7200 s record, `check --read` said ok (the start-up
    # check sees the whole file) and the run stopped in the PSD job. Two 60 s gaps in a 1 h record at 20 Hz leave
    # segments of at most 1260 s, below TINY's psd.window_s of 1800 s; one gap leaves 2000 s, which reads well,
    # with the reader's gap warning shown
    rng = np.random.default_rng(4)
    n = 72_000
    t = np.arange(n) / 20.0
    sheet = tmp_path / "sheet.tsv"
    cfg = tmp_path / "cfg.yaml"
    text = TINY.read_text().replace("datasets: null", f"datasets: {sheet}")
    cfg.write_text(text[: text.index("simulation:")] + "simulation: null\n" + text[text.index("sensors:"):])
    for gaps, ok in (((1200.0, 2400.0), False), ((2000.0,), True)):
        tt = t.copy()
        for g in gaps:
            tt[tt >= g] += 60.0
        x = np.column_stack([tt, 0.01 * rng.standard_normal((n, 5)), 9.80665 + 1e-3 * rng.standard_normal(n)])
        np.savetxt(tmp_path / "gappy.csv", x, delimiter=",", comments="", fmt="%.9f",
                   header="t,gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z")
        sheet.write_text("dataset\tpath\tformat\trate_hz\tgyro_unit\taccel_unit\ttime_column\tgap_policy\n"
                         f"gappy\t{tmp_path / 'gappy.csv'}\tcsv\t20\tdeg/s\tm/s^2\tt\tsplit\n")
        capsys.readouterr()
        assert main(["check", str(cfg), "--no-dry-run", "--read"]) == (0 if ok else 1)
        out = capsys.readouterr()
        if ok:
            assert "ok  read gappy: 40000 samples at 20 Hz" in out.out
            assert "warn " in out.out and "1 timestamp gap(s)" in out.out and "Kept the longest" in out.out
        else:
            # segments of 1200, 1140 and 1260 s (the second gap 60 s later in the shifted stamps)
            assert ("gappy: 1260 s read (gap_policy split kept the longest segment), shorter than psd.window_s = "
                    "1800 s") in out.err and "read well: gappy" not in out.err


def test_check_with_dry_run_and_run_dry(tmp_path):
    # the snakemake command line of the checkout, in a scratch working directory (nothing is run)
    proc = subprocess.run([sys.executable, "-m", "imupipe", "check", str(TINY), "--directory", str(tmp_path)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "ok  snakemake dry run" in proc.stdout
    proc = subprocess.run([sys.executable, "-m", "imupipe", "run", str(TINY), "--cores", "1", "--directory",
                           str(tmp_path), "--dry-run"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "rule bound" in proc.stdout + proc.stderr or "bound" in proc.stdout + proc.stderr
    assert not (tmp_path / "results").exists()  # a dry run writes no result


def test_check_takes_a_partial_config_on_top_of_the_defaults(tmp_path):
    # the README: "A config may be partial (the rest from config/config.yaml)"
    partial = tmp_path / "partial.yaml"
    partial.write_text("name: partial\npsd:\n  window_s: 3600.0\n")
    lines = check_config(partial)
    assert "the others from config/config.yaml" in lines[0]
    assert any("spec sheet stim300.yaml" in ln for ln in lines)


def test_check_names_a_misspelt_config_key(tmp_path):
    # the schema's verdict names the key; it stands above a long schema dump that a tail alone would cut off
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: bad\npsd:\n  windw_s: 100\n")
    proc = subprocess.run([sys.executable, "-m", "imupipe", "check", str(bad), "--directory", str(tmp_path)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 1
    assert "'windw_s' was unexpected" in proc.stderr


def test_run_keep_going_reaches_snakemake(monkeypatch, tmp_path):
    import imupipe.cli as cli

    calls = []
    monkeypatch.setattr(cli, "_call", lambda cmd, env=None: calls.append(cmd) or 0)
    assert main(["run", str(TINY), "--keep-going", "--directory", str(tmp_path)]) == 0
    assert "--keep-going" in calls[0]
    assert main(["run", str(TINY), "--directory", str(tmp_path)]) == 0
    assert "--keep-going" not in calls[1]


def test_run_works_in_the_checkout_whatever_the_current_directory(monkeypatch, tmp_path):
    # `imupipe run --help` says the working directory defaults to the checkout; an outside evaluation ran from /tmp
    # and Snakemake worked there (a second run from elsewhere found nothing of the first)
    import imupipe.cli as cli
    from imupipe.cli import checkout_root

    calls = []
    monkeypatch.setattr(cli, "_call", lambda cmd, env=None: calls.append(cmd) or 0)
    monkeypatch.chdir(tmp_path)
    assert main(["run", str(TINY)]) == 0
    assert calls[0][calls[0].index("--directory") + 1] == str(checkout_root())


def test_version_and_help():
    proc = subprocess.run([sys.executable, "-m", "imupipe", "--version"], capture_output=True, text=True)
    assert proc.returncode == 0 and proc.stdout.startswith("imupipe ")
    proc = subprocess.run([sys.executable, "-m", "imupipe", "--help"], capture_output=True, text=True)
    assert all(c in proc.stdout for c in ("run", "allan", "check"))


@pytest.mark.slow
def test_run_tiny_config_prints_the_summary(tmp_path):
    import shutil

    import yaml

    shutil.copytree(ROOT / "config" / "specs", tmp_path / "specs")
    cfg = yaml.safe_load(TINY.read_text())
    cfg["spec_dir"] = str(tmp_path / "specs")
    config = tmp_path / "config.yaml"
    config.write_text(yaml.safe_dump(cfg))
    proc = subprocess.run([sys.executable, "-m", "imupipe", "run", str(config), "--cores", "2", "--directory",
                           str(tmp_path)], capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.count("imupipe run summary: tiny, spec sheet stim300") == 1  # printed once, by the workflow
    # the first screen: the verdict table and the values to paste; the details stay in summary.md
    assert "| gyro | " in proc.stdout and "| accel | " in proc.stdout and "## Values to paste" in proc.stdout
    assert "# Details" not in proc.stdout and "## gyro: " not in proc.stdout
    assert "rule bound" not in proc.stdout + proc.stderr  # job blocks quiet by default (details in logs/)


def test_run_options_after_the_config_are_imupipes_and_after_dashes_snakemakes(monkeypatch, tmp_path):
    import imupipe.cli as cli

    calls = []
    monkeypatch.setattr(cli, "_call", lambda cmd, env=None: calls.append(cmd) or 0)
    assert main(["run", str(TINY), "--cores", "3", "--directory", str(tmp_path), "--", "--keep-going"]) == 0
    cmd = calls[0]
    assert cmd[cmd.index("--cores") + 1] == "3"
    assert cmd[cmd.index("--directory") + 1] == str(tmp_path.resolve())
    assert "--keep-going" in cmd and cmd[cmd.index("--quiet") + 1] == "rules"
    assert len(calls) == 1  # the summary is the workflow's own last output, not printed a second time


def test_summary_command_writes_markdown_and_html(tmp_path, capsys):
    from imupipe.io import write_yaml_atomic

    res = tmp_path / "results"
    write_yaml_atomic({"sensor": "accel", "bounded": False, "margin": 0.5, "margin_curve": "d/x",
                       "margin_frequency_hz": 0.1}, res / "bound" / "spec1" / "accel.yaml")
    md, page = tmp_path / "s.md", tmp_path / "s.html"
    assert main(["summary", str(res), "--markdown", str(md), "--html", str(page)]) == 0
    out = capsys.readouterr().out
    assert "## accel: NOT BOUNDED" in out and md.read_text().rstrip() == out.rstrip()
    assert "<h2>accel: NOT BOUNDED</h2>" in page.read_text()
    assert main(["summary", str(tmp_path / "none")]) == 1
    assert "no such results folder" in capsys.readouterr().err


def test_summary_command_gives_the_workflows_summary(tiny_run, capsys, monkeypatch):
    # imupipe summary reads every file the summary job reads (contract, verify, lines, outliers, PSD usage, Kalibr),
    # so a finished run's summary is summary.md itself, not a shorter one from the bound files alone (from the
    # run's working folder: the files are named as the workflow names them)
    work, _ = tiny_run
    monkeypatch.chdir(work)
    run = work / "results" / "tiny"
    assert main(["summary", "results/tiny"]) == 0
    assert capsys.readouterr().out.rstrip() == (run / "summary.md").read_text().rstrip()
    assert main(["summary", "results"]) == 0  # the results folder above the run: the same run
    assert capsys.readouterr().out.rstrip() == (run / "summary.md").read_text().rstrip()


def _stamped_csv(tmp_path, rate, factor, name="t", n=20_000):
    """White gyro noise at `rate` Hz with a time column `name` in units of `factor` s (ms: 1e-3)."""
    rng = np.random.default_rng(5)
    t = np.arange(n) / rate / factor
    path = tmp_path / f"stamped_{factor:g}.csv"
    np.savetxt(path, np.column_stack([t, 0.01 * rng.standard_normal(n)]), header=f"{name},gx", comments="",
               delimiter=",", fmt="%.17g")
    return path


@pytest.mark.parametrize("unit, factor", [("s", 1.0), ("ms", 1e-3), ("us", 1e-6), ("ns", 1e-9)])
def test_allan_infers_the_time_unit_of_a_t_column_and_says_so(tmp_path, capsys, unit, factor):
    # 100 Hz stamped in `unit`, no --time-column and no --time-unit: read as seconds, ms stamps gave 0.1 Hz (every
    # tau 1000x too long) and a `t` column was not taken for the time column ("sample rate unknown")
    path = _stamped_csv(tmp_path, 100.0, factor)
    assert main(["allan", str(path), "--channel", "gyro_x=gx", "--units", "gyro=deg/s"]) == 0
    cap = capsys.readouterr()
    assert "100 Hz" in cap.out.splitlines()[0]
    assert float(cap.out.splitlines()[2].split("\t")[0]) == pytest.approx(0.01)  # first tau = 1 / rate
    assert "column 't' read as the time column" in cap.err and f"time unit {unit} (" in cap.err
    # against a stated rate: the unit that matches it within 1 %
    assert main(["allan", str(path), "--channel", "gyro_x=gx", "--units", "gyro=deg/s", "--rate-hz", "100.5"]) == 0
    cap = capsys.readouterr()
    assert f"time unit {unit} (" in cap.err and "matches --rate-hz 100.5" in cap.err


def test_allan_time_unit_refused_when_ambiguous_or_no_unit_fits(tmp_path, capsys):
    # 5 Hz stamped in s reads 5 kHz in ms: both plausible, so no guess; a stated rate decides
    path = _stamped_csv(tmp_path, 5.0, 1.0, name="stamp")
    assert main(["allan", str(path), "--channel", "gyro_x=gx", "--units", "gyro=deg/s", "--time-column", "stamp"]) == 1
    err = capsys.readouterr().err
    assert "cannot infer the time unit: s and ms both put the sample rate in 1 .. 10000 Hz" in err
    assert "give --time-unit" in err
    assert main(["allan", str(path), "--channel", "gyro_x=gx", "--units", "gyro=deg/s", "--time-column", "stamp", "--rate-hz", "5"]) == 0
    assert "time unit s (" in capsys.readouterr().err
    # a rate no unit matches (100 Hz stamps against --rate-hz 120): named, with the rate each unit gives
    path = _stamped_csv(tmp_path, 100.0, 1e-3)
    assert main(["allan", str(path), "--channel", "gyro_x=gx", "--units", "gyro=deg/s", "--rate-hz", "120"]) == 1
    err = capsys.readouterr().err
    assert "no time unit makes the timestamps' spacing 10 match --rate-hz 120 within 1 %" in err
    assert "ms: 100 Hz" in err and "--time-unit" in err
    # a stated unit is used as given, without inference
    assert main(["allan", str(path), "--channel", "gyro_x=gx", "--units", "gyro=deg/s", "--time-unit", "ms"]) == 0
    assert "time unit" not in capsys.readouterr().err


@pytest.mark.parametrize("case", ["commas", "notes", "loop", "windows"])
def test_check_names_the_culprit_of_a_first_hour_sheet(tmp_path, capsys, case):
    # before: "no 'path' column", "does not exist" for a loop and a Windows path; the workflow's "Error validating
    # config file." for an extra column (the workflow reads the sheet header with the same check)
    rec = tmp_path / "lab1.csv"
    rec.write_text("gyro_x\n0.1\n0.2\n")
    head, row = ["dataset", "path", "format", "rate_hz", "gyro_unit"], ["lab1", str(rec), "csv", "100", "deg/s"]
    sep, expected = "\t", None
    if case == "commas":
        sep, expected = ",", "line 1: not tab-separated (found commas"
    elif case == "notes":
        head, row = head + ["notes"], row + ["bench 2"]
        expected = "unknown column 'notes' (column 6); allowed columns: dataset, path,"
    elif case == "loop":
        (tmp_path / "a.csv").symlink_to(tmp_path / "b.csv")
        (tmp_path / "b.csv").symlink_to(tmp_path / "a.csv")
        row[1] = str(tmp_path / "a.csv")
        expected = "line 2 (dataset 'lab1'): " + str(tmp_path / "a.csv") + ": symbolic link loop"
    else:
        row[1] = "data\\lab1.csv"
        expected = "the path has backslashes, a Windows path?"
    sheet = tmp_path / "sheet.tsv"
    sheet.write_text(sep.join(head) + "\n" + sep.join(row) + "\n")
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(TINY.read_text().replace("datasets: null", f"datasets: {sheet}"))
    assert main(["check", str(cfg), "--no-dry-run"]) == 1
    err = capsys.readouterr().err
    assert expected in err, err
