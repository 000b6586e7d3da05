"""Run summary (imupipe.summary): verdicts, inflation table in spec-sheet units, states, flagged checks."""

from pathlib import Path

import pytest

from imupipe.summary import first_screen, flags_of, render_summary


def _bound(bounded=True, margin=1.0, **extra):
    return {
        "spec_name": "STIM-300", "mode": "raw", "n_curves": 6, "bounded": bounded, "margin": margin,
        "margin_curve": "sim1/y", "margin_frequency_hz": 0.0123,
        "bound": {"white": 1.2e-4, "gauss_markov": [{"sigma": 2e-5, "T": 200.0}], "random_walk": 1e-7},
        "spec": {"white": 4.4e-5, "gauss_markov": [{"sigma": 7.3e-6, "T": 1500.0}], "random_walk": 9.7e-8},
        "bound_spec_units": {"white": {"value": 0.41, "unit": "deg/sqrt(h)"},
                             "random_walk": {"value": 0.0206, "unit": "(deg/h)/sqrt(s)"},
                             "gauss_markov": [{"sigma": {"value": 4.1, "unit": "deg/h"},
                                               "T": {"value": 200.0, "unit": "s"}}]},
        "spec_spec_units": {"white": {"value": 0.15, "unit": "deg/sqrt(h)"},
                            "random_walk": {"value": 0.02, "unit": "(deg/h)/sqrt(s)"},
                            "gauss_markov": [{"sigma": {"value": 1.5, "unit": "deg/h"},
                                              "T": {"value": 1500.0, "unit": "s"}}]},
        "allan_check": {"white": {"passed": True, "margin": 7.0, "tau_at_min": None, "reason": ""}},
        "per_axis": [{"curve": "sim1/x", "bounded": True, "margin": 1.0}],
        **extra,
    }


IDENTIFY = {"selection": {"kept": ["white", "gauss_markov"], "dropped": ["random_walk"],
                          "reasons": {"white": "significant", "gauss_markov": "significant and in band",
                                      "random_walk": "contributes < 5 % in the application band"}},
            "fit": {"adequacy": {"chi2": 40.0, "dof": 30, "chi2_per_dof": 1.33, "p_value": 0.1, "adequate": True}}}
STATIONARITY = {"curves": [{"dataset": "sim1", "axis": "x", "stationary": True, "p_value": 0.4, "test": "calibrated",
                            "included": True},
                           {"dataset": "sim2", "axis": "z", "stationary": False, "p_value": 0.003,
                            "test": "calibrated", "included": True}]}


def test_clean_run_says_bounded_with_inflation_table_and_states():
    text = render_summary({"gyro": {"bound": _bound(), "identify": IDENTIFY,
                                    "stationarity": {"curves": STATIONARITY["curves"][:1]}}})
    assert "## gyro: BOUNDED" in text
    assert "**Verdict:** gyro: BOUNDED. 0 failed, 0 flagged" in text
    # inflation table in the spec sheet's units, ratio bound/spec = 0.41 / 0.15 = 2.73
    assert "| white noise N | deg/sqrt(h) | 0.15 | 0.41 | 2.73 |" in text
    assert "| GM sigma | deg/h | 1.5 | 4.1 | 2.73 |" in text
    assert "- components the identification kept (identify file, selection: what the bound covers, not the " \
           "filter's states): white, gauss_markov" in text
    assert "random_walk (dropped): contributes < 5 % in the application band" in text
    assert "gyro: none failed or flagged." in first_screen(text)


def test_flagged_and_failed_checks_appear_with_where():
    bound = _bound(bounded=False, margin=0.93,
                   allan_check={"gauss_markov": {"passed": False, "margin": 0.8, "tau_at_min": 64.0,
                                                 "reason": "bound GM below identified GM"}},
                   failed_checks=[{"check": "covariance", "curve": "sim1/x", "detail": "P_f < MSE at step 40"}],
                   verified=False, narrowband=[{"sigma": 1e-5, "f0_hz": 12.5, "zeta": 0.01}])
    identify = {**IDENTIFY, "fit": {"adequacy": {"chi2_per_dof": 4.2, "p_value": 1e-6, "adequate": False}}}
    stat = {**STATIONARITY, "outliers": {"sim1/x": [{"index": 1203, "time_s": 9.6, "value": 0.3}]},
            "gaps": [{"dataset": "sim2", "start_s": 100.0, "stop_s": 100.5}]}
    text = render_summary({"gyro": {"bound": bound, "identify": identify, "stationarity": stat},
                           "accel": {"bound": _bound()}})
    assert "## gyro: NOT BOUNDED" in text and "## accel: BOUNDED" in text
    assert "FAIL bound [sim1/y at 0.0123 Hz]: not bounded: margin 0.93 < 1" in text
    assert "FAIL allan check [gauss_markov at tau 64 s]" in text
    assert "FAIL verification" in text
    assert "FAIL covariance [curve=sim1/x]: detail=P_f < MSE at step 40" in text
    assert "FLAG stationarity [sim2/gyro/z]: non-stationary (p = 0.003, calibrated); kept in the bound" in text
    assert "FLAG fit adequacy" in text and "chi2/dof = 4.2" in text
    assert "FLAG lines [-]: 12.5 Hz, sigma 1e-05 (unit not stated)" in text
    assert "FLAG outliers [curve=sim1/x, index=1203, time_s=9.6]" in text
    assert "FLAG gaps [dataset=sim2, start_s=100, stop_s=100.5]" in text
    assert "**Verdict:** gyro: NOT BOUNDED; accel: BOUNDED. 4 failed" in text


def test_data_far_below_the_spec_sheet_are_flagged():
    # a margin >= FAR_BELOW_SPEC_MARGIN: every sample bin far below the bound (the spec sheet's), as a record in
    # deg/s declared as mrad/s gives (an outside tester's run: margin 63); a margin of 5 is a normal spec sheet
    from imupipe.summary import FAR_BELOW_SPEC_MARGIN

    # under a unit slip the bound is the spec sheet's: its white noise is the sheet's
    at_spec = {"white": 4.4e-5, "gauss_markov": [{"sigma": 7.3e-6, "T": 1500.0}], "random_walk": 9.7e-8}
    far = [f for f in flags_of("gyro", bound=_bound(margin=63.06, bound=at_spec))
           if f.check == "data far below the spec sheet"]
    assert len(far) == 1 and "63.1x below the bound" in far[0].detail and "unit" in far[0].detail
    assert not [f for f in flags_of("gyro", bound=_bound(margin=5.0, bound=at_spec)) if f.check.startswith("data far")]
    assert [f for f in flags_of("gyro", bound=_bound(margin=FAR_BELOW_SPEC_MARGIN, bound=at_spec))
            if f.check.startswith("data far")]


def test_a_bound_far_above_the_data_from_the_envelope_does_not_blame_the_unit():
    # an outside tester's accel: spec sheet half the truth, the bound 23x the truth's white noise from an upper
    # envelope covering a GM time constant the records left open (margin 191): the bound is not the sheet's, so the
    # FLAG names the envelope, not the data's unit
    far = flags_of("accel", bound=_bound(margin=190.7, bound={"white": 0.0383, "gauss_markov": [], "random_walk": 0.0},
                                         spec={"white": 8.3e-4, "gauss_markov": [], "random_walk": 0.0}))
    [f] = [f for f in far if f.check in ("bound far above the data", "data far below the spec sheet")]
    assert f.check == "bound far above the data" and "46.1x the spec sheet's" in f.detail
    assert "upper envelope" in f.detail and "unit" not in f.detail


def test_missing_keys_are_tolerated_and_nothing_is_invented():
    assert flags_of("gyro") == []
    text = render_summary({"accel": {}})
    assert "## accel: no bound" in text
    assert "FAIL" not in text and "FLAG" not in text


@pytest.mark.parametrize("on_fail_included, phrase", [(False, "excluded from the bound"), (True, "kept in the bound")])
def test_stationarity_inclusion_is_stated(on_fail_included, phrase):
    stat = {"curves": [{"dataset": "d", "axis": "x", "stationary": False, "p_value": 0.01, "test": "paper",
                        "included": on_fail_included}]}
    (flag,) = flags_of("accel", stationarity=stat)
    assert phrase in flag.detail and flag.where == "d/accel/x"


@pytest.mark.parametrize("test, phrase", [
    ("paper", "which the paper's test's null (independent samples) does not hold"),
    ("calibrated", "which the test leaves out (notched from the record"),
])
def test_a_non_stationary_axis_with_a_spectral_line_says_what_the_test_does_with_it(test, phrase):
    # two outside evaluations: steady lines flagged their stationary axes (6 of 6, 4 of 6). The calibrated test now
    # notches the axis's lines out (imupipe.stages.stationarity); the paper's test cannot: the FLAG of an axis that
    # holds a line says which, and an axis without one reads as before
    stat = {"curves": [{"dataset": "d", "axis": ax, "stationary": False, "p_value": 0.001, "test": test}
                       for ax in "xy"],
            "lines": [{"dataset": "d", "sensor": "accel", "axis": "x", "frequency_hz": 0.05, "f_lo_hz": 0.04,
                       "f_hi_hz": 0.06, "peak_ratio": 50.0}]}
    flags = {f.where: f for f in flags_of("accel", stationarity=stat) if f.check == "stationarity"}
    assert phrase in flags["d/accel/x"].detail
    assert "spectral line" not in flags["d/accel/y"].detail


def test_summarise_results_finds_the_files_of_a_results_folder(tmp_path):
    from imupipe.io import write_yaml_atomic
    from imupipe.stages.summary import run_files, summarise_results

    res = tmp_path / "results" / "myrun"  # a run-name level is found as well
    write_yaml_atomic({**_bound(), "sensor": "gyro"}, res / "bound" / "stim300" / "gyro.yaml")
    write_yaml_atomic({"curve": "sim1/x", "bounded": True, "sensor": "gyro"},
                      res / "bound" / "stim300" / "axes" / "sim1" / "gyro" / "x.yaml")  # per-axis: not a contract
    write_yaml_atomic(IDENTIFY, res / "identify" / "gyro.yaml")
    write_yaml_atomic(STATIONARITY, res / "stationarity" / "gyro.yaml")
    files, sensors, specs = run_files(res)
    assert specs == ["stim300"] and sensors == ["gyro"] and len(files["bound"]) == 1
    text = summarise_results(tmp_path / "results")
    assert text.startswith("# imupipe run summary: myrun, spec sheet stim300")
    assert "FLAG stationarity [sim2/gyro/z]" in text
    assert "not the filter's states): white, gauss_markov" in text
    assert summarise_results(tmp_path / "empty") == ""


