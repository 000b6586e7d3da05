"""Tests of imupipe.bound: the PSD-bounding linear program, the paper's hand inflation, AV checks."""

import math

import numpy as np
import pytest

from imupipe.bound import (
    BoundResult,
    bound_psd,
    check_allan_components,
    gm_bounds_gm,
    looseness,
    margin,
    paper_inflation,
)
from imupipe.models import NoiseModel
from imupipe.spectra import psd, smooth_log_bands

RATE = 1.0  # Hz, the paper's block-averaged rate
N_SAMPLES = 36000  # 10 h
WINDOW_S, STEP_S = 25200.0, 36000.0  # one 7 h Hann window per 10 h record (paper's t = 7 h, t_s = 10 h)
EULER_GAMMA = 0.5772156649015329


def periodograms(model, n_curves, rng):
    """Two-sided single-window periodograms of `n_curves` simulated 10 h records at 1 Hz."""
    from imupipe.simulate import simulate

    out = []
    for _ in range(n_curves):
        x = simulate(model, N_SAMPLES, RATE, rng)
        ds = psd(x, RATE, window_s=WINDOW_S, step_s=STEP_S)
        out.append(ds.psd.values)
    return ds.frequency.values, np.array(out), ds.edf.values


def white_periodograms(N, n_curves, rng):
    """Same for white noise of density N (u/sqrt(Hz)): samples N*sqrt(rate)*randn (no simulate needed)."""
    out = []
    for _ in range(n_curves):
        ds = psd(N * math.sqrt(RATE) * rng.standard_normal(N_SAMPLES), RATE, window_s=WINDOW_S, step_s=STEP_S)
        out.append(ds.psd.values)
    return ds.frequency.values, np.array(out), ds.edf.values


# a STIM-300-like gyro in SI (paper Table 2 spec column, K read as (deg/h)/sqrt(s): docs/method.md, section "Slip: units of K")
DEG_H = math.pi / 180 / 3600
TRUTH = NoiseModel(
    white=0.3 / 60 * math.pi / 180,  # 0.3 deg/sqrt(h)
    gauss_markov=((3.0 * DEG_H, 300.0),),
    random_walk=0.03 * DEG_H,
)
SPEC = NoiseModel(
    white=0.15 / 60 * math.pi / 180,
    gauss_markov=((1.5 * DEG_H, 1500.0),),
    random_walk=2e-2 * DEG_H,
)


@pytest.fixture(scope="module")
def gyro_curves():
    rng = np.random.default_rng(300)
    return periodograms(TRUTH, 15, rng)


@pytest.fixture(scope="module")
def gyro_bound(gyro_curves):
    f, curves, _ = gyro_curves
    return bound_psd(f, curves, SPEC, mode="raw")


class TestGaussMarkovIdentity:
    def test_condition_matches_psd_difference(self):
        # S_m - S over the common denominator is linear in (2 pi f)^2: its sign on [0, inf) is decided
        # by the two end values, sigma_m^2 T_m - sigma^2 T and sigma_m^2/T_m - sigma^2/T
        rng = np.random.default_rng(7)
        f = np.concatenate(([0.0], np.logspace(-9, 9, 4001)))
        checked = {True: 0, False: 0}
        for _ in range(400):
            sigma, T = 10 ** rng.uniform(-6, -2), 10 ** rng.uniform(0, 4)
            sigma_m, T_m = sigma * 10 ** rng.uniform(-0.5, 1.0), T * 10 ** rng.uniform(-1.5, 1.5)
            lo = sigma_m**2 * T_m / (sigma**2 * T) - 1
            hi = (sigma_m**2 / T_m) / (sigma**2 / T) - 1
            if min(abs(lo), abs(hi)) < 1e-3:  # too close to the boundary for a sampled check
                continue
            s_m = NoiseModel(gauss_markov=((sigma_m, T_m),)).psd(f)
            s = NoiseModel(gauss_markov=((sigma, T),)).psd(f)
            numeric = bool(np.all(s_m >= s * (1 - 1e-12)))
            assert gm_bounds_gm(sigma_m, T_m, sigma, T) == numeric
            checked[numeric] += 1
        assert checked[True] > 30 and checked[False] > 30

    def test_equal_processes_bound_each_other(self):
        assert gm_bounds_gm(1.0, 10.0, 1.0, 10.0)
        # same variance, shorter T: more high-frequency power but less at DC -> not a bound
        assert not gm_bounds_gm(1.0, 5.0, 1.0, 10.0)


class TestBoundPsdRaw:
    def test_bounds_every_curve_at_every_frequency(self, gyro_curves, gyro_bound):
        f, curves, _ = gyro_curves
        r = gyro_bound
        assert isinstance(r, BoundResult)
        assert r.bounded
        assert r.margin >= 1 - 1e-9
        # independent recomputation on every curve and every positive frequency
        s_m = r.model.psd(f[1:])
        assert np.all(s_m[None, :] >= curves[:, 1:] * (1 - 1e-9))
        # ... and above the spec
        assert np.all(s_m >= SPEC.psd(f[1:]) * (1 - 1e-9))
        m, label, fm = margin(r.model, f, curves)
        assert m == pytest.approx(r.margin, rel=1e-12)
        assert label == r.margin_curve and fm == r.margin_frequency

    def test_tight(self, gyro_bound):
        # the LP optimum touches the envelope somewhere (otherwise scaling down would be cheaper)
        assert min(gyro_bound.margin, gyro_bound.spec_margin) == pytest.approx(1.0, abs=1e-6)

    def test_inflation_factors(self, gyro_bound):
        r = gyro_bound
        assert r.inflation["N"] == pytest.approx(r.model.white / SPEC.white)
        assert r.inflation["K"] == pytest.approx(r.model.random_walk / SPEC.random_walk)
        assert r.inflation["sigma"] == pytest.approx(r.model.gauss_markov[0][0] / SPEC.gauss_markov[0][0])
        assert r.inflation["T"] == pytest.approx(r.model.gauss_markov[0][1] / SPEC.gauss_markov[0][1])

    def test_no_looser_than_paper_hand_inflation(self, gyro_curves, gyro_bound):
        f, curves, _ = gyro_curves
        hand = paper_inflation(f, curves, SPEC)
        assert hand.bounded
        assert hand.details["n_steps"] > 0
        lp = gyro_bound
        # same looseness measure on the same targets
        assert looseness(hand.model, f, curves, SPEC) == pytest.approx(hand.looseness, rel=1e-12)
        assert lp.looseness <= hand.looseness * (1 + 1e-9)
        # at the hand procedure's own time constant the LP is optimal among all bounds with that T
        fixed = bound_psd(f, curves, SPEC, T_grid=[hand.model.gauss_markov[0][1]], n_gm=1,
                          keep=("white", "gauss_markov", "random_walk"))
        assert fixed.looseness <= hand.looseness * (1 + 1e-9)

    def test_to_dict_is_yaml_safe(self, gyro_bound):
        import yaml

        d = yaml.safe_load(yaml.safe_dump(gyro_bound.to_dict()))
        assert d["bounded"] is True
        assert d["mode"] == "raw"
        assert d["bound"]["gauss_markov"][0]["T"] > 0
        assert set(d["inflation"]) >= {"N", "K", "sigma", "T"}

    def test_to_dict_in_spec_units(self, gyro_bound):
        # N in deg/sqrt(h): N_SI / (pi/180/60); GM sigma in deg/h: sigma_SI / (pi/180/3600). The factor here and
        # the one imupipe.units builds each carry at most 4 roundings of 2^-53, the division one more: < 2^-49
        units = {"white": "deg/sqrt(h)", "gm_sigma": "deg/h", "time": "s", "random_walk": "(deg/h)/sqrt(s)"}
        d = gyro_bound.to_dict(spec_units=units, sensor="gyro")
        deg = math.pi / 180.0
        b = d["bound_spec_units"]
        assert b["white"] == {"value": pytest.approx(gyro_bound.model.white / (deg / 60.0), rel=2.0**-49),
                              "unit": "deg/sqrt(h)"}
        s, T = gyro_bound.model.gauss_markov[0]
        assert b["gauss_markov"][0]["sigma"]["value"] == pytest.approx(s / (deg / 3600.0), rel=2.0**-49)
        assert b["gauss_markov"][0]["T"] == {"value": T, "unit": "s"}
        assert d["spec_spec_units"]["white"]["unit"] == "deg/sqrt(h)" and "unit_note" not in d

    def test_labels_from_dict(self, gyro_curves):
        f, curves, _ = gyro_curves
        named = {f"d{i // 3 + 1}/{'xyz'[i % 3]}": c for i, c in enumerate(curves)}
        r = bound_psd(f, named, SPEC, T_grid=[300.0])
        assert r.margin_curve in named


