"""The user-facing sentences of imupipe.verdict against closed forms: stationarity failures against the binomial
count chance gives (P(X >= k), X ~ Binomial(n, alpha), checked against scipy.stats.binom), and where each sentence
reaches the files and the summary a user reads."""

from __future__ import annotations

import pytest
from scipy.stats import binom

from imupipe.verdict import chance_failures, within_tolerance


@pytest.mark.parametrize("k,n,alpha", [(1, 24, 0.05), (3, 24, 0.05), (5, 15, 0.05), (2, 6, 0.01)])
def test_chance_failures_is_the_binomial_tail(k, n, alpha):
    text = chance_failures(k, n, alpha)
    tail = binom.sf(k - 1, n, alpha)  # P(X >= k)
    assert f"{k} of {n} axes failed at level {alpha:g} each" in text
    assert f"{n * alpha:.2g} fail by chance on average and P(>= {k}) = {tail:.2g}" in text
    # the wording follows the tail against the level: 1 of 24 at 0.05 (P 0.71) is chance, 5 of 15 (P 0.006) is not
    assert ("consistent with chance" in text) == (tail >= alpha)
    assert ("more than chance gives" in text) == (tail < alpha)


def test_chance_failures_is_silent_without_failures_or_level():
    assert chance_failures(0, 24, 0.05) is None
    assert chance_failures(2, 24, None) is None and chance_failures(2, 24, 0.0) is None


def test_the_stationarity_summary_states_its_level_and_chance_and_the_flag_carries_it():
    from imupipe.stages.stationarity import summary_stage
    from imupipe.summary import flags_of

    def verdict(axis, ok, segments=None):
        v = {"dataset": "a", "axis": axis, "stationary": ok, "p_value": 0.5 if ok else 0.01, "test": "calibrated",
             "paper": {"stationary": ok}, "calibrated": {"alpha": 0.05 / len(segments or [0])}}
        return {**v, "segments": segments} if segments else v

    axes = [verdict(ax, ax != "z") for ax in ("x", "y", "z")] * 4  # 12 axes, 4 failing
    s = summary_stage(axes, "warn", "gyro")
    assert s["alpha"] == 0.05 and s["chance"] == chance_failures(4, 12, 0.05)
    (f, *_) = [f for f in flags_of("gyro", stationarity=s) if f.check == "stationarity"]
    assert f.detail.endswith("; " + s["chance"]) and "more than chance gives" in f.detail
    # a record split into 2 segments is tested at alpha/2 per segment: the axis's level is alpha again
    split = summary_stage([verdict("x", False, segments=[{}, {}])] + [verdict("y", True)] * 23, "warn", "gyro")
    assert split["alpha"] == pytest.approx(0.05) and "consistent with chance" in split["chance"]


def test_a_pass_within_the_replay_tolerance_names_what_to_do():
    text = within_tolerance({"worst_ratio": 1.1, "tolerance": 0.15, "passed": True, "method": "replay of static "
                             "records", "n_eff": 400.0, "relative_standard_error": 0.0707})
    assert "tolerance 1 + 0.15 = 1.15" in text
    assert "rests on the exact checks" in text and "record more or longer" in text
    assert "so would a filter that under-states its error by up to that much" in text


def test_a_replay_verdict_in_the_file_says_its_worst_is_in_the_fixes():
    # an outside evaluation read "1.19 at 227 s" in the FLAG beside "1.12" in the candidates' table (the outage's):
    # the verification's own sentence (what the verify and contract files carry) now says where the worst lies
    from imupipe.verify import Verification

    v = Verification(t_s=None, mse=None, P=None, ratio=None, worst_ratio=1.19, worst_t_s=227.0,
                     worst_outage_ratio=1.12, mean_conservatism=2.0, first_exceed_s=227.0, passed=True, tol=0.667,
                     details={"method": "replay of static records", "n_eff": 18.0,
                              "relative_standard_error": 0.333}, worst_outage_t_s=610.0)
    text = v.to_dict()["within_tolerance"]
    assert "ratio 1.19 at 227 s, in the fixes; the outage's worst 1.12" in text


