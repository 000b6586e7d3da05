"""The ``envelope`` candidate of ``bound.mode: auto`` (docs/method.md "The auto bound", "The envelope candidate"):
``bound_psd(mode="envelope")`` is the tightest model above the identified upper envelope and the spec sheet at every
frequency (an envelope the components can represent exactly comes back as itself), the sample PSDs are not its
targets, and :func:`imupipe.bound.auto.candidate_modes` builds it only where its level is the joint band's."""

from __future__ import annotations

import numpy as np
import pytest

from imupipe.bound import bound_psd
from imupipe.bound.auto import AUTO_MODES, ENVELOPE_MODE, candidate_modes
from imupipe.models import NoiseModel
from imupipe.simulate import simulate
from imupipe.spectra import psd

RATE = 1.0
SPAN = 4200.0  # fix + outage, s


def _curves(truth, n_curves=2, hours=2.0, seed=11):
    X = np.asarray(simulate(truth, int(hours * 3600 * RATE), RATE, rng=np.random.default_rng(seed),
                            n_records=n_curves)).reshape(n_curves, -1)
    sp = [psd(x, RATE, window_s=3600.0, step_s=1800.0) for x in X]
    return sp[0]["frequency"].values, np.array([s["psd"].values for s in sp]), np.array([s["edf"].values for s in sp])


def _psd_ratio(a, b, f):
    return np.asarray(a.psd(f)) / np.asarray(b.psd(f))


def test_an_envelope_the_components_represent_comes_back_as_itself():
    # min mean(model / max(spec, E)) subject to model >= E: when E is a model of the bound's components with its T on
    # the trial grid, E itself is feasible with objective 1 and every other feasible model is above it at some
    # frequency, so the LP's optimum is E (to the LP's and the T refinement's tolerance, 1e-3 relative here)
    truth = NoiseModel(white=1e-3, gauss_markov=((5e-4, 100.0),), random_walk=1e-5)
    upper = NoiseModel(white=1.5e-3, gauss_markov=((8e-4, 100.0),), random_walk=2e-5)
    spec = NoiseModel(white=0.5e-3, gauss_markov=((2.5e-4, 100.0),), random_walk=0.5e-5)
    f, curves, edf = _curves(truth)
    res = bound_psd(f, curves, spec, dt=1.0 / RATE, mode="envelope", n_gm=1, edf=edf, span_s=SPAN,
                    upper_model=upper, keep=["white", "gauss_markov", "random_walk"], T_grid=[30.0, 100.0, 300.0])
    assert res.bounded and res.margin >= 1 - 1e-9 and res.margin_curve == "upper envelope"
    ff = np.geomspace(1e-5, 0.5, 400)
    r = _psd_ratio(res.model, upper, ff)
    assert r.min() >= 1 - 1e-3 and r.max() <= 1 + 1e-3, (r.min(), r.max())
    # and never below it, between the LP's grid points included (the dense check: 100 per decade, padded
    # exp(delta^2 / 4)), on a grid 7x finer than the dense one
    fd = np.geomspace(0.01 / SPAN, 0.5, 7 * 100 * 7 + 1)
    assert _psd_ratio(res.model, upper, fd).min() >= 1.0
    assert _psd_ratio(res.model, spec, fd).min() >= 1.0
    # the sample periodograms are not targets: with two 3 h records some ordinates exceed the truth's envelope
    # (the largest of 2 x 1800 ordinates, each an average of 3 Hann windows (edf about 5), is several times the mean)
    assert res.raw_margin < 1


def test_the_envelope_candidate_lies_below_the_per_curve_candidates():
    # the raw and smoothed bounds must also cover every sample PSD; the envelope candidate need not: against the same
    # envelope (the truth x 1.3, above which no estimate is required) it is at most as loose as they are
    truth = NoiseModel(white=1e-3, gauss_markov=((5e-4, 100.0),))
    upper = NoiseModel(white=1.3e-3, gauss_markov=((1.3 * 5e-4, 100.0),))
    f, curves, edf = _curves(truth, n_curves=2)
    kw = dict(dt=1.0 / RATE, n_gm=1, edf=edf, span_s=SPAN, upper_model=upper, keep=["white", "gauss_markov"])
    env = bound_psd(f, curves, None, mode="envelope", **kw)
    ff = np.geomspace(1.0 / SPAN, 0.5, 200)
    # up to the dense check's scale of the envelope candidate (engine._dominate_densely: at least exp(delta^2 / 4))
    pad = np.log(env.details["dense_check"]["variance_factor"])
    assert pad >= (np.log(10) / 100) ** 2 / 4 - 1e-12
    for m in ("raw", "smoothed"):
        other = bound_psd(f, curves, None, mode=m, **kw)
        assert np.mean(np.log(_psd_ratio(env.model, other.model, ff))) <= pad + 1e-9, m
    assert np.all(_psd_ratio(env.model, upper, ff) >= 1 - 1e-6)


