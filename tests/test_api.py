"""One-call API (imupipe.api.noise_model): the same result as the stage functions the workflow's scripts call
(imupipe.stages), on the files the workflow would have written (per-axis netCDF, per-sensor stacks, the
identify, bound and verify YAML read back), so that the in-memory path and the file path agree. The workflow
itself against the API: tests/test_orchestration_parity.py."""

from pathlib import Path

import numpy as np
import pytest

from imupipe.api import noise_model
from imupipe.io import read_yaml
from imupipe.models import NoiseModel
from imupipe.simulate import simulate

ROOT = Path(__file__).resolve().parents[1]
SPEC = ROOT / "config" / "specs" / "stim300.yaml"
RATE = 10.0  # Hz
DURATION_S = 3600.0
TRUTH = NoiseModel(white=1.0e-4, gauss_markov=((2.0e-5, 300.0),), random_walk=5.0e-8)  # rad/s
SETTINGS = dict(window_s=1200.0, step_s=600.0)
BOOT = dict(n_boot=20)  # the reference computation below uses 20 replicates (the API default is 100)
HORIZON = dict(outage_s=600.0)  # the reference computation below uses a 600 s outage; the API default is 3600 s


@pytest.fixture(scope="module")
def records():
    rng = np.random.default_rng(3)
    return {f"d{i}/{a}": simulate(TRUTH, int(DURATION_S * RATE), RATE, rng=rng) for i in (1, 2) for a in "xy"}


@pytest.fixture(scope="module")
def result(records):
    return noise_model(records, RATE, "gyro", SPEC, **SETTINGS, **BOOT, **HORIZON)


@pytest.fixture(scope="module")
def workflow(records, tmp_path_factory):
    """The workflow's per-axis files (allan, decimate + psd), per-sensor stacks (stack) and the stage functions of
    the identify, bound, verify and kf rules on them (imupipe.stages), for the same records and the same
    (default) settings; each stage's YAML is written and read back as the next stage reads it."""
    from imupipe.allan import allan_variance
    from imupipe.io import write_yaml_atomic
    from imupipe.merge import Stacked
    from imupipe.spectra import decimate, psd
    from imupipe.specsheet import load_spec

    tmp = tmp_path_factory.mktemp("wf")
    av_paths, psd_paths, curves = [], [], []
    for label, x in records.items():
        d, a = label.split("/")
        labels = {"dataset": d, "sensor": "gyro", "axis": a}
        av = allan_variance(x, RATE, taus="octave", confidence=0.683, units="rad/s")
        av.attrs.update(labels)
        av.to_netcdf(tmp / f"av_{d}_{a}.nc")
        y, r = decimate(x, RATE, 1.0)
        sp = psd(y, r, taper="hann", detrend="constant", confidence=0.95, units="rad/s", **SETTINGS)
        sp.attrs.update(labels)
        sp.to_netcdf(tmp / f"psd_{d}_{a}.nc")
        av_paths.append(tmp / f"av_{d}_{a}.nc")
        psd_paths.append(tmp / f"psd_{d}_{a}.nc")
        curves.append({"dataset": d, "axis": a, "included": True})
    for paths, join, out in ((av_paths, "outer", tmp / "allan.nc"), (psd_paths, "exact", tmp / "spectra.nc")):
        st = Stacked.from_axis_files(paths, join=join)
        st.set_included({"curves": curves})
        st.attrs["sensor"] = "gyro"
        st.to_netcdf(out)

    # identify (imupipe.stages.identify, as workflow/scripts/identify.py calls it on the stacked Allan file)
    from imupipe.stages.bound import bound_stage
    from imupipe.stages.identify import curves_of, identification_stage
    from imupipe.stages.kf import exported_kf
    from imupipe.stages.verify import verify_stage

    ident = identification_stage(
        curves_of(Stacked(tmp / "allan.nc")), sensor="gyro",
        components=["white", "gauss_markov", "flicker", "random_walk", "quantization", "ramp"], n_gm=1, n_boot=20,
        confidence=0.95, significance=0.05, relevance=0.05, filter_rate_hz=1.0, outage_s=600.0,
        span_s=600.0 + 600.0)
    write_yaml_atomic(ident, tmp / "identify.yaml")
    identify = read_yaml(tmp / "identify.yaml")

    # bound (imupipe.stages.bound on the stacked spectra and Allan files, as workflow/scripts/bound.py)
    sp, al = Stacked(tmp / "spectra.nc"), Stacked(tmp / "allan.nc")
    inc = sp.curves(included_only=True)
    spec = load_spec(SPEC)
    bound_doc = bound_stage(
        sp["frequency"], {f"{d}/{a}": sp.at("psd", d, a) for d, a in inc},
        {f"{d}/{a}": sp.at("edf", d, a) for d, a in inc}, spec.models["gyro"], identify,
        dt=1.0 / float(sp.attrs["rate_hz"]), sensor="gyro", mode="raw", n_gm=1, confidence=0.95, bands_per_decade=10,
        span_s=600.0 + 600.0, filter_rate_hz=1.0, taper=sp.attrs.get("taper", "hann"),
        allan=(al["tau"], {f"{d}/{a}": (al.at("avar", d, a), al.at("edf", d, a)) for d, a in al.curves(True)}),
        spec_name=spec.name)
    write_yaml_atomic(bound_doc, tmp / "bound.yaml")
    bound = read_yaml(tmp / "bound.yaml")

    # verification of the bound file on the decimated records, then the KF matrices of the model it exports
    dec = {label: decimate(np.asarray(x), RATE, 1.0)[0] for label, x in records.items()}
    ver = verify_stage(bound, "gyro", spec=spec.models["gyro"], records=dec, record_rate_hz=1.0, fix_s=600.0,
                       outage_s=600.0, filter_rate_hz=1.0, sigma_fix=0.001745)  # config.yaml's sigma_fix_rad
    write_yaml_atomic(ver, tmp / "verify.yaml")
    ver = read_yaml(tmp / "verify.yaml")
    kf = exported_kf(ver["exported"], 1.0, "gyro")
    return {"identify": identify, "bound": bound, "kf": kf, "verification": ver}