def test_end_of_run_text_gives_the_runs_paths_from_anywhere(tmp_path, monkeypatch):
    """The run works in the checkout or --directory, the user types from elsewhere (an outside evaluation followed
    `results/mydata/kf/...` from its own folder): on the terminal the summary's paths are absolute, summary.md keeps
    its own."""
    from imupipe.stages.summary import end_of_run_text

    monkeypatch.chdir(tmp_path)
    md = tmp_path / "results" / "r1" / "summary.md"
    md.parent.mkdir(parents=True)
    md.write_text("# summary\n\n| gyro | BOUNDED | `results/r1/kf/s/gyro.yaml` |\n\nKalibr [results/r1/kf/s/k.yaml]; "
                  "/elsewhere/results/r1/x and results/r10/y stay\n")
    text = end_of_run_text("results/r1", "logs/r1", "results/r1/summary.md")
    where = (tmp_path / "results" / "r1").resolve().as_posix()
    assert f"`{where}/kf/s/gyro.yaml`" in text and f"[{where}/kf/s/k.yaml]" in text
    assert "/elsewhere/results/r1/x and results/r10/y stay" in text
    assert "`results/r1/kf/s/gyro.yaml`" in md.read_text()


def test_end_of_run_text_after_a_failure_a_partial_run_and_a_success(tmp_path):
    from imupipe.io import write_yaml_atomic
    from imupipe.stages.summary import end_of_run_text

    md = tmp_path / "summary.md"
    text = end_of_run_text(str(tmp_path / "none"), "logs/t", md, failed=True)
    # absolute paths: `imupipe run` runs in the checkout, not where the user typed it (an outside evaluation)
    assert text.strip().startswith(f"RUN FAILED: the failed job's log is under {Path('logs/t').resolve()}/")
    assert end_of_run_text(str(tmp_path / "none"), "logs/t", md) == ""
    # a failed run that left a bound file: its first screen, marked partial, before the failure line
    res = tmp_path / "results" / "myrun"
    write_yaml_atomic({**_bound(), "sensor": "gyro"}, res / "bound" / "stim300" / "gyro.yaml")
    partial = end_of_run_text(str(res), "logs/t", md, failed=True)
    assert partial.lstrip().startswith("(partial: from the files this run has written so far; a job failed, so no "
                                       "check count below says the run passed)\n# imupipe run summary")
    # its verdict line's counts ("0 failed") are not the run's: the line says the run failed
    assert "**Verdict (run FAILED; partial, not a verdict):** gyro: BOUNDED" in partial
    assert "# Details" not in partial and partial.rstrip().splitlines()[-1].startswith("RUN FAILED")
    assert "summary.md is written only by a complete run" in partial
    md.write_text("# summary\n")
    ok = end_of_run_text(str(tmp_path), "logs/t", md)
    assert ok.startswith("\n# summary\n\nSummary with the details: ") and "make report CONFIG=<this run's config>" in ok
    assert f"imupipe run <this run's config> -- --report {tmp_path.resolve()}/report.html" in ok
    # a job failed after the summary was written (an outside evaluation read "written only by a complete run"
    # beside the file): the line says what the file is
    late = end_of_run_text(str(res), "logs/t", md, failed=True)
    assert f"{md} was written before the failure and does not cover the failed job" in late
    # the integrity job failed the run on purpose (NOT BOUNDED, verify.on_failure: fail) after the summary job: the
    # summary is the verdict, not partial (an outside evaluation read "partial, not a verdict" beside NOT BOUNDED)
    gate = tmp_path / "logs" / "t" / "contract" / "verdict.log"
    gate.parent.mkdir(parents=True)
    gate.write_text("ERROR imupipe integrity: NOT BOUNDED (gyro against STIM-300: allan components).\n")
    md.write_text("# summary\n\n**Verdict:** gyro: NOT BOUNDED; 1 failed\n")
    gated = end_of_run_text(str(res), str(tmp_path / "logs" / "t"), md, failed=True)
    assert "**Verdict:** gyro: NOT BOUNDED" in gated and "partial" not in gated
    assert gated.rstrip().splitlines()[-1].startswith("NOT BOUNDED: the integrity job failed the run on purpose")


def test_markdown_to_html_renders_the_summary_and_the_inflation_table():
    import re

    from imupipe.summary import markdown_to_html

    bound = _bound(bounded=False, margin=0.9)
    page = markdown_to_html(render_summary({"gyro": {"bound": bound, "identify": IDENTIFY,
                                                     "stationarity": STATIONARITY}}))
    assert page.startswith("<!DOCTYPE html>")
    assert "<h2>gyro: NOT BOUNDED</h2>" in page
    # the inflation table as an HTML table: header + 4 rows (N, K, GM sigma, GM T)
    # the first screen's verdict table, then the inflation table
    verdicts, table = re.findall(r"<table>.*?</table>", page)
    assert "<td>gyro</td><td>NOT BOUNDED</td><td>0.9</td>" in verdicts
    assert table.count("<tr>") == 5 and "<th>bound/spec</th>" in table
    assert "<td>deg/sqrt(h)</td><td>0.15</td><td>0.41</td><td>2.73</td>" in table
    assert '<li class="fail">FAIL bound [sim1/y at 0.0123 Hz]' in page
    assert '<li class="flag">FLAG stationarity [sim2/gyro/z]' in page
    assert "<strong>Verdict:</strong>" in page
    # nested reasons list, and text is escaped
    assert "<ul><li>white (kept): significant</li>" in page
    assert "<li>random_walk (dropped): contributes &lt; 5 % in the application band</li></ul></ul>" in page


def test_per_axis_models_table_band_and_a_refused_axis_flagged():
    """A contract with per-axis models: the table says which axis has its own model in the KF file; an axis whose
    own contract failed is flagged (the global model covers it, so the verdict stays BOUNDED); the Allan check's
    band is stated. Without per-axis models, neither the table nor the flag appears."""
    per = {"x": {"inflation": {"N": 2.66}, "exported_in_kf": True, "kf": "axis x: its own model"},
           "z": {"inflation": {"N": 1.31}, "exported_in_kf": False,
                 "kf": "axis z: the global model (its own failed: allan_total adis_imu1/z (0.649))"}}
    text = render_summary({"gyro": {"bound": _bound(per_axis_models=per, allan_tau_band_s=[0.01, 1200.0])}})
    assert "## gyro: BOUNDED" in text and "0 failed, 1 flagged" in text
    assert "| x | 2.66 | yes | axis x: its own model |" in text
    assert "| z | 1.31 | no (global model) |" in text
    assert "- FLAG per-axis model [z]: not exported: axis z: the global model (its own failed: allan_total" in text
    assert "- Allan total check over the application band: tau from 0.01 to 1.2e+03 s" in text
    plain = render_summary({"gyro": {"bound": _bound()}})
    assert "Per-axis models" not in plain and "per-axis model" not in plain


def _scope(dropped, vrate=1.0, kf_rate=1.0, horizon=600.0):
    from imupipe.kf import export_scope

    exported = {"reduced": bool(dropped), "model": {"white": 1e-4},
                "verification": {"scenario": {"rate_hz": vrate, "fix_s": 600.0, "horizon_s": horizon, "sigma_fix": 0.5,
                                              "sigma_fix_unit": "m"}}}
    return export_scope(exported, {"accepted": dropped}, kf_rate)


def test_the_exported_filter_model_and_its_reduction_are_stated_per_sensor_and_per_axis():
    """The inflation table shows the bound's K; the KF export dropped it: the summary says so, with the horizon
    (s) the reduced export holds for, for the sensor and for an axis with its own model."""
    per = {"x": {"inflation": {"N": 2.66}, "exported_in_kf": True, "kf": "axis x: its own model",
                 "export": _scope(["gauss_markov T=200 s"], horizon=600.0)},
           "y": {"inflation": {"N": 1.2}, "exported_in_kf": False, "kf": "axis y: the global model"}}
    bound = _bound(export=_scope(["random_walk", "narrowband f0=0.564 Hz"]), per_axis_models=per)
    text = render_summary({"gyro": {"bound": bound, "identify": IDENTIFY}})
    assert ("- exported filter model (KF file): reduced model: the verified reduction dropped random_walk, "
            "narrowband f0=0.564 Hz; the export is then valid for the configured scenario only (600 s of outage "
            "after 600 s of fixes of sigma 0.5 m), not beyond it: a longer outage or more accurate fixes need the "
            "model before the reduction") in text
    assert "| x | 2.66 | yes | axis x: its own model | reduced model: the verified reduction dropped gauss_markov" in text
    assert "| y | 1.2 | no (global model) | axis y: the global model | global: reduced model: the verified" in text
    # the first screen's per-axis export table says it too, where a user picks the model for an axis
    from imupipe.summary import per_axis_export_lines

    table = "\n".join(per_axis_export_lines({"gyro": {"bound": bound}}))
    assert ("| gyro | x | own model |" in table and "| its own contract is bounded (the pooling test says the axes "
            "differ); the verified reduction dropped gauss_markov: valid for the configured outage and fixes only |") in table
    assert "| gyro | y | global model |" in table and "the verified reduction dropped random_walk: valid" in table
    # the bound exported whole: said so, no horizon restriction claimed
    whole = render_summary({"gyro": {"bound": _bound(export=_scope([]))}})
    assert "- exported filter model (KF file): the bound's model, no state dropped" in whole
    assert "scenario only" not in whole
    # the first screen says it too, under the values to paste (an outside evaluation read only that screen)
    from imupipe.summary import summary_sections

    head, _ = summary_sections({"gyro": {"bound": {**bound, "model": {"white": 1e-4}}}})
    assert ("- gyro: reduced model: the verified reduction dropped random_walk, narrowband f0=0.564 Hz; the export is "
            "then valid for the configured scenario only") in head
    whole_head = summary_sections({"gyro": {"bound": _bound(export=_scope([]), model={"white": 1e-4})}})[0]
    assert "| gyro | KF | white noise N |" in whole_head and "- gyro: " not in whole_head
    assert "exported filter model" not in render_summary({"gyro": {"bound": _bound()}})  # no contract: no claim


