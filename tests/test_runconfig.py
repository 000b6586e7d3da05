"""imupipe.runconfig without Snakemake: config merge and renamed keys, cross-key checks, the dataset sheet's
parser, the simulated datasets, the start-up probe, spec sheets, the stale-output clean-up; and the size of the
rule files' helper code."""

import os
import re
from pathlib import Path

import numpy as np
import pytest
import yaml

from imupipe import runconfig as rc

ROOT = Path(__file__).resolve().parents[1]
TINY = yaml.safe_load((ROOT / "tests" / "configs" / "tiny.yaml").read_text())
SHEET_SCHEMA = ROOT / "workflow" / "schemas" / "datasets.schema.yaml"


def tiny(**sections):
    cfg = yaml.safe_load(yaml.safe_dump(TINY))
    for key, value in sections.items():
        cfg[key] = value if not isinstance(value, dict) else {**(cfg.get(key) or {}), **value}
    return cfg


# ---------------------------------------------------------------------------------------------------------
# merge, renamed keys, schema, cross-key checks


def test_tiny_config_merges_over_the_defaults():
    cfg = rc.load_config(tiny(), ROOT)
    assert cfg["application"] == {"filter_rate_hz": 1.0, "outage_s": 600.0}
    assert cfg["verify"]["fix_s"] == 600.0  # not in tiny.yaml: config/config.yaml's
    assert "filter_rate_hz" not in cfg["verify"]
    assert cfg["simulation"]["record_rate_hz"] == 20.0


@pytest.mark.parametrize("section, old, new", [
    ("application", "rate_hz", "application.filter_rate_hz"),
    ("application", "horizon_s", "application.outage_s"),
    ("simulation", "rate_hz", "simulation.record_rate_hz"),
])
def test_renamed_key_refused_with_the_new_name(section, old, new):
    cfg = tiny()
    cfg[section][old] = 1.0
    with pytest.raises(ValueError, match=rf"{section}\.{old} is now {re.escape(new)}"):
        rc.load_config(cfg, ROOT, where="my.yaml")


def test_removed_verify_filter_rate_refused_naming_the_key_that_holds_it():
    cfg = tiny(verify={"filter_rate_hz": 1.0})
    with pytest.raises(ValueError, match=r"my\.yaml: .*verify\.filter_rate_hz is no longer a key: .*runs at "
                                         r"application\.filter_rate_hz.*remove it"):
        rc.load_config(cfg, ROOT, where="my.yaml")


def test_every_renamed_key_is_named_at_once():
    cfg = tiny(verify={"filter_rate_hz": 1.0})
    cfg["application"] = {"rate_hz": 1.0, "horizon_s": 600.0}
    with pytest.raises(ValueError) as err:
        rc.load_config(cfg, ROOT)
    assert all(k in str(err.value) for k in ("application.rate_hz", "application.horizon_s", "verify.filter_rate_hz"))


def test_schema_names_a_misspelt_key():
    pytest.importorskip("jsonschema")
    with pytest.raises(ValueError, match=r"'windw_s' was unexpected.*\(at psd\)"):
        rc.load_config(tiny(psd={"windw_s": 100.0}), ROOT)


def test_both_or_neither_data_source_refused():
    with pytest.raises(ValueError, match="either 'datasets'"):
        rc.check_cross_keys(rc.load_config(tiny(), ROOT) | {"datasets": "sheet.tsv"})
    with pytest.raises(ValueError, match="neither 'datasets' nor 'simulation'"):
        rc.load_config(tiny(simulation=None), ROOT)


@pytest.mark.parametrize("fix, ok", [(1.0, True), (0.5, True), (0.3, False), (2.0, False)])
def test_fix_rate_must_divide_the_filter_rate(fix, ok):
    cfg = tiny(verify={"fix_rate_hz": fix})
    if ok:
        rc.load_config(cfg, ROOT)
    else:
        with pytest.raises(ValueError, match="verify.fix_rate_hz = .* must divide application.filter_rate_hz = 1.0"):
            rc.load_config(cfg, ROOT)


