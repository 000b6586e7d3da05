"""The library pieces the workflow's integrity stages call: the upper envelope rebuilt from an identify file,
the line policy of lines files, and the verification stage (verification, reduction by integrity, the model to
export)."""

import math

import pytest

from imupipe.bound import upper_envelope_from_identification
from imupipe.models import NoiseModel
from imupipe.lines import line_policy_from_files
from imupipe.verify import verification_stage


def test_upper_envelope_from_an_identify_file_closed_form():
    # kept white and GM at their upper limits; the GM box sigma <= s_up, T in [T_lo, T_hi] dominated by the single
    # GM T_m = sqrt(T_lo T_hi), sigma_m = s_up (T_hi/T_lo)^(1/4); the random walk at its profile limit although
    # model selection dropped it (method: "Bound over all frequencies")
    ident = {"fit": {"params": {"white": 1e-3, "gm_sigma_1": 2e-4, "gm_T_1": 100.0, "random_walk": 0.0,
                                "flicker": None},
                     "intervals": {"white": [0.9e-3, 1.2e-3], "gm_sigma_1": [1e-4, 3e-4], "gm_T_1": [50.0, 200.0],
                                   "random_walk": [0.0, None]},
                     "random_walk_profile": {"upper": 1e-6, "threshold": 2.7}},
             "selection": {"kept": ["white", "gauss_markov"]}}
    m = upper_envelope_from_identification(ident)
    assert m.white == pytest.approx(1.2e-3, rel=1e-15)
    ((s, T),) = m.gauss_markov
    assert T == pytest.approx(100.0, rel=1e-15) and s == pytest.approx(3e-4 * 4.0**0.25, rel=1e-15)
    assert m.random_walk == pytest.approx(1e-6, rel=1e-15)
    # a written envelope is used as it is
    given = NoiseModel(white=2e-3, random_walk=3e-6)
    assert upper_envelope_from_identification({**ident, "upper_envelope_model": given.to_dict()}).white == 2e-3
    with pytest.raises(ValueError, match="upper_envelope_model"):
        upper_envelope_from_identification({"selection": {"kept": []}})


def test_line_policy_from_files_names_a_bad_file():
    assert line_policy_from_files({}, 1.0) is None
    with pytest.raises(ValueError, match="x.yaml"):
        line_policy_from_files({"x.yaml": {"nothing": 1}}, 1.0)
    with pytest.raises(ValueError, match="y.yaml"):
        line_policy_from_files({"y.yaml": {"lines": [{"not_a_field": 1.0}]}}, 1.0)


# a short reference filter (fixes 100 s, outage 600 s at 1 Hz) keeps these analyses fast
SHORT = dict(fix_s=100.0, outage_s=600.0, filter_rate_hz=1.0)
TRUTH = NoiseModel(white=2e-3, gauss_markov=((5e-4, 200.0),), random_walk=2e-5)


def test_matched_model_passes_and_an_unflated_one_fails():
    rep, series = verification_stage(TRUTH, "accel", upper=TRUTH, spec=TRUTH, reduce=False, **SHORT)
    # exact analysis of a filter matched to its truth: MSE/P = 1 to the recursions' rounding (1e-6 allowed)
    assert rep["passed"] and rep["exported"]["reduced"] is False
    assert set(series) == {"upper_envelope", "spec"}
    assert all(abs(v.worst_ratio - 1.0) < 1e-6 for v in series.values())
    # white noise at half its true value: the filter under-states its error, the stage says so
    low = NoiseModel(white=1e-3, gauss_markov=TRUTH.gauss_markov, random_walk=TRUTH.random_walk)
    rep, _ = verification_stage(low, "accel", upper=TRUTH, reduce=False, **SHORT)
    assert rep["passed"] is False and rep["verification"]["checks"]["upper_envelope"]["worst_ratio"] > 1.0


def test_reduction_exported_only_when_verified():
    # a bound with a GM term far below the truth's white noise over the horizon: dropping it is verified
    # (the remaining white noise and random walk dominate it), dropping the random walk is not
    bound = NoiseModel(white=3e-3, gauss_markov=((1e-6, 50.0),), random_walk=3e-5)
    rep, _ = verification_stage(bound, "accel", upper=TRUTH, spec=TRUTH, reduce=True, **SHORT)
    red = rep["reduction"]
    assert {t["drop"] for t in red["tried"]} == set(red["accepted"]) | set(red["refused"])
    assert "random_walk" in red["refused"]
    assert any(a.startswith("gauss_markov") for a in red["accepted"])
    assert rep["exported"]["reduced"] is True and rep["exported"]["verification"]["passed"]
    assert rep["exported"]["model"]["gauss_markov"] == [] and math.isclose(rep["exported"]["model"]["white"], 3e-3)


