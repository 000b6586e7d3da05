"""One table of defaults (imupipe.defaults): the workflow's config/config.yaml and the API agree; the PSD rule."""

import inspect
from pathlib import Path

import pytest
import yaml

from imupipe.api import noise_model
from imupipe.defaults import DEFAULTS, PSD_MAX_WINDOW_S, psd_window_step

ROOT = Path(__file__).resolve().parents[1]

API_ARG = {"decimate.rate_hz": "decimate_hz", "psd.taper": "taper", "psd.detrend": "detrend",
           "psd.confidence": "psd_confidence", "allan.taus": "taus", "allan.confidence": "allan_confidence",
           "identify.components": "components", "identify.n_gm": "n_gm", "identify.confidence": "fit_confidence",
           "identify.significance": "significance", "identify.relevance": "relevance",
           "identify.adequacy_level": "adequacy_level", "identify.pooling_level": "pooling_level",
           "identify.pooling_n_boot": "pooling_n_boot", "identify.n_boot": "n_boot", "verify.reduce": "reduce", "verify.replay_z": "replay_z",
           "lines.floor_window_bins": "lines_floor_window_bins", "identify.envelope": "envelope",
           "application.filter_rate_hz": "filter_rate_hz", "application.outage_s": "outage_s",
           "bound.mode": "mode", "bound.confidence": "bound_confidence", "bound.bands_per_decade": "bands_per_decade",
           "lines.resolution_hz": "lines_resolution_hz", "lines.alpha": "lines_alpha", "verify.fix_s": "fix_s",
           "lines.scales": "lines_scales", "lines.low_band_resolution_hz": "lines_low_band_resolution_hz"}


def test_config_yaml_ships_the_table():
    cfg = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
    for key, value in DEFAULTS.items():
        section, name = key.split(".")
        assert cfg[section][name] == value, key


#: keys the API resolves inside noise_model (one argument, `sigma_fix`, whose default depends on the sensor; the
#: `stationarity` argument's settings, each defaulting to the table's)
RESOLVED_INSIDE = {"verify.sigma_fix_m", "verify.sigma_fix_rad", "stationarity.n_segments", "stationarity.alpha",
                   "stationarity.test", "stationarity.n_sim", "stationarity.n_sim_max", "stationarity.close_z"}


def test_api_defaults_are_the_table():
    params = inspect.signature(noise_model).parameters
    # verify.filter_rate_hz: not an API argument (the verification runs at the one filter rate, issue 30)
    assert set(API_ARG) | RESOLVED_INSIDE == set(DEFAULTS) - {"verify.filter_rate_hz"}
    assert params["sigma_fix"].default is None
    for key, arg in API_ARG.items():
        got = params[arg].default
        assert (list(got) if isinstance(got, tuple) else got) == DEFAULTS[key], key
    assert params["window_s"].default is None and params["step_s"].default is None
    # the verification's reference filter runs at the one filter rate (verify.filter_rate_hz is no config key)
    assert params["filter_rate_hz"].default == DEFAULTS["application.filter_rate_hz"]
    assert "verify.filter_rate_hz" not in DEFAULTS


def test_psd_rule_two_hours_and_long_records():
    assert psd_window_step(7200.0, 1.0) == (1800.0, 900.0)
    w, s = psd_window_step(50 * 3600.0, 1.0)
    assert w == PSD_MAX_WINDOW_S and s == PSD_MAX_WINDOW_S / 2
    for t in (40.0, 7200.0, 36000.0, 99999.0):  # at least 7 segments up to 4 x 7 h, and < 1/7 of the record unused
        w, s = psd_window_step(t, 1.0)
        k = int((t - w) // s) + 1
        used = (k - 1) * s + w
        assert k >= 7 and (t - used) < t / 7.0
    with pytest.raises(ValueError, match="too short"):
        psd_window_step(5.0, 1.0)


def test_summary_flags_a_record_mostly_unused():
    """The issue's case: 2 h at 1 Hz, window 1800 s, step left at 36000 s: one segment, 1800 of 7200 samples."""
    from imupipe.summary import psd_usage_flags, render_summary

    usage = [{"dataset": "mine", "axis": a, "n_samples": 7200, "n_samples_used": 1800, "window_s": 1800.0,
              "step_s": 36000.0, "rate_hz": 1.0} for a in "xyz"]
    flags = psd_usage_flags("gyro", usage)
    assert len(flags) == 1  # one per dataset, not per axis
    assert "1800 of 7200 samples" in flags[0].detail and "75 %" in flags[0].detail and "5400 s" in flags[0].detail
    assert "psd.step_s: 900" in flags[0].detail
    text = render_summary({"gyro": {"bound": {"bounded": True, "margin": 1.2, "psd_usage": usage}}})
    assert "FLAG record partly unused [mine/gyro]" in text and "the paper's setting" not in text
    # the default run's one 7 h window of a 10 h record (the paper's setting): said so
    paper = psd_usage_flags("gyro", [{"dataset": "sim01", "n_samples": 36000, "n_samples_used": 25200,
                                      "window_s": 25200.0, "step_s": 36000.0, "rate_hz": 1.0}])
    assert len(paper) == 1 and "one 7 h window is the paper's setting (Gallon et al. 2021)" in paper[0].detail
    # the rule's own setting leaves 0 % of a 2 h record: no flag; 10 % exactly is not "more than 10 %"
    assert psd_usage_flags("gyro", [{"n_samples": 7200, "n_samples_used": 7200}]) == []
    assert psd_usage_flags("gyro", [{"n_samples": 1000, "n_samples_used": 900}]) == []
    assert len(psd_usage_flags("gyro", [{"n_samples": 1000, "n_samples_used": 899}])) == 1


def test_api_default_window_fits_a_short_record():
    """The README's library example as written (no window_s) on a 2 h record: the rule's 1800 s / 900 s."""
    import numpy as np

    rng = np.random.default_rng(3)
    x = 4.4e-5 * np.sqrt(10.0) * rng.standard_normal(10 * 7200)  # rad/s at 10 Hz, 2 h
    res = noise_model({"lab1/x": x}, record_rate_hz=10.0, sensor="gyro", spec=ROOT / "config" / "specs" / "stim300.yaml",
                      verify=False)
    sp = res.spectra["lab1/x"]
    assert sp.attrs["window_s"] == 1800.0 and sp.attrs["step_s"] == 900.0
    assert sp.attrs["n_samples_used"] == sp.attrs["n_samples"]  # the whole record
    assert res.bound.model.white > 0