def test_the_random_walk_does_not_stand_in_for_a_long_gm():
    # the envelope's stationary part (white + a GM of T = 3000 s, longer than the records' windows) must be covered
    # by the bound's white and GM terms at every frequency down to the all-frequency floor 0.01 / span, and its
    # random walk carried beside (K_B = max(K_E, K_spec)): a random walk from 0 carries none of the GM's variance at
    # t = 0, so covering the GM's low-frequency plateau with it would not bound a filter's error (engine docstring)
    truth = NoiseModel(white=1e-3, gauss_markov=((3e-4, 3000.0),), random_walk=1e-6)
    upper = NoiseModel(white=1.3e-3, gauss_markov=((4e-4, 3000.0),), random_walk=2e-6)
    spec = NoiseModel(white=0.5e-3, random_walk=0.5e-6)
    f, curves, edf = _curves(truth)
    res = bound_psd(f, curves, spec, dt=1.0 / RATE, mode="envelope", n_gm=1, edf=edf, span_s=SPAN,
                    upper_model=upper, keep=["white", "gauss_markov", "random_walk"])
    stat = NoiseModel(white=res.model.white, gauss_markov=res.model.gauss_markov)
    fd = np.geomspace(0.01 / SPAN, 500.0, 2001)
    e_stat = NoiseModel(white=upper.white, gauss_markov=upper.gauss_markov)
    assert _psd_ratio(stat, e_stat, fd).min() >= 1.0
    assert res.model.random_walk == pytest.approx(upper.random_walk, rel=1e-12)
    assert res.details["random_walk"] == upper.random_walk


def test_a_sheet_under_the_envelope_s_random_walk_needs_no_stationary_term_of_its_own():
    # a sheet's long GM (3e-4 at 2000 s) that lies under the envelope's random walk wherever it is above the envelope's
    # white noise: S_spec <= E_stat + K_B^2 / (2 pi f)^2 at every frequency, so B >= S_spec follows from B_stat >= E_stat
    # and K_B (engine._spec_covered); the bound's stationary part then carries no GM for the sheet, and B still lies
    # above the sheet's PSD at every frequency of a dense grid (checked here from 1e-9 Hz up)
    truth = NoiseModel(white=1e-3, random_walk=1e-5)
    upper = NoiseModel(white=1.3e-3, random_walk=2e-5)
    spec = NoiseModel(white=0.5e-3, gauss_markov=((3e-4, 2000.0),))
    f, curves, edf = _curves(truth)
    res = bound_psd(f, curves, spec, dt=1.0 / RATE, mode="envelope", n_gm=1, edf=edf, span_s=SPAN,
                    upper_model=upper, keep=["white", "random_walk"])
    assert res.details["spec_covered"]["covered"]
    fd = np.geomspace(1e-9, 500.0, 11 * 100 * 7 + 1)
    assert _psd_ratio(res.model, spec, fd).min() >= 1.0
    assert _psd_ratio(res.model, upper, fd).min() >= 1.0
    stat = NoiseModel(white=res.model.white, gauss_markov=res.model.gauss_markov)
    spec_gm = NoiseModel(gauss_markov=spec.gauss_markov)
    assert stat.psd(np.array([1.0 / SPAN]))[0] < 0.1 * spec_gm.psd(np.array([1.0 / SPAN]))[0]
    # a sheet whose random walk is the larger one is not covered by K_B's: its GM rows stay in the LP
    spec_rw = NoiseModel(white=0.5e-3, gauss_markov=((3e-4, 2000.0),), random_walk=3e-5)
    res2 = bound_psd(f, curves, spec_rw, dt=1.0 / RATE, mode="envelope", n_gm=1, edf=edf, span_s=SPAN,
                     upper_model=upper, keep=["white", "random_walk"])
    assert not res2.details["spec_covered"]["covered"]
    # (the bound's claim from the all-frequency floor 0.01 / span up, module docstring of imupipe.bound.engine)
    assert _psd_ratio(res2.model, spec_rw, np.geomspace(0.01 / SPAN, 500.0, 7001)).min() >= 1.0