def test_a_verification_at_another_rate_than_the_export_is_flagged():
    bound = _bound(export=_scope(["random_walk"], vrate=1.0, kf_rate=100.0))
    text = render_summary({"accel": {"bound": bound}})
    assert "verified with a reference filter at 1 Hz, exported at 100 Hz" in text
    assert "- FLAG export rate [KF file]: verified with a reference filter at 1 Hz, exported at 100 Hz" in text
    assert "0 failed, 1 flagged" in text
    same = render_summary({"accel": {"bound": _bound(export=_scope(["random_walk"], vrate=100.0, kf_rate=100.0))}})
    assert "export rate" not in same and "exported at" not in same

    # the contract's failed export_rate check: one FAIL line in words, no second FLAG line for the same mismatch
    failed = {**bound, "bounded": False, "verified": False, "failed_checks": [
        {"check": "export_rate", "verified_filter_rate_hz": 1.0, "kf_rate_hz": 100.0, "note": "set ..."}]}
    text = render_summary({"accel": {"bound": failed}})
    assert "- FAIL export rate [KF file]: verified with a reference filter at 1 Hz, exported at 100 Hz" in text
    assert "FLAG export rate" not in text and "export_rate" not in text
    assert "verification failed" not in text  # the reference filter's verification passed; the rate did not
    assert "2 failed, 0 flagged" in text  # the rate and the bound's verdict


def test_a_random_walk_resting_on_the_spec_sheet_alone_is_stated():
    # IDENTIFY dropped the random walk; the bound and the spec sheet have one (_bound: 1e-7 and 9.7e-8 SI)
    text = render_summary({"gyro": {"bound": _bound(export=_scope(["random_walk"])), "identify": IDENTIFY}})
    assert ("- random walk: the data showed none (identification dropped it); the bound's K rests on the spec sheet "
            "alone; the exported filter drops it (reduction above)") in text
    kept = {**IDENTIFY, "selection": {**IDENTIFY["selection"], "kept": ["white", "gauss_markov", "random_walk"]}}
    assert "rests on the spec sheet" not in render_summary({"gyro": {"bound": _bound(), "identify": kept}})
    no_spec_k = _bound(spec={"white": 4.4e-5, "random_walk": 0.0})
    assert "rests on the spec sheet" not in render_summary({"gyro": {"bound": no_spec_k, "identify": IDENTIFY}})
    # the envelope carries the dropped random walk's upper limit: the bound's K covers it, not the spec sheet alone
    env_k = _bound(export=_scope(["random_walk"]), upper_envelope={"white": 4.6e-5, "random_walk": 5.55e-8})
    text = render_summary({"gyro": {"bound": env_k, "identify": IDENTIFY}})
    assert "rests on the spec sheet" not in text
    # K in the spec sheet's unit: 5.55e-8 rad/s/sqrt(s) * (180/pi deg/rad) * (3600 s/h) = 0.01145 (deg/h)/sqrt(s)
    assert ("- random walk: the data showed none (identification dropped it) but do not exclude one up to K = 0.0114 "
            "(deg/h)/sqrt(s) (the identified envelope); the bound's K covers that limit and the spec sheet's; the exported filter "
            "drops it (reduction above)") in text


def test_line_flags_name_dataset_sensor_axis_frequency_amplitude_unit_and_floor_ratio():
    """A lines file (one dataset/sensor/axis, units under `units`) merged by the summary script: each FLAG names
    where the line is, its frequency in Hz, its amplitude in the sensor's unit and its peak over the floor; the same
    line on another axis (full-rate intervals that overlap, as the bound merges lines) is one FLAG naming both axes
    and the strongest."""
    from imupipe.stages import summary as mod

    def lines_file(axis, f, amplitude, ratio):
        return {"dataset": "adis_imu2", "sensor": "accel", "axis": axis,
                "lines": [{"frequency_hz": f, "power": amplitude**2 / 2, "amplitude": amplitude,
                           "sigma": amplitude / 2**0.5, "peak_ratio": ratio, "f_lo_hz": f - 0.006, "f_hi_hz": f + 0.006}],
                "units": {"frequency_hz": "Hz", "amplitude": "m/s^2", "sigma": "m/s^2", "peak_ratio": "1"}}

    one = {}
    mod.merge_checks(one, lines_file("z", 0.5669195, 0.0069233, 78.573))
    # the amplitude is the peak, its sd (the values to paste's sigma) beside it: 0.0069233 / sqrt(2) = 0.0048955
    assert ("- FLAG lines [adis_imu2/accel/z]: 0.5669 Hz, amplitude 0.00692 m/s^2 (sd 0.0049), peak PSD 78.6x the "
            "floor" in render_summary({"accel": {"bound": one}}))
    mod.merge_checks(one, lines_file("x", 0.5669000, 0.0093500, 133.0))
    flags = [ln for ln in render_summary({"accel": {"bound": one}}).splitlines() if ln.startswith("- FLAG lines")]
    assert flags == ["- FLAG lines [adis_imu2/accel/x,z]: one line (2 axes) at 0.5669 Hz; the strongest "
                     "[adis_imu2/accel/x]: 0.5669 Hz, amplitude 0.00935 m/s^2 (sd 0.00661), peak PSD 133x the "
                     "floor"], flags
    # lines whose intervals do not overlap stay apart (2 <= MAX_LINE_FLAGS: one FLAG each)
    apart = {}
    mod.merge_checks(apart, lines_file("z", 0.5669, 0.0069, 78.0))
    mod.merge_checks(apart, lines_file("x", 0.6677, 0.0020, 9.0))
    flags = [ln for ln in render_summary({"accel": {"bound": apart}}).splitlines() if ln.startswith("- FLAG lines")]
    assert len(flags) == 2 and "[adis_imu2/accel/z]: 0.5669 Hz" in flags[0] and "[adis_imu2/accel/x]: 0.6677 Hz" in flags[1]
    # two detections of one line on one axis beside one on another: two axes, three detections
    mod.merge_checks(one, lines_file("x", 0.5670, 0.0050, 60.0))
    flags = [ln for ln in render_summary({"accel": {"bound": one}}).splitlines() if ln.startswith("- FLAG lines")]
    assert flags[0].startswith("- FLAG lines [adis_imu2/accel/x,z]: one line (2 axes, 3 detections) at "
                               "0.5669-0.567 Hz"), flags
    # the same axis in two records is one axis (an outside evaluation read "one line (4 axes)" for 2 axes x 2 records)
    two = {}
    for ds, axis in (("r0", "x"), ("r1", "x"), ("r0", "y"), ("r1", "y")):
        mod.merge_checks(two, {**lines_file(axis, 0.5669, 0.0069, 78.0), "dataset": ds})
    flags = [ln for ln in render_summary({"accel": {"bound": two}}).splitlines() if ln.startswith("- FLAG lines")]
    assert "one line (2 axes, 4 detections)" in flags[0], flags


def test_a_sensor_with_a_line_family_gets_one_flag_naming_every_frequency_and_the_strongest():
    """An accelerometer line with its sidebands and harmonics (the ADIS16405's 0.46 / 0.56 / 0.67 / 1.69 Hz): more
    than MAX_LINE_FLAGS lines on one sensor type make one FLAG (frequencies, the axes each is seen on, the strongest
    by peak over the floor); a line seen on two axes counts once."""
    from imupipe.stages import summary as mod
    from imupipe.linewords import MAX_LINE_FLAGS

    def line(f, ratio):
        return {"frequency_hz": f, "amplitude": 1e-3 * ratio, "peak_ratio": ratio, "f_lo_hz": f - 0.005,
                "f_hi_hz": f + 0.005}

    units = {"frequency_hz": "Hz", "amplitude": "m/s^2", "peak_ratio": "1"}
    family = [line(0.4631, 6.69), line(0.5641, 203.0), line(0.6654, 6.27), line(1.691, 8.5)]
    assert len(family) > MAX_LINE_FLAGS
    entry = {}
    mod.merge_checks(entry, {"dataset": "d", "sensor": "accel", "axis": "x", "lines": family, "units": units})
    mod.merge_checks(entry, {"dataset": "d", "sensor": "accel", "axis": "y", "lines": [line(0.564, 143.0)],
                              "units": units})
    flags = [ln for ln in render_summary({"accel": {"bound": entry}}).splitlines() if ln.startswith("- FLAG lines")]
    assert flags == ["- FLAG lines [d/accel/x,y]: 4 lines at 0.4631, 0.564-0.5641 (2 axes), 0.6654, 1.691 Hz; the "
                     "strongest [d/accel/x]: 0.5641 Hz, amplitude 0.203 m/s^2, peak PSD 203x the floor"], flags


def test_inflation_table_shows_a_component_the_spec_sheet_does_not_give_as_in_the_tables():
    """The ADIS16405 sheet gives no random walk and no GM (only N and flicker): summary.md's table shows such a spec
    cell "-" with no ratio, as tables/<spec>/inflation.md does (imupipe.specsheet.inflation_rows), not "0"; every
    cell the two tables share agrees (both print 4 significant digits)."""
    from pathlib import Path

    from imupipe.models import NoiseModel
    from imupipe.specsheet import display_units, inflation_rows, load_spec, model_in_units

    spec = load_spec(Path(__file__).resolve().parents[1] / "config" / "specs" / "adis16405.yaml")
    assert spec.models["gyro"].random_walk == 0 and not spec.models["gyro"].gauss_markov
    bound_model = NoiseModel(white=2e-3, gauss_markov=((3e-4, 50.0),), random_walk=4e-6)  # rad/s
    units = display_units(spec, "gyro")
    bound = {**_bound(), "bound_spec_units": model_in_units(bound_model, units, "gyro")[0],
             "spec_spec_units": model_in_units(spec.models["gyro"], units, "gyro")[0]}
    text = render_summary({"gyro": {"bound": bound}})

    def fmt(v):
        return "-" if v is None else f"{v:.4g}"

    tables = {r["parameter"]: r for r in inflation_rows(spec, "gyro", bound_model)}
    k = tables["random walk K"]
    assert k["spec"] is None and k["ratio"] is None
    assert f"| random walk K | {k['unit']} | - | {fmt(k['bound'])} | - |" in text
    for name in ("white noise N", "GM sigma", "GM T"):
        r = tables[name]
        assert f"| {name} | {r['unit']} | {fmt(r['spec'])} | {fmt(r['bound'])} |" in text
    assert "| 0 |" not in text


