"""The real ADIS16405 records (../shared/data/adis16405): bound + verification as a user would run them (slow)."""

import math

import numpy as np
import pytest

pytestmark = pytest.mark.slow


@pytest.mark.parametrize("sensor", ["gyro", "accel"])
def test_adis16405_bound_verifies_and_the_spec_sheet_fails_on_replay(shared_data, sensor):
    rdata = pytest.importorskip("rdata")
    from imupipe import allan_variance
    from imupipe.bound import bound_psd, check_allan, upper_envelope
    from imupipe.identify import fit_allan, select_components
    from imupipe.spectra import decimate, psd
    from imupipe.specsheet import load_spec
    from imupipe.verify import integrity_contract, reference_scenario, replay, verify_model

    from conftest import PROJECT_ROOT

    raw = shared_data / "adis16405" / "raw"
    recs = [np.asarray(rdata.read_rda(str(raw / f"adis_16405_imu{i}.rda"))[f"adis_16405_imu{i}"]) for i in (1, 2)]
    cols, scale = ((0, 1, 2), math.pi / 180.0) if sensor == "gyro" else ((3, 4, 5), 9.80665)  # deg/s, g -> SI
    series = [r[:, c] * scale for r in recs for c in cols]
    spec = load_spec(PROJECT_ROOT / "config" / "specs" / "adis16405.yaml").models[sensor]
    taus, avs, edfs, curves, ns = [], [], [], [], []
    for x in series:
        x = x - x.mean()
        av = allan_variance(x, 100.0)
        taus.append(av["tau"].values)
        avs.append(av["avar"].values)
        edfs.append(av["edf"].values)
        ns.append(x.size)
        y, _ = decimate(x, 100.0, 1.0)
        sp = psd(y, 1.0, window_s=3600.0, step_s=1800.0)  # the shipped adis16405 config's PSD windows
        f, edf = sp["frequency"].values, sp["edf"].values
        curves.append(sp["psd"].values)
    fit = fit_allan(taus, avs, edfs, n_gm=1, n_boot=100, confidence=0.9, rng=20211, dt=0.01, rate=100.0, n_samples=ns)
    sel = select_components(fit, taus, avs, edfs, rate_hz=1.0, horizon_s=600.0)
    up = upper_envelope(fit, sel)
    b = bound_psd(f, np.array(curves), spec, dt=1.0, keep=sel, horizon_s=1200.0, upper_model=up, edf=edf)
    sc = reference_scenario(sensor, horizon_s=600.0)
    ver = {sensor: verify_model(b.model, sensor, upper=up, spec=spec, records=series, rate_hz=100.0, scenario=sc)}
    al = check_allan(b.model, fit.model, taus[0], kept=sel, sample_avar=np.array(avs), sample_edf=np.array(edfs),
                     horizon_s=600.0)
    contract = integrity_contract(b, al, ver)
    assert contract["bounded"], contract["failed_checks"]
    # 6 series x 10 000 s / 1200 s windows = 50 independent windows
    assert ver[sensor]["checks"]["replay"]["n_eff"] == pytest.approx(50.0)
    # the unflated spec sheet as the filter's model under-states the replayed error (measured 4.5x gyro, 9.2x accel)
    assert not replay(spec, series, 100.0, sc).passed
