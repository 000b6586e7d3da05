"""imupipe.identify.joint: the simultaneous band of a fit's PSD over its bootstrap replicates and the envelope model
above it (closed forms on constructed replicates; the identification's joint envelope on a simulated record)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from imupipe.identify.joint import JOINT_PAD, joint_band, joint_envelope
from imupipe.models import NoiseModel


def _fit(params, names, boots):
    return SimpleNamespace(params=params, param_names=names, bootstrap=np.asarray(boots, dtype=float))


def test_white_only_band_is_the_order_statistic_of_the_replicates():
    # white noise alone: ln S_b - ln S_hat = 2 ln(N_b / N_hat) at every f, so the sup over f of the standardised
    # deviation orders the replicates as N_b does and the band is the ceil((B + 1) c)-th smallest N_b^2 exactly
    rng = np.random.default_rng(1)
    n_b = 1e-3 * np.exp(0.05 * rng.standard_normal(199))
    fit = _fit({"white": 1e-3}, ["white"], n_b[:, None])
    f = np.geomspace(1e-3, 1.0, 50)
    band = joint_band(fit, ["white"], f, 0.9)
    k = math.ceil(200 * 0.9)
    np.testing.assert_allclose(band["upper"], np.sort(n_b**2)[k - 1], rtol=1e-12)


def _gm_rw_fit(B=200, seed=2):
    """Replicates of white + GM + random walk whose GM and random walk trade off (a longer T with a smaller K)."""
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((B, 3))
    white = 1e-4 * np.exp(0.02 * u[:, 0])
    T = 300.0 * np.exp(0.5 * u[:, 1])
    sigma = 5e-5 * np.exp(0.2 * u[:, 2])
    k = np.maximum(2e-7 * (1.0 - 0.8 * u[:, 1]), 0.0)  # K falls as T grows: negatively correlated
    names = ["white", "gm_sigma_1", "gm_T_1", "random_walk"]
    return _fit({"white": 1e-4, "gm_sigma_1": 5e-5, "gm_T_1": 300.0, "random_walk": 2e-7}, names,
                np.stack([white, sigma, T, k], axis=1))


def test_band_holds_the_stated_fraction_of_whole_replicate_curves():
    fit = _gm_rw_fit()
    f = np.geomspace(1.0 / 4200, 5.0, 400)
    band = joint_band(fit, None, f, 0.9)
    curves = np.stack([NoiseModel(white=w, gauss_markov=((s, T),), random_walk=k).psd(f)
                       for w, s, T, k in fit.bootstrap])
    inside = np.mean(np.all(curves <= band["upper"] * (1 + 1e-12), axis=1))
    # by construction: the ceil((B + 1) c)-th order statistic of the sup statistic, so at least c of the B curves
    assert inside >= 0.9
    assert inside <= 0.9 + 2.0 / 200  # and not more than the order statistic's step (ties aside)


def test_envelope_model_lies_above_the_padded_band():
    fit = _gm_rw_fit()
    env, rec = joint_envelope(fit, None, 4200.0, 5.0, 0.9)
    assert rec["worst_ratio_to_band"] >= JOINT_PAD * (1 - 1e-9)
    f = np.geomspace(1.0 / 4200, 5.0, 1201)  # a grid the LP never saw
    band = joint_band(fit, None, f, 0.9)
    assert np.all(env.psd(f) >= band["upper"])
    # the LP's representation stays close to the band (the pad and the basis's shape): mean ratio within 1.2
    assert rec["mean_ratio_to_band"] < 1.2


def test_too_few_replicates_give_no_envelope():
    fit = _fit({"white": 1e-3}, ["white"], np.full((5, 1), 1e-3))
    env, rec = joint_envelope(fit, None, 4200.0, 5.0, 0.95)
    assert env is None and "fewer than 20" in rec["note"]


def test_bad_band_and_kind_are_errors():
    fit = _gm_rw_fit()
    with pytest.raises(ValueError, match="f_min_hz < f_max_hz"):
        joint_envelope(fit, None, 4200.0, 1e-5, 0.95)
    from imupipe.stages.identify import envelope

    with pytest.raises(ValueError, match="identify.envelope"):
        envelope(fit, None, [], 0.95, 4200.0, kind="joint_marginal")
