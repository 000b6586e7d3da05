"""Kalibr export (imupipe.kalibr): Kalibr's field names, units and conventions, read back from the file."""

import math

import numpy as np
import pytest
import yaml

from imupipe.kalibr import (
    KALIBR_UNITS, LP_FEASIBILITY_TOL, imu_rate, kalibr_imu, kalibr_pair, kalibr_text, model_of_bound, read_kalibr,
    write_kalibr,
)
from imupipe.models import NoiseModel

GYRO = NoiseModel(white=1.3e-4, gauss_markov=((2.2e-5, 300.0),), random_walk=3.0e-7)  # rad/s
ACCEL = NoiseModel(white=2.5e-3, gauss_markov=((6.0e-4, 120.0),), random_walk=5.0e-5)  # m/s^2
GYRO_ID = NoiseModel(white=0.5e-4, gauss_markov=((1.0e-5, 300.0),), random_walk=1.0e-7)
ACCEL_ID = NoiseModel(white=1.0e-3, random_walk=2.0e-5)


#: application band of the unit tests, [1/horizon_s, filter_rate/2] = [1/600, 0.5] Hz
BAND = (1.0 / 600.0, 0.5)
#: the band of the stage files below: horizon 600 s, verified at 100 Hz
STAGE_BAND = (1.0 / 600.0, 50.0)


def _pair(m, band=BAND):
    p = kalibr_pair(m, band)
    return p.noise_density, p.random_walk


def _pair_psd(n, k, f):
    return n**2 + k**2 / (2.0 * np.pi * f) ** 2


def test_file_reads_back_with_kalibrs_fields_and_values(tmp_path):
    imu = kalibr_imu(GYRO, ACCEL, update_rate_hz=125.0, band_hz=BAND, rostopic="/imu/data", identified_gyro=GYRO_ID,
                     identified_accel=ACCEL_ID)
    path = tmp_path / "imu.yaml"
    write_kalibr(imu, path, source="unit test")
    back = read_kalibr(path)
    # Kalibr's five fields plus the topic, nothing renamed
    assert set(back) == set(KALIBR_UNITS) | {"rostopic"}
    assert back["update_rate"] == 125.0  # the IMU's sample rate, not a filter rate
    assert back["rostopic"] == "/imu/data"
    # the densities are the LP pair of each model (two-sided N; Kalibr: E[n(t1) n(t2)] = sigma^2 delta(t1 - t2));
    # written with 7 significant digits -> rtol 1e-6
    for prefix, m in (("gyroscope", GYRO), ("accelerometer", ACCEL)):
        n, k = _pair(m)
        np.testing.assert_allclose(back[f"{prefix}_noise_density"], n, rtol=1e-6)
        np.testing.assert_allclose(back[f"{prefix}_random_walk"], k, rtol=1e-6)
    text = path.read_text()
    # units as Kalibr defines them, in the comments next to the fields
    for field, unit in KALIBR_UNITS.items():
        line = next(ln for ln in text.splitlines() if ln.startswith(field + ":"))
        assert unit in line, (field, line)
    assert "BOUNDING VALUES" in text and "no further inflation" in text
    # inflation against the identified model's pair by the same rule and band
    r = _pair(GYRO)[0] / _pair(GYRO_ID)[0]
    assert f"gyroscope_noise_density: {r:.3g} times the identified value" in text
    assert imu.inflation["accelerometer_noise_density"] == pytest.approx(_pair(ACCEL)[0] / _pair(ACCEL_ID)[0])
    assert "Rule: (N, K) is the pair whose two-sided PSD N^2 + K^2/(2 pi f)^2 bounds" in text


LP_MODELS = {
    "gyro": GYRO, "accel": ACCEL,
    # a GM that acts as white noise in band (corner 0.96 Hz > 0.5 Hz), flicker, and a slow GM (corner 5e-5 Hz)
    "short GM": NoiseModel(white=2e-4, gauss_markov=((1.8e-2, 0.165), (3e-5, 3000.0)), random_walk=1e-7),
    "flicker": NoiseModel(white=1e-4, flicker=3e-5, random_walk=2e-7),
    "GM corner in band": NoiseModel(white=1e-4, gauss_markov=((1e-3, 10.0),)),
}