@pytest.mark.parametrize("low, ok", [(None, True), (1 / 3600, True), (0.002, False), (0.01, False)])
def test_the_low_band_must_be_finer_than_the_line_search(low, ok):
    # refused at start-up, before any job (the lines job would fail on every axis otherwise)
    cfg = tiny(lines={"resolution_hz": 0.002, "low_band_resolution_hz": low})
    if ok:
        assert rc.load_config(cfg, ROOT)["lines"]["low_band_resolution_hz"] == low
    else:
        with pytest.raises(ValueError, match=r"lines.low_band_resolution_hz = .* Hz must be finer \(smaller\) than "
                                             r"lines.resolution_hz = 0.002 Hz"):
            rc.load_config(cfg, ROOT)


@pytest.mark.parametrize("policy", ["warn", "exclude", "split"])
def test_every_events_policy_is_accepted_at_start_up(policy):
    assert rc.load_config(tiny(events={"policy": policy}), ROOT)["events"]["policy"] == policy


def test_an_unknown_events_policy_is_refused_at_start_up():
    with pytest.raises(ValueError, match="events"):
        rc.load_config(tiny(events={"policy": "cut"}), ROOT)


def test_divides_is_a_whole_ratio_of_at_least_one():
    assert rc.divides(125.0, 1.0) and rc.divides(0.3, 0.1) and rc.divides(100.0, 100.0)
    assert not rc.divides(10.0, 3.0) and not rc.divides(1.0, 2.0)


def test_span_and_replay_source():
    cfg = rc.load_config(tiny(), ROOT)
    assert rc.span_s(cfg) == 600.0 + 600.0  # verify.fix_s + application.outage_s
    assert rc.replay_from_decimated(cfg)  # 1 Hz decimation, 1 Hz filter
    cfg["application"]["filter_rate_hz"] = 10.0
    assert not rc.replay_from_decimated(cfg)


# ---------------------------------------------------------------------------------------------------------
# dataset sheet, simulated datasets, axes, ingest rules


def write_sheet(path, text):
    path.write_text(text)
    return path


def test_sheet_cells_cast_and_comments_skipped(tmp_path):
    sheet = write_sheet(tmp_path / "s.tsv", "# a comment\ndataset\tpath\trate_hz\tfill_max_samples\tgyro_x\n"
                                            "lab1\tlab1.csv\t100\t3\tgx\nlab2\tlab2.csv\t\t\t\n")
    rows = rc.read_sheet(sheet, SHEET_SCHEMA)
    assert rows["lab1"] == {"dataset": "lab1", "path": "lab1.csv", "rate_hz": 100.0, "fill_max_samples": 3,
                            "gyro_x": "gx"}
    assert isinstance(rows["lab1"]["rate_hz"], float) and isinstance(rows["lab1"]["fill_max_samples"], int)
    assert rows["lab2"] == {"dataset": "lab2", "path": "lab2.csv"}  # empty cells left out


@pytest.mark.parametrize("body, message", [
    ("lab1\tlab1.csv\tten\n", r"s\.tsv, line 2: rate_hz = 'ten' is not a number \(Hz\)"),
    ("lab1\tlab1.csv\t10\nlab1\tb.csv\t10\n", r"s\.tsv, line 3: dataset 'lab1' appears twice"),
    ("lab1\tlab1.csv\t10\textra\n", r"s\.tsv, line 2: 1 more cell\(s\) than the header has columns"),
    ("../x\tlab1.csv\t10\n", r"s\.tsv, line 2: dataset name '\.\./x'"),
])
def test_sheet_errors_name_the_line(tmp_path, body, message):
    sheet = write_sheet(tmp_path / "s.tsv", "dataset\tpath\trate_hz\n" + body)
    with pytest.raises(ValueError, match=message):
        rc.read_sheet(sheet, SHEET_SCHEMA)


def test_sheet_missing_or_empty(tmp_path):
    with pytest.raises(ValueError, match="config key 'datasets': dataset sheet .* not found"):
        rc.read_sheet(tmp_path / "none.tsv", SHEET_SCHEMA)
    with pytest.raises(ValueError, match="has no rows"):
        rc.read_sheet(write_sheet(tmp_path / "e.tsv", "dataset\tpath\n"), SHEET_SCHEMA)


def test_sheet_row_against_the_schema(tmp_path):
    pytest.importorskip("jsonschema")
    sheet = write_sheet(tmp_path / "s.tsv", "dataset\tpath\trate_hz\nlab1\tlab1.csv\t-5\n")
    with pytest.raises(ValueError, match=r"s\.tsv, line 2 \(dataset 'lab1'\): -5\.0 is less than or equal"):
        rc.read_sheet(sheet, SHEET_SCHEMA)


