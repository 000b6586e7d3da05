"""Kalibr export (imupipe.kalibr): Kalibr's field names, units and conventions, read back from the file."""

import math

import numpy as np
import pytest
import yaml

from imupipe.kalibr import KALIBR_UNITS, imu_rate, kalibr_imu, kalibr_text, model_of_bound, read_kalibr, write_kalibr
from imupipe.models import NoiseModel

GYRO = NoiseModel(white=1.3e-4, gauss_markov=((2.2e-5, 300.0),), random_walk=3.0e-7)  # rad/s
ACCEL = NoiseModel(white=2.5e-3, gauss_markov=((6.0e-4, 120.0),), random_walk=5.0e-5)  # m/s^2
GYRO_ID = NoiseModel(white=0.5e-4, gauss_markov=((1.0e-5, 300.0),), random_walk=1.0e-7)
ACCEL_ID = NoiseModel(white=1.0e-3, random_walk=2.0e-5)


def _k_eff(m):
    return math.sqrt(m.random_walk**2 + sum(2 * s**2 / T for s, T in m.gauss_markov))


def test_file_reads_back_with_kalibrs_fields_and_values(tmp_path):
    imu = kalibr_imu(GYRO, ACCEL, update_rate_hz=125.0, rostopic="/imu/data", identified_gyro=GYRO_ID,
                     identified_accel=ACCEL_ID)
    path = tmp_path / "imu.yaml"
    write_kalibr(imu, path, source="unit test")
    back = read_kalibr(path)
    # Kalibr's five fields plus the topic, nothing renamed
    assert set(back) == set(KALIBR_UNITS) | {"rostopic"}
    assert back["update_rate"] == 125.0  # the IMU's sample rate, not a filter rate
    assert back["rostopic"] == "/imu/data"
    # the white noise density is the two-sided N (Kalibr: E[n(t1) n(t2)] = sigma^2 delta(t1 - t2));
    # written with 7 significant digits -> rtol 1e-6
    np.testing.assert_allclose(back["gyroscope_noise_density"], GYRO.white, rtol=1e-6)
    np.testing.assert_allclose(back["accelerometer_noise_density"], ACCEL.white, rtol=1e-6)
    np.testing.assert_allclose(back["gyroscope_random_walk"], _k_eff(GYRO), rtol=1e-6)
    np.testing.assert_allclose(back["accelerometer_random_walk"], _k_eff(ACCEL), rtol=1e-6)
    text = path.read_text()
    # units as Kalibr defines them, in the comments next to the fields
    for field, unit in KALIBR_UNITS.items():
        line = next(ln for ln in text.splitlines() if ln.startswith(field + ":"))
        assert unit in line, (field, line)
    assert "BOUNDING VALUES" in text and "no further inflation" in text
    # inflation against the identified values: 1.3e-4 / 0.5e-4 = 2.6
    assert "gyroscope_noise_density: x2.6" in text
    assert imu.inflation["accelerometer_noise_density"] == pytest.approx(2.5)


def test_folded_random_walk_bounds_gm_plus_rw_psd():
    imu = kalibr_imu(GYRO, ACCEL, update_rate_hz=200.0)
    f = np.geomspace(1e-6, 100.0, 400)
    kalibr_model = NoiseModel(white=imu.gyroscope_noise_density, random_walk=imu.gyroscope_random_walk)
    assert np.all(kalibr_model.psd(f) >= GYRO.psd(f) * (1 - 1e-12))
    # and it is not loose at high frequency: the white noise is passed unchanged
    assert kalibr_model.psd(f[-1:]) == pytest.approx(GYRO.psd(f[-1:]), rel=1e-3)


def test_discretisation_matches_kalibrs_rule():
    # Kalibr: sigma_d = sigma / sqrt(dt) (white), sigma_bd = sigma_b sqrt(dt) (random walk), dt = 1/update_rate;
    # a simulated white sequence at 125 Hz with that sigma_d has PSD N^2 (two-sided) -> the density is N.
    rate = 125.0
    imu = kalibr_imu(GYRO, ACCEL, update_rate_hz=rate)
    rng = np.random.default_rng(5)
    x = imu.gyroscope_noise_density * math.sqrt(rate) * rng.standard_normal(2**18)
    # two-sided PSD estimate of white noise: var / rate; relative s.e. of the variance sqrt(2/n) = 0.28 %
    np.testing.assert_allclose(x.var() / rate, GYRO.white**2, rtol=5 * math.sqrt(2 / x.size))