def test_a_spec_sheet_far_above_the_data_is_said():
    # spec N 4.4e-5 (0.15 deg/sqrt(h)); the records allow at most 4.4e-6: the bound's N rests on the spec sheet,
    # which a bound/spec of 1 in the table does not show
    b = _bound(upper_envelope={"white": 4.4e-6})
    text = render_summary({"gyro": {"bound": b}})
    assert ("- white noise: the records allow at most N = 0.015 deg/sqrt(h) (the identification's upper "
            "envelope), 10x below the spec sheet's: the bound's N rests on the spec sheet, not on these records") in text
    near = render_summary({"gyro": {"bound": _bound(upper_envelope={"white": 3e-5})}})  # 1.47x: not said
    assert "the records allow at most" not in near


def test_a_gm_sigma_below_the_spec_sheets_is_explained():
    b = _bound(spec_margin=1.02)
    b["bound_spec_units"]["gauss_markov"][0]["sigma"]["value"] = 1.2  # below the spec's 1.5 deg/h
    text = render_summary({"gyro": {"bound": b}})
    assert ("- GM sigma below the spec sheet's: the spec sheet's PSD is bounded at every frequency by the bound's "
            "terms together (white noise, GM and random walk; spec margin 1.02), not term by term") in text
    assert "not term by term" not in render_summary({"gyro": {"bound": _bound(spec_margin=1.02)}})  # 4.1 > 1.5


def test_the_in_band_inflation_line_is_beside_the_table_per_sensor_and_per_axis():
    """The contract's inband_inflation (imupipe.inband) gives one line after the inflation table, and one per axis
    under the per-axis table; a GM acting as white noise in band is named so."""
    from imupipe.inband import inband_inflation
    from imupipe.models import NoiseModel

    band = (1 / 600.0, 0.5)
    spec = NoiseModel(white=1e-4)
    glob = inband_inflation(NoiseModel(white=3e-4, gauss_markov=((5e-3, 0.01),)), spec, band)
    ax = inband_inflation(NoiseModel(white=2e-4), spec, band)
    per = {"x": {"inflation": {"N": 2.0}, "exported_in_kf": True, "kf": "axis x: its own model",
                 "inband_inflation": ax}}
    text = render_summary({"gyro": {"bound": _bound(inband_inflation=glob, per_axis_models=per)}})
    lines = text.splitlines()
    i = next(k for k, ln in enumerate(lines) if ln.startswith("- in-band (0.00167 to 0.5 Hz): median "))
    assert lines[i - 2].startswith("| ")  # right after the table (a blank line between)
    assert "the spec's PSD; " in lines[i] and "x the spec's white noise (median; max " in lines[i]
    assert "GM of T 0.01 s (corner 15.9 Hz) acts as white noise" in lines[i]
    assert ("- axis x: in-band (0.00167 to 0.5 Hz): median 2x, max 2x at 0.00167 Hz the spec's PSD; 2x the spec's "
            "white noise") in text
    assert "in-band" not in render_summary({"gyro": {"bound": _bound()}})


def test_white_noise_far_above_the_spec_sheet_asks_for_the_unit_of_the_dataset(tmp_path):
    # deg/s declared rad/s inflates N by 180/pi = 57.3x: a bound N 98.8x the spec's (an outside tester's run) is
    # flagged from the run's files, naming the sheet column and the dataset; the fixture's 2.73x is not
    from imupipe.io import write_yaml_atomic
    from imupipe.stages.summary import summarise_results
    from imupipe.summary import ABOVE_SPEC_RATIO_BOUND, ABOVE_SPEC_RATIO_DATA

    spec_n = 4.4e-5
    bad = _bound(bound={"white": 98.8 * spec_n, "gauss_markov": [], "random_walk": 1e-7},
                 upper_envelope={"white": 60.0 * spec_n}, curves=["lab1/x", "lab2/x"],
                 per_axis=[{"curve": "lab1/x", "bounded": True, "margin": 1.2, "inflation": {"N": 98.8}},
                           {"curve": "lab2/x", "bounded": True, "margin": 3.0, "inflation": {"N": 1.5}}])
    res = tmp_path / "results" / "myrun"
    write_yaml_atomic({**bad, "sensor": "gyro"}, res / "bound" / "stim300" / "gyro.yaml")
    write_yaml_atomic({**_bound(), "sensor": "accel"}, res / "bound" / "stim300" / "accel.yaml")
    text = summarise_results(tmp_path / "results")
    assert "FLAG data far above the spec sheet [lab1]: white noise N bound/spec 98.8x, data/spec 60x" in text
    assert "check the unit of gyro (dataset sheet column gyro_unit of lab1)" in text
    assert "of accel" not in text and "lab2" not in text.split("data far above")[1].split("\n")[0]
    # the limits: above the largest correct-unit ratio, below the smallest inflating slip (m/s^2 as g, 9.81)
    assert 2 * 1.47 < ABOVE_SPEC_RATIO_DATA < 9.81 and 2 * 4.31 < ABOVE_SPEC_RATIO_BOUND < 9.81
    edge = _bound(bound={"white": 30 * spec_n, "gauss_markov": [], "random_walk": 1e-7},
                  upper_envelope={"white": 0.99 * ABOVE_SPEC_RATIO_DATA * spec_n})  # the data decide, not the bound
    assert not [f for f in flags_of("gyro", bound=edge) if f.check == "data far above the spec sheet"]
    accel = _bound(bound={"white": 1.01 * ABOVE_SPEC_RATIO_BOUND * spec_n, "gauss_markov": [], "random_walk": 0.0},
                   curves=["bench/x"], per_axis=[])  # no envelope: bound/spec against its own limit
    (f,) = [f for f in flags_of("accel", bound=accel) if f.check == "data far above the spec sheet"]
    assert "dataset sheet column accel_unit of bench" in f.detail and "data/spec" not in f.detail
    assert "m/s^2 declared g gives 9.81x" in f.detail and "deg/s" not in f.detail
    correct = {**accel, "bound": {"white": 8.6 * spec_n}}  # the largest correct-unit bound/spec: not flagged
    assert all(f.check != "data far above the spec sheet" for f in flags_of("accel", bound=correct))


def test_a_replay_passed_only_by_its_allowance_is_flagged():
    """A replay whose worst MSE/P is above 1 but within its Monte Carlo allowance (few windows: an outside
    evaluation's 1.875 against 2.49 with two windows) passes the check and is FLAGged; one at or below 1 is not."""
    from imupipe.summary import replay_allowance_flags

    contract = {"verification": {"replay": {"worst_ratio": 1.875, "tolerance": 2.49, "worst_t_s": 4200.0,
                                            "passed": True}}}
    (f,) = replay_allowance_flags("gyro", contract)
    assert f.severity == "flag" and "1.88" in f.detail and "2.49" in f.detail
    contract["verification"]["replay"]["worst_ratio"] = 0.98
    assert replay_allowance_flags("gyro", contract) == []
    contract["verification"]["replay"].update(worst_ratio=3.0, passed=False)  # a failed replay is a FAIL elsewhere
    assert replay_allowance_flags("gyro", contract) == []


def test_the_first_screen_gives_the_values_to_paste_in_spec_units_and_si_in_separate_tables():
    """The first screen: the verdict table, then the exported model (KF) and Kalibr's densities as two tables, one
    in the spec sheet's units and one in SI (never both in one table), then the checks; the details after it."""
    from imupipe.summary import DETAILS_HEADING, paste_rows

    contract = _bound(sensor="gyro", kf_file="results/x/kf/s/gyro.yaml", verified=True,
                      model={"white": 1.8147e-4, "gauss_markov": [{"sigma": 4.0e-6, "T": 500.0}], "random_walk": 0.0},
                      model_spec_units={"white": {"value": 0.6239, "unit": "deg/sqrt(h)"},
                                        "gauss_markov": [{"sigma": {"value": 0.825, "unit": "deg/h"},
                                                          "T": {"value": 500.0, "unit": "s"}}],
                                        "random_walk": {"value": 0.0, "unit": "(deg/h)/sqrt(s)"}})
    # Kalibr's gyroscope_random_walk 1e-7 rad/s^2/sqrt(Hz) = 1e-7 rad/s/sqrt(s) = 1e-7 * 180/pi * 3600
    # = 0.02063 (deg/h)/sqrt(s); its noise density 1.8147e-4 rad/s/sqrt(Hz) = 1.8147e-4 * 180/pi * 60
    # = 0.6239 deg/sqrt(h) (sqrt(h) = 60 sqrt(s))
    kalibr = {"gyroscope_noise_density": 1.8147e-4, "gyroscope_random_walk": 1e-7, "update_rate": 100.0,
              "rostopic": "/imu"}
    rows = paste_rows("gyro", contract, kalibr)
    assert [r[:2] for r in rows] == [("KF", "white noise N"), ("KF", "GM sigma"), ("KF", "GM T"),
                                     ("Kalibr", "gyroscope_noise_density"), ("Kalibr", "gyroscope_random_walk")]
    assert rows[3][2] == pytest.approx(0.6239, rel=1e-3) and rows[3][3] == "deg/sqrt(h)"
    assert rows[4][2] == pytest.approx(0.020626, rel=1e-4) and rows[4][3] == "(deg/h)/sqrt(s)"
    assert rows[4][4:] == (1e-7, "rad/s^2/sqrt(Hz)")
    text = render_summary({"gyro": {"bound": contract}}, kalibr=kalibr, kalibr_path="results/x/kf/s/kalibr_imu.yaml")
    head = first_screen(text)
    assert DETAILS_HEADING not in head and "## gyro: BOUNDED" not in head and "## gyro: BOUNDED" in text
    assert "| gyro | BOUNDED | 1 | passed | `results/x/kf/s/gyro.yaml` |" in head
    spec_table = head.split("## Values to paste, in the spec sheet's units")[1].split("## The same values in SI")[0]
    si_table = head.split("## The same values in SI")[1].split("## Checks")[0]
    assert "| gyro | KF | white noise N | 0.6239 | deg/sqrt(h) |" in spec_table
    assert "| gyro | KF | GM sigma | 0.825 | deg/h |" in spec_table
    assert "| gyro | Kalibr | gyroscope_random_walk | 0.02063 | (deg/h)/sqrt(s) |" in spec_table
    assert "| gyro | KF | white noise N | 0.0001815 | rad/s/sqrt(Hz) |" in si_table
    assert "| gyro | Kalibr | gyroscope_random_walk | 1e-07 | rad/s^2/sqrt(Hz) |" in si_table
    assert "rad" not in spec_table and "deg" not in si_table  # one unit system per table
    assert "Kalibr imu.yaml [results/x/kf/s/kalibr_imu.yaml]: update_rate 100 Hz" in head
    assert "## Checks: 0 failed, 0 flagged" in head
    refused = render_summary({"gyro": {"bound": contract}}, kalibr={"refused": True, "reason": "a line state"})
    assert "- FLAG kalibr export: refused: a line state" in first_screen(refused)
    assert "0 failed, 1 flagged" in refused and "gyroscope_random_walk" not in refused
    # under a heading of its own, not read as the last sensor's (an outside evaluation read it as an accel FLAG)
    screen = first_screen(refused).splitlines()
    at = next(i for i, ln in enumerate(screen) if ln.startswith("- FLAG kalibr export"))
    assert screen[at - 1] == "export (Kalibr): 0 failed, 1 flagged"
    # axes with their own model in the KF file: the first screen says the KF rows are the global model and which
    # model each axis exports
    per = {**contract, "per_axis_models": {"x": {"exported_in_kf": True}, "y": {"exported_in_kf": False}}}
    per_head = first_screen(render_summary({"gyro": {"bound": per}}))
    assert "The axes differ: give each axis the model the KF file's `per_axis` exports for it, below (the tables " \
           "above are the global model, verified on every axis's envelope too" in per_head
    assert "| gyro | x | own model |" in per_head and "| gyro | y | global model |" in per_head
    assert "the axes differ" not in head.lower()
    # ... and says so before the tables: the global model is not what an axis with its own model takes (an outside
    # evaluation pasted the first table, 30x looser on the axes without another's line)
    tables = per_head.index("| sensor | file | parameter |")
    assert per_head.index("**The axes differ (gyro):** paste each axis's own model") < tables
    # the bias state's initial sd: sqrt(P0 of p) = 7.62e-5 rad/s = 7.62e-5 * 180/pi * 3600 = 15.72 deg/h, after the
    # model's terms and before Kalibr's
    biased = {**contract, "bias_initialisation": {"p0_random_walk": 7.62e-5 ** 2}}
    rows = paste_rows("gyro", biased, kalibr)
    assert rows[3][:2] == ("KF", "initial sd of the random-walk bias state p (sqrt P0)") and rows[4][0] == "Kalibr"
    assert rows[3][2] == pytest.approx(15.717, rel=1e-4) and rows[3][3] == "deg/h"
    assert rows[3][4:] == (pytest.approx(7.62e-5, rel=1e-12), "rad/s")
    # the verified scenario, once for the sensors that share it
    scen = {"horizon_s": 1800.0, "fix_s": 600.0, "verified_filter_rate_hz": 1.0, "verified_fix_rate_hz": 1.0,
            "verified_sigma_fix": 0.001745, "verified_sigma_fix_unit": "rad"}
    shown = first_screen(render_summary({"gyro": {"bound": {**contract, "export": scen}},
                                         "accel": {"bound": {**contract, "sensor": "accel", "export": scen}}}))
    assert ("Verified in (gyro, accel): the reference filter at 1 Hz, 600 s of fixes every 1 s (sd 0.00175 rad), "
            "then an outage of 1800 s; a filter used otherwise") in shown
    assert "| gyro | KF | initial sd of the random-walk bias state p (sqrt P0) | 15.72 | deg/h |" in first_screen(
        render_summary({"gyro": {"bound": biased}}, kalibr=kalibr))