@pytest.mark.parametrize("name", list(LP_MODELS))
def test_lp_pair_bounds_the_model_on_a_finer_grid(name):
    """The pair bounds the model's PSD on a grid 10x denser than the LP's (offset from it), to the LP's relative
    feasibility tolerance: the rows are S-normalised, so HiGHS meets each to LP_FEASIBILITY_TOL relative in PSD, and
    the cutting planes stop when every local minimum of the ratio between rows is at least 1 - that tolerance."""
    m = LP_MODELS[name]
    p = kalibr_pair(m, BAND)
    f = np.geomspace(BAND[0], BAND[1], 10 * 200 * 3 + 7)
    ratio = _pair_psd(p.noise_density, p.random_walk, f) / m.psd(f)
    assert ratio.min() >= 1.0 - LP_FEASIBILITY_TOL
    assert p.min_ratio >= 1.0 and p.active_hz  # touching somewhere: not loose everywhere


@pytest.mark.parametrize("name", list(LP_MODELS))
def test_lp_pair_is_minimal(name):
    """Shrinking either value by 1 % (2 % in PSD, far above the tolerance) makes the pair fall below the model's PSD
    somewhere in the band: neither can shrink alone."""
    m = LP_MODELS[name]
    p = kalibr_pair(m, BAND)
    f = np.geomspace(BAND[0], BAND[1], 6007)
    shrunk = [(0.99 * p.noise_density, p.random_walk)] if p.noise_density > 0 else []
    shrunk += [(p.noise_density, 0.99 * p.random_walk)] if p.random_walk > 0 else []
    assert shrunk
    for n, k in shrunk:
        assert np.any(_pair_psd(n, k, f) < m.psd(f) * (1.0 - LP_FEASIBILITY_TOL)), (name, n, k)


def test_lp_pair_closed_forms():
    """A white model gives N = its white noise and K = 0; a random walk alone gives N = 0 and K = its K; a GM far
    below the band acts as its random walk K = sigma sqrt(2/T) (its PSD is below that asymptote at every f)."""
    n, k = _pair(NoiseModel(white=3e-4))
    assert n == pytest.approx(3e-4, rel=LP_FEASIBILITY_TOL) and k == 0.0
    n, k = _pair(NoiseModel(random_walk=2e-6))
    assert n == pytest.approx(0.0, abs=1e-12) and k == pytest.approx(2e-6, rel=LP_FEASIBILITY_TOL)
    s, T = 1e-4, 1e6
    n, k = _pair(NoiseModel(gauss_markov=((s, T),)))
    # the GM's PSD is below the asymptote by 1/(1 + 1/(2 pi f T)^2), at most 1/(2 pi f_lo T)^2 = 9e-9 relative
    assert k == pytest.approx(s * math.sqrt(2.0 / T), rel=1.0 / (2 * math.pi * BAND[0] * T) ** 2 + LP_FEASIBILITY_TOL)


def test_lp_pair_of_a_model_with_no_power_at_some_frequency():
    """A sampled quantization term (dt 0.1 s) has no power at 10 Hz, inside a band up to 10 Hz (an outside
    evaluation's identified accel model, whose pair the Kalibr file's comment compares with): such a frequency needs
    no cover. Its 1/S made the LP's input infinite, and the Kalibr file was refused with linprog's message. The pair
    is finite and bounds the PSD below the model's Nyquist frequency on a finer grid."""
    m = NoiseModel(quantization=1.4e-3, dt=0.1)
    pair = kalibr_pair(m, (5.6e-4, 10.0))
    assert pair.noise_density > 0 and math.isfinite(pair.noise_density) and math.isfinite(pair.random_walk)
    # the band-limited term is largest just below its Nyquist frequency, 5 Hz, and 0 from there on: its limit from
    # below is covered too
    f = np.geomspace(5.6e-4, 5.0 * (1 - 1e-12), 4001)
    cover = pair.noise_density**2 + pair.random_walk**2 / (2 * np.pi * f) ** 2
    assert np.all(cover >= m.psd(f) * (1 - 1e-6))


