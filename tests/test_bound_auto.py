"""bound.mode auto (imupipe.bound.auto) and the pooled mode's family-wise limit (imupipe.bound.engine, docs/method.md
"The auto bound"): the detrend bias in closed form, the pooled limit's coverage by simulation against the nominal
level (binomial 95 % range), its tightening with more curves, the selection rule on hand-made candidates, and the
one-call pipeline with mode auto end to end (every candidate verified, the winner exported)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.stats import binom

from imupipe.bound.auto import AUTO_MODES, ENVELOPE_MODE
from imupipe.bound.auto import select as _select
from imupipe.bound.engine import _prepare, detrend_bias
from imupipe.models import NoiseModel
from imupipe.spectra import psd


def test_detrend_bias_closed_form():
    # Hann, constant detrend: b_1 = 1 - (N/4)^2 / (N * 3N/8) = 5/6, b_k = 1 for k >= 2 (W(k) = 0 there)
    b = detrend_bias("hann", [1, 2, 3])
    assert b[0] == pytest.approx(5.0 / 6.0, rel=1e-3)  # O(1/N) at N = 4096
    assert b[1:] == pytest.approx(1.0, abs=1e-9)
    assert detrend_bias("hann", [1, 2], "none") == pytest.approx(1.0)
    # a linear detrend takes more from the lowest ordinates than a constant one
    assert np.all(detrend_bias("hann", [1, 2], "linear") < detrend_bias("hann", [1, 2]) + 1e-12)


def _coverage(truth, n_curves, n_rep, seed, mode="pooled"):
    """Fraction of replicates whose limits (mode's targets) lie above the true band-averaged sampled PSD at every
    row; and the mean over replicates of the rows' mean envelope/true ratio. 4 h at 1 Hz, 1800 s Hann windows
    with 50 % overlap, 10 bands per decade, min_edf 30 (the defaults' shape at a smaller scale)."""
    from imupipe.simulate import simulate

    rng = np.random.default_rng(seed)
    n = 4 * 3600
    hits, fac = 0, []
    for _ in range(n_rep):
        X = np.asarray(simulate(truth, n, 1.0, rng=rng, n_records=n_curves)).reshape(n_curves, n)
        sp = [psd(X[c], 1.0, window_s=1800.0, step_s=900.0) for c in range(n_curves)]
        f = sp[0]["frequency"].values
        prob = _prepare(f, np.array([s["psd"].values for s in sp]), None, 1.0, mode, 0.95, 10,
                        np.array([s["edf"].values for s in sp]), "hann", 30.0)
        true_rows = prob.to_rows(np.asarray(truth.psd_sampled(prob.f, 1.0)))
        hits += bool(np.all(prob.targets >= true_rows[None, :]))
        fac.append(float(np.mean(prob.targets.max(axis=0) / true_rows)))
    return hits / n_rep, float(np.mean(fac))


@pytest.mark.parametrize("kind,truth", [
    ("white", NoiseModel(white=1.0)),
    ("red", NoiseModel(white=1.0, gauss_markov=((0.5, 300.0),), random_walk=0.003)),
])
def test_pooled_limit_coverage_is_nominal(kind, truth):
    # Sidak over (group, band) pairs of nearly independent band averages: the family-wise coverage is the nominal
    # 0.95 to within the simulation's own binomial 95 % range (400 replicates: [0.9275, 0.97])
    n_rep = 400
    cov, _ = _coverage(truth, 5, n_rep, seed=2718)
    lo, hi = binom.ppf(0.025, n_rep, 0.95) / n_rep, binom.ppf(0.975, n_rep, 0.95) / n_rep
    assert lo <= cov <= hi, (kind, cov, lo, hi)


def test_pooled_limit_tightens_with_more_curves_and_beats_bonferroni():
    # the pooled limit's factor nu / chi2_nu(q) falls towards 1 as nu = sum of the curves' edf grows; the per-curve
    # Bonferroni limit's envelope (max over curves) does not
    truth = NoiseModel(white=1.0)
    _, one = _coverage(truth, 1, 30, seed=5)
    _, five = _coverage(truth, 5, 30, seed=6)
    _, bonf = _coverage(truth, 5, 30, seed=6, mode="confidence")
    assert five < one
    assert five < bonf
    assert five > 1.0  # still a limit above the truth on average


def _cand(margin=1.5, allan=True):
    return {"margin": margin, "margin_curve": "d0/x", "margin_frequency_hz": 0.01, "spec_margin": 2.0,
            "all_frequency_margin": 1.1, "allan_check_passed": allan,
            "allan_check": {"passed": allan, "total": {"passed": allan, "worst_ratio": 1.0 if allan else 0.8,
                                                       "curve": "d0/x", "tau_s": 100.0}},
            "identification_intervals": {"n_boot": 100, "confidence": 0.9}, "inflation": {"white": 1.0}}


def _rep(cons, worst, passed=True):
    ch = {"upper_envelope": {"worst_outage_ratio": worst, "mean_conservatism": cons, "passed": passed,
                             "worst_ratio": worst, "worst_t_s": 10.0, "tolerance": 1e-6,
                             "first_exceed_s": None if passed else 10.0},
          "spec": {"worst_outage_ratio": 0.5, "mean_conservatism": 3.0, "passed": True, "worst_ratio": 0.5,
                   "worst_t_s": 10.0, "tolerance": 1e-6, "first_exceed_s": None}}
    return {"exported": {"verification": {"checks": ch, "passed": all(c["passed"] for c in ch.values())},
                         "reduced": False}}


def select(cands, reps):
    from imupipe.stages.contract import candidate_contract

    return _select(cands, reps, candidate_contract)


def test_select_the_tightest_passing_candidate():
    cands = {m: _cand() for m in AUTO_MODES}
    reps = {"raw": _rep(3.0, 0.5), "smoothed": _rep(2.0, 0.7), "confidence": _rep(1.5, 1.2, passed=False),
            "pooled": _rep(1.8, 0.9)}
    sel = select(cands, reps)
    assert sel["winner"] == "pooled" and sel["bounded"]  # confidence is tighter but fails its envelope check
    rows = {r["mode"]: r for r in sel["candidates"]}
    assert not rows["confidence"]["bounded"] and rows["pooled"]["criterion_mean_conservatism"] == 1.8
    # the reason follows the winner's name (the summary prints "exported **pooled**: <reason>"), naming the others
    assert sel["reason"].startswith("bounded and the tightest passing") and "confidence" in sel["reason"]
    assert "pooled" not in sel["reason"].split("(")[0]
    # a candidate whose PSD margin fails is not bounded either, however tight
    cands["pooled"] = _cand(margin=0.9)
    assert select(cands, reps)["winner"] == "smoothed"


def test_the_reason_says_why_the_envelope_candidate_is_absent():
    # where the envelope candidate was not built, the reason (which the summary prints) ends with why; where it was
    # built, the reason is the selection's alone
    cands = {m: _cand() for m in AUTO_MODES}
    reps = {"raw": _rep(3.0, 0.5), "smoothed": _rep(2.0, 0.7), "confidence": _rep(1.5, 0.8), "pooled": _rep(1.8, 0.9)}
    from imupipe.stages.contract import candidate_contract

    base = _select(cands, reps, candidate_contract)["reason"]
    why = "not built: the data reject the selected model (adequacy: chi2/dof 3.34, p 3.9e-53), ..."
    assert _select(cands, reps, candidate_contract, why)["reason"] == f"{base}; the envelope candidate was {why}"
    built = {**cands, ENVELOPE_MODE: _cand()}
    reps_b = {**reps, ENVELOPE_MODE: _rep(1.2, 0.9)}
    assert _select(built, reps_b, candidate_contract, "built: ...")["reason"] == _select(
        built, reps_b, candidate_contract)["reason"]


def test_the_reason_says_when_the_winner_was_lifted_to_the_data():
    # an envelope candidate scaled where the records' lower confidence limit lay above it by chance (the bound's
    # details.data_lift) wins: the reason says so with the factor; an unlifted winner's reason does not mention it
    cands = {m: _cand() for m in AUTO_MODES}
    reps = {"raw": _rep(3.0, 0.5), "smoothed": _rep(2.0, 0.7), "confidence": _rep(1.5, 0.8), "pooled": _rep(1.8, 0.9)}
    plain = select({**cands, ENVELOPE_MODE: _cand()}, {**reps, ENVELOPE_MODE: _rep(1.1, 0.95)})
    assert plain["winner"] == ENVELOPE_MODE and "data_lift" not in plain["reason"]
    lifted = {**_cand(), "details": {"data_lift": {"variance_factor": 1.038, "frequency_hz": 0.465}}}
    sel = select({**cands, ENVELOPE_MODE: lifted}, {**reps, ENVELOPE_MODE: _rep(1.1, 0.95)})
    assert sel["winner"] == ENVELOPE_MODE and "scaled by 1.038" in sel["reason"] and "data_lift" in sel["reason"]
    row = {r["mode"]: r for r in sel["candidates"]}[ENVELOPE_MODE]
    assert row["data_lift"] == 1.038


def test_select_none_passing_exports_the_safest_marked():
    cands = {m: _cand(allan=False) for m in AUTO_MODES}
    reps = {"raw": _rep(3.0, 0.8), "smoothed": _rep(2.0, 0.7), "confidence": _rep(1.5, 1.2), "pooled": _rep(1.8, 0.9)}
    sel = select(cands, reps)
    assert sel["winner"] == "smoothed" and not sel["bounded"]
    assert "NOT BOUNDED" in sel["reason"]


def test_select_ties_go_to_the_earlier_mode():
    cands = {m: _cand() for m in AUTO_MODES}
    reps = {m: _rep(2.0, 0.5) for m in AUTO_MODES}
    assert select(cands, reps)["winner"] == "raw"


def test_noise_model_auto_end_to_end(half_spec_accel_case):
    from imupipe.api import noise_model
    truth, records, spec = half_spec_accel_case
    res = noise_model(records, 5.0, "accel", spec, mode="auto", n_boot=30, outage_s=1800.0,
                      truth=truth)
    sel = res.verification["auto_selection"]
    assert [r["mode"] for r in sel["candidates"]] == list(AUTO_MODES)
    assert set(res.records["bound"]["candidates"]) == set(AUTO_MODES)
    win = next(r for r in sel["candidates"] if r["mode"] == sel["winner"])
    passing = [r["criterion_mean_conservatism"] for r in sel["candidates"] if r["bounded"]]
    if passing:
        assert win["bounded"] and win["criterion_mean_conservatism"] == min(passing)
    # the contract, the KF file and the result's bound are the winner's
    assert res.contract["mode"] == f"auto ({sel['winner']})"
    assert res.contract["auto_selection"]["winner"] == sel["winner"]
    assert res.bound.mode == sel["winner"]
    # every candidate verified against the truth too (a check of each, simulated data)
    assert all("truth" in r["checks"] for r in sel["candidates"])


def test_init_writes_auto():
    from imupipe.init import Settings, config_text

    s = Settings(decimate_rate_hz=1.0, window_s=25200.0, step_s=12600.0, outage_s=3600.0, shortest_s=36000.0,
                 unused={"a": 0.0})
    import yaml

    doc = yaml.safe_load(config_text("my", "sheet.tsv", "specs", "stim300", ["gyro"], s))
    assert doc["bound"] == {"mode": "auto"}


def test_summary_shows_the_candidates():
    from imupipe.summary import auto_selection_lines

    cands = {m: _cand() for m in AUTO_MODES}
    reps = {"raw": _rep(3.0, 0.5), "smoothed": _rep(2.0, 0.7), "confidence": _rep(1.5, 1.2, passed=False),
            "pooled": _rep(1.8, 0.9)}
    text = "\n".join(auto_selection_lines({"auto_selection": select(cands, reps)}))
    assert "exported **pooled**" in text
    assert "| pooled (exported) | yes |" in text and "| confidence | NO | verification upper_envelope |" in text
    assert auto_selection_lines({}) == []


def test_the_candidate_table_keeps_the_sampled_replay_apart_from_the_exact_checks():
    # an outside evaluation read "worst MSE/P (any check) 1.1" beside "bounded yes": the replay's sampled ratio passes
    # up to its own limit 1 + tolerance, the exact checks only up to 1; the table gives each its column and limit
    from imupipe.summary import auto_selection_lines

    reps = {m: _rep(2.0, 0.7) for m in AUTO_MODES}
    for r in reps.values():
        r["exported"]["verification"]["checks"]["replay"] = {
            "worst_outage_ratio": 1.1, "mean_conservatism": 1.5, "passed": True, "worst_ratio": 1.1,
            "worst_t_s": 300.0, "tolerance": 0.15, "first_exceed_s": None, "method": "replay of static records"}
    sel = select({m: _cand() for m in AUTO_MODES}, reps)
    row = sel["candidates"][0]
    assert row["worst_outage_ratio_exact"] == 0.7  # upper_envelope 0.7, spec 0.5: not the replay's 1.1
    assert row["worst_outage_ratio_sampled"] == 1.1 and row["sampled_tolerance"] == 0.15
    text = "\n".join(auto_selection_lines({"auto_selection": sel}))
    assert "| worst MSE/P, outage (exact checks: <= 1) | replay MSE/P, outage (sampled: passes up to its limit) |" in text
    assert "| 2 | 0.7 | 1.1 (limit 1.15) |" in text


def test_table_shows_the_exported_candidate_not_the_first():
    # an auto run's bound file holds the raw candidate at its top level; the table (and the figures, through the
    # same exported_bound) must show the candidate the contract exports, labelled with its mode
    from imupipe.specsheet import load_spec
    from imupipe.stages.tables import exported_bound, tables_stage

    spec = load_spec(Path(__file__).resolve().parents[1] / "config" / "specs" / "stim300.yaml")
    n_spec = spec.models["gyro"].white

    def entry(mode, factor):
        return {"mode": mode, "margin": 1.0, "psd_bounded": True,
                "bound": {"white": factor * n_spec, "random_walk": 0.0, "gauss_markov": []}}

    bound = {**entry("auto", 7.0), "candidates": {"raw": entry("raw", 7.0), "pooled": entry("pooled", 2.0)}}
    contract = {"auto_selection": {"winner": "pooled"}}
    assert exported_bound(bound, contract)["mode"] == "auto (pooled)"
    assert exported_bound(entry("raw", 7.0), None)["mode"] == "raw"  # not auto: the bound file as it is
    md = tables_stage(spec, {"gyro": bound}, {"gyro": contract})["markdown"]
    assert "(auto (pooled) mode)" in md
    row = next(ln for ln in md.splitlines() if "| gyro |" in ln and "white" in ln.lower())
    assert row.rstrip(" |").endswith("2"), row  # bound/spec 2, the pooled candidate's, not the raw one's 7
    with pytest.raises(ValueError, match="needs the contract"):
        tables_stage(spec, {"gyro": bound})


def test_no_passing_candidate_names_the_export_with_three_digits():
    # an outside evaluation read "(... against the envelope, 0.8895657899110195)" in the auto reason
    cands = {m: _cand() for m in AUTO_MODES}
    reps = {m: _rep(2.0, 0.8895657899110195 + 0.01 * k, passed=False) for k, m in enumerate(AUTO_MODES)}
    sel = select(cands, reps)
    assert not sel["bounded"] and "against the envelope, 0.89), NOT BOUNDED" in sel["reason"]
