"""One-call API (imupipe.api.noise_model): the same result as the workflow's identify and bound scripts run on
the same records (their `main` functions, on the per-sensor files the workflow would have written)."""

import importlib.util
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


def _script(name):
    spec = importlib.util.spec_from_file_location(f"wf_{name}", ROOT / "workflow" / "scripts" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def records():
    rng = np.random.default_rng(3)
    return {f"d{i}/{a}": simulate(TRUTH, int(DURATION_S * RATE), RATE, rng=rng) for i in (1, 2) for a in "xy"}


@pytest.fixture(scope="module")
def result(records):
    return noise_model(records, RATE, "gyro", SPEC, **SETTINGS)


@pytest.fixture(scope="module")
def workflow(records, tmp_path_factory):
    """The workflow's per-axis files (reduce), per-sensor stacks (collect) and the identify and bound
    scripts' outputs for the same records and the same (default) settings."""
    from imupipe.allan import allan_variance
    from imupipe.merge import Stacked
    from imupipe.spectra import decimate, psd

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
    _script("identify").main(
        path_allan=str(tmp / "allan.nc"), components=["white", "gauss_markov", "flicker", "random_walk",
                                                       "quantization", "ramp"],
        n_gm=1, n_boot=0, confidence=0.95, significance=0.05, relevance=0.05, rate_hz=1.0, horizon_s=600.0,
        truth=None, path_out=str(tmp / "identify.yaml"), sensor="gyro")
    axis_out = [str(tmp / "axes" / d / "gyro" / f"{a}.yaml") for d, a in (k.split("/") for k in records)]
    _script("bound").main(
        path_spectra=str(tmp / "spectra.nc"), path_allan=str(tmp / "allan.nc"),
        path_identified=str(tmp / "identify.yaml"), path_spec=str(SPEC), mode="raw", n_gm=1, confidence=0.95,
        bands_per_decade=10, compare_paper=False, kf_dt_s=1.0, horizon_s=600.0, axis_out=axis_out,
        path_out=str(tmp / "bound.yaml"), kf_out=str(tmp / "kf.yaml"), sensor="gyro")
    return {k: read_yaml(tmp / f"{k}.yaml") for k in ("identify", "bound", "kf")}


def test_identification_equals_the_workflows(result, workflow):
    assert result.selection["kept"] == workflow["identify"]["selection"]["kept"]
    # same library calls on the same numbers; YAML writes floats by repr, so the round trip is exact
    assert result.fit.model.to_dict() == workflow["identify"]["model"]


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


def test_result_object(result, capfd):
    assert result.bounded is True and result.model is result.bound.model
    d = result.to_dict()
    assert set(d) >= {"bound", "identify", "kf", "curves", "rate_hz"}
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
    with pytest.raises(ValueError, match="shorter than window_s"):
        noise_model({"a": np.random.default_rng(0).standard_normal(1000)}, RATE, "gyro", SPEC)