@pytest.fixture(scope="module")
def white():
    """15 records (5 datasets x 3 axes) of white noise, 10 h at 1 Hz, one 7 h Hann window each."""
    return white_periodograms(TestWhiteNoiseInflation.N, 15, np.random.default_rng(2021))


class TestWhiteNoiseInflation:
    N = 1e-3

    def test_raw_mode_follows_the_periodogram_maximum(self, white):
        # Each ordinate of a single periodogram of white noise is S * Exp(1) (chi^2_2 / 2). The bound
        # must reach the largest of n = 15 x 12600 of them, whose mean is the harmonic number
        # H_n = ln n + gamma + 1/(2n) = 12.73 (power), i.e. sqrt(12.73) = 3.57 in amplitude; the
        # maximum is Gumbel-distributed with sd pi/sqrt(6) = 1.28 (neighbouring Hann ordinates are
        # correlated, which lowers the mean slightly: 12.66 +- 1.32 over 40 simulated sets).
        f, curves, edf = white
        n = curves[:, 1:].size
        h_n = math.log(n) + EULER_GAMMA + 1 / (2 * n)
        r = bound_psd(f, curves, NoiseModel(white=self.N), dt=1.0, mode="raw", edf=edf, keep=("white",))
        assert r.bounded
        power = r.inflation["N"] ** 2
        assert power == pytest.approx(np.max(curves[:, 1:]) / self.N**2, rel=1e-9)
        assert h_n - 4.0 < power < h_n + 5.0
        assert 3.0 < r.inflation["N"] < 4.3

    def test_confidence_mode_inflates_much_less(self, white):
        f, curves, edf = white
        spec = NoiseModel(white=self.N)
        raw = bound_psd(f, curves, spec, mode="raw", edf=edf, keep=("white",))
        conf = bound_psd(f, curves, spec, mode="confidence", edf=edf, keep=("white",))
        assert conf.bounded and conf.mode == "confidence"
        assert conf.details["n_tests"] == 15 * conf.details["n_bands"]
        assert conf.inflation["N"] < 0.7 * raw.inflation["N"]
        # the statement is on band averages: single raw ordinates may exceed the bound
        assert conf.raw_margin < 1
        # letting the LP use a GM for the poorly resolved lowest bands leaves N close to the truth
        full = bound_psd(f, curves, spec, mode="confidence", edf=edf, keep=("white", "gauss_markov"))
        assert full.inflation["N"] < 1.4

    def test_per_ordinate_confidence_is_honest_but_useless(self, white):
        # a single chi^2_2 ordinate's Bonferroni upper limit is about n/(1-c) times the estimate
        f, curves, edf = white
        r = bound_psd(f, curves, NoiseModel(white=self.N), mode="confidence", edf=edf, keep=("white",),
                      bands_per_decade=None)
        assert r.inflation["N"] > 100

    def test_white_spec_gets_no_extra_components_in_raw_mode(self, white):
        f, curves, edf = white
        r = bound_psd(f, curves, NoiseModel(white=self.N), mode="raw", T_grid=np.logspace(0, 4, 9))
        assert r.components == ["white"]
        assert "not needed" in r.decisions["gauss_markov"]
        assert "not needed" in r.decisions["random_walk"]


class TestSmoothed:
    def test_bands_match_spectra(self, gyro_curves):
        from imupipe.bound.engine import _band_groups, _group_mean

        f, curves, edf = gyro_curves
        bands = smooth_log_bands(f, curves, 10, edf=edf, taper="hann")
        fp = f[1:]
        starts, counts, gedf = _band_groups(fp, 10, edf[1:], "hann", None)
        np.testing.assert_allclose(_group_mean(curves[:, 1:], starts, counts), bands.psd, rtol=1e-12)
        np.testing.assert_allclose(gedf[0], bands.edf, rtol=1e-12)
        np.testing.assert_array_equal(counts, bands.n_bins)

    def test_smoothed_bound_of_band_averages(self, gyro_curves, gyro_bound):
        f, curves, edf = gyro_curves
        r = bound_psd(f, curves, SPEC, mode="smoothed", edf=edf)
        assert r.bounded and r.margin >= 1 - 1e-9
        assert r.looseness <= gyro_bound.looseness * 1.000001 or r.model.white <= gyro_bound.model.white
        assert r.model.white < gyro_bound.model.white  # less periodogram scatter at high frequency

    def test_min_edf_merges_low_bands(self, gyro_curves):
        from imupipe.bound.engine import _band_groups

        f, _, edf = gyro_curves
        starts, counts, gedf = _band_groups(f[1:], 10, edf[1:], "hann", 20.0)
        assert np.all(gedf[0, :] >= 20.0)
        assert counts.sum() == f.size - 1


class TestComponentsAndDegenerateInputs:
    def test_curve_of_zeros_is_harmless(self, gyro_curves):
        f, curves, _ = gyro_curves
        with_zero = np.vstack([curves[:3], np.zeros_like(curves[0])])
        r = bound_psd(f, with_zero, SPEC, T_grid=[300.0])
        ref = bound_psd(f, curves[:3], SPEC, T_grid=[300.0])
        assert r.bounded
        assert r.model.white == pytest.approx(ref.model.white, rel=1e-9)

    def test_all_zero_and_no_spec(self):
        f = np.linspace(0, 0.5, 101)
        r = bound_psd(f, np.zeros((2, f.size)))
        assert r.bounded and r.model.white == 0 and r.model.gauss_markov == ()

    def test_spec_without_gm_gets_one_when_the_data_need_it(self, gyro_curves):
        f, curves, _ = gyro_curves
        spec = NoiseModel(white=SPEC.white, random_walk=SPEC.random_walk)
        r = bound_psd(f, curves, spec)
        assert r.bounded
        assert "gauss_markov" in r.components and "added" in r.decisions["gauss_markov"]
        assert r.inflation["sigma"] is None and r.inflation["T"] is None
        d = r.to_dict()
        assert d["inflation"]["sigma"] is None

    def test_keep_without_random_walk(self, gyro_curves):
        f, curves, _ = gyro_curves
        r = bound_psd(f, curves, None, keep={"kept": ["white", "gauss_markov", "flicker"]})
        assert r.components == ["white", "gauss_markov"]
        assert r.model.random_walk == 0 and r.bounded

    def test_two_gm_terms_no_looser(self, gyro_curves, gyro_bound):
        f, curves, _ = gyro_curves
        r = bound_psd(f, curves, SPEC, n_gm=2, T_grid=np.logspace(0, 4.5, 19))
        assert r.bounded
        assert r.looseness <= gyro_bound.looseness * 1.01

    def test_bad_inputs(self):
        f = np.linspace(0, 0.5, 11)
        with pytest.raises(ValueError, match="mode"):
            bound_psd(f, np.ones((1, 11)), mode="loose")
        with pytest.raises(ValueError, match="shape"):
            bound_psd(f, np.ones((1, 10)))
        with pytest.raises(ValueError, match="non-negative"):
            bound_psd(f, -np.ones((1, 11)))