def test_per_axis_models_take_the_largest_of_each():
    """Two axis models, one with the larger white noise, the other with the larger drift: Kalibr's pair is the
    largest N and the largest K, each named by its axis in the comment, and bounds both axes."""
    x = NoiseModel(white=3e-4, random_walk=1e-7)
    y = NoiseModel(white=1e-4, random_walk=5e-7)
    imu = kalibr_imu({"x": x, "y": y}, ACCEL, update_rate_hz=100.0, band_hz=BAND)
    assert imu.gyroscope_noise_density == pytest.approx(_pair(x)[0]) and imu.set_by["gyroscope_noise_density"] == "x"
    assert imu.gyroscope_random_walk == pytest.approx(_pair(y)[1]) and imu.set_by["gyroscope_random_walk"] == "y"
    text = kalibr_text(imu)
    assert "# gyroscope: the largest of each over the per-axis exported models (SI; x: N " in text
    assert "gyroscope_noise_density set by axis x; gyroscope_random_walk set by axis y" in text
    assert "# accelerometer: the largest" not in text  # one model: no per-axis line
    f = np.geomspace(BAND[0], BAND[1], 2001)
    for m in (x, y):
        assert np.all(_pair_psd(imu.gyroscope_noise_density, imu.gyroscope_random_walk, f) >= m.psd(f) * (1 - 1e-9))


def test_discretisation_matches_kalibrs_rule():
    # Kalibr: sigma_d = sigma / sqrt(dt) (white), sigma_bd = sigma_b sqrt(dt) (random walk), dt = 1/update_rate;
    # a simulated white sequence at 125 Hz with that sigma_d has PSD N^2 (two-sided) -> the density is N.
    rate = 125.0
    imu = kalibr_imu(GYRO, ACCEL, update_rate_hz=rate, band_hz=BAND)
    rng = np.random.default_rng(5)
    x = imu.gyroscope_noise_density * math.sqrt(rate) * rng.standard_normal(2**18)
    # two-sided PSD estimate of white noise: var / rate; relative s.e. of the variance sqrt(2/n) = 0.28 %
    np.testing.assert_allclose(x.var() / rate, imu.gyroscope_noise_density**2, rtol=5 * math.sqrt(2 / x.size))


def test_update_rate_refuses_datasets_of_different_rates():
    assert imu_rate({"a": 125.0, "b": 125.0}) == 125.0
    with pytest.raises(ValueError, match=r"differ in sample rate.*a: 125 Hz, b: 200 Hz"):
        imu_rate({"a": 125.0, "b": 200.0})
    with pytest.raises(ValueError, match="positive number"):
        imu_rate({"a": 0.0})
    # the config names the rate Kalibr's IMU runs at (kalibr.update_rate_hz): one of the datasets' rates
    assert imu_rate({"a": 125.0, "b": 200.0}, named=200.0) == 200.0
    assert imu_rate({"a": 125.0}, named=125.0) == 125.0
    with pytest.raises(ValueError, match=r"kalibr.update_rate_hz 400: not the rate of any dataset \(a: 125 Hz, b: 200"):
        imu_rate({"a": 125.0, "b": 200.0}, named=400.0)
    with pytest.raises(ValueError, match="set kalibr.update_rate_hz"):
        imu_rate({"a": 125.0, "b": 200.0})


def test_narrowband_lines_are_refused():
    with_line = NoiseModel(white=1e-4, random_walk=1e-7, narrowband=((1e-4, 10.0, 0.01),))
    with pytest.raises(ValueError, match="narrowband"):
        kalibr_pair(with_line, BAND, name="gyro")


