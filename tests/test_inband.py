"""Effective in-band inflation of a whole model against a spec sheet (imupipe.inband), against closed forms."""

import math

import numpy as np
import pytest

from imupipe.inband import acts_as, application_band, inband_inflation, inband_line
from imupipe.models import NoiseModel

#: [1/horizon_s, filter_rate/2] for a 600 s horizon and a 1 Hz reference filter
BAND = application_band(600.0, 1.0)
SPEC = NoiseModel(white=1e-4)
EPS = np.finfo(float).eps


def test_band_is_one_over_horizon_to_nyquist():
    assert BAND == (pytest.approx(1 / 600.0), 0.5)
    with pytest.raises(ValueError, match="not below"):
        application_band(1.0, 1.0)


@pytest.mark.parametrize("x", [1.0, 2.5, 17.8])
def test_white_over_white_is_x_at_every_frequency(x):
    """psd_sampled of white noise is exactly N^2: sqrt(x^2 N^2 / N^2) = x at every f, so median = max = min = x."""
    out = inband_inflation(NoiseModel(white=x * 1e-4), SPEC, BAND)
    for key in ("vs_spec_psd", "vs_spec_white"):
        for stat in ("median", "max", "min"):
            assert out[key][stat] == pytest.approx(x, rel=10 * EPS)
    assert [c["acts_as"] for c in out["components"]] == ["white noise"]


def test_gm_far_below_the_band_acts_as_a_random_walk():
    """A GM of T = 1e6 s (corner 1.6e-7 Hz, far below 1/600 Hz) is labelled a random walk of K = sigma sqrt(2/T); its
    ratio to the white spec is that random walk's: sqrt(psd_sampled of K) / N_spec. The GM's sampled PSD differs from
    the random walk's by terms of order 1/(2 pi f T)^2 and dt/T, at most 1/(2 pi f_lo T)^2 + dt/T relative."""
    s, T = 1e-4, 1e6
    m = NoiseModel(gauss_markov=((s, T),))
    out = inband_inflation(m, SPEC, BAND)
    (c,) = out["components"]
    assert c["acts_as"] == "random walk" and c["as_K"] == pytest.approx(s * math.sqrt(2 / T), rel=10 * EPS)
    rw = NoiseModel(random_walk=c["as_K"])
    rel = 1.0 / (2 * math.pi * BAND[0] * T) ** 2 + 1.0 / T  # dt = 1 s
    f_lo, f_hi = np.array([BAND[0]]), np.array([BAND[1]])
    # the largest ratio is at the band's bottom (f^-2), the smallest at its top
    assert out["vs_spec_white"]["max"] == pytest.approx(math.sqrt(rw.psd_sampled(f_lo, 1.0)[0]) / 1e-4, rel=rel)
    assert out["vs_spec_white"]["max_frequency_hz"] == pytest.approx(BAND[0])
    assert out["vs_spec_white"]["min"] == pytest.approx(math.sqrt(rw.psd_sampled(f_hi, 1.0)[0]) / 1e-4, rel=rel)
    assert "acts as random walk" in inband_line(out)


def test_gm_above_the_band_acts_as_white_noise():
    """A GM of T = 0.01 s (corner 15.9 Hz above 0.5 Hz) is labelled white noise of N = sigma sqrt(2 T); with a white
    model beside it, the in-band level is sqrt(N^2 + 2 sigma^2 T) within the GM's roll-off over the band,
    (f_hi/f_c)^2 = 1e-3, plus the block-mean correction of the sampled GM, of order T/dt (dt = 1 s >> T)."""
    s, T = 5e-3, 0.01
    m = NoiseModel(white=1e-4, gauss_markov=((s, T),))
    out = inband_inflation(m, SPEC, BAND)
    gm = next(c for c in out["components"] if c["component"] == "gauss_markov")
    assert gm["acts_as"] == "white noise" and gm["as_N"] == pytest.approx(s * math.sqrt(2 * T), rel=10 * EPS)
    level = math.sqrt(1e-8 + 2 * s * s * T) / 1e-4
    fc = 1.0 / (2 * math.pi * T)
    rel = (BAND[1] / fc) ** 2 + T / 1.0  # roll-off in band, and the block-mean correction of order T/dt
    assert out["vs_spec_white"]["median"] == pytest.approx(level, rel=rel)
    assert out["vs_spec_psd"]["max"] == pytest.approx(level, rel=rel)
    assert "acts as white noise" in inband_line(out)


def test_gm_corner_in_band_stays_a_gm_and_the_max_is_where_the_psd_peaks():
    m = NoiseModel(white=1e-4, gauss_markov=((1e-3, 10.0),))
    out = inband_inflation(m, SPEC, BAND)
    assert [c["acts_as"] for c in out["components"]] == ["white noise", "Gauss-Markov"]
    # a GM plus white over a white spec peaks at the band's bottom
    assert out["vs_spec_psd"]["max_frequency_hz"] == pytest.approx(BAND[0])
    expect = math.sqrt(m.psd_sampled(np.array([BAND[0]]), 1.0)[0]) / 1e-4
    assert out["vs_spec_psd"]["max"] == pytest.approx(expect, rel=10 * EPS)


def test_ratio_against_the_whole_spec_psd():
    """A spec with a random walk: the ratio is to the spec's whole sampled PSD, its white-noise ratio to N alone."""
    spec = NoiseModel(white=1e-4, random_walk=1e-6)
    m = NoiseModel(white=2e-4, random_walk=2e-6)  # twice the spec in every term: exactly 2 everywhere
    out = inband_inflation(m, spec, BAND)
    assert out["vs_spec_psd"]["median"] == pytest.approx(2.0, rel=1e-12)
    assert out["vs_spec_psd"]["max"] == pytest.approx(2.0, rel=1e-12)
    assert out["vs_spec_white"]["max"] > out["vs_spec_white"]["median"] > 2.0
    text = inband_line(out)
    assert text.startswith("in-band (0.00167 to 0.5 Hz): median 2x, max 2x at ")
    assert "the spec's PSD; " in text and "x the spec's white noise (median; max " in text


def test_acts_as_labels_lines_and_the_other_components():
    m = NoiseModel(white=1e-4, random_walk=1e-7, flicker=1e-5, narrowband=((1e-3, 2.0, 0.01), (1e-3, 0.1, 0.01)))
    got = {(c["component"], c.get("f0_hz")): c["acts_as"] for c in acts_as(m, BAND)}
    assert got[("narrowband", 2.0)] == "white noise" and got[("narrowband", 0.1)] == "line"
    assert got[("flicker", None)] == "flicker" and got[("random_walk", None)] == "random walk"
