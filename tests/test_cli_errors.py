"""Bad input to ``imupipe check`` / ``imupipe run``: one line ``imupipe: error: ...`` naming the file and the key or
column and what was expected, exit status 1, no Python traceback; and a YAML key given twice refused by the one YAML
loader (imupipe.io.read_yaml) that configs and spec sheets go through. ``run`` checks before it starts Snakemake
(``_call`` is replaced: a test that reached Snakemake would fail on the call list, not hang)."""

from pathlib import Path

import pytest

import imupipe.cli as cli
from imupipe.cli import main

ROOT = Path(__file__).resolve().parents[1]
TINY = ROOT / "tests" / "configs" / "tiny.yaml"


@pytest.fixture
def no_snakemake(monkeypatch):
    calls = []
    monkeypatch.setattr(cli, "_call", lambda cmd, env=None: calls.append(cmd) or 0)
    return calls


def _one_error_line(capsys) -> str:
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("imupipe: error: ") and "Traceback" not in err, err
    return lines[0]


def _sheet_config(tmp_path, rows: str, extra: str = "") -> Path:
    sheet = tmp_path / "sheet.tsv"
    sheet.write_text("dataset\tpath\tformat\trate_hz\tgyro_unit\taccel_unit\n" + rows)
    text = TINY.read_text().replace("datasets: null", f"datasets: {sheet}")
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(text[: text.index("simulation:")] + "simulation: null\n" + text[text.index("sensors:"):] + extra)
    return cfg


def test_a_key_given_twice_is_refused_naming_the_file_the_key_and_both_lines(tmp_path, capsys, no_snakemake):
    from imupipe.io import DuplicateKeyError, read_yaml

    doc = tmp_path / "d.yaml"
    doc.write_text("name: a\npsd:\n  window_s: 100\n  step_s: 50\n  window_s: 200\nx: &A {p: 1}\ny:\n  <<: *A\n  q: 2\n")
    with pytest.raises(DuplicateKeyError, match=r"d\.yaml: key 'psd\.window_s' is given twice, on line 3 and line 5"):
        read_yaml(doc)
    doc.write_text("x: &A {p: 1}\ny:\n  <<: *A\n  p: 2\nz: [{a: 1}, {a: 2}]\n")  # a merge key and a list: no duplicate
    assert read_yaml(doc) == {"x": {"p": 1}, "y": {"p": 2}, "z": [{"a": 1}, {"a": 2}]}
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(TINY.read_text() + "name: again\n")
    n = len(TINY.read_text().splitlines())
    for argv in (["check", str(cfg), "--no-dry-run"], ["run", str(cfg)]):
        assert main(argv) == 1
        line = _one_error_line(capsys)
        assert f"{cfg}: key 'name' is given twice, on line 3 and line {n + 1}" in line
    assert no_snakemake == []


def test_a_spec_sheet_with_a_key_given_twice_is_refused(tmp_path):
    from imupipe.specsheet import SpecError, load_spec

    spec = tmp_path / "imu.yaml"
    spec.write_text("name: imu\ngyro:\n  white: {value: 0.1, unit: deg/sqrt(h)}\n  white: {value: 0.2, unit: deg/sqrt(h)}\n")
    with pytest.raises(SpecError, match=r"imu\.yaml: key 'gyro\.white' is given twice, on line 3 and line 4"):
        load_spec(spec)


@pytest.mark.parametrize("case", ["broken yaml", "bad key", "missing file", "bad unit", "short record"])
def test_check_and_run_give_one_line_naming_the_file_and_key(tmp_path, capsys, no_snakemake, case):
    rec = tmp_path / "rec.csv"
    rec.write_text("gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z\n" + "0.1,0.1,0.1,0.0,0.0,1.0\n" * 2000)
    if case == "broken yaml":
        cfg, expect = tmp_path / "cfg.yaml", ["cfg.yaml: not valid YAML (", "line 3, column 1"]  # the parser stops at the end
        cfg.write_text("name: x\npsd: [1,\n")
    elif case == "bad key":
        cfg = _sheet_config(tmp_path, f"d1\t{rec}\tcsv\t100\tdeg/s\tg\n", "events: {polcy: warn}\n")
        expect = ["cfg.yaml: Additional properties are not allowed ('polcy' was unexpected) (at events)"]
    elif case == "missing file":
        cfg = _sheet_config(tmp_path, f"d1\t{tmp_path / 'none.csv'}\tcsv\t100\tdeg/s\tg\n")
        expect = ["sheet.tsv, line 2 (dataset 'd1'): ", "none.csv: file not found"]
    elif case == "bad unit":
        cfg = _sheet_config(tmp_path, f"d1\t{rec}\tcsv\t100\tfurlong/s\tg\n")
        expect = ["sheet.tsv, line 2 (dataset 'd1'), column gyro_unit: cannot parse unit 'furlong/s'"]
    else:  # 20 s of samples against a 1800 s PSD window: the workflow's start-up probe, run before Snakemake
        cfg = _sheet_config(tmp_path, f"d1\t{rec}\tcsv\t100\tdeg/s\tg\n")
        expect = ["dataset 'd1' lasts 20 s", "psd.window_s = 1800 s"]
    for argv in (["check", str(cfg), "--no-dry-run"], ["run", str(cfg)]):
        assert main(argv) == 1
        err = capsys.readouterr().err
        assert "Traceback" not in err and err.startswith("imupipe: error: ")
        if case != "short record":  # (the probe lists every record that does not fit, one per line)
            assert len(err.strip().splitlines()) == 1, err
        for part in expect:
            assert part in err, err
    assert no_snakemake == []