class TestAllanComponents:
    TAU = np.logspace(-1, 4.5, 60)

    def test_each_component_checked(self):
        identified = NoiseModel(white=1e-4, gauss_markov=((2e-5, 200.0),), random_walk=1e-7)
        bound = NoiseModel(white=1.5e-4, gauss_markov=((4e-5, 150.0),), random_walk=1.2e-7)
        res = check_allan_components(bound, identified, self.TAU)
        assert res["white"]["passed"] and res["white"]["margin"] == pytest.approx(2.25)
        assert res["random_walk"]["passed"] and res["random_walk"]["margin"] == pytest.approx(1.44)
        assert res["gauss_markov"]["passed"]
        # GM bound in PSD implies GM bound in AV (AV is a positive-weighted integral of the PSD)
        assert gm_bounds_gm(4e-5, 150.0, 2e-5, 200.0)

    def test_gm_with_sigma_b_does_not_bound_flicker_b(self):
        # docs/method.md, section "Slip: the flicker constant and Gauss-Markov": a GM's ADEV peaks at 0.6174 sigma < 0.664 B, so sigma = B fails everywhere
        B = 1e-5
        identified = NoiseModel(white=1e-4, flicker=B)
        res = check_allan_components(NoiseModel(white=1e-4, gauss_markov=((B, 100.0),)), identified, self.TAU)
        assert res["flicker"]["passed"] is False
        assert res["flicker"]["margin"] < (0.6174 / 0.664) ** 2 * 1.001
        # over a finite tau grid a ladder of GM terms, one per decade, covers flicker
        ladder = tuple((B, T) for T in (0.03, 0.3, 3.0, 30.0, 300.0, 3000.0))
        res = check_allan_components(NoiseModel(white=1e-4, gauss_markov=ladder), identified, np.logspace(-1, 3, 30))
        assert res["flicker"]["passed"] is True

    def test_missing_random_walk_fails(self):
        res = check_allan_components(NoiseModel(white=1e-4), NoiseModel(white=1e-4, random_walk=1e-7), self.TAU)
        assert res["random_walk"]["passed"] is False and res["random_walk"]["margin"] == 0.0
        assert res["white"]["passed"] and res["white"]["margin"] == pytest.approx(1.0)


@pytest.mark.slow
class TestPaperScale:
    def test_block_averaged_with_sampled_model(self):
        # 125 Hz records decimated to 1 Hz; the bound compares with NoiseModel.psd_sampled(f, 1 s)
        from imupipe.simulate import simulate
        from imupipe.spectra import decimate

        rng = np.random.default_rng(11)
        curves = []
        for _ in range(15):
            x = simulate(TRUTH, 125 * N_SAMPLES, 125.0, rng)
            y, _ = decimate(x, 125.0, 1.0)
            ds = psd(y, 1.0, window_s=WINDOW_S, step_s=STEP_S)
            curves.append(ds.psd.values)
        f = ds.frequency.values
        r = bound_psd(f, np.array(curves), SPEC, dt=1.0)
        assert r.bounded
        s_m = r.model.psd_sampled(f[1:], 1.0)
        assert np.all(s_m >= np.array(curves)[:, 1:] * (1 - 1e-9))