def test_a_component_absent_at_zero_is_not_flagged_on_its_boundary():
    # a coefficient at its lower limit 0 is the component absent (dropped), not a fit pressed against its range
    ident = {"model": {"white": 1e-4, "flicker": 0.0, "gauss_markov": []},
             "fit": {"on_boundary": {"white": False, "flicker": True, "gm_T_1": True}}}
    flagged = [f.where for f in flags_of("gyro", identify=ident) if f.check == "parameter on boundary"]
    assert flagged == ["gm_T_1"]


def test_a_stuck_channel_is_flagged_first_with_value_span_and_share(tmp_path):
    """An outliers report with a stuck half (the stage script on a written series), merged by the summary script:
    the FLAG names dataset/sensor/axis, the value in the sensor's unit, the span in seconds and its share of the
    record, ahead of the same record's non-stationarity and line FLAGs, which point back at it."""
    import importlib.util
    from pathlib import Path

    import numpy as np
    import yaml

    from imupipe.io import write_series

    scripts = Path(__file__).resolve().parents[1] / "workflow" / "scripts"

    def script(name):
        spec = importlib.util.spec_from_file_location(f"stage_{name}", scripts / f"{name}.py")
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        return mod

    rng = np.random.default_rng(7)
    x = np.round(rng.standard_normal(200_000) / 0.3) * 0.3 * 0.01
    x[100_000:] = 0.021  # the second half stuck
    series = tmp_path / "x.nc"
    write_series(series, x, rate_hz=100.0, units="m/s^2", attrs={"dataset": "trial", "sensor": "accel", "axis": "x"})
    report = tmp_path / "outliers.yaml"
    script("outliers").main(path_series=str(series), policy="warn", k=7.0, window_samples=100, max_indices=10,
                            path_report=str(report))
    rep = yaml.safe_load(report.read_text())
    assert rep["n_stuck_spans"] == 1 and rep["stuck_spans"][0]["start_s"] == pytest.approx(1000.0, abs=0.01)
    entry = {}
    from imupipe.stages import summary as summ
    summ.merge_checks(entry, rep)
    summ.merge_checks(entry, {"dataset": "trial", "sensor": "accel", "axis": "x", "units": {"amplitude": "m/s^2"},
                               "lines": [{"frequency_hz": 0.25, "amplitude": 1e-3, "peak_ratio": 40.0}]})
    # the same line on a clean axis: one FLAG for both, and the stuck record's note stays on it
    summ.merge_checks(entry, {"dataset": "trial", "sensor": "accel", "axis": "y", "units": {"amplitude": "m/s^2"},
                               "lines": [{"frequency_hz": 0.25, "amplitude": 2e-3, "peak_ratio": 50.0}]})
    stat = {"curves": [{"dataset": "trial", "axis": "x", "stationary": False, "p_value": 1e-6, "test": "calibrated",
                        "included": True}]}
    text = render_summary({"accel": {"bound": {**_bound(), **entry}, "stationarity": stat}})
    flag = ("- FLAG stuck channel [trial/accel/x]: constant at 0.021 m/s^2 from 1000 s to 1999.99 s "
            "(50 % of the record)")
    assert flag in text
    checks = [ln for ln in text.splitlines() if ln.startswith("- FLAG") or ln.startswith("- FAIL")]
    assert checks[0] == flag
    stat_line = next(ln for ln in checks if ln.startswith("- FLAG stationarity [trial/accel/x]"))
    line_line = next(ln for ln in checks if ln.startswith("- FLAG lines [trial/accel/x,y]: one line (2 axes)"))
    assert "stuck span" in stat_line and "stuck span" in line_line


def test_a_clean_outliers_report_adds_no_flag():
    from imupipe.stages import summary as mod
    entry = {}
    mod.merge_checks(entry, {"dataset": "d", "sensor": "accel", "axis": "x", "n_outliers": 0, "stuck_spans": [],
                              "n_stuck_spans": 0})
    assert entry == {}
    assert render_summary({"accel": {"bound": _bound(), "stationarity": STATIONARITY}}) == \
        render_summary({"accel": {"bound": {**_bound(), **entry}, "stationarity": STATIONARITY}})


def test_a_per_axis_model_passing_its_replay_by_tolerance_is_flagged_on_the_first_screen():
    """An exported per-axis model whose replay's worst MSE/P (1.78, in the fix phase) passed only by the replay's
    sampling tolerance (1 + 0.98): an outside evaluation found the summary silent on it. It is a FLAG naming the
    axis with the contract's sentence, and the verdict table's verification column says so."""
    from imupipe.summary import summary_sections

    rep = {"worst_ratio": 1.78, "worst_t_s": 312.0, "tolerance": 0.98, "passed": True, "n_eff": 8.33,
           "within_tolerance": "passes within the replay's sampling tolerance (ratio 1.78 at 312 s, tolerance 1 + "
                               "0.98 = 1.98; t = 2 sqrt(2/n_eff), n_eff 8.33 independent windows)"}
    bound = _bound(verified=True, verification={"replay": {"worst_ratio": 0.9, "tolerance": 0.5, "passed": True}},
                   per_axis_models={"x": {"exported_in_kf": True, "verification": {"replay": rep}},
                                    "y": {"exported_in_kf": False, "kf": "axis y: the global model",
                                          "verification": {"replay": rep}}})
    flags = [f for f in flags_of("accel", bound=bound) if f.check == "replay within its tolerance"]
    assert [f.where for f in flags] == ["axis x model"]  # y exports the global model: its own replay is not used
    assert flags[0].severity == "flag" and "ratio 1.78" in flags[0].detail and "1.98" in flags[0].detail
    head, _ = summary_sections({"accel": {"bound": bound}})
    assert "- FLAG replay within its tolerance [axis x model]: passes within the replay's sampling tolerance" in head
    assert "| passed, replay (axis x model) only within its sampling tolerance (FLAG below) |" in head
    # a contract written before the sentence existed: the numbers give it
    old = _bound(verified=True, per_axis_models={"x": {"exported_in_kf": True, "verification": {
        "replay": {k: rep[k] for k in ("worst_ratio", "worst_t_s", "tolerance", "passed")}}}})
    (f,) = [f for f in flags_of("accel", bound=old) if f.check == "replay within its tolerance"]
    assert "ratio 1.78" in f.detail and "1 + 0.98 = 1.98" in f.detail