def test_simulated_datasets_and_seeds():
    sim = {"n_datasets": 3, "duration_h": 1.0, "record_rate_hz": 20, "truth": "t.yaml", "seed": 7,
           "gravity_axis": None}
    rows = rc.simulated_datasets(sim, "results/x")
    assert list(rows) == ["sim01", "sim02", "sim03"]
    assert rows["sim02"]["path"] == "results/x/simulated/sim02.nc" and rows["sim02"]["rate_hz"] == 20.0
    assert rows["sim01"]["gravity_removed"] == "yes"  # no gravity axis: nothing to check
    assert "gravity_removed" not in rc.simulated_datasets({**sim, "gravity_axis": "z"}, "r")["sim01"]
    assert rc.simulation_seeds(sim) == {"sim01": 7, "sim02": 8, "sim03": 9}
    assert rc.simulation_seeds(None) == {}


def test_axes_and_ingest_rules():
    datasets = {"a": {"gyro_x": "gx", "gyro_z": "gz"}, "b": {}, "c": {}}
    axes = rc.axes_of(datasets, ["gyro", "accel"])
    assert axes["a"] == {"gyro": ["x", "z"], "accel": ["x", "y", "z"]} and axes["b"]["gyro"] == ["x", "y", "z"]
    groups = rc.ingest_rule_groups(axes, ["gyro", "accel"])
    assert groups["ingest"][1] == ["b", "c"]
    assert groups["ingest_gyro_x_gyro_z_accel_x_accel_y_accel_z"][1] == ["a"]


def test_sheet_column_and_lines_params():
    ds = {"a": {"rate_hz": 100.0, "topic": "/imu"}, "b": {}}
    assert rc.sheet_column(ds, "rate_hz", float) == {"a": 100.0, "b": None}
    assert rc.sheet_column(ds, "topic") == {"a": "/imu", "b": None}
    assert rc.lines_params({"lines": {"policy": {"gyro": "keep"}}}) == {
        "policy": {"gyro": "keep", "accel": "model"}, "application_band_hz": None}


def test_datasets_of_a_sheet_paths_relative_to_the_working_directory(tmp_path, monkeypatch):
    write_sheet(tmp_path / "s.tsv", "dataset\tpath\nlab1\tdata/lab1.csv\n")
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    cfg = {"datasets": "s.tsv", "simulation": None}
    rows = rc.datasets_of(cfg, tmp_path, "results/x", SHEET_SCHEMA.parent)
    assert rows["lab1"]["path"] == os.path.join("..", "data", "lab1.csv")


# ---------------------------------------------------------------------------------------------------------
# start-up probe of the records, spec sheets


def test_simulated_records_fit_and_psd_window_filled():
    cfg = rc.load_config(tiny(psd={"window_s": None, "step_s": None}), ROOT)
    rc.check_records(cfg, rc.simulated_datasets(cfg["simulation"], "r"))
    # 1.5 h decimated to 1 Hz: imupipe.defaults.psd_window_step gives a quarter of the record, step half that
    assert (cfg["psd"]["window_s"], cfg["psd"]["step_s"]) == (1350.0, 675.0)


def test_record_rate_not_a_multiple_of_the_filter_rate_refused():
    cfg = rc.load_config(tiny(application={"filter_rate_hz": 3.0}), ROOT)
    with pytest.raises(ValueError, match=r"sim01: record rate 20 Hz is not a whole multiple of "
                                         r"application\.filter_rate_hz = 3\.0 Hz"):
        rc.check_records(cfg, rc.simulated_datasets(cfg["simulation"], "r"))


def test_short_record_names_psd_window(tmp_path):
    x = np.zeros((300, 6))
    path = tmp_path / "short.csv"
    np.savetxt(path, x, delimiter=",", header="gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z", comments="")
    cfg = rc.load_config({**tiny(simulation=None), "datasets": "s.tsv"}, ROOT)
    rows = {"short": {"dataset": "short", "path": str(path), "format": "csv", "rate_hz": 1.0, "gyro_unit": "rad/s",
                      "accel_unit": "m/s^2"}}
    with pytest.raises(ValueError, match="dataset 'short' lasts 300 s.*psd.window_s = 1800 s"):
        rc.check_records(cfg, rows)