def test_model_of_bound_contract_and_plain_yaml():
    contract = {"bound": {"white": 1e-4, "gauss_markov": [{"sigma": 1e-5, "T": 100.0}], "random_walk": None}}
    m = model_of_bound(contract)
    assert m.white == 1e-4 and m.gauss_markov == ((1e-5, 100.0),) and m.random_walk == 0.0
    text = kalibr_text(kalibr_imu(m, ACCEL, update_rate_hz=100.0, band_hz=BAND))
    assert yaml.safe_load(text)["gyroscope_random_walk"] == pytest.approx(_pair(m)[1], rel=1e-6)
    with pytest.raises(ValueError, match="'bound'"):
        model_of_bound({})


def test_rostopic_from_the_dataset_sheet():
    from imupipe.kalibr import rostopic_of

    assert rostopic_of({"a": "/imu/data", "b": None, "c": ""}) == "/imu/data"
    assert rostopic_of({"a": None, "b": float("nan")}) == "/imu0"
    with pytest.raises(ValueError, match=r"different topics \(a: /imu/data, b: /imu1\)"):
        rostopic_of({"a": "/imu/data", "b": "/imu1"})


def test_read_kalibr_names_a_missing_field(tmp_path):
    path = tmp_path / "imu.yaml"
    path.write_text("gyroscope_noise_density: 1e-4\n")
    with pytest.raises(ValueError, match=r"imu.yaml: Kalibr field 'accelerometer_noise_density' \(m/s\^2/sqrt\(Hz\)\)"):
        read_kalibr(path)


def test_dataset_rates_take_the_timestamps_rate_where_the_sheet_gives_none():
    from imupipe.kalibr import dataset_rates

    curves = {"a/x": 100.0, "a/y": 100.0, "b+1.v2/z": 300.0}
    assert dataset_rates({"a": 125.0, "b+1.v2": None}, curves) == {"a": 125.0, "b+1.v2": 300.0}
    with pytest.raises(ValueError, match=r"dataset 'c' has no rate_hz in the sheet and no curve .*\(curves: a/x"):
        dataset_rates({"c": None}, curves)


def _kalibr_script():
    from workflow_helpers import stage_script

    return stage_script("kalibr")


def _stage_files(tmp_path, accel_bound: NoiseModel, accel_kf: NoiseModel, accel_dropped: list):
    """Synthetic bound, identify and KF files of both sensors as the kf rule writes them (imupipe.kf.export_kf and
    export_scope on a verification report whose reduction dropped `accel_dropped`)."""
    from imupipe.kf import export_kf, export_scope

    paths = {}
    for sensor, bound, kfm, dropped in (("gyro", GYRO, GYRO, []), ("accel", accel_bound, accel_kf, accel_dropped)):
        exported = {"reduced": bool(dropped), "model": kfm.to_dict(),
                    "verification": {"scenario": {"rate_hz": 100.0, "fix_s": 600.0, "horizon_s": 600.0}}}
        kf = {"sensor": sensor, "bounded": True, "dt_s": 0.01,
              "export": export_scope(exported, {"accepted": dropped}, 100.0, 600.0),
              **export_kf(kfm, 0.01, sensor=sensor, p0_random_walk=kfm.random_walk**2 * 600.0 or None)}
        for kind, doc in (("bound", {"spec_name": "X", "mode": "raw", "bound": bound.to_dict()}),
                          ("identify", {"model": (GYRO_ID if sensor == "gyro" else ACCEL_ID).to_dict()}),
                          ("kf", kf)):
            paths[f"{kind}_{sensor}"] = tmp_path / f"{kind}_{sensor}.yaml"
            paths[f"{kind}_{sensor}"].write_text(yaml.safe_dump(doc))
    return {k: str(v) for k, v in paths.items()}


