"""The line search under events.policy warn reads each burst's stretch filled (imupipe.events.fill_bursts through
imupipe.stages.outliers.line_search_series, the one entry of the lines job and the API): a knock's ringing is no
line, and a stationary line through the knock keeps its power."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from imupipe.events import burst_spans, fill_bursts, find_bursts
from imupipe.io import write_series
from imupipe.lines import find_lines, line_power_lower, line_power_upper
from imupipe.models import NoiseModel
from imupipe.stages.outliers import EVENT_DEFAULTS, line_search_series, outliers_stage

RATE = 100.0
#: a MEMS-like gyro axis (rad/s): white 2e-4 rad/s/sqrt(Hz), a 100 s GM of 5e-5 rad/s, random walk 2e-6
MODEL = NoiseModel(white=2e-4, gauss_markov=((5e-5, 100.0),), random_walk=2e-6)
SD = 2e-4 * np.sqrt(RATE)  # per-sample white sd, rad/s
#: the knock: 2 s of three decaying tones (Hz, amplitude in per-sample sds), decay time 0.5 s
RINGING = ((4.7, 60.0), (12.3, 40.0), (31.0, 30.0))
#: the search init writes for a user's records (lines.scales [1, 8, 64] at the default 0.002 Hz)
SEARCH = dict(resolution_hz=0.002, alpha=0.01, floor_window_bins=51, scales=(1, 8, 64))


def _record(seed: int, seconds: float = 1800.0, knock_s: float = 700.3, line_amplitude: float = 0.0):
    from imupipe.simulate import simulate

    rng = np.random.default_rng(seed)
    n = int(seconds * RATE)
    x = simulate(MODEL, n, RATE, rng)
    if line_amplitude:
        x += line_amplitude * np.sin(2 * np.pi * 12.0 * np.arange(n) / RATE + 1.0)
    t = np.arange(int(2 * RATE)) / RATE
    i0 = int(knock_s * RATE)
    for f, a in RINGING:
        x[i0:i0 + t.size] += a * SD * np.exp(-t / 0.5) * np.sin(2 * np.pi * f * t)
    return x


class TestFillBursts:
    def test_the_widened_burst_is_filled_from_the_median_before_to_that_after_and_nothing_else(self):
        x = _record(1)
        b = find_bursts(x, RATE, alpha=EVENT_DEFAULTS["alpha"] / 2)  # detect_events' share of the level
        assert len(b["bursts"]) == 1
        w = b["window"]
        ((start, stop),) = burst_spans(b)  # the span, or the energetic blocks and their tail
        e = b["bursts"][0]
        assert e["tail_start"] <= e["block_start"] <= e["start"] and e["stop"] <= e["block_stop"] <= e["tail_stop"]
        y, stretches = fill_bursts(x, RATE)
        a, c = start - w, stop + w
        assert len(stretches) == 1 and stretches[0] == pytest.approx((a / RATE, c / RATE), abs=1e-12)
        r = max(w, (c - a) // 2)  # the levels read over a window or half the stretch, whichever is longer
        assert np.allclose(y[a:c], np.linspace(np.median(x[a - r:a]), np.median(x[c:c + r]), c - a), rtol=0, atol=1e-15)
        assert np.array_equal(y[:a], x[:a]) and np.array_equal(y[c:], x[c:])

    def test_a_record_without_burst_is_returned_as_it_is(self, rng):
        x = 0.01 * rng.standard_normal(60_000)
        y, stretches = fill_bursts(x, RATE)
        assert np.shares_memory(y, x) and np.array_equal(y, x) and stretches == ()

    def test_only_warn_fills(self):
        x = _record(2)
        for policy in ("split", "exclude"):
            y, stretches = line_search_series(x, RATE, {"policy": policy})
            assert np.shares_memory(y, x) and stretches == ()
        assert line_search_series(x, RATE, {})[1]  # the defaults: warn

    def test_the_filled_stretch_holds_the_outliers_reports_burst_widened_by_one_window(self):
        # the lines job scans again rather than reading the report: both must name the same burst, the fill reaching
        # one window beyond the reported span (and beyond its energetic blocks)
        x = _record(3)
        report, _ = outliers_stage(x, RATE, units="rad/s", sensor="gyro")
        bursts = [e for e in report["events"] if e["kind"] == "burst"]
        window_s = report["events_scan"]["burst_scan"]["window_s"]
        (a, c), = line_search_series(x, RATE, {})[1]
        assert len(bursts) == 1
        assert a <= bursts[0]["start_s"] - window_s + 1e-9 and c >= bursts[0]["stop_s"] + window_s - 1e-9
        assert c - a < 10.0  # the 2 s knock's blocks and a window each side, not more

    def test_a_long_vibration_is_filled_over_its_energetic_blocks(self):
        # 20 s of a 22 Hz tone of 5 sds: its samples beyond burst_k = 7 sds cover part of it only; filling that part
        # left a line at 22 Hz (benchmarks/line_bursts.py)
        x = _record(4)
        t = np.arange(int(20 * RATE)) / RATE
        i0 = int(1000 * RATE)
        x[i0:i0 + t.size] += 5 * SD * np.clip(np.minimum(t, 20 - t) / 0.3, 0, 1) * np.sin(2 * np.pi * 22.0 * t)
        assert any(abs(ln.frequency_hz - 22.0) < 0.2 for ln in find_lines(x, RATE, **SEARCH).lines)
        y, stretches = line_search_series(x, RATE, {})  # the record's knock at 700 s and the vibration
        assert len(stretches) == 2 and stretches[1][0] <= 1000 and stretches[1][1] >= 1020
        assert find_lines(y, RATE, **SEARCH).lines == ()


class TestSlowRinging:
    @pytest.mark.parametrize("decay_s", [2.0, 5.0, 8.0])
    def test_a_ringing_decaying_over_seconds_is_filled_to_its_end(self, decay_s):
        # an outside evaluation's knock (7.3 Hz, 100 sds, decay 5 s) rang 4-5 sds beyond its span: filling the span
        # left a line in 4 of 4 records at decays of 4 and 8 s. The tail (adjacent blocks above BURST_TAIL_Z) is filled
        # too; the decay times here are others than the evaluation's, the tone and record too
        rng = np.random.default_rng(int(decay_s * 10))
        x = SD * rng.standard_normal(int(3600 * RATE))
        t = np.arange(int(8 * decay_s * RATE)) / RATE
        i0 = int(1234.56 * RATE)
        x[i0:i0 + t.size] += 80 * SD * np.exp(-t / decay_s) * np.sin(2 * np.pi * 9.7 * t)
        assert any(abs(ln.frequency_hz - 9.7) < 0.2 for ln in find_lines(x, RATE, **SEARCH).lines)
        y, ((a, c),) = line_search_series(x, RATE, {})
        assert a <= 1234.56 and c >= 1234.56 + 3 * decay_s  # the ringing's amplitude down to 5 % of its start
        assert find_lines(y, RATE, **SEARCH).lines == ()


class TestLineSearch:
    @pytest.mark.parametrize("seed", [11, 12, 13])
    def test_a_knocks_ringing_is_three_lines_unless_filled(self, seed):
        x = _record(seed)
        raw = find_lines(x, RATE, **SEARCH)
        # the failure mode: each tone of the knock found as a line within a coarse bin (0.128 Hz) of its frequency
        assert all(any(abs(ln.frequency_hz - f) < 0.2 for ln in raw.lines) for f, _ in RINGING)
        y, stretches = line_search_series(x, RATE, {})
        assert len(stretches) == 1
        assert find_lines(y, RATE, **SEARCH).lines == ()

    @pytest.mark.parametrize("seed", [21, 22, 23])
    def test_a_line_through_the_knock_keeps_its_power(self, seed):
        # a 12 Hz tone of 0.05 per-sample sds (power A^2 / 2 = 5e-9 (rad/s)^2) through the knock: the filled stretch
        # (~3.5 s of 1800 s) takes 0.2 % of its coherent power, far inside the search's own interval at 0.999
        amp = 0.05 * SD
        y, _ = line_search_series(_record(seed, line_amplitude=amp), RATE, {})
        lines = find_lines(y, RATE, **SEARCH).lines
        assert len(lines) == 1 and abs(lines[0].frequency_hz - 12.0) < 0.002
        ln = lines[0]
        assert line_power_lower(ln.power, ln.dof, 0.999) <= amp**2 / 2 <= line_power_upper(ln.power, ln.dof, 0.999)


def test_the_lines_job_and_the_api_fill_the_same_stretches_and_find_the_same_lines(tmp_path):
    pytest.importorskip("snakemake", reason="the stage scripts import what the workflow installs")
    from workflow_helpers import stage_script

    from imupipe.api import _lines_of

    x = _record(31, line_amplitude=0.05 * SD)
    series, out = tmp_path / "series.nc", tmp_path / "lines.yaml"
    write_series(series, x, rate_hz=RATE, units="rad/s", attrs={"dataset": "rec", "sensor": "gyro", "axis": "x"})
    stage_script("lines").main(path_series=str(series), path_lines=str(out), events={}, **{
        k: v for k, v in SEARCH.items()})
    job = yaml.safe_load(out.read_text())
    api = _lines_of({"rec/x": x}, RATE, "gyro", events=dict(EVENT_DEFAULTS), **SEARCH)["rec/x"]
    assert job["bursts_filled"] == api["bursts_filled"] and len(job["bursts_filled"]) == 1
    assert job["units"]["bursts_filled"] == "s from the record's start"
    assert job["lines"] == api["lines"] and job["n_lines"] == 1