def test_the_fix_rate_reaches_the_scenario_and_the_filter():
    """verify.fix_rate_hz: a filter at 10 Hz with fixes at 1 Hz. The spec sheet as its own filter is matched
    (MSE = P at every step: worst ratio 1 within round-off), the scenario says the fix rate, and the filter's
    variance differs from the one with a fix every step (the fix rate is used, not only reported)."""
    m = NoiseModel(white=1e-4, gauss_markov=((3e-4, 300.0),))
    kw = dict(spec=m, fix_s=100.0, outage_s=300.0, filter_rate_hz=10.0, reduce=False)
    rep, series = verification_stage(m, "accel", fix_rate_hz=1.0, **kw)
    every, series_every = verification_stage(m, "accel", **kw)
    assert rep["verification"]["scenario"]["fix_rate_hz"] == 1.0
    assert every["verification"]["scenario"]["fix_rate_hz"] == 10.0
    assert rep["verification"]["checks"]["spec"]["passed"]
    assert abs(rep["verification"]["checks"]["spec"]["worst_ratio"] - 1.0) < 1e-9
    n_fix = int(100.0 * 10.0)
    assert series["spec"].P[n_fix - 1] > 1.5 * series_every["spec"].P[n_fix - 1]  # fewer fixes: larger variance
    with pytest.raises(ValueError, match="fix_rate_hz"):
        verification_stage(m, "accel", fix_rate_hz=3.0, **kw)


def test_the_contract_needs_the_identifications_bootstrap():
    """identification_intervals: fewer than ceil(1/(1 - c)) replicates (0: no bootstrap) fail the contract, which
    is then not bounded even when every other check passed; 20 at c = 0.95 pass."""
    from types import SimpleNamespace

    from imupipe.verify import integrity_contract, min_bootstrap

    assert min_bootstrap(0.95) == 20 and min_bootstrap(0.9) == 10 and min_bootstrap(0.99) == 100
    ok = SimpleNamespace(margin=1.0, margin_curve="a/x", margin_frequency=0.1, spec_margin=1.0,
                         spec_margin_frequency=0.1, allf_margin=1.0, allf_margin_frequency=0.1)
    ver = {"f": {"checks": {"spec": {"passed": True}}}}
    for n_boot, bounded in ((0, False), (19, False), (20, True)):
        c = integrity_contract(ok, None, ver, intervals={"n_boot": n_boot, "confidence": 0.95})
        assert c["bounded"] is bounded and "identification_intervals" in c["checks_run"]
        assert bounded or c["failed_checks"][0]["check"] == "identification_intervals"


def test_earlier_keyword_names_are_refused_naming_the_new_one():
    """One meaning per name (outage_s, filter_rate_hz, record_rate_hz): the earlier horizon_s and rate_hz are refused
    with the name to use; a misspelt keyword is refused as unexpected; the YAML field keeps its name."""
    from imupipe.stages.verify import verify_sensor
    from imupipe.verify import reference_scenario, verify_model

    with pytest.raises(TypeError, match="'horizon_s' is now 'outage_s'"):
        reference_scenario("gyro", horizon_s=50.0)
    with pytest.raises(TypeError, match="'rate_hz' is now 'filter_rate_hz'"):
        reference_scenario("gyro", rate_hz=10.0)
    with pytest.raises(TypeError, match="'horizon_s' is now 'outage_s'"):
        verification_stage(TRUTH, "accel", spec=TRUTH, fix_s=100.0, horizon_s=600.0, reduce=False)
    with pytest.raises(TypeError, match="'rate_hz' is now 'record_rate_hz'"):
        verify_model(TRUTH, "accel", spec=TRUTH, rate_hz=1.0)
    with pytest.raises(TypeError, match="'rate_hz' is now 'record_rate_hz'"):
        verify_sensor({}, "accel", spec=TRUTH, rate_hz=1.0)
    a = verification_stage(TRUTH, "accel", spec=TRUTH, fix_s=100.0, outage_s=600.0, reduce=False)[0]
    assert a["verification"]["scenario"]["horizon_s"] == 600.0  # the YAML field keeps its name
    with pytest.raises(TypeError, match="unexpected keywords"):
        verification_stage(TRUTH, "accel", spec=TRUTH, horizont_s=600.0)