def test_an_event_flag_says_how_many_events_chance_gives():
    # the default run FLAGs one step on one of 15 gyro axes, each scanned at a false-alarm rate of 0.01 per record:
    # 0.15 expected by chance, P(>= 1) = 1 - 0.99^15 = 0.14, consistent with chance (an outside evaluation asked)
    from imupipe.summary import flags_of

    ev = {"dataset": "sim03", "sensor": "gyro", "axis": "x", "kind": "step", "time_s": 16801.2, "size": 2.2e-5,
          "units": "rad/s", "policy": "warn", "action": "kept in the analysis (events.policy warn)"}
    (f,) = [f for f in flags_of("gyro", bound={"events": [ev], "events_scanned": [0.01] * 15}) if f.check == "event"]
    assert f.detail.endswith("; " + chance_failures(1, 15, 0.01, "show an event", "show one", "no event in any record"))
    assert "1 of 15 axes show an event at level 0.01 each; with no event in any record 0.15 show one" in f.detail
    assert "P(>= 1) = 0.14: consistent with chance" in f.detail
    (g,) = [f for f in flags_of("gyro", bound={"events": [ev]}) if f.check == "event"]  # no scan record: no clause
    assert "by chance" not in g.detail
    # the event's own p_value (the scan's false-alarm rate at its z): the default run's step, p 0.006, is not beyond
    # alpha / 15; an outside evaluation's 1 mg step at z 45.9 (threshold 6.06), p 1e-29, is, whatever the count says
    weak = {**ev, "z": 6.2, "threshold_z": 6.06, "p_value": 0.006}
    (f,) = [f for f in flags_of("gyro", bound={"events": [weak], "events_scanned": [0.01] * 15}) if f.check == "event"]
    assert f.detail.endswith(": consistent with chance") and "the strongest" not in f.detail
    strong = {**ev, "z": 45.9, "threshold_z": 6.06, "p_value": 1e-29}
    (f,) = [f for f in flags_of("gyro", bound={"events": [strong], "events_scanned": [0.01] * 3}) if f.check == "event"]
    assert ("1 of 3 axes show an event at level 0.01 each; with no event in any record 0.03 show one by chance on "
            "average and P(>= 1) = 0.03; the strongest, a step on sim03/gyro/x at z 45.9 (threshold 6.06), has p = "
            "1e-29 per record, below alpha / 3 = 0.0033: more than chance gives") in f.detail


def test_a_line_flag_says_how_many_lines_chance_gives():
    # the default run (a line-free truth) FLAGs a weak line on one of 15 gyro series, each searched at family-wise
    # level 0.01: P(>= 1) = 1 - 0.99^15 = 0.14, consistent with chance (an outside evaluation asked); six of six axes
    # with lines (the ADIS16405 accelerometers) are more than chance gives
    from imupipe.summary import flags_of

    line = {"dataset": "sim03", "sensor": "gyro", "axis": "x", "frequency_hz": 16.88, "amplitude": 5e-6,
            "peak_ratio": 1.77, "units": {"amplitude": "rad/s"}}
    search = [{"f_min_hz": 0.052, "f_max_hz": 62.45, "resolution_hz": 0.002, "alpha": 0.01}] * 15
    (f,) = [f for f in flags_of("gyro", bound={"lines": [line], "line_search": search}) if f.check == "lines"]
    assert f.detail.endswith("; " + chance_failures(1, 15, 0.01, "show a line", "show one", "no line in any record"))
    assert "P(>= 1) = 0.14: consistent with chance" in f.detail
    six = [{**line, "dataset": d, "axis": a} for d in ("i1", "i2") for a in "xyz"]
    flags = [f for f in flags_of("gyro", bound={"lines": six, "line_search": search[:6]}) if f.check == "lines"]
    assert flags and all("6 of 6 axes show a line" in f.detail and "more than chance gives" in f.detail
                         for f in flags)
    (g,) = [f for f in flags_of("gyro", bound={"lines": [line]}) if f.check == "lines"]  # no search record: no clause
    assert "by chance" not in g.detail


