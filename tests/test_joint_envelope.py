"""imupipe.identify.joint: the simultaneous band of a fit's PSD over its bootstrap replicates and the envelope model
above it (closed forms on constructed replicates; the identification's joint envelope on a simulated record)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from imupipe.identify.joint import JOINT_PAD, PER_DECADE, joint_band, joint_envelope
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


def test_envelope_model_lies_above_the_padded_band_and_every_covered_curve_between_grid_points():
    fit = _gm_rw_fit()
    env, rec = joint_envelope(fit, None, 4200.0, 5.0, 0.9)
    assert rec["worst_ratio_to_band"] >= JOINT_PAD * (1 - 1e-9)
    # the statement the pad carries (module docstring): a curve of the model family under U on the band's grid is
    # under the envelope at every frequency between, here a 16x finer grid the LP never saw
    n = int(np.ceil(PER_DECADE * np.log10(5.0 * 4200.0))) + 1
    f = np.geomspace(1.0 / 4200, 5.0, n)
    band = joint_band(fit, None, f, 0.9)
    ff = np.geomspace(1.0 / 4200, 5.0, 16 * (n - 1) + 1)
    env_ff = env.psd(ff)
    covered = 0
    for w, sg, T, k in fit.bootstrap:
        m = NoiseModel(white=w, gauss_markov=((sg, T),), random_walk=k)
        if np.all(m.psd(f) <= band["upper"]):
            covered += 1
            assert np.all(m.psd(ff) <= env_ff)
    assert covered >= 0.9 * len(fit.bootstrap)
    # the LP's representation stays close to the band (the basis's shape): mean ratio within 1.1
    assert rec["mean_ratio_to_band"] < 1.1


def test_heavy_tailed_high_frequencies_do_not_set_the_band_at_low_frequencies():
    # replicates whose random walk (low frequencies) scatters lognormally and whose short GM (high frequencies) is
    # tiny in most replicates and large in a heavy tail: each frequency on its own upper tail's scale, the band at the
    # lowest frequency stays within the replicates' own spread there; a symmetric 16-84 % scale (the former band)
    # put it at exp(c s) with c set by the heavy tail, far above every replicate
    rng = np.random.default_rng(5)
    B = 400
    k = 2e-7 * np.exp(0.3 * rng.standard_normal(B))
    sg = 2e-6 * np.abs(rng.standard_t(1.5, B))
    names = ["white", "gm_sigma_1", "gm_T_1", "random_walk"]
    fit = _fit({"white": 1e-4, "gm_sigma_1": 2e-6, "gm_T_1": 0.5, "random_walk": 2e-7}, names,
               np.stack([np.full(B, 1e-4), sg, np.full(B, 0.5), k], axis=1))
    f = np.geomspace(1.0 / 4200, 5.0, 431)
    band = joint_band(fit, None, f, 0.95)
    d_lo = np.log(k**2 / 2e-7**2)  # ln S_b - ln S_hat at the lowest frequency, where the random walk is all
    assert band["upper"][0] / band["estimate"][0] <= np.exp(np.max(d_lo)) * (1 + 1e-9)
    # and the band still holds at least 95 % of whole replicate curves
    curves = np.stack([NoiseModel(white=1e-4, gauss_markov=((a, 0.5),), random_walk=b).psd(f) for a, b in zip(sg, k)])
    assert np.mean(np.all(curves <= band["upper"] * (1 + 1e-12), axis=1)) >= 0.95


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