def _run_kalibr(tmp_path, paths):
    out = tmp_path / "kalibr_imu.yaml"
    _kalibr_script().main(paths["bound_gyro"], paths["bound_accel"], paths["identify_gyro"], paths["identify_accel"],
                          {"a": 100.0}, {"a": None}, str(out), "x", path_kf_gyro=paths["kf_gyro"],
                          path_kf_accel=paths["kf_accel"])
    return out


def test_kalibr_follows_the_kf_export_that_dropped_every_line(tmp_path):
    """The bound has a line, the verified reduction dropped it (and the random walk) from the KF export: the Kalibr
    file is written from the exported model, not refused, and says what was dropped and for which horizon."""
    from dataclasses import replace

    bound = replace(ACCEL, narrowband=((6.6e-3, 0.564, 1.8e-3),))
    kfm = replace(ACCEL, random_walk=0.0)
    paths = _stage_files(tmp_path, bound, kfm, ["random_walk", "narrowband f0=0.564 Hz"])
    out = _run_kalibr(tmp_path, paths)
    k = read_kalibr(out)  # all Kalibr fields present: not refused
    text = out.read_text()
    assert "refused" not in yaml.safe_load(text)
    # the exported model's values: the pair of the KF model (no random walk: the GM alone), not the bound's
    n, kk = _pair(kfm, STAGE_BAND)
    assert k["accelerometer_noise_density"] == pytest.approx(n, rel=1e-6)
    assert k["accelerometer_random_walk"] == pytest.approx(kk, rel=1e-6)
    assert kk < _pair(ACCEL, STAGE_BAND)[1] * (1 - 1e-3)  # the two differ: the check can tell which was used
    assert "dropped random_walk, narrowband f0=0.564 Hz" in text and "scenario only (600 s of outage" in text
    # verified at the reference filter's 100 Hz, the Kalibr update_rate 100 Hz: no rate caveat
    assert "at that rate only" not in text


def test_an_export_without_bias_drift_takes_the_bounds_random_walk(tmp_path):
    """The verified reduction dropped the GM and the random walk (a white-noise-only export for the horizon):
    Kalibr needs a positive random walk, so the file takes the bound's drift terms and says so; the run does not
    fail (it did: "Kalibr needs a positive value" stopped the kalibr job). A bound with no drift at all is refused
    in the file, again without failing the run."""
    from dataclasses import replace

    kfm = replace(ACCEL, random_walk=0.0, gauss_markov=())
    paths = _stage_files(tmp_path, ACCEL, kfm, ["random_walk", "gauss_markov"])
    out = _run_kalibr(tmp_path, paths)
    k = read_kalibr(out)
    # the export's white noise with the bound's drift terms: ACCEL again, its pair
    n, kk = _pair(replace(ACCEL, white=kfm.white), STAGE_BAND)
    assert k["accelerometer_noise_density"] == pytest.approx(n, rel=1e-6)
    assert k["accelerometer_random_walk"] == pytest.approx(kk, rel=1e-6) and kk > 0
    assert "accel: the exported KF model has no bias drift" in out.read_text()
    # a verification at 1 Hz and a Kalibr update_rate of 100 Hz: said, per sensor
    for s in ("gyro", "accel"):
        kf = yaml.safe_load(open(paths[f"kf_{s}"]))
        kf["export"]["verified_filter_rate_hz"] = 1.0
        open(paths[f"kf_{s}"], "w").write(yaml.safe_dump(kf))
    text = _run_kalibr(tmp_path, paths).read_text()
    assert ("accel: verified with a reference filter at 1 Hz, not at this update_rate (100 Hz): the verification, "
            "and any state its reduction dropped, hold at that rate only") in text
    white_only = replace(ACCEL, random_walk=0.0, gauss_markov=())
    paths = _stage_files(tmp_path, white_only, white_only, [])
    data = yaml.safe_load(_run_kalibr(tmp_path, paths).read_text())
    assert data["refused"] is True and "accelerometer_random_walk" in data["reason"]