def test_envelope_mode_needs_the_envelope():
    f, curves, edf = _curves(NoiseModel(white=1.0), n_curves=1, hours=1.5)
    with pytest.raises(ValueError, match="upper envelope"):
        bound_psd(f, curves, None, dt=1.0, mode="envelope", edf=edf)


def _identified(kind="joint", note=None, consistent=True, adequate=True, axes=None):
    """An identify record as candidate_modes reads it; `axes` {axis: (band note or None, adequate)}: the per-axis
    entries of a record whose pooling test rejects one model (each band at 0.95)."""
    rec = {"band_hz": [1 / SPAN, 0.5], "confidence": 0.95, "worst_ratio_to_band": 1.05}
    if note:
        rec = {"band_hz": [1 / SPAN, 0.5], "confidence": 0.95, "note": note}
    out = {"pooling": {"consistent": consistent},
           "adequacy": {"pooled": {"adequate": adequate, "chi2_per_dof": 1.0 if adequate else 3.34,
                                   "p_value": 0.5 if adequate else 3.9e-53}}}
    if kind != "marginal":
        out |= {"upper_envelope_kind": kind, "upper_envelope_joint": rec}
    if axes is not None:
        level = 0.95
        out["per_axis"] = {
            ax: {"adequacy": {"adequate": ok, "chi2_per_dof": 1.0 if ok else 9.0, "p_value": 0.5 if ok else 1e-9},
                 **({"upper_envelope_joint": {"band_hz": [1 / SPAN, 0.5], "confidence": level,
                                              **({"note": bn} if bn else {"worst_ratio_to_band": 1.1})}}
                    if kind != "marginal" else {})}
            for ax, (bn, ok) in axes.items()}
    return out


def test_candidate_modes_build_the_envelope_candidate_only_at_the_joint_level():
    modes, why = candidate_modes(_identified())
    assert modes == AUTO_MODES + (ENVELOPE_MODE,) and why.startswith("built")
    no_line = {"d0/x": {"lines": []}}
    assert candidate_modes(_identified(), no_line)[0][-1] == ENVELOPE_MODE
    for ident, lines, word in ((_identified("marginal"), None, "marginal"),
                               (_identified(note="fewer than 20 finite bootstrap replicates"), None, "fell back"),
                               (_identified(consistent=False), None, "no per-axis fits"),
                               # not pooled: every axis's band and fit must hold, as the pooled ones must
                               (_identified(consistent=False, axes={"x": (None, True), "y": ("fewer than 20", True)}),
                                None, "(axis y) fell back"),
                               (_identified(consistent=False, axes={"x": (None, True), "y": (None, False)}),
                                None, "reject the model of axis y"),
                               # records that differ are not what per-axis envelopes answer
                               (_identified(consistent=False, axes={"x": (None, True)})
                                | {"record_consistency": {"flagged": [{"dataset": "d3", "param": "white"}]}},
                                None, "names d3 (white)"),
                               (_identified(), {"d0/x": {"lines": [{"frequency_hz": 0.1}]}}, "line"),
                               # one line on two axes of two records: one line, four detections (an outside
                               # evaluation read "6 spectral line(s)" beside FLAGs naming two)
                               (_identified(), {f"d{d}/{a}": {"lines": [{"frequency_hz": 0.05, "f_lo_hz": 0.04,
                                                                          "f_hi_hz": 0.06}]}
                                                for d in (0, 1) for a in "xy"},
                                "1 spectral line(s) (4 detections over axes and records)"),
                               # the band is the spread of the selected model's refits: not where the data reject it
                               (_identified(adequate=False), None, "reject the selected model")):
        modes, why = candidate_modes(ident, lines)
        assert modes == AUTO_MODES and why.startswith("not built") and word in why, why


def test_curves_that_are_not_pooled_build_the_envelope_candidate_on_every_axis_band():
    # a pooling false alarm (its 1 % by design) removed the envelope candidate of five records of one truth; with
    # every axis's own band and fit in order, the candidate is built on their envelope, its level stated as the
    # Bonferroni bound over the axes
    ident = _identified(consistent=False, adequate=False, axes={"x": (None, True), "y": (None, True),
                                                                 "z": (None, True)})
    modes, why = candidate_modes(ident)
    assert modes == AUTO_MODES + (ENVELOPE_MODE,), why
    assert "level 0.95 per axis over 3 axes: together at least 0.85 (Bonferroni)" in why, why


