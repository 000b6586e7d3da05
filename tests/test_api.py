"""One-call API (imupipe.api.noise_model): the same result as the library calls the workflow's stages make, on
the files the workflow would have written (per-axis netCDF, per-sensor stacks, the identify and bound YAML read
back), so that the in-memory path and the file path agree. The comparison is with the library calls, not with
the workflow scripts' internals (their signatures change with the rules)."""

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
HORIZON = dict(horizon_s=600.0)  # the reference computation below uses a 600 s horizon; the API default is 3600 s


@pytest.fixture(scope="module")
def records():
    rng = np.random.default_rng(3)
    return {f"d{i}/{a}": simulate(TRUTH, int(DURATION_S * RATE), RATE, rng=rng) for i in (1, 2) for a in "xy"}


@pytest.fixture(scope="module")
def result(records):
    return noise_model(records, RATE, "gyro", SPEC, **SETTINGS, **HORIZON)


@pytest.fixture(scope="module")
def workflow(records, tmp_path_factory):
    """The workflow's per-axis files (allan, decimate + psd), per-sensor stacks (stack) and the library calls of
    the identify, bound and kf stages on them, for the same records and the same (default) settings; each
    stage's YAML is written and read back as the next stage reads it."""
    from imupipe.allan import allan_variance
    from imupipe.bound import bound_psd, upper_envelope
    from imupipe.identify import fit_allan, refit_selected, select_components
    from imupipe.io import write_yaml_atomic
    from imupipe.kf import export_kf
    from imupipe.merge import Stacked
    from imupipe.spectra import decimate, psd
    from imupipe.specsheet import load_spec
    from imupipe.verify import verification_report

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

    # identify: pooled fit, selection, selected refit (identify YAML: model, selection, model_selected)
    av = Stacked(tmp / "allan.nc")
    data = []
    for d, a in av.curves(included_only=True):
        avar, edf = av.at("avar", d, a), av.at("edf", d, a)
        ok = np.isfinite(avar) & np.isfinite(edf)
        data.append((av["tau"][ok], avar[ok], edf[ok], int(av.at("n_samples", d, a))))
    taus, avars, edfs = ([c[i] for c in data] for i in range(3))
    rate = float(av.attrs["rate_hz"])
    kw = dict(n_boot=0, confidence=0.95, rng=20211, dt=1.0 / rate, rate=rate, n_samples=[c[3] for c in data])
    fit = fit_allan(taus, avars, edfs, components=["white", "gauss_markov", "flicker", "random_walk",
                                                   "quantization", "ramp"], n_gm=1, **kw)
    selection = select_components(fit, taus, avars, edfs, rate_hz=1.0, horizon_s=600.0, significance=0.05,
                                  relevance=0.05)
    selected = refit_selected(fit, selection, taus, avars, edfs, **kw)
    write_yaml_atomic({"model": fit.model.to_dict(), "model_selected": selected.model.to_dict(),
                       "selection": {"kept": list(selection["kept"])}}, tmp / "identify.yaml")
    identify = read_yaml(tmp / "identify.yaml")

    # bound: all-frequency bound of the kept components with the selected refit's upper envelope
    sp = Stacked(tmp / "spectra.nc")
    f = sp["frequency"]
    psds = {f"{d}/{a}": sp.at("psd", d, a) for d, a in sp.curves(included_only=True)}
    edf = np.array([np.broadcast_to(sp.at("edf", d, a), f.shape) for d, a in sp.curves(included_only=True)])
    spec = load_spec(SPEC)
    upper = upper_envelope(selected, selection, horizon_s=600.0 + 600.0)
    result = bound_psd(f, psds, spec.models["gyro"], dt=1.0 / float(sp.attrs["rate_hz"]), mode="raw", n_gm=1,
                       confidence=0.95, bands_per_decade=10, edf=edf, keep=identify["selection"]["kept"],
                       taper=sp.attrs.get("taper", "hann"), horizon_s=600.0 + 600.0, upper_model=upper)
    write_yaml_atomic(result.to_dict(sensor="gyro"), tmp / "bound.yaml")
    bound = read_yaml(tmp / "bound.yaml")

    # kf and verification: the bound YAML's model
    # the verification first: the KF file's P0 of p is the verified one (imupipe.biasinit.filter_p0 of the
    # verification's least initial bias variance), the longest decimated record setting the slow-bias family
    from imupipe.biasinit import filter_p0

    m = NoiseModel.from_dict(bound["bound"])
    record_s = max(decimate(np.asarray(x), RATE, 1.0)[0].size for x in records.values()) / 1.0
    ver = verification_report(m, "gyro", spec=spec.models["gyro"], upper=upper, fix_s=600.0, horizon_s=600.0,
                              filter_rate_hz=1.0, record_s=record_s)
    bi = ver["exported"]["bias_initialisation"]
    p0 = filter_p0(m, bi["required_variance"], bi["wander_s"], bi["required_slow_variance"]) or None
    kf = export_kf(m, 1.0, sensor="gyro", p0_random_walk=p0, reduced=p0 is None)
    return {"identify": identify, "bound": bound, "kf": kf, "verification": ver}


def test_identification_equals_the_workflows(result, workflow):
    assert result.selection["kept"] == workflow["identify"]["selection"]["kept"]
    # same library calls on the same numbers; YAML writes floats by repr, so the round trip is exact
    assert result.fit.model.to_dict() == workflow["identify"]["model"]
    assert result.selected.model.to_dict() == workflow["identify"]["model_selected"]


def test_bound_and_kf_equal_the_workflows(result, workflow):
    wb = workflow["bound"]
    d = result.bound.to_dict(sensor="gyro")
    assert d["bounded"] == wb["bounded"]
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
            f"r = noise_model({{'a/x': x}}, 10.0, 'gyro', {str(SPEC)!r}, window_s=1200.0, step_s=600.0)")
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
    r = noise_model(curves, RATE, "gyro", SPEC, lines_policy="model", **SETTINGS, **HORIZON)
    assert len(r.lines.narrowband) == 1 and r.lines.narrowband[0][0] == pytest.approx(0.3, abs=1e-3)
    assert len(r.model.narrowband) == 1 and r.bounded
    assert "nb" in r.kf["states"]
    assert r.to_dict()["lines"]["policy"] == "model"