def test_identification_equals_the_workflows(result, workflow):
    assert result.selection["kept"] == workflow["identify"]["selection"]["kept"]
    # same library calls on the same numbers; YAML writes floats by repr, so the round trip is exact
    assert result.fit.model.to_dict() == workflow["identify"]["model"]
    assert result.selected.model.to_dict() == workflow["identify"]["model_selected"]


def test_bound_and_kf_equal_the_workflows(result, workflow):
    wb = workflow["bound"]
    d = result.bound.to_dict(sensor="gyro")
    assert d["bounded"] == wb["psd_bounded"]  # the bound file names the PSD verdict psd_bounded
    np.testing.assert_allclose(d["margin"], wb["margin"], rtol=1e-12)
    assert d["bound"]["white"] == pytest.approx(wb["bound"]["white"], rel=1e-12)
    assert d["bound"]["random_walk"] == pytest.approx(wb["bound"]["random_walk"], rel=1e-12, abs=1e-300)
    assert [g["sigma"] for g in d["bound"]["gauss_markov"]] == pytest.approx(
        [g["sigma"] for g in wb["bound"]["gauss_markov"]], rel=1e-12)
    np.testing.assert_allclose(np.array(result.kf["Qd"], dtype=float), np.array(workflow["kf"]["Qd"], dtype=float),
                               rtol=1e-12, atol=0)
    np.testing.assert_allclose(np.array(result.kf["P0"], dtype=float), np.array(workflow["kf"]["P0"], dtype=float),
                               rtol=1e-12, atol=0)
    assert result.verification["passed"] == workflow["verification"]["passed"]
    checks, wchecks = result.verification["verification"]["checks"], workflow["verification"]["verification"]["checks"]
    assert set(checks) == set(wchecks) and checks
    for name in checks:  # same model, same scenario: the covariance analysis is deterministic
        assert checks[name]["worst_outage_ratio"] == pytest.approx(wchecks[name]["worst_outage_ratio"], rel=1e-12)