def test_kalibr_refuses_only_for_line_states_of_the_kf_export_with_nonzero_sigma(tmp_path):
    from dataclasses import replace

    kfm = replace(ACCEL, narrowband=((0.0, 0.463, 2e-3), (6.6e-3, 0.564, 1.8e-3)))
    paths = _stage_files(tmp_path, kfm, kfm, [])
    out = _run_kalibr(tmp_path, paths)
    data = yaml.safe_load(out.read_text())
    assert data["refused"] is True and "exported accel KF model" in data["reason"]
    text = out.read_text()
    assert "f0 0.564 Hz" in text and "0.463" not in text  # the sigma-0 term is no state and no reason
    with pytest.raises(ValueError, match="accelerometer_noise_density"):
        read_kalibr(out)


def test_pair_ignores_a_sigma_zero_line():
    from dataclasses import replace

    m = replace(ACCEL, narrowband=((0.0, 0.463, 2e-3),))
    assert _pair(m) == pytest.approx(_pair(ACCEL), rel=1e-12)


def test_a_ratio_below_one_is_not_called_an_inflation():
    """An identified accel model with a larger random walk than the bound's drift (the bound traded it against its
    GM and white noise): the written random walk over the identified pair's (same rule, band) is below 1 and printed
    as below the identified value, naming the identified terms that act as a random walk in band, never as an
    inflation; ratios above 1 stay plain factors. An identified short GM (T = 0.01 s, corner 15.9 Hz above the band)
    acts as white noise: it raises the identified N, not K."""
    ident = NoiseModel(white=1.0e-3, gauss_markov=((5.0e-3, 0.01),), random_walk=2.0e-4)
    imu = kalibr_imu(GYRO, ACCEL, update_rate_hz=125.0, band_hz=BAND, identified_gyro=GYRO_ID, identified_accel=ident)
    r = imu.inflation["accelerometer_random_walk"]
    assert r == pytest.approx(_pair(ACCEL)[1] / _pair(ident)[1], rel=1e-9) and r < 1
    assert _pair(ident)[0] == pytest.approx(math.sqrt(1e-6 + 2 * 25e-6 * 0.01), rel=1e-3)  # N^2 + 2 sigma^2 T
    text = kalibr_text(imu)
    (line,) = [ln for ln in text.splitlines() if ln.startswith("#   accelerometer_random_walk:")]
    assert line.startswith(f"#   accelerometer_random_walk: {r:.3g} times the identified value (the written value is "
                           "the smaller one, still the bounding value to use): ")
    assert "its terms acting as random walk in band: random_walk)" in line
    rn = imu.inflation["accelerometer_noise_density"]
    assert rn > 1 and f"#   accelerometer_noise_density: {rn:.3g} times the identified value\n" in text
    assert set(imu.below) == {"accelerometer_random_walk"}
    assert "(above 1: the bound's inflation)" in text


def test_a_global_line_refuses_kalibr_only_when_some_axis_exports_the_global_model():
    """Per-axis models: Kalibr's values are the per-axis exported models' (stages.kalibr.axis_models). A line state
    of the global model that no axis exports (every axis has its own model, the verified reduction dropped the line
    there) is no reason to refuse; an axis given the global model brings its line back, as does an axis's own."""
    from imupipe.stages.kalibr import lines_of

    line = {"sigma": 6.6e-3, "f0_hz": 0.564, "zeta": 1.8e-3}
    own = {"model": "own", "parameters": {"white": 1e-2, "narrowband": []}}
    kf = {"parameters": {"white": 1e-2, "narrowband": [line]}, "per_axis": {"x": own, "y": own, "z": own}}
    assert lines_of(kf) == []
    kf["per_axis"]["z"] = {"model": "global"}
    assert lines_of(kf) == [line]
    kf["per_axis"]["z"] = {"model": "own", "parameters": {"white": 1e-2, "narrowband": [line]}}
    assert lines_of(kf) == [line]
    assert lines_of({"parameters": {"narrowband": [line]}}) == [line]  # pooled axes: the global model's