def test_a_reassigned_gm_and_record_consistency_are_shown_in_spec_and_si_units():
    """An outside evaluation read "sigma 0.00306 u" and "(white = 0.000764 SI)" in the summary of a spec sheet that
    gives no GM term: every value of a re-assigned GM (its sigma, the white noise it acts as) and of the
    record-consistency FLAG is shown in the spec sheet's unit (or the data sheets' usual one) and in SI. The
    conversions are closed forms: 0.00306 rad/s x 180/pi x 3600 = 631 deg/h; 0.000764 rad/s/sqrt(Hz) x 180/pi x 60
    = 2.63 deg/sqrt(h)."""
    from imupipe.summary import summary_sections

    moved = {"term": 1, "sigma": 0.00306, "T_s": 0.0106, "acts_as": "white", "value": 0.000764,
             "why": "its T interval reaches the shortest T the records resolve"}
    identify = {"gm_reassigned": [moved],
                "selection": {"kept": ["white"], "dropped": ["gauss_markov"],
                              "reasons": {"white": "significant",
                                          "gauss_markov": "re-assigned: GM term 1 (sigma 0.00306 u, T 0.0106 s) acts as "
                                              "white noise (white = 0.000764 SI); was: kept: significant"}},
                "record_consistency": {"datasets": ["a", "b", "c"], "z_crit": 2.9, "alpha": 0.01, "flagged": [
                    {"dataset": "a", "param": "white", "estimate": 0.000764, "others": 0.000382, "z": 5.0}]}}
    bound = _bound(sensor="gyro", spec_spec_units={"white": {"value": 2.0, "unit": "deg/sqrt(h)"}, "gauss_markov": []},
                   bound_spec_units={"white": {"value": 3.0, "unit": "deg/sqrt(h)"}, "gauss_markov": []})
    head, details = summary_sections({"gyro": {"bound": bound, "identify": identify}})
    (gm,) = [ln for ln in head.splitlines() if ln.startswith("- FLAG GM re-assigned")]
    assert "sigma 631 deg/h (0.00306 rad/s)" in gm and "white noise N 2.63 deg/sqrt(h) (0.000764 rad/s/sqrt(Hz))" in gm
    (rc,) = [ln for ln in head.splitlines() if "record consistency" in ln]
    assert "N = 2.63 deg/sqrt(h) (0.000764 rad/s/sqrt(Hz))" in rc
    (why,) = [ln for ln in details.splitlines() if ln.startswith("  - gauss_markov (dropped)")]
    assert "631 deg/h (0.00306 rad/s)" in why and "was: kept: significant" in why
    for text in (head, details):
        assert " u," not in text and " u)" not in text and " SI)" not in text


def test_the_first_screen_states_each_axis_export_and_why_kalibr_is_refused():
    """Per-axis models: an outside evaluation saw the first screen show the global model's 0.5 Hz line while the
    axes' own models (what the KF file exports per axis) had dropped it, and Kalibr refused without saying whose
    line. The first screen now lists, per axis, the model exported, its values and line states (and the lines its
    reduction dropped), and the Kalibr FLAG names the exported models holding a line."""
    from imupipe.summary import summary_sections

    line = {"sigma": 6.6e-3, "f0_hz": 0.564, "zeta": 1.8e-3}
    glob = {"white": 0.0107, "gauss_markov": [], "random_walk": 0.00115, "narrowband": [line]}
    own = {"exported_in_kf": True, "model": {"white": 0.00769, "gauss_markov": [{"sigma": 0.00465, "T": 9.91}],
                                             "random_walk": 0.000788, "narrowband": []},
           "export": {"dropped_by_reduction": ["narrowband f0=0.564 Hz"]}}
    bound = _bound(sensor="accel", model=glob, bound_spec_units={"white": {"value": 0.642, "unit": "m/s/sqrt(h)"}},
                   spec_spec_units={"white": {"value": 0.2, "unit": "m/s/sqrt(h)"}, "gauss_markov": []},
                   per_axis_models={"x": own, "y": {"exported_in_kf": False, "kf": "axis y: the global model (its own "
                                                    "failed: verification replay (1.2))"}})
    kalibr = {"refused": True, "reason": "narrowband line state(s) in the exported accel KF model"}
    head, _ = summary_sections({"accel": {"bound": bound}}, kalibr=kalibr)
    rows = [ln for ln in head.splitlines() if ln.startswith("| accel | x |") or ln.startswith("| accel | y |")]
    assert len(rows) == 2
    x, y = rows
    assert "own model" in x and "none; dropped by the verified reduction: 0.564 Hz" in x
    assert "sigma 0.474 mg (0.00465 m/s^2), T 9.91 s" in x  # 0.00465 / 9.80665e-3 = 0.474 mg
    assert "global model" in y and "0.564 Hz (sigma 0.673 mg (0.0066 m/s^2))" in y and "its own failed" in y
    (k,) = [ln for ln in head.splitlines() if ln.startswith("- FLAG kalibr export")]
    assert "the exported line states: accel global model (exported for axis y): 0.564 Hz" in k
    assert "axis x" not in k


def test_a_per_axis_gm_left_open_above_is_flagged():
    """One record's z axis kept a GM at the longest T searched with a T interval open above (re-assigned to the
    random walk it acts as, its envelope kept over the interval): that axis's bound, KF model and Kalibr value rose
    3.4x over the other record's, and only the pooled fit's re-assignment was FLAGged. The axis's own is now."""
    r = {"term": 1, "sigma": 0.00034, "T_s": 345.0, "acts_as": "random_walk", "value": 2.66e-5, "T_open_above": True,
         "why": "its T interval reaches the longest T the records resolve"}
    closed = {**r, "T_open_above": False, "T_s": 0.0106}
    ident = {"per_axis": {"x": {"gm_reassigned": [closed]}, "z": {"gm_reassigned": [r]}}}
    (f,) = [f for f in flags_of("gyro", identify=ident) if f.check == "GM re-assigned"]
    assert f.where == "axis z gm_1" and "open above" in f.detail
    assert "70.1 deg/h (0.00034 rad/s)" in f.detail and "random walk K 5.49 (deg/h)/sqrt(s)" in f.detail


def test_an_initial_bias_resting_on_the_default_time_constant_is_flagged_on_the_first_screen():
    """The KF file's P0 rests on the longest bias time constant T_max; nobody stated it, the default assumption
    (10 x the longest record) sets it and the records cannot check it: a FLAG on the first screen (an outside
    evaluation found it only in the details). Stated (identify.max_bias_time_s) or within the records: no FLAG."""
    from imupipe.biasinit import bias_initialisation
    from imupipe.models import NoiseModel
    from imupipe.summary import summary_sections

    model = NoiseModel(white=1e-4, gauss_markov=((2e-5, 200.0),), random_walk=1e-7)

    def contract(**kw):
        bi = bias_initialisation(model, spec=model, upper=model, record_s=3600.0, run_s=4200.0, **kw)
        return _bound(bias_initialisation={**bi.to_dict("rad/s"), "statement": bi.statement("rad/s")})

    (f,) = [f for f in flags_of("gyro", bound=contract()) if f.check == "initial bias"]
    assert f.severity == "flag" and "T_max = 3.6e+04 s (assumption: 10 x the longest record" in f.detail
    assert "identify.max_bias_time_s" in f.detail
    head, _ = summary_sections({"gyro": {"bound": contract()}})
    assert "- FLAG initial bias [KF file P0]: the exported initial bias (std " in head
    for stated in (1800.0, 1e5):  # within the records, or a stated T_max beyond them
        assert not [f for f in flags_of("gyro", bound=contract(max_bias_time_s=stated)) if f.check == "initial bias"]


def test_a_stated_bias_time_within_the_records_reads_as_checked_and_one_member():
    """identify.max_bias_time_s (1500 s) below the longest record (5400 s): an outside evaluation read "...extrapolated
    to the longest admitted time constant; which the records resolve" and "for T 5.4e+03-5.4e+03 s". The statement
    says T_max, the record that checks it, and the family's one member in words."""
    from imupipe.biasinit import bias_initialisation
    from imupipe.models import NoiseModel
    from imupipe.summary import _bias_lines

    model = NoiseModel(white=1e-4, random_walk=1e-7)
    bi = bias_initialisation(model, spec=model, upper=model, record_s=5400.0, run_s=1950.0, max_bias_time_s=1500.0)
    lines = _bias_lines(_bound(bias_initialisation={**bi.to_dict("rad/s"), "statement": bi.statement("rad/s")}))
    text = "\n".join(lines)
    assert "T_max = 1500 s (config: identify.max_bias_time_s) is within the longest record (5400 s)" in text, text
    assert "5.4e+03-5.4e+03" not in text and "the GM of T = that record, 5.4e+03 s" in text, text
    assert "cannot check" not in text


def test_an_initial_bias_resting_on_the_spec_sheets_gm_time_constant_is_flagged():
    """A spec sheet whose longest GM time constant (7200 s) exceeds the records (3600 s) sets T_max; the sheet states
    its bias instability's correlation time, not that no bias persists longer, and the records cannot check it
    (``checked_by_records`` false): the FLAG stays, naming the sheet as the source (an outside evaluation found it
    dropped). A T_max the user states (identify.max_bias_time_s) still clears it."""
    from imupipe.biasinit import bias_initialisation
    from imupipe.models import NoiseModel

    model = NoiseModel(white=1e-4, gauss_markov=((2e-5, 200.0),), random_walk=1e-7)
    sheet = NoiseModel(white=1e-4, gauss_markov=((2e-5, 7200.0),), random_walk=1e-7)

    def contract(**kw):
        bi = bias_initialisation(model, spec=sheet, upper=model, record_s=3600.0, run_s=4200.0, **kw)
        assert bi.to_dict()["checked_by_records"] is (kw.get("max_bias_time_s", 7200.0) <= 3600.0)
        return _bound(bias_initialisation={**bi.to_dict("rad/s"), "statement": bi.statement("rad/s")})

    (f,) = [f for f in flags_of("gyro", bound=contract()) if f.check == "initial bias"]
    assert "T_max = 7.2e+03 s (spec sheet: longest GM time constant" in f.detail
    assert "identify.max_bias_time_s" in f.detail
    # and the sheet's key for a turn-on bias, which mean-removed records cannot show (an outside evaluation: a 2 mg
    # turn-on bias under the exported 0.6 mg, MSE/P 2.7 in the fixes; the first screen named max_bias_time_s alone)
    assert "the spec sheet's turn_on_bias" in f.detail
    assert not [f for f in flags_of("gyro", bound=contract(max_bias_time_s=1e5)) if f.check == "initial bias"]