def test_default_fix_is_the_workflows(result):
    # sigma_fix left unset: the workflow's verify.sigma_fix_rad (config/config.yaml, imupipe.defaults.DEFAULTS)
    from imupipe.defaults import DEFAULTS

    assert result.verification["verification"]["scenario"]["sigma_fix"] == DEFAULTS["verify.sigma_fix_rad"]


def test_result_object(result, capfd):
    assert result.bounded is True and result.model is result.bound.model
    d = result.to_dict()
    assert set(d) >= {"bound", "identify", "kf", "curves", "rate_hz", "upper_envelope", "verification"}
    assert "model_selected" in d["identify"]
    assert d["curves"] == ["d1/x", "d1/y", "d2/x", "d2/y"]
    import yaml

    yaml.safe_dump(d)  # plain types only


def test_library_call_prints_nothing_on_stdout():
    # a fresh interpreter: a solver banner is printed once per process, at its first use
    import subprocess
    import sys

    code = ("import numpy as np; from imupipe.api import noise_model; from imupipe.models import NoiseModel; "
            "from imupipe.simulate import simulate; "
            "x = simulate(NoiseModel(white=1e-4), 20000, 10.0, rng=1); "
            f"r = noise_model({{'a/x': x}}, 10.0, 'gyro', {str(SPEC)!r}, window_s=1200.0, step_s=600.0, "
            "outage_s=600.0)")  # the verification replays fix_s + outage_s = 1200 s of the 2000 s record
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == ""


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="sensor"):
        noise_model({"a": np.zeros(10)}, RATE, "magnetometer", SPEC)
    with pytest.raises(ValueError, match=r"curves\['a'\]: expected a 1-D record"):
        noise_model({"a": np.zeros((2, 10))}, RATE, "gyro", SPEC)
    with pytest.raises(ValueError, match="shorter than window_s"):  # an explicit window (the default fits the record)
        noise_model({"a": np.random.default_rng(0).standard_normal(1000)}, RATE, "gyro", SPEC, window_s=25200.0)
    with pytest.raises(ValueError, match=r"curves\['b'\]: a record of .* too short for a PSD"):
        noise_model({"a": np.zeros(1000), "b": np.zeros(10)}, RATE, "gyro", SPEC)


def test_lines_policy_model_carries_the_line_to_the_filter():
    # a 0.3 Hz sinusoid (amplitude 3e-4 rad/s, inside the 1 Hz decimated band) on two records: the search
    # finds it, the policy models it, the bound carries it as a narrowband term and the KF gets its states
    rng = np.random.default_rng(3)
    t = np.arange(int(DURATION_S * RATE)) / RATE
    line = 3e-4 * np.sin(2 * np.pi * 0.3 * t)
    curves = {f"d{i}/x": simulate(TRUTH, t.size, RATE, rng=rng) + line for i in (1, 2)}
    r = noise_model(curves, RATE, "gyro", SPEC, lines_policy="model", **SETTINGS, **BOOT, **HORIZON)
    assert len(r.lines.narrowband) == 1 and r.lines.narrowband[0][0] == pytest.approx(0.3, abs=1e-3)
    assert len(r.model.narrowband) == 1 and r.bounded
    assert "nb" in r.kf["states"]
    assert r.to_dict()["lines"]["policy"] == "model"
    # the FLAG names the records and axis where the line is, as the workflow's summary does (it named the line
    # policy's own keys, "[decisions,narrowband]": an outside evaluation)
    (flag,) = [f for f in r.flags if f.startswith("FLAG lines")]
    where, _, detail = flag.removeprefix("FLAG lines [").partition("]: ")
    assert sorted(where.split("; ")) == ["d1/gyro/x", "d2/gyro/x"], flag
    assert detail.startswith("one line (one axis, 2 detections) at 0.3"), flag