class TestConfidenceStatement:
    """imupipe.verdict.confidence_statement / confidence_lines: the level a bounded verdict rests on, read from the
    bound's identification level and each per-axis model's, stated where the user reads the verdict."""

    def test_the_identification_level_and_the_envelope_kind(self):
        from imupipe.verdict import confidence_statement

        st = confidence_statement({"identification_intervals": {"n_boot": 100, "confidence": 0.9},
                                   "upper_envelope_kind": "joint", "per_axis_models": None})
        assert st["level"] == 0.9 and st["envelope"] == "joint" and st["per_axis_level"] is None
        assert "confidence 0.9" in st["statement"] and "0.1 of runs" in st["statement"]
        # the level's assumption is stated with it: a process coherent over a whole record is seen once
        assert "decorrelates within the records" in st["statement"] and "slow narrow oscillation" in st["statement"]
        marginal = confidence_statement({"identification_intervals": {"confidence": 0.95}})
        assert marginal["envelope"] == "marginal" and "each at 0.95" in marginal["statement"]
        # components at 0.95 each hold together at 1 - k 0.05 at least (an outside evaluation): the statement says so
        # and that the 0.95 it states for the envelope is the measured coverage
        assert "at least 1 - k (1 - 0.95) for k components by Bonferroni" in marginal["statement"]
        assert "97 of 100" in marginal["statement"]
        assert confidence_statement({}) is None

    def test_per_axis_models_state_their_own_level(self):
        from imupipe.stages.identify import axis_level
        from imupipe.verdict import confidence_statement

        level = axis_level(0.95, 3, pooled=False, envelope_kind="joint", n_boot=100)
        st = confidence_statement({"identification_intervals": {"confidence": 0.95}, "upper_envelope_kind": "joint",
                                   "per_axis_models": {ax: {"identification_level": level} for ax in "xyz"}})
        assert st["per_axis_level"] == pytest.approx(1 - 0.05 / 3)
        assert "0.9833" in st["statement"] and "Bonferroni over 3 axes" in st["statement"]

    def test_the_summary_line_names_the_sensors_of_each_statement(self):
        from imupipe.verdict import confidence_lines

        st = {"statement": "the envelope X"}
        lines = confidence_lines({"gyro": {"confidence": st}, "accel": {"confidence": st}, "mag": {}})
        assert lines == ["What BOUNDED rests on (gyro, accel): the envelope X", ""]
        assert confidence_lines({"gyro": None}) == []
        # the first screen's sentence where the contract has one, the paragraph where it has none
        both = {"gyro": {"confidence": {**st, "short": "X in short"}}, "accel": {"confidence": st}}
        assert confidence_lines(both, "short") == ["What BOUNDED rests on (gyro): X in short", "",
                                                   "What BOUNDED rests on (accel): the envelope X", ""]

    def test_the_first_screen_states_it_in_one_sentence_and_the_details_in_full(self):
        from imupipe.summary import DETAILS_HEADING, render_summary
        from imupipe.verdict import confidence_statement

        st = confidence_statement({"identification_intervals": {"confidence": 0.95, "model_adequate": False},
                                   "upper_envelope_kind": "joint"})
        assert st["short"].startswith("the identified upper envelope at confidence 0.95 (joint) is the one "
                                      "statistical statement: in the other 0.05 of runs a filter on the exported "
                                      "model can under-state its error; it assumes noise that decorrelates")
        assert "a model the data reject" in st["short"] and len(st["short"]) < len(st["statement"]) / 2
        text = render_summary({"gyro": {"bound": {"sensor": "gyro", "bounded": True, "confidence": st}}})
        head, details = text.split(DETAILS_HEADING)
        assert f"What BOUNDED rests on (gyro): {st['short']}" in head and st["statement"] not in head
        assert "## What BOUNDED rests on" in details and f"What BOUNDED rests on (gyro): {st['statement']}" in details


class TestAxisLevel:
    """imupipe.stages.identify.axis_level: each axis's own identification at the Bonferroni level where the axes get
    their own models (pooling rejected, joint band), with the bootstrap replicates that resolve that quantile."""

    def test_bonferroni_where_the_axes_have_their_own_models(self):
        import math

        from imupipe.stages.identify import axis_level

        lv = axis_level(0.95, 3, pooled=False, envelope_kind="joint", n_boot=99)
        assert lv["confidence"] == pytest.approx(1 - 0.05 / 3) and lv["family_confidence"] == 0.95
        # as many replicates beyond the band's order statistic as beyond the pooled band's: (B + 1)(1 - c)
        assert (lv["n_boot"] + 1) * (1 - lv["confidence"]) == pytest.approx(100 * 0.05)
        assert math.ceil((lv["n_boot"] + 1) * lv["confidence"]) < lv["n_boot"]  # not the largest replicate
        # k axes at c_a each hold together with probability at least 1 - k (1 - c_a) = c
        assert 1 - 3 * (1 - lv["confidence"]) == pytest.approx(0.95)

    @pytest.mark.parametrize("pooled, kind, k", [(True, "joint", 3), (False, "marginal", 3), (False, "joint", 1)])
    def test_the_identification_level_elsewhere(self, pooled, kind, k):
        from imupipe.stages.identify import axis_level

        lv = axis_level(0.95, k, pooled=pooled, envelope_kind=kind, n_boot=100)
        assert lv["confidence"] == 0.95 and lv["n_boot"] == 100 and lv["family_confidence"] is None