def test_pooled_curves_build_the_envelope_candidate_only_on_every_axis_band():
    # accepting one model does not show the axes equal (an outside evaluation's gyro z drifting 20 % more than x and
    # y passed the pooling test, and the candidate on the pooled band under-stated z's error): with more than one
    # axis the candidate needs each axis's own band and fit, as where the test rejects
    three = {"curves": ["d0/x", "d0/y", "d0/z"]}
    modes, why = candidate_modes(_identified() | three)
    assert modes == AUTO_MODES and "no envelope of each of its 3 axes" in why, why
    axes = _identified(axes={"x": (None, True), "y": (None, True), "z": (None, True)})["per_axis"]
    modes, why = candidate_modes(_identified() | three | {"axis_envelopes": axes})
    assert modes == AUTO_MODES + (ENVELOPE_MODE,), why
    assert "accepts one model, which does not show the axes equal" in why and "together at least 0.85" in why, why
    for bad, word in ((("fewer than 20", True), "(axis z) fell back"), ((None, False), "reject the model of axis z")):
        ax = _identified(axes={"x": (None, True), "y": (None, True), "z": bad})["per_axis"]
        modes, why = candidate_modes(_identified() | three | {"axis_envelopes": ax})
        assert modes == AUTO_MODES and word in why, why
    # one axis: the pooled band is that axis's own
    assert candidate_modes(_identified() | {"curves": ["d0/x", "d1/x"]})[0][-1] == ENVELOPE_MODE


@pytest.mark.slow
def test_noise_model_auto_builds_verifies_and_may_export_the_envelope_candidate(half_spec_accel_case):
    # the one-call pipeline with the joint envelope: the envelope candidate is built, verified like the others (the
    # truth check included) and the exported model is the tightest passing one; against the truth it is bounded
    from imupipe.api import noise_model
    truth, records, spec = half_spec_accel_case
    res = noise_model(records, 5.0, "accel", spec, mode="auto", n_boot=30, outage_s=1800.0,
                      truth=truth, envelope="joint")
    bound = res.records["bound"]
    assert bound["auto_envelope_candidate"].startswith("built"), bound["auto_envelope_candidate"]
    sel = res.verification["auto_selection"]
    rows = {r["mode"]: r for r in sel["candidates"]}
    assert list(rows) == list(AUTO_MODES) + [ENVELOPE_MODE]
    assert "truth" in rows[ENVELOPE_MODE]["checks"]
    assert bound["candidates"][ENVELOPE_MODE]["margin_curve"] == "upper envelope"
    passing = [r["criterion_mean_conservatism"] for r in rows.values() if r["bounded"]]
    assert passing and rows[sel["winner"]]["criterion_mean_conservatism"] == min(passing)
    assert res.bounded and rows[sel["winner"]]["checks"]["truth"]["worst_outage_ratio"] <= 1.0


def test_the_auto_reason_says_why_the_envelope_candidate_is_absent(monkeypatch):
    # the summary prints the selection's reason: where the envelope candidate was not built, the reason says why
    # (the bound file's auto_envelope_candidate, passed by the verification stage to the selection)
    import imupipe.bound.auto as auto
    from imupipe.stages import verify

    seen = []
    monkeypatch.setattr(verify, "verify_sensor", lambda cand, sensor, **kw: ({"exported": {}}, None))
    monkeypatch.setattr(auto, "select", lambda c, r, f, note=None: seen.append(note) or {
        "winner": "raw", "reason": "raw: the tightest", "candidates": []})
    why = "not built: the data reject the selected model (adequacy: chi2/dof 3.34, p 3.9e-53), ..."
    verify._verify_auto({"candidates": {"raw": {}}, "auto_envelope_candidate": why}, "gyro", {})
    assert seen == [why]


