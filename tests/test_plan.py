"""imupipe.plan and `imupipe plan`: closed forms, monotonicity, --target, --from and bad input."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.stats import norm

from imupipe import cli
from imupipe.allan import edf_greenhall
from imupipe.models import NoiseModel
from imupipe.plan import (expected_allan, parse_target, plan_table, predict, shortest_plan)
from imupipe.specsheet import load_spec, parse_spec

ROOT = Path(__file__).resolve().parents[1]
STIM = ROOT / "config" / "specs" / "stim300.yaml"

# Bootstrap noise of a half-width: the 2.5 % / 97.5 % percentile of B replicates has standard error
# sqrt(p (1 - p) / B) / phi(z_0.975) standard deviations (asymptotic quantile variance); for B = 1600 that is
# 0.067 sd, 3.4 % of the 1.96 sd end, and 2.4 % for the mean of the two ends. The tolerances below are 3 such
# standard errors (3 x 2.4 % ~ 7.5 % for one half-width, 3 x sqrt(2) x 2.4 % ~ 10 % for a ratio of two).
N_BOOT = 1600
TOL_ONE, TOL_RATIO = 0.075, 0.10


def _white():
    return NoiseModel(white=1.0e-4)


def test_expected_allan_is_the_model_and_greenhall_edf():
    m = _white()
    tau, avar, edf, n = expected_allan(m, 1.0, 10.0)
    assert n == 36000
    np.testing.assert_allclose(avar, 1.0e-8 / tau, rtol=1e-12)  # white noise: AV = N^2 / tau
    # white rate noise is alpha = 0 at every tau
    assert edf[0] == pytest.approx(float(edf_greenhall(0, 2, 1, n + 1)), rel=1e-12)


def test_white_noise_half_width_between_cramer_rao_and_the_single_tau_edf():
    """N^2 from n white samples: relative sd at best sqrt(2/n) (Cramer-Rao), at worst sqrt(2/nu_1) (the AV at
    tau_0 alone); the half-width of N is z/2 times that relative sd of N^2, times N."""
    m = _white()
    z = norm.ppf(0.975)
    tau, avar, edf, n = expected_allan(m, 1.0, 10.0)
    rel = predict(m, 1.0, 1, 10.0, 1, n_boot=N_BOOT)["relative"]["N"]
    assert z / math.sqrt(2 * n) * (1 - TOL_ONE) <= rel <= z / math.sqrt(2 * edf[0]) * (1 + TOL_ONE)
    assert math.isnan(predict(m, 1.0, 1, 10.0, 1, n_boot=50)["relative"]["K"])  # no random walk: no K interval


def test_white_noise_half_width_scales_as_one_over_sqrt_of_recorded_time():
    m = _white()
    base = predict(m, 1.0, 1, 10.0, 1, n_boot=N_BOOT)["half_width"]["N"]
    # four times the records: four times every edf (independent curves pooled), half the half-width
    more = predict(m, 1.0, 4, 10.0, 1, n_boot=N_BOOT)["half_width"]["N"]
    assert more / base == pytest.approx(0.5, rel=TOL_RATIO)
    # four times as long: nu_k / n is the same at every shared tau (Greenhall: M grows with n), the extra long taus
    # add little, so the same 1/2 within the bootstrap noise
    longer = predict(m, 4.0, 1, 10.0, 1, n_boot=N_BOOT)["half_width"]["N"]
    assert longer / base == pytest.approx(0.5, rel=TOL_RATIO)
    # three axes pooled per record count as three curves
    axes = predict(m, 1.0, 1, 10.0, 3, n_boot=N_BOOT)["half_width"]["N"]
    assert axes / base == pytest.approx(1 / math.sqrt(3), rel=TOL_RATIO)


MEMS = {"gyro": {"white": {"value": 0.4, "unit": "deg/sqrt(h)"},
                 "gauss_markov": [{"sigma": {"value": 10.0, "unit": "deg/h"}, "T": {"value": 100.0, "unit": "s"}}],
                 "random_walk": {"value": 0.2, "unit": "(deg/h)/sqrt(s)"}}}


def test_half_widths_fall_with_record_length():
    """A GM with T = 100 s, far below every record length: N, B and K all tighten. (Not so for the STIM-300 spec's
    GM, T = 1500 s beside K = 0.02 (deg/h)/sqrt(s): GM and random walk are confounded up to 20 h and the
    identification's B and K intervals do not shrink monotonically there; docs/performance.md, 2026-12-04.)"""
    model = parse_spec(MEMS).models["gyro"]
    rows = plan_table(model, [2.0, 6.0, 20.0], [1], 1.0, 1)
    for p in ("N", "B", "K"):
        rel = [r["relative"][p] for r in rows]
        assert all(np.isfinite(rel)), (p, rel)
        # each step triples (and more) the record: the half-width falls by ~1/sqrt(3) = 0.58, far beyond the
        # ~7 % bootstrap noise of 100 replicates
        assert rel[0] > rel[1] > rel[2], (p, rel)


WRW = {"gyro": {"white": {"value": 0.15, "unit": "deg/sqrt(h)"},
                "random_walk": {"value": 0.02, "unit": "(deg/h)/sqrt(s)"}}}


def test_shortest_plan_is_the_least_recorded_time_meeting_the_target():
    model = parse_spec(WRW).models["gyro"]
    rows = plan_table(model, [1.0, 4.0], [1, 3], 1.0, 1, n_boot=100)
    target = ("N", sorted(r["relative"]["N"] for r in rows)[1] * 1.0001)  # met by exactly two rows
    best = shortest_plan(rows, target)
    assert best["relative"]["N"] <= target[1]
    for r in rows:
        if r["hours"] * r["records"] < best["hours"] * best["records"]:
            assert r["relative"]["N"] > target[1]
    assert shortest_plan(rows, ("N", 1e-9)) is None


def test_parse_target():
    assert parse_target("K:0.25") == ("K", 0.25)
    assert parse_target("n:0.1") == ("N", 0.1)
    for bad in ("K", "X:0.2", "K:abc", "K:-1", "K:0"):
        with pytest.raises(ValueError, match="--target"):
            parse_target(bad)


def _run(capsys, *argv):
    code = cli.main(["plan", *argv])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_cli_table_target_and_pilot_give_the_same_plan(tmp_path, capsys):
    spec = tmp_path / "wrw.yaml"
    spec.write_text(yaml.safe_dump(WRW))
    # two replicates where a cell is one-sided or confounded (the CLI's default 50 cost most of this test's
    # time; the replicates' median itself is tested in test_replicates_replace_a_confounded_cell_by_a_median)
    args = ["--sensor", "gyro", "--rate-hz", "1", "--hours", "1", "3", "--records", "1", "2", "--axes", "1",
            "--replicates", "2"]
    code, out, err = _run(capsys, "--spec", str(spec), *args, "--target", "N:0.5")
    assert code == 0
    assert "| hours | records | N +/- (deg/sqrt(h)) |" in out
    # a line per row before and after it on stderr (minutes at 50 replicates), none on stdout (the table)
    assert [ln.split()[2].rstrip(":") for ln in err.splitlines() if ln.startswith("plan: row")] == [
        f"{i}/4" for i in (1, 1, 2, 2, 3, 3, 4, 4)]
    assert "plan: row" not in out
    assert len([ln for ln in out.splitlines() if ln.startswith("| ") and ln[2].isdigit()]) == 4
    assert "shortest plan with N within +/-50 %: 1 record(s) of 1 h" in out
    # a pilot's identify file with the same model gives the same table (same units, same seed)
    model = parse_spec(WRW).models["gyro"]
    pilot = tmp_path / "gyro.yaml"
    pilot.write_text(yaml.safe_dump({"sensor": "gyro", "rate_hz": {"lab/x": 1.0},
                                     "model_selected": model.to_dict()}))
    # no --rate-hz: the pilot's rate
    code2, out2, _ = _run(capsys, "--from", str(pilot), "--sensor", "gyro", "--hours", "1", "3", "--records", "1",
                          "2", "--axes", "1", "--replicates", "2")
    assert code2 == 0
    table = [ln for ln in out.splitlines() if ln.startswith("|")]
    assert [ln for ln in out2.splitlines() if ln.startswith("|")] == table


def test_cli_target_not_met(capsys):
    # the STIM-300 GM is confounded at 1 h: two replicates instead of the CLI's 50 (the message is the test)
    code, out, _ = _run(capsys, "--spec", str(STIM), "--sensor", "gyro", "--rate-hz", "1", "--hours", "1",
                        "--records", "1", "--axes", "1", "--target", "K:0.0001", "--replicates", "2")
    assert code == 1
    assert "no plan of the table gives K within +/-0.01 %" in out


def test_cli_target_on_a_term_the_model_lacks_is_refused_before_any_row(tmp_path, capsys):
    # a pilot whose identified model has no random walk: every K cell would be "-" and the old message "no plan of
    # the table gives K" read as if longer records would help; the target is refused by name before any fit
    pilot = tmp_path / "gyro.yaml"
    pilot.write_text(yaml.safe_dump({"sensor": "gyro", "rate_hz": {"lab/x": 1.0},
                                     "model_selected": NoiseModel(white=1e-4, gauss_markov=((1e-5, 100.0),)).to_dict()}))
    code, out, err = _run(capsys, "--from", str(pilot), "--sensor", "gyro", "--hours", "1", "--records", "1",
                          "--target", "K:0.25")
    assert code == 1 and out == ""
    assert "--target K:0.25" in err and "has no K term (random_walk = 0)" in err
    assert "plan: row" not in err  # refused before the table's first row


def test_a_flicker_only_sheet_plans_its_flicker_as_b_and_its_envelope_covers_it(capsys):
    # the shipped ADIS16405 sheet states its bias instability as a flicker floor and no GM: B is then the flicker
    # coefficient (an outside evaluation found the B column empty and --target B refused as "no B term"); the auto
    # columns come from the run's identification of the expected data, whose envelope carries a random walk floor
    # under the flicker's 1/f (the plan's own fit of the flicker alone flattened below the band, P/MSE 0.98 "!"),
    # so the filter on it is safe against the model: P/MSE >= 1, not marked
    spec = ROOT / "config" / "specs" / "adis16405.yaml"
    code, out, _ = _run(capsys, "--spec", str(spec), "--sensor", "accel", "--rate-hz", "100", "--hours", "2.78",
                        "--records", "2", "--replicates", "0", "--target", "B:0.25")
    assert code == 0
    assert "| B (flicker) +/- (mg) | B (flicker) +/- % |" in out
    row = [ln for ln in out.splitlines() if ln.startswith("| 2.78 |")][0].split("|")
    assert float(row[6]) < 25.0  # the flicker's half-width, % of the sheet's 0.2 mg
    assert "shortest plan with B within +/-25 %: 2 record(s) of 2.78 h" in out
    p_mse = row[-2].strip()
    assert not p_mse.endswith("!") and float(p_mse) >= 1.0
    assert "! the expected envelope alone lies below the model somewhere" not in out


@pytest.mark.parametrize("argv, flag", [
    (["--hours", "-1"], "--hours"),
    (["--hours", "nan"], "--hours"),
    (["--records", "0"], "--records"),
    (["--rate-hz", "0"], "--rate-hz"),
    (["--target", "X:0.2"], "--target"),
    (["--axes", "0"], "--axes"),
])
def test_cli_bad_input_names_the_flag(capsys, argv, flag):
    base = {"--hours": ["1"], "--records": ["1"], "--rate-hz": ["1"], "--axes": ["1"]}
    for i in range(0, len(argv), 2):
        base[argv[i]] = [argv[i + 1]]
    flat = [x for k, v in base.items() for x in (k, *v)]
    code, _, err = _run(capsys, "--spec", str(STIM), "--sensor", "gyro", *flat)
    assert code == 1
    assert flag in err


def test_cli_bad_sources(tmp_path, capsys):
    spec = tmp_path / "g.yaml"
    spec.write_text(yaml.safe_dump({"gyro": {"white": {"value": 0.1, "unit": "deg/sqrt(h)"}}}))
    code, _, err = _run(capsys, "--spec", str(spec), "--sensor", "accel", "--rate-hz", "1")
    assert code == 1 and "--spec" in err and "accel" in err
    code, _, err = _run(capsys, "--from", str(tmp_path / "missing.yaml"), "--sensor", "gyro", "--rate-hz", "1")
    assert code == 1 and "--from" in err
    bad = tmp_path / "bad.yaml"
    bad.write_text("sensor: gyro\n")
    code, _, err = _run(capsys, "--from", str(bad), "--sensor", "gyro", "--rate-hz", "1")
    assert code == 1 and "model_selected" in err
    nor = tmp_path / "norate.yaml"
    nor.write_text(yaml.safe_dump({"sensor": "gyro", "model_selected": NoiseModel(white=1e-4).to_dict()}))
    code, _, err = _run(capsys, "--from", str(nor), "--sensor", "gyro")
    assert code == 1 and "--rate-hz" in err
    with pytest.raises(SystemExit):  # argparse: --spec and --from exclude each other
        cli.main(["plan", "--spec", str(STIM), "--from", str(nor), "--sensor", "gyro"])


def test_plot_plan_check_draws_predicted_lines_and_simulated_points(tmp_path):
    from imupipe.plot import plot_plan_check, save_figure

    hw = [{"N": 1e-6 / math.sqrt(h), "B": 1e-5 / math.sqrt(h), "K": float("nan")} for h in (2.0, 8.0)]
    rows = [{"truth": "t", "hours": 2.0, "param": "N", "simulated": 7e-7, "q25": 6e-7, "q75": 8e-7}]
    fig = plot_plan_check({"t": {"hours": [2.0, 8.0], "half_width": hw}}, rows, sensor="gyro")
    ax_n, ax_b, ax_k = fig.axes
    assert ax_n.get_ylabel() == "interval half-width [deg/sqrt(h)]"
    # N: 1e-6 rad/s/sqrt(Hz) at 2 h is 1e-6 / sqrt(2) x (180/pi) x 60 deg/sqrt(h)
    assert ax_n.lines[0].get_ydata()[0] == pytest.approx(1e-6 / math.sqrt(2) * 180 / math.pi * 60, rel=1e-9)
    assert len(ax_b.lines) == 1 and len(ax_k.lines) == 0  # K NaN: not drawn; B has no simulated point
    assert len(ax_n.collections) >= 1  # the error bar of the simulated point
    save_figure(fig, tmp_path / "p.png")
    assert (tmp_path / "p.png").stat().st_size > 0


def test_format_table_marks_confounded_cells():
    from imupipe.plan import format_table

    row = {"hours": 6.0, "records": 1, "half_width": {"N": 1e-6, "B": 1e-6, "K": float("nan")},
           "relative": {"N": 0.01, "B": 0.5, "K": float("nan")},
           "confounded": {"N": False, "B": True, "K": False}}
    units = {"white": "deg/sqrt(h)", "gm_sigma": "deg/h", "random_walk": "(deg/h)/sqrt(s)"}
    text = format_table([row], units, "gyro")
    cells = text.splitlines()[2].split("|")
    assert cells[4].strip() == "1" and cells[6].strip() == "50 ~" and cells[8].strip() == "-"
    # 1e-6 rad/s is 1e-6 x 180/pi x 3600 deg/h; printed to 3 digits: within half a unit of the third, <= 5e-3
    assert float(cells[5]) == pytest.approx(1e-6 * 180 / math.pi * 3600, rel=5e-3)
    assert "~ the interval on the expected data is one-sided or confounded" in text
    # an expected envelope below the model somewhere: the P/MSE cell marked, with what the column leaves out
    below = dict(row, auto={"inflation": 1.1, "conservatism": 0.98, "worst": 1.02})
    text = format_table([below], units, "gyro")
    assert text.splitlines()[2].split("|")[-2].strip() == "0.98 !"
    assert "! the expected envelope alone lies below the model somewhere" in text


def test_plan_check_benchmark_runs(tmp_path, capsys):
    """benchmarks/plan_check.py on a tiny case (2 sets of a half-hour record at 1 Hz, 10 bootstrap replicates),
    then its --load / --figure path: it must not rot (no accuracy claim at this size)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("plan_check", ROOT / "benchmarks" / "plan_check.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    js, fig = tmp_path / "c.json", tmp_path / "c.png"
    assert mod.main(["--n", "2", "--rate-hz", "1", "--hours", "0.5", "--truth", "mems_like", "--json", str(js),
                     "--replicates", "2", "--n-boot", "10"]) == 0
    # one replicate in the --figure path (its seven predictions: the replicate branch, at half the CPU of two)
    assert mod.main(["--load", str(js), "--figure", str(fig), "--replicates", "1", "--n-boot", "10"]) == 0
    out = capsys.readouterr().out
    assert out.count("| mems_like | 0.5 | 1 |") == 6  # 3 parameters, printed by the run and by --load
    assert fig.stat().st_size > 0


def test_replicates_replace_a_confounded_cell_by_a_median():
    """The STIM-300 spec's GM at 2 h (T = 1500 s on the end of the T search): confounded on the expected data, so
    `replicates` gives the median over that many replicate curve sets; a white noise alone is never confounded and
    runs no replicate."""
    model = load_spec(STIM).models["gyro"]
    r = predict(model, 2.0, 1, 1.0, 1, replicates=3, n_boot=20)
    assert r["confounded"]["B"] and r["method"] == "median over 3 replicate Allan-variance curve sets"
    assert all(v > 0 for v in r["half_width"].values())
    assert predict(_white(), 1.0, 1, 1.0, 1, replicates=3, n_boot=20)["method"] == "expected Allan variance"
    with pytest.raises(ValueError, match="--replicates"):
        predict(_white(), 1.0, 1, 1.0, 1, replicates=-1)


def test_auto_prediction_is_safe_and_tightens_with_more_records():
    # the auto bound's expected conservatism (the joint envelope of the expected-data fit as the filter's model,
    # the model as the truth): the envelope dominates the model over its band, so the filter is safe against it
    # (worst MSE/P <= 1, to the verification's 1e-6) and its mean P/MSE >= 1; five records narrow the bootstrap
    # band (its width falls like 1/sqrt(records) to first order), so the inflation and the conservatism fall
    m = NoiseModel(white=2e-4, gauss_markov=((1e-4, 300.0),), random_walk=2e-6)
    one, five = (predict(m, 4.0, r, 10.0, 1, sensor="accel", n_boot=100)["auto"] for r in (1, 5))
    for a in (one, five):
        assert a["worst"] <= 1 + 1e-6 and a["conservatism"] >= 1.0 and a["inflation"] >= 1.0
    assert five["inflation"] < one["inflation"] and five["conservatism"] < one["conservatism"]