def test_dominance_reduction_keeps_the_lp_optimum(rng):
    # white + GM + random-walk columns on increasing frequency (non-increasing) and a noisy periodogram:
    # the LP over the undominated rows has the optimum of the LP over all rows, and every dropped row is
    # implied by a kept one
    from scipy.optimize import linprog

    from imupipe.bound.engine import _undominated
    from imupipe.models import NoiseModel

    f = np.linspace(1e-4, 0.5, 5000)
    B = np.stack([NoiseModel(white=1.0).psd_sampled(f, 1.0), NoiseModel(gauss_markov=((1.0, 300.0),)).psd_sampled(f, 1.0),
                  NoiseModel(random_walk=1.0).psd_sampled(f, 1.0)], axis=1)
    t = (B @ np.array([1e-8, 1e-10, 1e-14])) * rng.exponential(size=f.size)
    keep = _undominated(B, t)
    assert 0 < keep.size < f.size / 10
    dropped = np.setdiff1d(np.arange(f.size), keep)
    for i in dropped[:: max(1, dropped.size // 200)]:
        assert np.any(np.all(B[keep] <= B[i], axis=1) & (t[keep] >= t[i]))
    c = B.mean(axis=0) / B.max(axis=0)
    scale = B.max(axis=0)
    full = linprog(c, A_ub=-(B / scale) / t[:, None], b_ub=-np.ones(f.size), method="highs")
    red = linprog(c, A_ub=-(B[keep] / scale) / t[keep, None], b_ub=-np.ones(keep.size), method="highs")
    assert red.fun == pytest.approx(full.fun, rel=1e-9)
    # a column that increases somewhere: no reduction
    assert _undominated(np.c_[B, f], t).size == f.size


class TestAllFrequencies:
    """The bound dominates the spec and the identified upper envelope below the lowest bin (and the asymptotes)."""

    @staticmethod
    def white_curves(N=1e-3, n=2000):
        f = np.linspace(0, 0.5, n + 1)
        return f, np.full((1, f.size), N**2)

    def test_spec_random_walk_is_never_dropped(self):
        # keep says white only (identification dropped K), the spec has K: the bound keeps K >= K_spec, and
        # its PSD is >= the spec's at 1e-7 Hz (far below the lowest bin, 2.5e-4 Hz)
        f, c = self.white_curves()
        spec = NoiseModel(white=1e-3, random_walk=1e-5)
        r = bound_psd(f, c, spec, dt=1.0, keep=("white",), span_s=4200.0)
        assert r.model.random_walk >= spec.random_walk * (1 - 1e-9)
        assert "required by the all-frequency bound" in r.decisions["random_walk"]
        assert r.model.psd(np.array([1e-7]))[0] >= spec.psd(np.array([1e-7]))[0] * (1 - 1e-9)
        assert r.bounded and r.allf_margin >= 1 - 1e-9

    def test_upper_envelope_random_walk_is_kept(self):
        f, c = self.white_curves()
        up = NoiseModel(white=1e-3, random_walk=3e-6)
        r = bound_psd(f, c, NoiseModel(white=1e-3), dt=1.0, keep=("white",), upper_model=up, span_s=4200.0)
        assert r.model.random_walk >= 3e-6 * (1 - 1e-9)
        assert r.details["all_frequency"]["K_upper"] == pytest.approx(3e-6)

    def test_low_frequency_gm_is_covered_below_the_bins(self):
        # an identified GM with T = 1e5 s (corner 1.6e-6 Hz, below the lowest bin 2.5e-4 Hz) at its upper limit:
        # only the all-frequency rows see it; they hold the bound above it down to the floor 0.01/horizon
        f, c = self.white_curves()
        spec = NoiseModel(white=1e-3)
        up = NoiseModel(white=1e-3, gauss_markov=((1e-4, 1e5),))
        r = bound_psd(f, c, spec, dt=1.0, span_s=4200.0, upper_model=up, keep=("white", "gauss_markov"))
        lo = r.details["all_frequency"]["f_floor_hz"]
        assert lo == pytest.approx(0.01 / 4200.0)
        g = np.logspace(math.log10(lo), -3, 50)
        assert np.all(r.model.psd(g) >= up.psd(g) * (1 - 1e-6))
        # without the envelope the same data give a bound far below that GM there (the rows are what holds it)
        r0 = bound_psd(f, c, spec, dt=1.0, span_s=4200.0, keep=("white", "gauss_markov"))
        assert np.min(r0.model.psd(g) / up.psd(g)) < 0.5

    def test_envelope_above_the_sampled_band(self):
        """The exported model is continuous-time: above the decimated band (f > 0.5 Hz here) only the identified
        envelope (fitted to the full-rate AV) says what is there. Data: the 1 s block means of white 6e-4 plus a GM
        (sigma 0.02, T 0.285 s, corner 0.56 Hz: the ADIS16405 gyro's shape); envelope: the same with white 7.6e-4.
        In band the GM hides the white noise, so rows up to 0.5 Hz alone let the LP trade white for GM; above
        the band the envelope's white wins. With the rows above the band and N >= N_up at f -> inf, the bound
        covers the envelope at every frequency, and the exact covariance analysis of the gyro filter against
        the envelope passes (MSE/P <= 1 + 1e-6); with rows below the band only ("below"), neither holds."""
        from imupipe.verify import covariance_analysis, reference_scenario

        f = np.linspace(0, 0.5, 201)
        truth = NoiseModel(white=6e-4, gauss_markov=((0.02, 0.285),))
        c = np.asarray(truth.psd_sampled(np.maximum(f, f[1]), 1.0))[None, :]
        up = NoiseModel(white=7.6e-4, gauss_markov=((0.02, 0.285),))
        kw = dict(dt=1.0, keep=("white", "gauss_markov"), span_s=1200.0, upper_model=up)
        r = bound_psd(f, c, None, **kw)
        r0 = bound_psd(f, c, None, upper_band="below", **kw)
        g = np.logspace(math.log10(0.5), 4, 200)
        assert r.bounded and r.model.white >= up.white * (1 - 1e-9)
        assert np.all(r.model.psd(g) >= up.psd(g) * (1 - 1e-9))
        assert r.details["all_frequency"]["N_upper"] == pytest.approx(up.white)
        assert np.min(r0.model.psd(g) / up.psd(g)) < 0.999
        sc = reference_scenario("gyro", filter_rate_hz=1.0, fix_s=600.0, outage_s=600.0)
        assert covariance_analysis(r.model, up, sc).passed
        assert not covariance_analysis(r0.model, up, sc).passed

    def test_spec_white_asymptote(self):
        # spec white noise must be met as f -> inf (a short-T GM cannot stand in for it)
        f, c = self.white_curves()
        spec = NoiseModel(white=1e-3)
        r = bound_psd(f, c, spec, dt=1.0, keep=("gauss_markov", "white"))
        assert r.model.white >= 1e-3 * (1 - 1e-9)

    def test_exclude_lists_bins_and_keeps_the_spec(self):
        f, c = self.white_curves()
        c = c.copy()
        line = (f >= 0.43) & (f <= 0.45)  # the interval is closed
        c[0, line] *= 100.0
        spec = NoiseModel(white=1e-3)
        r_keep = bound_psd(f, c, spec, dt=1.0, keep=("white",))
        r = bound_psd(f, c, spec, dt=1.0, keep=("white",), exclude=((0.43, 0.45, "aliased 0.56 Hz line"),))
        (ex,) = r.details["excluded"]
        assert ex["reason"] == "aliased 0.56 Hz line" and ex["n_bins"] == int(line.sum())
        assert r_keep.model.white == pytest.approx(10e-3, rel=1e-6)
        assert r.model.white == pytest.approx(1e-3, rel=1e-6)  # the spec still holds it up
        with pytest.raises(ValueError, match="exclude"):
            bound_psd(f, c, spec, dt=1.0, exclude=((0.5, 0.4, "x"),))

    def test_solver_prints_nothing_on_stdout(self, capfd):
        import imupipe.bound.highs as b

        b._HIGHS = None  # force the solver's creation inside this test
        f, c = self.white_curves()
        bound_psd(f, c, NoiseModel(white=1e-3), dt=1.0)
        assert capfd.readouterr().out == ""


class TestCheckAllan:
    TAU = np.logspace(0, 4, 30)

    def test_flicker_against_gm_plus_white_and_no_counterpart(self):
        from imupipe.bound import check_allan

        ident = NoiseModel(white=1e-4, flicker=1e-5)
        bound = NoiseModel(white=1.5e-4, gauss_markov=((2e-5, 100.0),), random_walk=1e-7)
        rep = check_allan(bound, ident, self.TAU, kept=["white", "flicker"])
        assert rep["components"]["white"]["status"] == "ok"
        assert rep["components"]["random_walk"]["status"] == "no counterpart"
        assert "GM + white" in rep["components"]["flicker"]["reason"]

    def test_flicker_plateau_carried_by_the_bounds_random_walk_at_long_tau(self):
        """A GM (sigma 2e-5, T 100 s) covers a flicker plateau FLICKER_AV B^2 = 4.4e-11 (B = 1e-5) up to
        tau ~ 1800 s (its AV falls as 2 sigma^2 T / tau beyond); a random walk with K^2 tau / 3 >= 4.4e-11 from
        there (K = 3e-7: 5.4e-11 at 1800 s) carries the rest. A K 300x smaller does not: a real shortfall."""
        from imupipe.bound import check_allan

        ident = NoiseModel(white=1e-4, flicker=1e-5)
        for K, status in ((3e-7, "ok"), (1e-9, "shortfall"), (0.0, "shortfall")):
            bound = NoiseModel(white=1.2e-4, gauss_markov=((2e-5, 100.0),), random_walk=K)
            rep = check_allan(bound, ident, self.TAU, kept=["white", "flicker"])
            assert rep["components"]["flicker"]["status"] == status, K
            if status == "ok":
                assert "random walk" in rep["components"]["flicker"]["reason"]
            else:
                assert rep["components"]["flicker"]["tau_s"] > 1800

    def test_dropped_component_is_not_compared_but_a_real_shortfall_is_named(self):
        from imupipe.bound import check_allan

        ident = NoiseModel(white=1e-4, random_walk=1e-6)
        bound = NoiseModel(white=1.2e-4)
        rep = check_allan(bound, ident, self.TAU, kept=["white"])  # K dropped by selection: not compared
        assert "random_walk" not in rep["components"] and rep["passed"]
        # the total check: a sample AV whose lower limit (edf 1000) lies above the bound at long tau
        av = ident.avar(self.TAU)[None, :]
        rep = check_allan(bound, ident, self.TAU, kept=["white"], sample_avar=av, sample_edf=1000.0,
                          labels=["d1/x"], span_s=1e4)
        assert not rep["passed"] and rep["total"]["curve"] == "d1/x" and rep["total"]["worst_ratio"] < 1
        assert rep["total"]["tau_s"] == pytest.approx(self.TAU[-1])
        # a sample AV 1.5x the bound's: with edf 1000 its Bonferroni lower limit (30 taus, 95 %) is ~1.25x the
        # bound's (a shortfall); with edf 2 the limit is 1.5 x 2/chi2_2(1 - 0.05/30) = 0.23x (chance, no shortfall)
        av = 1.5 * bound.avar(self.TAU)[None, :]
        rep = check_allan(bound, ident, self.TAU, kept=["white"], sample_avar=av, sample_edf=1000.0, span_s=1e4)
        assert not rep["total"]["passed"] and len(rep["total"]["shortfalls"]) == self.TAU.size
        rep = check_allan(bound, ident, self.TAU, kept=["white"], sample_avar=av, sample_edf=2.0, span_s=1e4)
        assert rep["passed"] and rep["total"]["worst_ratio"] == pytest.approx(12.82 / 2 / 1.5, rel=0.01)


    def test_total_check_restricted_to_the_application_band(self):
        """The total-AV check runs over [1/application.filter_rate_hz, span_s]: a bound too small inside that band
        fails and is named; a shortfall only at taus below one filter step is reported (outside_band) and fails
        nothing. Sample AV 1.5x the bound's with edf 1000: its Bonferroni lower limit is ~1.25x the bound's
        (test above), a shortfall wherever it is compared."""
        from imupipe.bound import check_allan

        ident = NoiseModel(white=1e-4)
        bound = NoiseModel(white=1.2e-4)
        tau = np.logspace(-2, 3, 26)  # 0.01 s .. 1000 s
        av = bound.avar(tau) * np.where(tau < 1.0, 1.5, 0.5)  # above the bound below 1 s only
        rep = check_allan(bound, ident, tau, kept=["white"], sample_avar=av[None, :], sample_edf=1000.0,
                          labels=["d1/z"], span_s=1200.0, tau_min_s=1.0)
        tot = rep["total"]
        assert rep["passed"] and tot["passed"] and tot["tau_band_s"] == [1.0, 1200.0]
        assert tot["n_compared"] == int(np.sum(tau >= 1.0 - 1e-12))
        assert tot["outside_band"]["worst_ratio"] < 1 and tot["outside_band"]["tau_s"] < 1.0
        # the same check with the band from 0.01 s (a 100 Hz filter): the short-tau shortfall fails it
        rep = check_allan(bound, ident, tau, kept=["white"], sample_avar=av[None, :], sample_edf=1000.0,
                          labels=["d1/z"], span_s=1200.0, tau_min_s=0.01)
        assert not rep["passed"] and rep["total"]["curve"] == "d1/z" and rep["total"]["tau_s"] < 1.0
        # a bound too small INSIDE the band fails whatever the band's lower end
        small = NoiseModel(white=0.5e-4)
        rep = check_allan(small, ident, tau, kept=["white"], sample_avar=bound.avar(tau)[None, :],
                          sample_edf=1000.0, labels=["d1/x"], span_s=1200.0, tau_min_s=1.0)
        assert not rep["passed"] and rep["total"]["tau_s"] >= 1.0
        assert len(rep["total"]["shortfalls"]) == rep["total"]["n_compared"]
        with pytest.raises(ValueError, match="tau band"):
            check_allan(bound, ident, tau, sample_avar=av[None, :], span_s=1.0, tau_min_s=2.0)

    def test_component_check_restricted_to_the_application_band(self):
        """Component against component over the same band as the total check. A GM's AV is about
        2 sigma^2 tau / (3 T) for tau << T and 2 sigma^2 T / tau for tau >> T, so a bound GM with the identified
        sigma but T = 100 s against the identified T = 1000 s has an AV ratio near 10 at short tau and near
        0.1 at long tau, crossing 1 at a few hundred s. Horizon 50 s: the shortfall lies outside the band,
        reported and not failed; horizon 5000 s: inside, it fails and is named with its tau."""
        from imupipe.bound import check_allan

        ident = NoiseModel(white=1e-4, gauss_markov=((1e-4, 1000.0),))
        bound = NoiseModel(white=1e-4, gauss_markov=((1e-4, 100.0),))
        tau = np.logspace(-1, 4, 26)
        rep = check_allan(bound, ident, tau, kept=["white", "gauss_markov"], span_s=50.0, tau_min_s=1.0)
        gm = rep["components"]["gauss_markov"]
        assert gm["status"] == "ok" and rep["passed"]
        assert gm["outside_band"]["margin"] < 1 and gm["outside_band"]["tau_s"] > 50.0
        rep = check_allan(bound, ident, tau, kept=["white", "gauss_markov"], span_s=5000.0, tau_min_s=1.0)
        gm = rep["components"]["gauss_markov"]
        assert gm["status"] == "shortfall" and not rep["passed"] and 50.0 < gm["tau_s"] <= 5000.0

    def test_long_gm_represented_by_the_random_walk(self):
        """An identified GM of T = 1e5 s, far beyond the band (1 .. 3600 s), rises like a random walk with
        K^2 = 2 sigma^2 / T there. A bound whose GM is short (T = 10 s) but whose random walk has exactly that
        K covers it in the AV through GM + white + random walk (2 sigma^2 tau / (3 T) <= K^2 tau / 3): ok,
        and the reason says which representation. Without the random walk, or with half that K^2, the same
        bound falls short (a real shortfall, named)."""
        from imupipe.bound import check_allan

        sigma, T = 1e-4, 1e5
        k = np.sqrt(2 * sigma**2 / T)
        ident = NoiseModel(white=1e-5, gauss_markov=((sigma, T),))
        tau = np.logspace(0, np.log10(3600.0), 20)
        kw = dict(kept=["white", "gauss_markov"], span_s=3600.0, tau_min_s=1.0)
        short = ((1e-6, 10.0),)
        rep = check_allan(NoiseModel(white=1e-5, gauss_markov=short, random_walk=k), ident, tau, **kw)
        gm = rep["components"]["gauss_markov"]
        assert gm["status"] == "ok" and "random walk" in gm["reason"] and rep["passed"]
        for rw in (0.0, k / np.sqrt(2.0) * 0.99):
            rep = check_allan(NoiseModel(white=1e-5, gauss_markov=short, random_walk=rw), ident, tau, **kw)
            assert rep["components"]["gauss_markov"]["status"] == "shortfall" and not rep["passed"]

    def test_gm_fitted_beside_lines_is_represented_by_the_line_states(self):
        """An outside evaluation's gyro: lines at 0.06 and 0.09 Hz, the fit (each line's AV known at its estimate)
        put the rest of their power into a GM of T 1.66 s whose white equivalent 2 sigma^2 T lies above the bound's
        white noise. Its numbers, rounded: the bound's white, random walk and two lines (at their upper limits)
        hold that power in the AV at every tau of the band (ok, the reason names the lines); without the line
        states the same bound falls short (a real shortfall, named), as it did before, which failed the run."""
        from imupipe.bound import check_allan

        ident = NoiseModel(white=4.33e-5, gauss_markov=((4.03e-5, 1.66),))
        lines = ((3.96e-4, 0.0601, 0.0166), (3.07e-4, 0.0900, 0.0111))
        bound = NoiseModel(white=7.05e-5, random_walk=1.9e-7, narrowband=lines)
        tau = 0.1 * 2.0 ** np.arange(14)
        kw = dict(kept=["white", "gauss_markov"], span_s=1950.0, tau_min_s=1.0)
        gm = check_allan(bound, ident, tau, **kw)["components"]["gauss_markov"]
        assert gm["status"] == "ok" and "lines" in gm["reason"], gm
        gm = check_allan(NoiseModel(white=7.05e-5, random_walk=1.9e-7), ident, tau, **kw)["components"]["gauss_markov"]
        assert gm["status"] == "shortfall" and gm["margin"] < 0.97, gm


class TestPerAxis:
    def test_per_axis_models_differ_where_the_axes_differ_and_bound_their_own_curves(self):
        """Two datasets x three axes of white noise, z with twice the density of x and y (as the ADIS16405 gyro
        z differs from x, y). Each per-axis bound covers its own two curves, the spec sheet and its envelope; z's
        N is well above x's: with 2 x 12600 ordinates per axis the largest periodogram ordinate is between 8.2
        and 17.0 times the PSD (Gumbel 0.1 % and 99.9 % points of the largest of 2.5e4 unit exponentials), so
        N_z/N_x >= 2 sqrt(8.2/17.0) = 1.39 except with probability ~2e-3; x's model does not cover z's curves
        (the per-axis models are specific); the global bound covers every curve."""
        from imupipe.bound import bound_by_axis, curves_by_axis

        rng = np.random.default_rng(17)
        dens = {"x": 1e-3, "y": 1e-3, "z": 2e-3}
        curves = {}
        for d in ("d1", "d2"):
            for ax, N in dens.items():
                f, c, edf = white_periodograms(N, 1, rng)
                curves[f"{d}/{ax}"] = c[0]
        assert curves_by_axis(curves) == {ax: [f"d1/{ax}", f"d2/{ax}"] for ax in dens}
        spec = NoiseModel(white=0.5e-3)
        ups = {ax: NoiseModel(white=N) for ax, N in dens.items()}
        per = bound_by_axis(f, curves, spec, upper_models=ups, edf={k: edf for k in curves}, dt=1.0,
                            keep=("white",), span_s=4200.0)
        assert list(per) == ["x", "y", "z"]
        for ax, (labels, res) in per.items():
            assert labels == [f"d1/{ax}", f"d2/{ax}"]
            assert res.bounded and res.allf_margin >= 1 - 1e-9
            assert margin(res.model, f, np.array([curves[k] for k in labels]), dt=1.0)[0] >= 1 - 1e-9
            assert res.model.white >= max(spec.white, ups[ax].white) * (1 - 1e-9)
        assert per["z"][1].model.white / per["x"][1].model.white > 1.39
        assert margin(per["x"][1].model, f, np.array([curves["d1/z"], curves["d2/z"]]), dt=1.0)[0] < 1
        glob = bound_psd(f, np.array(list(curves.values())), spec, dt=1.0, keep=("white",), span_s=4200.0)
        assert glob.model.white == pytest.approx(max(r.model.white for _, r in per.values()), rel=1e-6)
        with pytest.raises(ValueError, match="dataset/axis"):
            curves_by_axis(["no-axis"])


class TestNarrowband:
    def test_line_column_closed_forms(self):
        from imupipe.bound.engine import _line_psd, _line_psd_sampled

        # variance: the two-sided PSD integrates to 1 (unit-variance column), checked by quadrature
        f = np.linspace(-20.0, 20.0, 400_001)  # 1e-4 Hz steps: 1/10 of the line width 2 zeta f0
        assert np.trapezoid(_line_psd(f, 0.56, 0.02), f) == pytest.approx(1.0, rel=2e-3)
        # block means: the sampled PSD integrates over one period to the variance of the block means, which is
        # below 1 by the sinc^2 weighting; for a line far below 1/dt it is ~ sinc^2(f0 dt)
        g = np.linspace(-0.5, 0.5, 8001)  # 1.25e-4 Hz steps: 1/8 of the line width 2 zeta f0 = 1e-3 Hz
        v = np.trapezoid(_line_psd_sampled(g, 0.01, 0.05, 1.0), g)
        assert v == pytest.approx(np.sinc(0.01) ** 2, rel=2e-3)

    def test_line_variance_is_an_lp_variable_and_excluded_bins_listed(self):
        from imupipe.bound.engine import _line_psd_sampled

        f = np.linspace(0, 0.5, 4001)
        N = 1e-3
        line = 3e-3**2 * _line_psd_sampled(f, 0.56, 0.01, 1.0)  # aliased to 0.44 Hz at dt = 1 s
        curves = (N**2 + line)[None, :]
        spec = NoiseModel(white=N)
        plain = bound_psd(f, curves, spec, dt=1.0, keep=("white",))
        r = bound_psd(f, curves, spec, dt=1.0, keep=("white",), narrowband=((0.56, 0.01),))
        assert plain.model.white > 5 * N  # white noise inflated to cover the line
        assert r.model.white == pytest.approx(N, rel=1e-6)  # the line column carries it instead
        (nb,) = r.details["narrowband"]
        assert nb["sigma"] == pytest.approx(3e-3, rel=1e-3) and nb["f0_hz"] == 0.56
        assert r.bounded
        with pytest.raises(ValueError, match="zeta"):
            bound_psd(f, curves, spec, dt=1.0, narrowband=((0.56, 1.5),))


def test_exclude_in_band_modes_drops_exactly_the_interval_bins():
    """Smoothed and confidence modes split their log bands at the exclusion's edges: the bins outside the interval
    keep constraining the bound (a spike just outside the interval still lifts it)."""
    f = np.linspace(0, 0.5, 1801)
    N = 1e-3
    curves = np.full((1, f.size), N**2)
    i_line, i_spike = 1585, 1560  # a line inside (0.44 Hz) and a spike outside (0.433 Hz) the interval
    curves[0, i_line] = 100 * N**2
    curves[0, i_spike] = 4 * N**2
    lo, hi = 0.438, 0.442
    inside = [float(v) for v in f[(f >= lo) & (f <= hi)]]
    for mode in ("raw", "smoothed", "confidence"):
        r = bound_psd(f, curves, NoiseModel(white=N), dt=1.0, mode=mode, keep=("white",),
                      exclude=((lo, hi, "test"),))
        (ex,) = r.details["excluded"]
        assert ex["bins_hz"] == inside, mode
        assert r.bounded
        if mode == "raw":  # the spike outside the interval still sets N (4x in power)
            assert r.model.white == pytest.approx(2 * N, rel=1e-6)
        # the excluded bins have no influence at all: the same bound with the line's bins at the floor
        flat = curves.copy()
        flat[0, (f >= lo) & (f <= hi)] = N**2
        r2 = bound_psd(f, flat, NoiseModel(white=N), dt=1.0, mode=mode, keep=("white",), exclude=((lo, hi, "test"),))
        assert r2.model.white == r.model.white, mode
        # and without the exclusion the line lifts the bound: raw to its own 10 N; in band modes the line's 99 N^2
        # excess spread over the ~370 bins of its 0.4-0.5 Hz band lifts the band mean by ~1.27 in power
        # (confidence mode: the split bands have fewer degrees of freedom and there are more of them, so their
        # upper limits rise; measured 0.7 % above the unexcluded bound here: exclusion is not free there)
        if mode != "confidence":
            r3 = bound_psd(f, curves, NoiseModel(white=N), dt=1.0, mode=mode, keep=("white",))
            assert r3.model.white > 1.1 * r.model.white, mode


class TestRandomWalkCap:
    """imupipe.bound.random_walk_cap: the largest K the recorded Allan variances allow (model-free)."""

    def test_pure_random_walk_cap_is_just_above_k(self):
        from scipy.stats import chi2

        from imupipe.bound import random_walk_cap

        tau = np.array([1.0, 10.0, 100.0, 1000.0])
        K = 1e-3
        edf = np.array([1e5, 1e4, 1e3, 100.0])
        cap = random_walk_cap([(tau, K**2 * tau / 3.0, edf)], confidence=0.95)
        # AV = K^2 tau / 3 exactly: the cap is K sqrt(edf / chi2_edf(alpha')) at the tau whose limit is
        # tightest, alpha' = 0.05 / 4; it can only be above K, and at most the loosest of the four factors
        factors = np.sqrt(edf / chi2.ppf(0.05 / 4, edf))
        assert K < cap <= K * factors.max() * (1 + 1e-12)
        assert cap == pytest.approx(K * factors.min(), rel=1e-9)

    def test_cap_covers_every_curve_and_ignores_nan(self):
        from imupipe.bound import random_walk_cap

        tau = np.array([1.0, 10.0, 100.0])
        edf = np.full(3, 1e4)
        small = random_walk_cap([(tau, 1e-8 * tau / 3.0, edf)])
        big = random_walk_cap([(tau, 1e-6 * tau / 3.0, edf)])
        both = random_walk_cap([(tau, 1e-8 * tau / 3.0, edf), (tau, np.r_[1e-6 * tau[:2] / 3.0, np.nan], edf)])
        assert both == pytest.approx(big, rel=2e-2) and both > small  # the envelope must cover each curve
        assert random_walk_cap([]) == np.inf

    def test_envelope_random_walk_capped_but_not_below_the_estimate(self):
        from types import SimpleNamespace

        from imupipe.bound import upper_envelope

        fit = SimpleNamespace(params={"white": 1e-3, "random_walk": 2e-5}, intervals={"random_walk": (0.0, 1.0)},
                              random_walk_profile={"upper": 5.0})
        assert upper_envelope(fit, ["white", "random_walk"]).random_walk == 5.0
        assert upper_envelope(fit, ["white", "random_walk"], random_walk_cap=1e-4).random_walk == 1e-4
        assert upper_envelope(fit, ["white", "random_walk"], random_walk_cap=1e-6).random_walk == 2e-5

    def test_a_fitted_ramp_is_carried_as_a_random_walk_over_the_window(self):
        """A rate ramp the fit gives power to (its estimate above 0) enters the envelope's K as the random walk whose
        Allan variance dominates the ramp's (at its upper limit) at every tau up to the window, and whose outage error
        dominates the ramp's drift: K_R^2 tau / 3 >= R^2 tau^2 / 2 and K_R^2 t^3 / 3 >= (R t^2 / 2)^2 for t <= h;
        a ramp fitted as zero changes nothing (a 2 h record whose K went to a ramp: a per-axis model under-stated
        its axis's error 2.03x)."""
        from types import SimpleNamespace

        from imupipe.bound import upper_envelope
        from imupipe.bound.allan_check import ramp_random_walk
        from imupipe.models import NoiseModel

        h, R_up = 2400.0, 3.0e-8
        fit = SimpleNamespace(params={"white": 1e-4, "random_walk": 0.0, "ramp": 2.8e-8},
                              intervals={"random_walk": (0.0, 5.5e-7), "ramp": (2.3e-8, R_up)})
        env = upper_envelope(fit, ["white", "ramp"], span_s=h)
        K_R = ramp_random_walk(R_up, h)
        assert env.random_walk == pytest.approx(math.hypot(5.5e-7, K_R), rel=1e-12)
        tau = np.geomspace(1.0, h, 200)
        assert np.all(NoiseModel(random_walk=K_R).avar(tau) >= (R_up * tau) ** 2 / 2.0 * (1 - 1e-12))
        assert np.all(K_R**2 * tau**3 / 3.0 >= (R_up * tau**2 / 2.0) ** 2)
        zero = SimpleNamespace(params={**fit.params, "ramp": 0.0}, intervals=fit.intervals)
        assert upper_envelope(zero, ["white"], span_s=h).random_walk == 5.5e-7
        assert upper_envelope(fit, ["white", "ramp"]).random_walk == 5.5e-7  # no window: nothing to cover
        assert ramp_random_walk(0.0, h) == 0.0 and ramp_random_walk(R_up, None) == 0.0


class TestUpperEnvelopeOpenInterval:
    """imupipe.bound.upper_envelope where the data leave a GM time constant's interval open (one-sided): the
    envelope must dominate, in two-sided PSD, every GM of the box sigma <= sigma_up, T in the interval, not the
    estimate's GM (docs/method.md, section "The upper envelope")."""

    @staticmethod
    def shortfall(env, s, T, f, white=0.0):
        """Smallest ratio envelope PSD / (white^2 + GM PSD) over the (T, f) grid: the envelope must cover the
        identified white noise at its upper end and, on top of it, any GM of the box (two-sided:
        2 s^2 T / (1 + (2 pi f T)^2))."""
        w = 2.0 * np.pi * np.asarray(f)[None, :]
        Tc = np.asarray(T)[:, None]
        gm = 2.0 * s * s * Tc / (1.0 + (w * Tc) ** 2)
        return float(np.min(np.asarray(env.psd(f))[None, :] / (white**2 + gm)))

    def test_open_upper_end_dominated_from_one_over_horizon(self):
        from types import SimpleNamespace

        from imupipe.bound import upper_envelope

        H, s = 3600.0, 3e-4
        fit = SimpleNamespace(params={"white": 1e-3, "gm_sigma_1": 2e-4, "gm_T_1": 50.0},
                              intervals={"white": (0.9e-3, 1.1e-3), "gm_sigma_1": (1e-4, s),
                                         "gm_T_1": (20.0, math.inf)},
                              T_grid=np.logspace(-2, 2, 33))
        # the single box GM (max_box_ratio = inf; by default a box of ratio > 10 is split, checked below)
        env = upper_envelope(fit, ["white", "gauss_markov"], span_s=H, max_box_ratio=math.inf)
        # closed at c = max(100 s searched, H / (2 pi) = 573 s): T_m = sqrt(20 c), sigma_m = s (c / 20)^(1/4)
        c = H / (2.0 * np.pi)
        ((s_m, T_m),) = env.gauss_markov
        assert T_m == pytest.approx(math.sqrt(20.0 * c), rel=1e-14)
        assert s_m == pytest.approx(s * (c / 20.0) ** 0.25, rel=1e-14)
        f = np.logspace(math.log10(1.0 / H), 3, 400)
        T = np.logspace(math.log10(20.0), math.log10(1e3 * H), 400)
        # dominance is exact (monotonicity in T beyond c); 1e-12: float rounding of the PSDs
        assert self.shortfall(env, s, T, f, white=1.1e-3) >= 1 - 1e-12
        # the old rule (the box closed at the estimate, T <= 50 s) misses the long-T GMs
        old = NoiseModel(white=1.1e-3, gauss_markov=((s * (50.0 / 20.0) ** 0.25, math.sqrt(20.0 * 50.0)),))
        assert self.shortfall(old, s, T, f, white=1.1e-3) < 0.5
        # c = H / (2 pi) is the least that reaches down to 1 / H: at f = 0.5 / H the GM with T = 1/(2 pi f) = 2 c
        # has PSD s^2/(2 pi f) = 2 s^2 c, above the box's 2 s^2 c / (1 + (2 pi f)^2 20 c)
        assert self.shortfall(env, s, T, np.array([0.5 / H]), white=1.1e-3) < 1.0
        # without a horizon: c = the longest T searched, dominated from 1/(2 pi 100 s) on only
        split = upper_envelope(fit, ["white", "gauss_markov"], span_s=H)
        assert len(split.gauss_markov) == 2  # c / 20 s = 28.6: two sub-boxes of ratio 5.3
        assert self.shortfall(split, s, T, f, white=1.1e-3) >= 1 - 1e-12
        env0 = upper_envelope(fit, ["white", "gauss_markov"], max_box_ratio=math.inf)
        assert env0.gauss_markov[0][1] == pytest.approx(math.sqrt(20.0 * 100.0), rel=1e-14)
        f0 = np.logspace(math.log10(1 / (2 * np.pi * 100.0)), 3, 200)
        assert self.shortfall(env0, s, T, f0, white=1.1e-3) >= 1 - 1e-12
        assert self.shortfall(env0, s, T, f, white=1.1e-3) < 1.0

    def test_open_lower_end_covered_by_white_noise(self):
        from types import SimpleNamespace

        from imupipe.bound import SHORT_T_WHITE_FACTOR, upper_envelope

        # the ADIS16405 accelerometer's shape: T at the shortest T searched (0.01 s), interval (0, 0.0133] s
        s, a, N_up = 0.0224, 0.01, 3.45e-3
        fit = SimpleNamespace(params={"white": 3.1e-3, "gm_sigma_1": 0.0223, "gm_T_1": a},
                              intervals={"white": (3.09e-3, N_up), "gm_sigma_1": (0.0221, s),
                                         "gm_T_1": (0.0, 0.0133)},
                              T_grid=np.logspace(-2, 2.8, 40))
        env = upper_envelope(fit, ["white", "gauss_markov"], span_s=1200.0)
        ((s_m, T_m),) = env.gauss_markov
        assert T_m == pytest.approx(math.sqrt(a * 0.0133), rel=1e-14)
        assert env.white**2 - N_up**2 == pytest.approx(SHORT_T_WHITE_FACTOR * s * s * a, rel=1e-9)
        f = np.logspace(-4, 6, 600)
        T = np.logspace(-9, math.log10(0.0133), 500)
        assert self.shortfall(env, s, T, f, white=N_up) >= 1 - 1e-12
        # the old rule (no white addition, the box [0.01, 0.0133]) misses the shorter T above 1/(2 pi a) = 16 Hz
        old = NoiseModel(white=N_up, gauss_markov=env.gauss_markov)
        assert self.shortfall(old, s, T, f, white=N_up) < 1.0
        # kappa is the least white addition for the interval (0, a]: 0.99 kappa falls short
        env1 = upper_envelope(SimpleNamespace(params={"gm_sigma_1": s, "gm_T_1": a}, intervals={"gm_T_1": (0.0, a)},
                                              T_grid=np.array([a, 1.0])), ["gauss_markov"])
        assert env1.white**2 == pytest.approx(SHORT_T_WHITE_FACTOR * s * s * a, rel=1e-12)
        T1, f1 = np.logspace(-9, math.log10(a), 500), np.logspace(0, 4, 4001)
        assert self.shortfall(env1, s, T1, f1) >= 1 - 1e-12
        short = NoiseModel(white=math.sqrt(0.99) * env1.white, gauss_markov=env1.gauss_markov)
        assert self.shortfall(short, s, T1, f1) < 1.0

    def test_short_t_white_factor_closed_form(self):
        from imupipe.bound import SHORT_T_WHITE_FACTOR

        u = np.logspace(0, 4, 400001)
        assert SHORT_T_WHITE_FACTOR == pytest.approx(np.max(1 / u - 2 / (1 + u * u)), rel=1e-9)
        assert 1 / 8 < SHORT_T_WHITE_FACTOR < 1 / 4  # between the large-u asymptote and the cruder bound

    def test_rebuilt_from_an_identify_file_with_an_open_end(self):
        from types import SimpleNamespace

        from imupipe.bound import upper_envelope, upper_envelope_from_identification

        sel = {"params": {"white": 1e-3, "gm_sigma_1": 2e-4, "gm_T_1": 50.0},
               "intervals": {"white": [0.9e-3, 1.1e-3], "gm_sigma_1": [1e-4, 3e-4], "gm_T_1": [20.0, None]},
               "T_search_s": [0.01, 100.0]}
        ident = {"fit": {"params": {"white": 5.0}, "selected": sel}, "selection": {"kept": ["white", "gauss_markov"]},
                 "upper_envelope_horizon_s": 1200.0}
        view = SimpleNamespace(params=sel["params"], intervals={"white": (0.9e-3, 1.1e-3), "gm_sigma_1": (1e-4, 3e-4),
                                                                "gm_T_1": (20.0, math.inf)},
                               T_grid=np.array([0.01, 100.0]))
        # the selected refit's, its open upper end (null in YAML) read as inf, the file's horizon
        assert upper_envelope_from_identification(ident) == upper_envelope(view, ["white", "gauss_markov"],
                                                                           span_s=1200.0)
        assert upper_envelope_from_identification(ident).gauss_markov[0][1] == pytest.approx(
            math.sqrt(20.0 * 1200.0 / (2 * np.pi)), rel=1e-14)


class TestSplitGmBox:
    """imupipe.bound.split_gm_box: a GM box of several decades in T as a sum of GM terms over sub-boxes."""

    @staticmethod
    def gm_psd(s, T, f):
        w = 2.0 * np.pi * np.asarray(f)
        return 2.0 * s * s * T / (1.0 + (w * T) ** 2)

    def test_sum_dominates_every_gm_of_the_box_and_is_far_below_the_single_gm(self):
        from imupipe.bound import gm_box_envelope, split_gm_box

        # an outside tester's gyro: sigma <= 2.68e-6 rad/s, T open from 0.01 s to 1310 s (5.1 decades)
        s, a, c = 2.68e-6, 0.01, 1310.0
        s_m, T_m, W, _, _ = gm_box_envelope(s, math.sqrt(a * c), a, c)
        terms = split_gm_box(s, a, c)
        assert len(terms) == 6  # ceil(log10(1.31e5)) sub-boxes of ratio 1.31e5^(1/6) = 7.1
        assert terms[0][1] > a and terms[-1][1] < c and all(t1[1] < t2[1] for t1, t2 in zip(terms, terms[1:]))
        f = np.logspace(-7, 4, 700)
        env = sum(self.gm_psd(sj, Tj, f) for sj, Tj in terms)
        T = np.logspace(math.log10(a), math.log10(c), 700)[:, None]
        # every GM of the box, exactly (closed-box rule per sub-box); 1e-12: float rounding
        assert np.min(env[None, :] / self.gm_psd(s, T, f[None, :])) >= 1 - 1e-12
        single = self.gm_psd(s_m, T_m, f)
        # at most r / (r - 1) above the single GM anywhere (r = 7.1: 1.16) and far below it in between
        r = (c / a) ** (1 / 6)
        assert np.max(env / single) <= r / (r - 1) * (1 + 1e-12)
        assert np.min(env / single) < 0.05
        # the check can fail: a sub-box too few (the last dropped) leaves the longest T uncovered
        short = sum(self.gm_psd(sj, Tj, f) for sj, Tj in terms[:-1])
        assert np.min(short[None, :] / self.gm_psd(s, T, f[None, :])) < 1.0

    def test_narrow_box_is_the_single_gm(self):
        from imupipe.bound import gm_box_envelope, split_gm_box

        s_m, T_m, *_ = gm_box_envelope(3e-4, 50.0, 20.0, 150.0)
        assert split_gm_box(3e-4, 20.0, 150.0) == ((s_m, T_m),)