def test_flags_say_what_the_summary_would_a_unit_slip_included():
    # gyro white noise in deg/s passed as rad/s: 57.3x the STIM-300 sheet's N; the PSD bound holds (the data are
    # what they are), so only the plausibility FLAG tells the user, and res.flags carries it as the summary words it
    rate, n = 10.0, 72_000  # 2 h at 10 Hz
    n_si = 0.15 * (np.pi / 180.0) / 60.0  # the sheet's 0.15 deg/sqrt(h) in rad/s/sqrt(Hz)
    rng = np.random.default_rng(20261204)
    curves = {f"d/{a}": 57.3 * n_si * np.sqrt(rate) * rng.standard_normal(n) for a in "xy"}
    res = noise_model(curves, record_rate_hz=rate, sensor="gyro", spec=SPEC, window_s=1800.0, step_s=900.0,
                      n_boot=20, verify=False)
    unit = [f for f in res.flags if f.startswith("FLAG data far above the spec sheet")]
    assert len(unit) == 1 and "check the unit" in unit[0], res.flags
    assert not [f for f in noise_model({k: v / 57.3 for k, v in curves.items()}, record_rate_hz=rate,
                                       sensor="gyro", spec=SPEC, window_s=1800.0, step_s=900.0, n_boot=20,
                                       verify=False).flags if "unit" in f]


def test_events_a_known_step_is_reported_in_flags_and_to_dict():
    # the workflow's outliers stage's event search (imupipe.stages.outliers), run by the library on each curve: a
    # mean step of delta = 1e-3 rad/s at t0 = 600.3 s on one of two white-noise axes (N = 1e-4 rad/s/sqrt(Hz), 10 Hz:
    # per-sample sd 3.2e-4 rad/s). At the scan's 1 s scale sigma_D = sqrt(2) N / sqrt(1 s) = 1.4e-4 rad/s, so the step
    # stands ~7 sigma_D clear of a threshold near 5 sigma_D, and the CUSUM places a step of 3 per-sample sds within
    # about sigma_1^2 / delta^2 ~ 0.1 sample: the time is asked within 1 s (the goal), the size inside its
    # interval. The clean axis (fixed seed) has no event: the false-alarm rate is 0.01 per axis.
    rate, n, t0, delta = 10.0, 12_000, 600.3, 1e-3
    rng = np.random.default_rng(20261205)
    x = 1.0e-4 * np.sqrt(rate) * rng.standard_normal((2, n))
    x[0, int(t0 * rate):] += delta
    curves = {"rec/x": x[0], "rec/y": x[1]}
    res = noise_model(curves, record_rate_hz=rate, sensor="gyro", spec=SPEC, window_s=300.0, step_s=150.0,
                      n_boot=20, components=("white",), pooling_n_boot=19, verify=False)
    steps = [e for e in res.events if e["kind"] == "step"]
    assert len(steps) == 1 and steps[0]["axis"] == "x" and steps[0]["dataset"] == "rec", res.events
    assert abs(steps[0]["time_s"] - t0) <= 1.0
    assert steps[0]["size_low"] <= delta <= steps[0]["size_high"]
    assert not [e for e in res.events if e["axis"] == "y"]
    flags = [f for f in res.flags if f.startswith("FLAG event [rec/gyro/x]")]
    assert len(flags) == 1 and "mean step" in flags[0] and "600.3 s from the record's start" in flags[0], res.flags
    d = res.to_dict()
    assert d["events"] == res.events and d["flags"] == res.flags
    import yaml

    yaml.safe_dump(d)  # plain types only
    with pytest.raises(ValueError, match="events: policy 'exclude'"):  # the API analyses the records as given
        noise_model(curves, record_rate_hz=rate, sensor="gyro", spec=SPEC, window_s=300.0, step_s=150.0,
                    events={"policy": "exclude"})