def test_records_shorter_than_one_fix_period_and_outage_refused_at_start_up(tmp_path):
    """A record that holds the PSD window but not verify.fix_s + application.outage_s: the verification's replay
    could not run, found at start-up (an outside evaluation met it after three minutes, in the verify job)."""
    x = np.zeros((2000, 6))
    path = tmp_path / "short.csv"
    np.savetxt(path, x, delimiter=",", header="gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z", comments="")
    row = {"dataset": "short", "path": str(path), "format": "csv", "rate_hz": 1.0, "gyro_unit": "rad/s",
           "accel_unit": "m/s^2"}
    cfg = rc.load_config({**tiny(simulation=None, psd={"window_s": 300.0, "step_s": 150.0},
                                 application={"outage_s": 1800.0}), "datasets": "s.tsv"}, ROOT)
    with pytest.raises(ValueError, match=r"longest record \('short', 2000 s\) is shorter than config keys "
                                         r"verify\.fix_s \+ application\.outage_s = 600 \+ 1800 = 2400 s"):
        rc.check_records(cfg, {"short": row})
    cfg["application"]["outage_s"] = 1200.0  # 600 + 1200 s fit in 2000 s
    rc.check_records(cfg, {"short": row})


def test_a_rate_the_timestamps_contradict_skips_the_length_checks_that_read_rows_over_rate(tmp_path, capsys):
    """An outside evaluation declared rate_hz 100 for a 50 Hz record with timestamps: the start-up check read
    rows / rate_hz as its duration (half the truth) and asked to shorten application.outage_s. The stamps' span
    contradicts the rate, so the record's length checks are left out at start-up and its ingest (here `imupipe check
    --read`, as the run's ingest job) names rate_hz and both rates, the other datasets going on. A record whose
    stamps agree is length-checked as before, also with a gap the policy fills (gap_policy fill) or splits at."""
    from imupipe.cli import main

    n = 2400
    t = np.arange(n) / 1.0
    path = tmp_path / "stamped.csv"
    data = np.column_stack([t, np.zeros((n, 5)), np.full(n, 9.80665)])

    def save(x):
        np.savetxt(path, x, delimiter=",", header="t,gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z", comments="")

    save(data)
    row = {"dataset": "stamped", "path": str(path), "format": "csv", "rate_hz": 2.0, "gyro_unit": "rad/s",
           "accel_unit": "m/s^2", "time_column": "t"}
    cfg = rc.load_config({**tiny(simulation=None, psd={"window_s": 300.0, "step_s": 150.0},
                                 application={"outage_s": 1300.0, "filter_rate_hz": 1.0}), "datasets": "s.tsv"}, ROOT)
    (warned,) = rc.check_records(cfg, {"stamped": row})  # 1200 s by rows / rate_hz: no length problem for a wrong rate
    assert warned.startswith("stamped: rate_hz = 2 Hz, but its 2400 rows span 2399 s of timestamps ((rows - 1) / "
                             "span = 1 Hz; a gap lowers it): its length is not checked here")
    with pytest.raises(ValueError, match=r"longest record \('stamped', 1200 s\) is shorter"):  # without the stamps
        rc.check_records(cfg, {"stamped": {**row, "time_column": ""}})
    save(np.delete(data, np.s_[600:1200], axis=0))  # a 600 s gap: 1800 rows over 2399 s of stamps
    rc.check_records(cfg, {"stamped": {**row, "rate_hz": 1.0}})  # left to the ingest (gap_policy fail)
    for policy in ({"long_gap_policy": "split"}, {"gap_policy": "split"}):  # 1800 rows < 600 + 1300 s
        with pytest.raises(ValueError, match="is shorter than config keys"):
            rc.check_records(cfg, {"stamped": {**row, "rate_hz": 1.0, **policy}})
    save(np.delete(data, np.s_[600:620], axis=0))  # 20 of 2400 rows dropped (0.8 %): what gap_policy fill fills
    assert rc._stamps_contradict(rc._probe({**row, "rate_hz": 1.0, "gap_policy": "fill"}, None)[2],
                                 {"gap_policy": "fill"}) is None
    # the evaluator's case through the command line: the ingest's message, naming rate_hz and both rates
    save(data)
    sheet, cfg_file = tmp_path / "s.tsv", tmp_path / "c.yaml"
    sheet.write_text("\t".join(row) + "\n" + "\t".join(str(v) for v in row.values()) + "\n")
    cfg_file.write_text(yaml.safe_dump({**tiny(simulation=None, psd={"window_s": 300.0, "step_s": 150.0},
                                              application={"outage_s": 1300.0, "filter_rate_hz": 1.0}),
                                        "datasets": str(sheet)}))
    assert main(["check", str(cfg_file), "--no-dry-run"]) == 0  # without --read: said, not refused
    assert "warn stamped: rate_hz = 2 Hz, but its 2400 rows span 2399 s" in capsys.readouterr().out
    assert main(["check", str(cfg_file), "--no-dry-run", "--read"]) == 1
    err = capsys.readouterr().err
    assert "rate_hz = 2 Hz but the timestamps ('t') give a mean rate of 1 Hz" in err and "outage_s" not in err