def test_update_rate_refuses_datasets_of_different_rates():
    assert imu_rate({"a": 125.0, "b": 125.0}) == 125.0
    with pytest.raises(ValueError, match=r"differ in sample rate.*a: 125 Hz, b: 200 Hz"):
        imu_rate({"a": 125.0, "b": 200.0})
    with pytest.raises(ValueError, match="positive number"):
        imu_rate({"a": 0.0})


def test_narrowband_lines_are_refused():
    class WithLine:
        white, random_walk, gauss_markov, narrowband = 1e-4, 1e-7, (), ((1e-4, 10.0, 0.01),)

    from imupipe import kalibr

    with pytest.raises(ValueError, match="narrowband"):
        kalibr._k_eff(WithLine(), "gyro")


def test_model_of_bound_contract_and_plain_yaml():
    contract = {"bound": {"white": 1e-4, "gauss_markov": [{"sigma": 1e-5, "T": 100.0}], "random_walk": None}}
    m = model_of_bound(contract)
    assert m.white == 1e-4 and m.gauss_markov == ((1e-5, 100.0),) and m.random_walk == 0.0
    text = kalibr_text(kalibr_imu(m, ACCEL, update_rate_hz=100.0))
    assert yaml.safe_load(text)["gyroscope_random_walk"] == pytest.approx(math.sqrt(2e-10 / 100.0), rel=1e-6)
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
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "workflow" / "scripts" / "kalibr.py"
    spec = importlib.util.spec_from_file_location("stage_kalibr", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


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
    # the exported model's values: K_eff of the KF model (no random walk: the GM alone), not the bound's
    assert k["accelerometer_noise_density"] == pytest.approx(kfm.white, rel=1e-6)
    assert k["accelerometer_random_walk"] == pytest.approx(_k_eff(kfm), rel=1e-6)
    assert _k_eff(kfm) < _k_eff(ACCEL) * (1 - 1e-3)  # the two differ: the check can tell which was used
    assert "dropped random_walk, narrowband f0=0.564 Hz" in text and "horizon only (600 s of outage" in text
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
    assert k["accelerometer_noise_density"] == pytest.approx(kfm.white, rel=1e-6)  # the export's white noise
    assert k["accelerometer_random_walk"] == pytest.approx(_k_eff(ACCEL), rel=1e-6)  # the bound's drift
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


def test_k_eff_ignores_a_sigma_zero_line():
    from dataclasses import replace

    from imupipe import kalibr

    m = replace(ACCEL, narrowband=((0.0, 0.463, 2e-3),))
    assert kalibr._k_eff(m, "accel") == pytest.approx(_k_eff(ACCEL), rel=1e-12)


def test_a_ratio_below_one_is_not_called_an_inflation():
    """An identified accel model that absorbed a narrowband line into a very short GM (sigma 5e-3 m/s^2, T = 0.01 s):
    its folded random walk sqrt(K^2 + 2 sigma^2/T) squared is 2e-5^2 + 5e-3 (m/s^2)^2/s, the GM's share rounding to 100 %, far above the
    bound's 9.2e-5 m/s^2/sqrt(s). The ratio (1.3e-3) is printed as below the identified value, with the GM's T and
    the frequency 1/(2 pi T) = 15.9 Hz below which that fold overstates the GM, never as an inflation; ratios above
    1 stay plain factors."""
    ident = NoiseModel(white=1.0e-3, gauss_markov=((5.0e-3, 0.01),), random_walk=2.0e-5)
    imu = kalibr_imu(GYRO, ACCEL, update_rate_hz=125.0, identified_gyro=GYRO_ID, identified_accel=ident)
    r = imu.inflation["accelerometer_random_walk"]
    assert r == pytest.approx(_k_eff(ACCEL) / _k_eff(ident), rel=1e-12) and r < 1
    text = kalibr_text(imu)
    (line,) = [ln for ln in text.splitlines() if ln.startswith("#   accelerometer_random_walk:")]
    assert line.startswith(f"#   accelerometer_random_walk: x{r:.3g}, BELOW the identified value, not an inflation: ")
    assert "100% of the identified value (squared) is its GM with T = 0.01 s" in line
    assert f"1/(2 pi T) = {1 / (2 * math.pi * 0.01):.3g} Hz" in line
    assert "#   accelerometer_noise_density: x2.5\n" in text and "#   gyroscope_noise_density: x2.6\n" in text
    assert set(imu.below) == {"accelerometer_random_walk"}
    assert "written / identified; above 1 an inflation" in text