def test_pooled_identification_holds_its_envelope_above_every_axis_band():
    # three axes, two 1.5 h records each, z's random walk 1.25x x and y's: the pooling test accepts one model (p 0.5
    # on this seed), and the pooled joint envelope's random walk lies below z's (the under-statement an outside
    # evaluation found, MSE/P 1.07 on a gyro z 20 % above x and y). Each axis's own band is at level c whatever the
    # others do: the envelope the bound reads dominates them all, and so holds z's random walk here
    from imupipe.allan import allan_variance
    from imupipe.stages.identify import Curve, identify_sensor

    rate, n, rng = 10.0, int(1.5 * 3600 * 10.0), np.random.default_rng(3)
    truths = {a: NoiseModel(white=1e-3, random_walk=1e-5 * (1.25 if a == "z" else 1.0)) for a in "xyz"}
    curves = []
    for d in range(2):
        for a in "xyz":
            av = allan_variance(simulate(truths[a], n, rate, rng), rate, taus="octave")
            ok = np.isfinite(av.avar.values) & np.isfinite(av.edf.values)
            curves.append(Curve(f"d{d}/{a}", av.tau.values[ok], av.avar.values[ok], av.edf.values[ok], n, rate, a))
    kw = dict(sensor="gyro", components=["white", "random_walk"], n_gm=1, n_boot=40, confidence=0.95,
              significance=0.05, relevance=0.05, filter_rate_hz=1.0, outage_s=1200.0, span_s=1800.0,
              pooling_n_boot=19)
    rec = identify_sensor(curves, envelope_kind="joint", **kw).record
    assert rec["pooling"]["consistent"], rec["pooling"]["note"]  # the case: accepted
    assert rec["upper_envelope_model"]["random_walk"] < truths["z"].random_walk  # the pooled band misses z
    env = NoiseModel.from_dict(rec["upper_envelope_model_axes"])  # the envelope candidate's target
    assert env.random_walk >= truths["z"].random_walk
    f = np.logspace(-4, np.log10(rate / 2), 200)
    for ax, entry in rec["axis_envelopes"].items():
        band = entry["upper_envelope_joint"]
        assert band["confidence"] == 0.95 and not band.get("note"), (ax, band)
        own = NoiseModel.from_dict(entry["upper_envelope_model"])
        assert np.all(_psd_ratio(env, own, f) >= 1 - 1e-12), ax
    modes, why = candidate_modes(rec)
    assert modes[-1] == ENVELOPE_MODE and "accepts one model" in why, why
    # the envelope candidate lies above that target; the file's upper_envelope (the verification's reference and
    # the other candidates' below the lowest PSD bin) stays the pooled one
    from imupipe.stages.bound import bound_sensor
    from imupipe.spectra import psd
    spectra = {c.label: psd(simulate(truths[c.axis], 7200, 1.0, np.random.default_rng(i)), 1.0, window_s=1800.0,
                            step_s=900.0) for i, c in enumerate(curves)}
    f = next(iter(spectra.values()))["frequency"].values
    cand = bound_sensor(f, {k: v["psd"].values for k, v in spectra.items()},
                        {k: v["edf"].values for k, v in spectra.items()}, NoiseModel(white=5e-4, random_walk=5e-6),
                        rec, dt=1.0, sensor="gyro", mode="envelope", n_gm=1, confidence=0.95, bands_per_decade=10,
                        span_s=1800.0).record
    assert cand["envelope_target"] == rec["upper_envelope_model_axes"]
    assert cand["upper_envelope"] == rec["upper_envelope_model"]
    assert NoiseModel.from_dict(cand["bound"]).random_walk >= truths["z"].random_walk
    # every other mode too lies above that target below the lowest PSD bin (an outside evaluation: a smoothed
    # candidate on the pooled envelope under-stated an axis whose random walk was 4x the others', pooling p 1.0),
    # and the verification reads each axis's own envelope (axis_upper_envelopes)
    raw = bound_sensor(f, {k: v["psd"].values for k, v in spectra.items()},
                       {k: v["edf"].values for k, v in spectra.items()}, NoiseModel(white=5e-4, random_walk=5e-6),
                       rec, dt=1.0, sensor="gyro", mode="smoothed", n_gm=1, confidence=0.95, bands_per_decade=10,
                       span_s=1800.0).record
    assert raw["envelope_target"] == rec["upper_envelope_model_axes"]
    assert raw["axis_upper_envelopes"] == {ax: e["upper_envelope_model"] for ax, e in rec["axis_envelopes"].items()}
    assert NoiseModel.from_dict(raw["bound"]).random_walk >= truths["z"].random_walk
    # the marginal envelope (the paper's) is unchanged: no per-axis identification where the curves are pooled
    assert "axis_envelopes" not in identify_sensor(curves, **kw).record