def test_pooled_axes_say_what_the_statement_assumes():
    """Where the pooling test accepts one model for several axes the statement is that model's: with each axis's own
    joint band (the bound file's axis_upper_envelopes) the model is also verified against each; without, it says the
    axes are pooled. One axis says neither."""
    from imupipe.verdict import confidence_statement

    base = {"identification_intervals": {"confidence": 0.95}, "curves": ["a/x", "a/y", "a/z"]}
    checked = confidence_statement({**base, "upper_envelope_kind": "joint",
                                    "axis_upper_envelopes": {"x": {}, "y": {}, "z": {}}})
    assert "each axis's own envelope (each at 0.95, all 3 together at least 0.85)" in checked["statement"]
    assert "The axes are pooled: the statement is for the one model" in confidence_statement(base)["statement"]
    one = confidence_statement({**base, "curves": ["a/x", "b/x"]})["statement"]
    assert "pooled" not in one


def test_an_inadequate_fit_is_named_beside_the_level():
    """Where the selected model does not describe the Allan variances (the identify file's adequacy, carried as
    intervals_bootstrap.model_adequate) the statement says the level holds only as far as the model does (an outside
    evaluation: the ADIS16405 summary stated 0.95 beside fits at chi2/dof in the thousands)."""
    from imupipe.verdict import confidence_statement

    bad = confidence_statement({"identification_intervals": {"confidence": 0.95, "model_adequate": False}})
    assert "does not describe the records' Allan variances" in bad["statement"]
    good = confidence_statement({"identification_intervals": {"confidence": 0.95, "model_adequate": True}})
    assert "does not describe" not in good["statement"]


def test_the_details_say_the_least_step_the_event_scan_reports():
    """An outside evaluation's 10 deg/h gyro step in a 3 h record went unnamed: the step scan's least reportable
    step there was 12.6 deg/h (threshold 6.06 x sigma_D 1.0e-5 rad/s at 64 s). The details now say the range of
    that floor over the axes and where it is largest; the floor itself is the scan's threshold times its sigma_D,
    the size a step at a window's centre needs to reach the threshold. On a record: a step of the floor plus 4 sigma_D
    (of the floor's window) is reported (missed with probability P(N(0, 1) < -4) = 3e-5) and one of half the floor
    is not (z about half the threshold, ~2.8: beyond it with probability ~3e-3 at one position)."""
    import numpy as np

    from imupipe.eventwords import step_scan_text
    from imupipe.events import detect_events
    from imupipe.models import NoiseModel
    from imupipe.simulate import simulate

    d = np.pi / 180 / 3600
    floors = [{"dataset": "step", "axis": a, "smallest_step": v * d, "smallest_step_tau_s": 64.0,
               "smallest_step_display": {"unit": "deg/h", "size": v}} for a, v in (("x", 12.6), ("y", 11.9))]
    text = step_scan_text(floors, [0.01, 0.01])
    assert text == ("- event scan (outliers stage, each full-rate record) at a false-alarm rate of 0.01 per record and "
                    "axis: the least mean step it reports is 11.9 to 12.6 deg/h over the axes (threshold x sigma_D at "
                    "the best window; largest on step/x, window 64 s): a smaller step stays in the record as "
                    "low-frequency noise, which the bound covers, without a FLAG that names it")
    assert step_scan_text([], [0.01]) is None
    rate, n = 50.0, 200_000
    x = simulate(NoiseModel(white=0.2 * np.pi / 180 / 60), n, rate, rng=5)
    scan = detect_events(x, rate, alpha=0.01, sensor="gyro")
    floor = scan["step_scan"]["smallest_step"]
    (best,) = [r for r in scan["step_scan"]["scales"]
               if r["tau_s"] == scan["step_scan"]["smallest_step_tau_s"]]
    assert scan["events"] == [] and scan["step_scan"]["smallest_step_display"]["unit"] == "deg/h"
    assert floor == best["threshold_z"] * best["sigma_d"]
    for size, found in ((floor + 4.0 * best["sigma_d"], True), (0.5 * floor, False)):
        y = x + np.where(np.arange(n) >= n // 2, size, 0.0)
        assert any(e["kind"] == "step" for e in detect_events(y, rate, alpha=0.01)["events"]) is found, size