def test_the_fit_adequacy_flag_names_auto_only_under_auto():
    # an outside evaluation read, in a raw-mode run, a FLAG about what auto does with a rejected model
    ident = {"adequacy": {"adequate": False, "chi2_per_dof": 4.2, "p_value": 1e-9}}
    (raw,) = [f for f in flags_of("gyro", bound=_bound(), identify=ident) if f.check == "fit adequacy"]
    (auto,) = [f for f in flags_of("gyro", bound=_bound(mode="auto (smoothed)"), identify=ident)
               if f.check == "fit adequacy"]
    assert "identify.n_gm: 2, longer records or" in raw.detail and "auto" not in raw.detail
    # a line below the line search's band is one cause it names (an outside evaluation: chi2/dof 1.2e4 from a 0.03 Hz
    # line, the band starting at 0.052 Hz, and the FLAG advising n_gm only)
    assert "for a line below the line search's band, lines.low_band_resolution_hz" in raw.detail
    assert "a resonance wider than about a tenth of the search's floor window lifts its own floor" in raw.detail
    assert "auto then builds no envelope candidate" in auto.detail
    # a p from the covariance statistic shows that statistic beside Pearson's (an outside evaluation read "chi2/dof =
    # 1.19, p = 2.33e-122"): here 620.5 / 10
    cov = {"adequacy": {"adequate": False, "chi2_per_dof": 1.19, "p_value": 2.33e-122, "dof": 10,
                        "chi2_covariance": 620.5, "method": "bootstrap (...); beyond every replicate, tail p from the "
                                                            "covariance statistic"}}
    (f,) = [f for f in flags_of("gyro", bound=_bound(), identify=cov) if f.check == "fit adequacy"]
    assert f.detail.startswith("chi2/dof = 1.19 (with the AV points' correlation: 62), p = 2.33e-122: ")
    # a p at the bootstrap's floor (no replicate reached the statistic: 1 / (1 + 100)) is an upper limit, not a p (an
    # outside evaluation read "p = 0.0099" twice, before and after a change of the model); a tail p below the floor
    # (above) is shown as computed
    floor = {"adequacy": {"adequate": False, "chi2_per_dof": 5.0, "p_value": 1 / 101, "p_value_resolution": 1 / 101}}
    (f,) = [f for f in flags_of("gyro", bound=_bound(), identify=floor) if f.check == "fit adequacy"]
    assert f.detail.startswith("chi2/dof = 5, p <= 0.0099: ")
    cov["adequacy"]["p_value_resolution"] = 1 / 101
    (f,) = [f for f in flags_of("gyro", bound=_bound(), identify=cov) if f.check == "fit adequacy"]
    assert ", p = 2.33e-122: " in f.detail


def test_a_failed_component_check_reads_in_words_and_the_verdict_line_names_it():
    # an outside evaluation read "FAIL bound [...]: the PSD margin 1 holds, another check failed" (a FAIL whose named
    # check passed) beside "FAIL allan_components [tau_s=1.6]: component=random_walk, ratio=0.974"
    failed = _bound(bounded=False, margin=1.0, failed_checks=[
        {"check": "allan_components", "component": "random_walk", "ratio": 0.974, "tau_s": 1.6}])
    fl = {f.check: f for f in flags_of("gyro", bound=failed) if f.severity == "fail"}
    assert "bound" not in fl
    assert fl["verdict"].detail == "not bounded: failed allan components (lines below); the PSD margin 1 holds"
    assert fl["allan_components"].where == "tau 1.6 s"
    assert fl["allan_components"].detail.startswith(
        "the bound's random_walk term, with the terms that may represent it (white noise, random walk, lines), has "
        "0.974x the Allan variance of the identified term there (the refit as fitted, identify file model_refit")


def test_a_failed_ratio_next_to_1_is_not_shown_as_1():
    # an outside evaluation read "worst_ratio=1" in FAIL lines whose ratios were 1.00015 and 1.0005: a ratio that
    # failed its limit of 1 keeps the digits that tell it from 1
    from imupipe.shown import ratio_text

    assert [ratio_text(v) for v in (1.00015, 1.0005, 0.99999979, 1.0, 0.958, None)] == [
        "1.0002", "1.0005", "0.9999998", "1", "0.958", "-"]
    failed = _bound(bounded=False, margin=1.0, failed_checks=[{"check": "verify envelope", "worst_ratio": 1.00015}])
    fl = [f for f in flags_of("gyro", bound=failed) if f.severity == "fail" and f.check == "verify envelope"]
    assert fl and "worst_ratio=1.0002" in fl[0].detail, fl


def test_the_line_search_band_is_stated_with_its_lower_limit():
    """A line below the line search's lowest frequency (half a running-median window above 0) is not searched for;
    the summary says where the search began, from the lines files (an outside evaluation's 0.01 Hz line went
    unnamed)."""
    from imupipe.stages import summary as mod

    entry = {}
    for axis in "xyz":
        mod.merge_checks(entry, {"dataset": "d", "sensor": "gyro", "axis": axis, "lines": [], "n_tested": 24950,
                                  "f_min_hz": 26 * 0.002, "f_max_hz": 49.95, "resolution_hz": 0.002, "alpha": 0.01})
    text = render_summary({"gyro": {"bound": {**_bound(), **entry}}})
    # a found line's centre may lie just outside the tested bins (an outside evaluation read a 0.0500 Hz line beside
    # "0.052 to 4.95 Hz"): the text says the band is of bins tested, and why
    assert ("- line search (lines stage, each full-rate record): bins tested 0.052 to 49.95 Hz at 0.002 Hz "
            "resolution (a found line's centre may lie up to 2 bins outside: its main lobe), family-wise level 0.01 "
            "per record and axis; a line below 0.052 Hz is not searched for") in text
    assert "line search" not in render_summary({"gyro": {"bound": _bound()}})
    # the bursts a search read filled (events.policy warn) are counted with their total length, from the lines files
    mod.merge_checks(entry, {"dataset": "e", "sensor": "gyro", "axis": "x", "lines": [], "n_tested": 24950,
                             "f_min_hz": 0.052, "f_max_hz": 49.95, "resolution_hz": 0.002, "alpha": 0.01,
                             "bursts_filled": [{"start_s": 699.31, "stop_s": 702.76}, {"start_s": 10.0, "stop_s": 12.0}]})
    text = render_summary({"gyro": {"bound": {**_bound(), **entry}}})
    assert ("- line search (lines stage, each full-rate record; 2 burst stretch(es), 5.45 s in all, read filled so "
            "that a knock's ringing is not taken for a line): bins tested") in text


def test_a_margin_at_one_within_round_off_is_not_called_a_failed_margin():
    # an outside evaluation read "FAIL bound [...]: not bounded: margin 1 < 1" beside a contract whose PSD margin
    # held (0.9999999999999998, within the one tolerance imupipe.verdict.BOUNDED_TOLERANCE)
    from imupipe.verdict import BOUNDED_TOLERANCE

    failed = _bound(bounded=False, margin=1.0 - 2e-16, failed_checks=[
        {"check": "allan_components", "component": "random_walk", "ratio": 0.27, "tau_s": 64.0}])
    fl = {f.check: f for f in flags_of("gyro", bound=failed) if f.severity == "fail"}
    assert "bound" not in fl and "the PSD margin 1 holds" in fl["verdict"].detail
    short = _bound(bounded=False, margin=1.0 - 10 * BOUNDED_TOLERANCE)
    assert any(f.check == "bound" and "margin" in f.detail for f in flags_of("gyro", bound=short))


def test_the_samples_a_gap_fill_made_up_are_counted_per_dataset():
    # an outside evaluation: the summary of a gap_policy fill run did not say that samples were made up
    usage = [{"dataset": "phone", "axis": a, "n_samples": 3600, "n_samples_used": 3600, "n_filled": 7,
              "filled_rows": "49,118,198,329,475,600,700"} for a in "xyz"]
    usage.append({"dataset": "lab", "axis": "x", "n_samples": 3600, "n_samples_used": 3600, "n_filled": 0,
                  "filled_rows": ""})
    text = render_summary({"gyro": {"bound": _bound(psd_usage=usage), "identify": IDENTIFY}})
    assert ("- samples made up by linear interpolation (gap_policy fill): phone 7 samples in 7 gap(s) (after file "
            "rows 49, 118, 198, 329, 475, ...)") in text
    assert "lab" not in text
    assert "made up" not in render_summary({"gyro": {"bound": _bound(psd_usage=usage[3:]), "identify": IDENTIFY}})


def test_an_event_on_an_axis_that_fails_the_stationarity_test_names_a_level_change():
    # an outside evaluation: white noise 3x over half a record gave 7 "mean steps", each FLAG blaming a step that
    # does not exist, while the stationarity test failed those axes; the FLAG now says a level change reads so too
    item = {"dataset": "rec", "sensor": "accel", "axis": "x", "kind": "step", "time_s": 2345.6, "start_s": 2345.6,
            "stop_s": 2345.6, "size": 0.0333, "size_low": 0.032, "size_high": 0.0345, "units": "m/s^2",
            "action": "kept in the analysis"}
    curves = [{"dataset": "rec", "axis": "x", "stationary": False, "p_value": 0.005, "test": "calibrated"},
              {"dataset": "rec", "axis": "y", "stationary": True, "p_value": 0.4, "test": "calibrated"}]
    two = [item, dict(item, time_s=4000.0, start_s=4000.0, stop_s=4000.0)]
    flags = [f for f in flags_of("accel", {"events": two}, {}, {"curves": curves}) if f.check == "event"]
    assert len(flags) == 2 and all("the record's axis x also fails the stationarity test or its stretch test: a "
                                   "change of the noise" in f.detail for f in flags)
    (flag,) = [f for f in flags_of("accel", {"events": two[:1] + [dict(two[1], axis="y")]}, {}, {"curves": curves[1:]})
               if f.check == "event" and f.where.endswith("/x")]
    assert "stationarity" not in flag.detail
    # one mean step alone on its axis fails the stationarity test by itself (an outside evaluation's 1 mg step read
    # as a possible level change): no note
    (flag,) = [f for f in flags_of("accel", {"events": [item]}, {}, {"curves": curves}) if f.check == "event"]
    assert "stationarity" not in flag.detail
    curves[1]["stationary"] = False
    group = [dict(item, axis=a, time_s=t) for a in "xy" for t in (100.0, 200.0, 300.0)]  # more than 3: one FLAG
    (flag,) = [f for f in flags_of("accel", {"events": group}, {}, {"curves": curves}) if f.check == "event"]
    assert flag.where == "rec/accel" and "the record's axes x, y also fail the stationarity test or its" in flag.detail


