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
           "application.rate_hz": "application_rate_hz", "application.horizon_s": "horizon_s",
           "bound.mode": "mode", "bound.confidence": "bound_confidence", "bound.bands_per_decade": "bands_per_decade",
           "lines.resolution_hz": "lines_resolution_hz", "lines.alpha": "lines_alpha", "verify.fix_s": "fix_s"}


def test_config_yaml_ships_the_table():
    cfg = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
    for key, value in DEFAULTS.items():
        section, name = key.split(".")
        assert cfg[section][name] == value, key


def test_api_defaults_are_the_table():
    params = inspect.signature(noise_model).parameters
    assert set(API_ARG) == set(DEFAULTS)
    for key, arg in API_ARG.items():
        got = params[arg].default
        assert (list(got) if isinstance(got, tuple) else got) == DEFAULTS[key], key
    assert params["window_s"].default is None and params["step_s"].default is None


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
