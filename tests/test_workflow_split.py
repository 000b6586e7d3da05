"""events.policy split end to end: a tiny run (tests/configs/tiny.yaml pattern: two 1.5 h records at 20 Hz of the
STIM-300-like truth) whose first record has a 2 mg accelerometer step at 2700 s. The axis is cut into two segments
that every modelling stage analyses as records; the other axes and the clean record are analysed whole."""

import re

import numpy as np
import pytest
import yaml

pytestmark = pytest.mark.slow  # a whole workflow run of two records (several minutes on 2 shared cores)

RATE, HOURS, STEP_S, STEP = 20.0, 1.5, 2700.0, 2e-3 * 9.80665  # Hz, h, s, m/s^2
COLS = ["gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"]


@pytest.fixture(scope="module")
def split_run(tmp_path_factory):
    pytest.importorskip("snakemake")
    from workflow_helpers import ROOT, TINY, copy_checkout, snakemake

    from imupipe.simulate import simulate
    from imupipe.specsheet import load_spec

    work = copy_checkout(tmp_path_factory.mktemp("split") / "checkout")
    truth = load_spec(ROOT / "config" / "truth" / "stim300_like.yaml").models
    n = int(HOURS * 3600 * RATE)
    t = np.arange(n) / RATE
    rows = []
    for k, name in enumerate(("stepped", "clean")):
        x = np.column_stack([simulate(truth[c.split("_")[0]], n, RATE, rng=100 * k + j) for j, c in enumerate(COLS)])
        if name == "stepped":
            x[int(STEP_S * RATE):, 3] += STEP
        np.savetxt(work / f"{name}.csv", np.column_stack([t, x]), delimiter=",", header=",".join(["time", *COLS]),
                   comments="")
        rows.append([name, f"{name}.csv", str(RATE), "time", "rad/s", "m/s^2", "yes", *COLS])
    head = ["dataset", "path", "rate_hz", "time_column", "gyro_unit", "accel_unit", "gravity_removed", *COLS]
    (work / "datasets.tsv").write_text("\n".join("\t".join(r) for r in [head, *rows]) + "\n")
    cfg = yaml.safe_load(TINY.read_text())
    cfg.update(name="split", datasets="datasets.tsv", simulation=None, events={"policy": "split"})
    config = work / "split.yaml"
    config.write_text(yaml.safe_dump(cfg))
    snakemake(work, config=config, snakefile=work / "Snakefile")
    return work / "results" / "split"


def test_the_stepped_axis_is_cut_and_the_others_are_whole(split_run):
    seg = yaml.safe_load((split_run / "segments" / "stepped" / "accel" / "x.yaml").read_text())
    (s0, s1) = seg["segments"]
    # the step found within 1 s, each side less the 1 s guard (events.burst_window_s)
    assert s0["start_s"] == 0.0 and abs(s0["stop_s"] - (STEP_S - 1.0)) <= 1.0
    assert abs(s1["start_s"] - (STEP_S + 1.0)) <= 1.0 and s1["stop_s"] == HOURS * 3600
    for other in (("stepped", "accel", "y"), ("clean", "accel", "x"), ("stepped", "gyro", "x")):
        assert yaml.safe_load((split_run / "segments" / "/".join(other)).with_suffix(".yaml").read_text()
                              )["n_segments"] == 1


def test_every_stage_analyses_the_segments(split_run):
    import netCDF4

    with netCDF4.Dataset(split_run / "decimated" / "stepped" / "accel" / "x.nc") as nc:
        bounds = np.asarray(nc.getncattr("record_segment_bounds")).reshape(-1, 2)
    assert bounds.shape == (2, 2) and bounds[0, 1] == bounds[1, 0]  # two decimated segments, stored end to end
    for kind in ("psd", "allan"):
        with netCDF4.Dataset(split_run / kind / "stepped" / "accel" / "x.nc") as nc:
            assert nc.getncattr("n_record_segments") == 2, kind
        with netCDF4.Dataset(split_run / kind / "clean" / "accel" / "x.nc") as nc:
            assert "n_record_segments" not in nc.ncattrs(), kind
    verdict = yaml.safe_load((split_run / "stationarity" / "stepped" / "accel" / "x.yaml").read_text())
    assert len(verdict["segments"]) == 2
    lines = yaml.safe_load((split_run / "lines" / "stepped" / "accel" / "x.yaml").read_text())
    assert "segments" in lines
    # the replay: one record per segment, never across the cut
    rep = yaml.safe_load((split_run / "verify" / "stim300" / "accel.yaml").read_text())
    assert {"stepped#1/x", "stepped#2/x", "clean/x"} <= set(rep["replayed_curves"])
    assert "stepped/x" not in rep["replayed_curves"]


def test_the_summary_names_the_event_and_the_cut(split_run):
    text = (split_run / "summary.md").read_text()
    flags = [ln for ln in text.splitlines() if ln.startswith("- FLAG event [stepped/accel/x")]
    assert flags and "cut: the record is analysed as 2 segment(s)" in flags[0], flags
    assert re.search(r"\baccel: BOUNDED\b", text), text[:2000]