def test_a_verdict_over_records_that_are_not_stationary_says_what_it_covers():
    # an outside evaluation: white noise 2.5x over the last third of a record, every axis non-stationary and kept:
    # BOUNDED, while the filter under-stated its error in that stretch (MSE/P up to 1.5). Where the bound covers the
    # records' noisiest stretch the verdict says so; where no scan was possible and the failures are more than
    # chance gives, it says the bound covers their average; failures consistent with chance add nothing
    base = {"curves": STATIONARITY["curves"], "on_fail": "warn", "alpha": 0.05}
    stretched = [dict(c, noisiest_stretch={"max_gain": 2.3}) if not c["stationary"] else c for c in base["curves"]]
    cases = [({**base, "curves": stretched, "n_non_stationary": 3, "n_curves": 3},
              "BOUNDED with the noisiest stretch of its 1 non-stationary curve (FLAGs below)."),
             ({**base, "n_non_stationary": 3, "n_curves": 3},
              "BOUNDED for the records' average noise (they are not stationary: FLAGs below)."),
             ({**base, "n_non_stationary": 3, "n_curves": 3, "on_fail": "exclude"}, "BOUNDED. "),
             ({**base, "n_non_stationary": 1, "n_curves": 3}, "BOUNDED. ")]
    for stat, verdict in cases:
        text = render_summary({"gyro": {"bound": _bound(), "identify": IDENTIFY, "stationarity": stat}})
        assert f"**Verdict:** gyro: {verdict}" in text, (stat, text[:300])


def test_a_stationarity_flag_says_the_bound_took_in_the_noisiest_stretch():
    scan = {"stretch_s": 900.0, "n_stretches": 15, "edf_min": 135.0, "max_gain": 2.6,
            "bands": [{"f_lo_hz": 0.0089, "f_hi_hz": 0.08, "ratio": 2.4, "start_s": 4950.0},
                      {"f_lo_hz": 0.089, "f_hi_hz": 0.5, "ratio": 2.6, "start_s": 5400.0}]}
    curves = [dict(c, noisiest_stretch=scan) if not c["stationary"] else c for c in STATIONARITY["curves"]]
    stat = {"curves": curves, "on_fail": "warn", "alpha": 0.05, "n_non_stationary": 1, "n_curves": 2}
    text = render_summary({"gyro": {"bound": _bound(), "identify": IDENTIFY, "stationarity": stat}})
    assert ("FLAG stationarity [sim2/gyro/z]: non-stationary (p = 0.003, calibrated); kept in the bound with its "
            "noisiest stretch: its PSD raised up to 2.6x (the 900 s from 5400 s, 0.089-0.5 Hz)") in text
    # a curve without a scan: the FLAG as before
    text = render_summary({"gyro": {"bound": _bound(), "identify": IDENTIFY, "stationarity": STATIONARITY}})
    assert "non-stationary (p = 0.003, calibrated); kept in the bound" in text and "noisiest" not in text


def test_a_curve_whose_level_changes_though_it_passes_the_stationarity_test_is_flagged_and_says_why():
    scan = {"stretch_s": 900.0, "n_stretches": 15, "edf_min": 135.0, "max_gain": 3.5,
            "bands": [{"f_lo_hz": 0.0089, "f_hi_hz": 0.5, "ratio": 3.5, "start_s": 3600.0}]}
    quiet = dict(STATIONARITY["curves"][0], noisiest_stretch=scan, stretch_test_p=0.001)
    stat = {"curves": [quiet], "on_fail": "warn", "alpha": 0.05, "n_non_stationary": 0, "n_curves": 1}
    text = render_summary({"gyro": {"bound": _bound(), "identify": IDENTIFY, "stationarity": stat}})
    assert ("FLAG noise level [sim1/gyro/x]: the noise level changes along the record (stretch test p = 0.001, below "
            "alpha / 1) though the stationarity test passes (p = 0.4); kept in the bound with its noisiest stretch: "
            "its PSD raised up to 3.5x (the 900 s from 3600 s, 0.0089-0.5 Hz)") in text
    assert "BOUNDED with the noisiest stretch of its 1 non-stationary curve" in text
    # a failing curve taken in by its own p-value where the count alone is chance says so beside the chance sentence
    failing = dict(STATIONARITY["curves"][1], noisiest_stretch=scan, taken_in_by="own p-value")
    stat = {"curves": [STATIONARITY["curves"][0], failing], "on_fail": "warn", "alpha": 0.05,
            "n_non_stationary": 1, "n_curves": 2, "chance": "1 of 2 axes failed ...: consistent with chance"}
    text = render_summary({"gyro": {"bound": _bound(), "identify": IDENTIFY, "stationarity": stat}})
    assert "(taken in: its own p-value is below alpha / 2 = 0.025)" in text


def test_first_screen_gives_a_flag_s_finding_and_its_details_give_it_in_full():
    """A lines FLAG with its chance text: the first screen gives the line and the chance verdict (the numbers behind
    the verdict in the details, whose sensor section lists the FLAG in full); the line search's statement names the
    low band where the lines file has one."""
    from imupipe.stages import summary as mod
    from imupipe.summary import first_screen

    entry = {}
    mod.merge_checks(entry, {
        "dataset": "d", "sensor": "gyro", "axis": "x", "n_tested": 25_000, "f_min_hz": 0.0072, "f_max_hz": 9.95,
        "resolution_hz": 0.002, "alpha": 0.01,
        "low_band": {"resolution_hz": 1 / 3600, "f_max_hz": 0.0517, "n_segments": 4, "alpha": 0.005},
        "low_band_finer": {"resolution_hz": 1 / 7200, "f_max_hz": 0.0518, "n_segments": 2, "alpha": 0.005},
        "lines": [{"frequency_hz": 0.03, "power": 5e-7, "amplitude": 1e-3, "sigma": 7.07e-4, "peak_ratio": 900.0,
                   "f_lo_hz": 0.029, "f_hi_hz": 0.031}],
        "units": {"frequency_hz": "Hz", "amplitude": "rad/s", "sigma": "rad/s", "peak_ratio": "1"}})
    text = render_summary({"gyro": {"bound": entry}})
    head, details = first_screen(text), text[len(first_screen(text)):]
    (short,) = [ln for ln in head.splitlines() if ln.startswith("- FLAG lines")]
    assert short == ("- FLAG lines [d/gyro/x]: 0.03 Hz, amplitude 0.001 rad/s (sd 0.000707), peak PSD 900x the floor; "
                     "1 of 1 axes show a line, consistent with chance (in full: the details, gyro)"), short
    (full,) = [ln for ln in details.splitlines() if ln.startswith("- FLAG lines")]
    assert full.startswith(short.partition("; ")[0] + "; 1 of 1 axes show a line at level 0.01 each")
    assert "P(>= 1)" in full
    assert "Checks: on the first screen (above); in full:" in details
    assert ("bins tested 0.0072 to 9.95 Hz at 0.002 Hz resolution (below 0.0517 Hz at 0.0001389-0.0002778 Hz: "
            "lines.low_band_resolution_hz and half of it)") in details
    # below the searched band the bound covers a line as the records hold it: one draw where it is coherent
    assert ("which the bound covers as the records hold it, not as a line term (a line coherent beyond a record is "
            "one draw of its amplitude there") in details


def test_a_flag_s_clauses_split_outside_parentheses_only():
    from imupipe.flagtext import clauses, short_form

    text = "std 8.6 deg/h (assumption: 10 x; the record cannot check it): state T; e.g. 3 [a; b]"
    assert clauses(text) == ["std 8.6 deg/h (assumption: 10 x; the record cannot check it): state T", "e.g. 3 [a; b]"]
    # the finding and the second clause up to its ':'; with the chance text's verdict; none where nothing is cut
    chance = "; 1 of 2 axes failed at level 0.05 each; with every axis ... P(>= 1) = 0.098: consistent with chance"
    assert short_form("a step at 3 s; kept (warn): it inflates K", chance,
                      keep=2) == "a step at 3 s; kept (warn); 1 of 2 axes failed, consistent with chance"
    assert short_form("a line at 2 Hz") == ""


def test_a_line_beyond_the_level_over_every_series_is_not_called_chance():
    """An outside evaluation: a line 805x its floor on one of three axes read "1 of 3 axes show a line, consistent
    with chance" (the count's verdict). A line above the detection threshold of its own search at alpha / n (n the
    series searched; imupipe.lines.detection_threshold with the search's M, K, W) is more than chance gives on its
    own; a line below it leaves the count's verdict."""
    from imupipe.lines import detection_threshold
    from imupipe.stages import summary as mod
    from imupipe.summary import first_screen

    strict = detection_threshold(0.01 / 3, 25_000, 14, 51)

    def run(ratio):
        entry = {}
        for axis in "xyz":
            found = [{"frequency_hz": 0.3, "power": 5e-7, "amplitude": 1e-3, "sigma": 7.07e-4, "peak_ratio": ratio,
                      "f_lo_hz": 0.29, "f_hi_hz": 0.31, "resolution_hz": 0.002}] if axis == "y" else []
            mod.merge_checks(entry, {
                "dataset": "d", "sensor": "gyro", "axis": axis, "n_tested": 25_000, "n_segments": 14,
                "floor_window_bins": 51, "f_min_hz": 0.052, "f_max_hz": 9.95, "resolution_hz": 0.002, "alpha": 0.01,
                "lines": found, "units": {"frequency_hz": "Hz", "amplitude": "rad/s", "sigma": "rad/s"}})
        (line,) = [ln for ln in first_screen(render_summary({"gyro": {"bound": entry}})).splitlines()
                   if ln.startswith("- FLAG lines")]
        return line

    assert "1 of 3 axes show a line, consistent with chance" in run(0.9 * strict)
    strong = run(805.0)
    assert (f"1 of 3 axes show a line, the most significant, 805x its floor, above its search's threshold at "
            f"alpha / 3 ({strict:.3g}x), more than chance gives: look at the records named") in strong, strong


def test_a_line_flag_gives_its_sd_with_the_upper_limit_the_envelope_holds():
    """An outside evaluation read a wandering line's estimate (4.6x under its truth) where the bound held the upper
    limit: the FLAG gives both, the limit P1 nu / chi2_nu(1 - c) of its power (here nu = 8, four looks), checked
    against scipy.stats's quantile."""
    from scipy.stats import chi2

    from imupipe.linewords import line_text

    it = {"dataset": "d", "sensor": "gyro", "axis": "y", "frequency_hz": 0.011, "power": 1.866e-9,
          "amplitude": 6.1e-5, "sigma": 4.32e-5, "dof": 8.0, "peak_ratio": 12.0, "units": {"amplitude": "rad/s"}}
    limit = (1.866e-9 * 8.0 / chi2.ppf(0.05, 8.0)) ** 0.5
    where, text = line_text(it, confidence=0.95)
    assert where == "d/gyro/y" and f"(sd 4.32e-05, at most {limit:.3g} at 0.95)" in text, text
    assert "at most" not in line_text(it)[1] and "at most" not in line_text({**it, "dof": None}, 0.95)[1]