def test_unreadable_record_left_to_its_ingest_job(tmp_path):
    cfg = rc.load_config({**tiny(simulation=None), "datasets": "s.tsv"}, ROOT)
    rc.check_records(cfg, {"gone": {"dataset": "gone", "path": str(tmp_path / "gone.csv"), "format": "csv"}})


def test_spec_sheets_read_and_missing_one_named(tmp_path):
    cfg = rc.load_config(tiny(), ROOT)
    assert [s.name for s in rc.check_specs(cfg, ROOT)] == ["STIM-300"]
    with pytest.raises(ValueError, match=r"specs lists 'nope' but .*nope\.yaml does not exist"):
        rc.check_specs({**cfg, "specs": ["nope"]}, ROOT)
    with pytest.raises(ValueError, match="no section for magneto"):
        rc.check_specs({**cfg, "sensors": ["gyro", "magneto"]}, ROOT)


# ---------------------------------------------------------------------------------------------------------
# stale outputs


def touch(path):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("x")
    return str(path)


def test_remove_stale_keeps_what_the_run_writes(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    res, logs = Path("results/t"), Path("logs/t")
    made = touch(res / "bound" / "a.yaml")
    rerun = touch(res / "kf" / "a.yaml")
    stale = touch(res / "bound" / "old_spec" / "a.yaml")
    kept = touch(res / "extra" / "note.txt")
    tmp = touch(logs / "kf" / ".tmp-a.log")
    removed = rc.remove_stale((str(res), str(logs)), produced=[made, rerun], rerun=[rerun], keep=["extra/*"])
    assert set(removed) == {os.path.normpath(p) for p in (rerun, stale, tmp)}
    assert Path(made).is_file() and Path(kept).is_file() and not Path(stale).exists()
    assert not (res / "bound" / "old_spec").exists()  # the folder left empty
    assert (res / "bound").is_dir()


def test_remove_stale_of_named_targets_walks_nothing(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    other = touch(Path("results/t/bound/b.yaml"))
    tmp = touch(Path("results/t/.tmp-x"))
    assert rc.remove_stale(("results/t", "logs/t")) == [os.path.normpath(tmp)]
    assert Path(other).is_file()


# ---------------------------------------------------------------------------------------------------------
# the rule files keep rules, names, input functions and resources


def helper_lines(text: str) -> int:
    """Non-blank, non-comment lines outside `rule` blocks (a block: the `rule` line and its indented body) and
    outside the Snakemake directives that take a value (include, wildcard_constraints, report, on*)."""
    count, inside = 0, False
    for line in text.splitlines():
        stripped = line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        top = not line[0].isspace()
        if top:
            inside = bool(re.match(r"(rule\b|wildcard_constraints:|include:|report:|onstart:|onsuccess:|onerror:)",
                                   stripped))
            if not inside and re.match(r"for .*:$", stripped):  # a loop of rules (ingest.smk)
                inside = True
        if not inside:
            count += 1
    return count


def test_rule_files_helper_code_within_250_lines():
    total = {p.name: helper_lines(p.read_text()) for p in (ROOT / "workflow" / "rules").glob("*.smk")}
    assert sum(total.values()) <= 250, total


def test_helper_lines_counts_outside_rules_only():
    text = "X = 1\n\n# c\nrule a:\n    input:\n        'f'\n\n\ndef f(w):\n    return 2\n"
    assert helper_lines(text) == 3