def test_a_global_model_is_checked_against_each_axis_envelope():
    """When the axes differ the global model is given to any axis, so it must bound each axis's own envelope too.
    A global model matched to the global envelope (MSE/P = 1 to round-off there) but with half the random walk of
    axis z's envelope under-states axis z's error over the outage: the stage names that axis's check and fails;
    axis x's envelope, equal to the global one, passes."""
    z_env = NoiseModel(white=TRUTH.white, gauss_markov=TRUTH.gauss_markov, random_walk=2.0 * TRUTH.random_walk)
    rep, series = verification_stage(TRUTH, "accel", upper=TRUTH, spec=TRUTH, reduce=False,
                                     axis_uppers={"x": TRUTH, "z": z_env}, **SHORT)
    checks = rep["verification"]["checks"]
    assert {"upper_envelope", "spec", "upper_envelope_x", "upper_envelope_z"} <= set(series)
    assert checks["upper_envelope"]["passed"] and checks["upper_envelope_x"]["passed"]
    # the random walk's share of the drift quadruples on axis z: its MSE outgrows P late in the outage
    assert not checks["upper_envelope_z"]["passed"] and checks["upper_envelope_z"]["worst_outage_ratio"] > 1.0
    assert rep["passed"] is False
    # with records (300 s) axis z's envelope admits a slower, larger bias: the global model's initial bias variance
    # rises to what that envelope asks (here 4x the random walk's share: K_eff^2 T_max / 2 with K doubled), and the
    # worst such bias of axis z is a truth of its own
    def init(**kw):
        rep, _ = verification_stage(TRUTH, "accel", upper=TRUTH, spec=TRUTH, reduce=False, record_s=300.0, **kw,
                                    **SHORT)
        return rep

    alone, with_z = init(), init(axis_uppers={"z": z_env})
    req = [r["exported"]["bias_initialisation"]["required_slow_variance"] for r in (alone, with_z)]
    assert req[1] == pytest.approx(4.0 * req[0], rel=1e-12)
    assert "slow_bias_z" in with_z["verification"]["checks"] and "truth_model" in \
        with_z["verification"]["checks"]["slow_bias_z"]
    # the reduction is judged on every axis's envelope too: dropping the random walk costs more on axis z
    loose = NoiseModel(white=3e-3, gauss_markov=TRUTH.gauss_markov, random_walk=5e-5)

    def drop_rw(**kw):
        rep, _ = verification_stage(loose, "accel", upper=TRUTH, spec=TRUTH, reduce=True, **kw, **SHORT)
        return next(t["worst_ratio"] for t in rep["reduction"]["tried"] if t["drop"] == "random_walk")

    assert drop_rw(axis_uppers={"z": z_env}) > 2.0 * drop_rw()


def test_pooled_axes_with_their_own_bands_are_each_checked():
    """Where the pooling test accepts one model while each axis has its own joint band, the bound file carries
    ``axis_upper_envelopes`` and the verification checks the global model against each, as where the axes differ: a
    model on the pooled envelope with half the random walk of axis y's own fails upper_envelope_y (an outside
    evaluation: y's random walk 4x x and z's, pooling p 1.0, MSE/P 1.42 under a model checked on the pooled one)."""
    from imupipe.stages.verify import verify_sensor

    y_env = NoiseModel(white=TRUTH.white, gauss_markov=TRUTH.gauss_markov, random_walk=2.0 * TRUTH.random_walk)
    bound = {"bound": TRUTH.to_dict(), "upper_envelope": TRUTH.to_dict(), "spec_name": "s", "psd_bounded": True,
             "per_axis_models": None, "axis_upper_envelopes": {"x": TRUTH.to_dict(), "y": y_env.to_dict()}}
    rep, _ = verify_sensor(bound, "accel", spec=TRUTH, reduce=False, **SHORT)
    checks = rep["verification"]["checks"]
    assert checks["upper_envelope_x"]["passed"] and not checks["upper_envelope_y"]["passed"]
    assert rep["passed"] is False
    rep, _ = verify_sensor({**bound, "axis_upper_envelopes": None}, "accel", spec=TRUTH, reduce=False, **SHORT)
    assert "upper_envelope_y" not in rep["verification"]["checks"]
