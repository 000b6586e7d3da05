"""Run summary (imupipe.summary): verdicts, inflation table in spec-sheet units, states, flagged checks."""

import pytest

from imupipe.summary import flags_of, render_summary, write_summary


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
    assert "- states kept: white, gauss_markov" in text
    assert "random_walk (dropped): contributes < 5 % in the application band" in text
    assert "Checks: none failed or flagged." in text


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
    assert "FLAG lines [f0_hz=12.5]" in text
    assert "FLAG outliers [curve=sim1/x, index=1203, time_s=9.6]" in text
    assert "FLAG gaps [dataset=sim2, start_s=100, stop_s=100.5]" in text
    assert "**Verdict:** gyro: NOT BOUNDED; accel: BOUNDED. 4 failed" in text


def test_missing_keys_are_tolerated_and_nothing_is_invented():
    assert flags_of("gyro") == []
    text = render_summary({"accel": {}})
    assert "## accel: no bound" in text
    assert "FAIL" not in text and "FLAG" not in text


def test_write_summary(tmp_path):
    path = tmp_path / "summary.md"
    text = write_summary({"gyro": {"bound": _bound()}}, path)
    assert path.read_text() == text


@pytest.mark.parametrize("on_fail_included, phrase", [(False, "excluded from the bound"), (True, "kept in the bound")])
def test_stationarity_inclusion_is_stated(on_fail_included, phrase):
    stat = {"curves": [{"dataset": "d", "axis": "x", "stationary": False, "p_value": 0.01, "test": "paper",
                        "included": on_fail_included}]}
    (flag,) = flags_of("accel", stationarity=stat)
    assert phrase in flag.detail and flag.where == "d/accel/x"


def test_summarise_run_finds_the_files_of_a_results_folder(tmp_path):
    from imupipe.io import write_yaml_atomic
    from imupipe.summary import discover_run, summarise_run

    res = tmp_path / "results" / "myrun"  # a run-name level is found as well
    write_yaml_atomic({**_bound(), "sensor": "gyro"}, res / "bound" / "stim300" / "gyro.yaml")
    write_yaml_atomic({"curve": "sim1/x", "bounded": True, "sensor": "gyro"},
                      res / "bound" / "stim300" / "axes" / "sim1" / "gyro" / "x.yaml")  # per-axis: not a contract
    write_yaml_atomic(IDENTIFY, res / "identify" / "gyro.yaml")
    write_yaml_atomic(STATIONARITY, res / "stationarity" / "gyro.yaml")
    found = discover_run(tmp_path / "results")
    assert list(found) == ["stim300"] and list(found["stim300"]) == ["gyro"]
    text = summarise_run(tmp_path / "results")
    assert text.startswith("# imupipe run summary: stim300")
    assert "FLAG stationarity [sim2/gyro/z]" in text and "states kept: white, gauss_markov" in text
    assert summarise_run(tmp_path / "empty") == ""


def test_markdown_to_html_renders_the_summary_and_the_inflation_table():
    import re

    from imupipe.summary import markdown_to_html

    bound = _bound(bounded=False, margin=0.9)
    page = markdown_to_html(render_summary({"gyro": {"bound": bound, "identify": IDENTIFY,
                                                     "stationarity": STATIONARITY}}))
    assert page.startswith("<!DOCTYPE html>")
    assert "<h2>gyro: NOT BOUNDED</h2>" in page
    # the inflation table as an HTML table: header + 4 rows (N, K, GM sigma, GM T)
    (table,) = re.findall(r"<table>.*?</table>", page)
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
