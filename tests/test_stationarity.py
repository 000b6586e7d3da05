"""Tests of imupipe.stationarity: the paper's Levene + KS test and its calibrated versions.

Rejection rates are checked against binomial tolerances (4 standard deviations) over simulated
records; every simulation has a fixed seed. The null records come from a small local generator
(exact AR(1) Gauss-Markov + white noise) so the tests do not depend on imupipe.simulate; one test
uses imupipe.simulate with a NoiseModel when it is importable.
"""

import math

import numpy as np
import pytest
import scipy.stats
from scipy.signal import lfilter

from imupipe import stationarity
from imupipe.stationarity import (
    _null_statistics,
    bootstrap_stationarity,
    calibrated_stationarity,
    ks_statistics,
    levene_statistic,
    stationarity_tests,
)


def white_plus_gm(white_std, gm_sigma, gm_T, dt=1.0):
    """Null-record generator gen(n, rng): white noise + first-order GM started at steady state.

    Exact discretisation: phi = exp(-dt/T), driving std sigma * sqrt(1 - phi^2) (docs/method.md, section "Slip: discrete driving noise").
    """
    phi = math.exp(-dt / gm_T)
    q = gm_sigma * math.sqrt(1.0 - phi**2)

    def gen(n, rng):
        drive = q * rng.standard_normal(n)
        drive[0] = gm_sigma * rng.standard_normal()
        return lfilter([1.0], [1.0, -phi], drive) + white_std * rng.standard_normal(n)

    return gen


def binomial_band(p, n, k=4.0):
    sd = math.sqrt(p * (1 - p) / n)
    return p - k * sd, p + k * sd


# ---------------------------------------------------------------------------------------------
class TestStatistics:
    @pytest.mark.parametrize("k", [2, 3, 5])
    def test_levene_equals_scipy(self, k, rng):
        segs = rng.standard_normal((k, 301)) * np.linspace(1, 1.3, k)[:, None]
        expected = scipy.stats.levene(*segs, center="median").statistic
        assert levene_statistic(segs) == pytest.approx(expected, rel=1e-12)

    def test_levene_vectorised(self, rng):
        segs = rng.standard_normal((4, 3, 100))
        np.testing.assert_allclose(levene_statistic(segs), [levene_statistic(s) for s in segs], rtol=1e-14)

    @pytest.mark.parametrize("quantised", [False, True])
    def test_ks_equals_scipy(self, quantised, rng):
        # quantised data (an ADIS-like LSB) produce ties: D is read at the end of each tie run
        segs = rng.standard_normal((3, 500))
        if quantised:
            segs = np.round(segs * 3) / 3
        segs[1] += 0.1
        expected = [scipy.stats.ks_2samp(segs[i], segs[i + 1]).statistic for i in range(2)]
        np.testing.assert_allclose(ks_statistics(segs), expected, rtol=1e-12)
        np.testing.assert_allclose(ks_statistics(segs[None])[0], expected, rtol=1e-12)

    def test_ks_hand_example(self):
        # F1 - F2 after {1, 2}: 1, after 3: 1/3 ... -> D = 2/3 at x = 2
        segs = np.array([[1.0, 2.0, 5.0], [3.0, 4.0, 6.0]])
        assert ks_statistics(segs)[0] == pytest.approx(2 / 3)
        assert ks_statistics(np.ones((2, 5)))[0] == 0.0

    @pytest.mark.parametrize("backend", ["numpy", pytest.param("c", marks=pytest.mark.skipif(
        stationarity._kernels is None, reason="imupipe._kernels not built"))])
    @pytest.mark.parametrize("k, m, quantised", [(2, 301, False), (2, 300, True), (3, 17, False), (4, 250, True)])
    def test_null_statistics_equal_scipy(self, backend, k, m, quantised, rng):
        """(W, max D) of the Monte Carlo null, per record, against scipy.stats on the unsorted segments; two
        extra samples per record are dropped as in the test. D is a ratio of integer counts: exact. W differs
        from scipy's only by summation order: each segment mean of m |deviations| carries a relative error
        below m u, and the between-segment sum magnifies it by sum(zbar_i^2) / sum((zbar_i - zbar)^2)."""
        scale = np.r_[np.repeat(np.linspace(1.0, 1.2, k), m), 1.0, 1.0]
        records = rng.standard_normal((6, k * m + 2)) * scale
        if quantised:  # an LSB of a third of the noise: many ties
            records = np.round(records * 3) / 3
        expect_w, expect_d, bound = [], [], []
        for r in records:
            segs = r[: k * m].reshape(k, m)
            expect_w.append(scipy.stats.levene(*segs, center="median").statistic)
            expect_d.append(max(scipy.stats.ks_2samp(segs[i], segs[i + 1]).statistic for i in range(k - 1)))
            zi = np.abs(segs - np.median(segs, axis=1, keepdims=True)).mean(axis=1)
            bound.append(8 * k * m * 2.0**-53 * np.sum(zi**2) / np.sum((zi - zi.mean()) ** 2))
        w, d = _null_statistics(records.copy(), k, m, backend=backend)
        np.testing.assert_array_equal(d, expect_d)
        assert np.all(np.abs(w / np.array(expect_w) - 1) <= np.array(bound))

    def test_null_statistics_degenerate_and_signed_zeros(self, rng):
        records = rng.standard_normal((3, 41))
        before = records.copy()
        _null_statistics(records, 2, 20)
        assert np.array_equal(records, before)  # the input is left alone
        # no spread about the medians anywhere: W = 0 (equal spreads), D = 0 or 1 by level; no spread within
        # the segments' |deviations| but different deviations: W = inf; -0.0 and 0.0 are one value (a tie)
        flat = np.array([[1.0] * 8, [1.0] * 4 + [2.0] * 4, [1.0] * 4 + [0.0, 2.0, 0.0, 2.0],
                         [-0.0, 0.0, -0.0, 0.0, 0.0, -0.0, 0.0, 0.0]])
        for backend in ["numpy"] + (["c"] if stationarity._kernels is not None else []):
            w, d = _null_statistics(flat, 2, 4, backend=backend)
            assert w.tolist() == [0.0, 0.0, np.inf, 0.0] and d.tolist() == [0.0, 1.0, 0.5, 0.0]

    @pytest.mark.skipif(stationarity._kernels is None, reason="imupipe._kernels not built")
    def test_segment_kernel_rejects_bad_buffers(self):
        kern = stationarity._kernels
        x, w, d = np.zeros(12), np.zeros(2), np.zeros(2)
        with pytest.raises(ValueError, match="len\\(x\\) == len\\(w\\) \\* n"):
            kern.segment_stats(x, 5, 2, 2, w, d)
        with pytest.raises(ValueError, match="k \\* m <= n"):
            kern.segment_stats(x, 6, 2, 4, w, d)
        with pytest.raises(ValueError, match="k >= 2"):
            kern.segment_stats(x, 6, 1, 6, w, d)
        with pytest.raises(TypeError, match="float64"):
            kern.segment_stats(x.astype(np.float32), 6, 2, 3, w, d)


# ---------------------------------------------------------------------------------------------
class TestPaperTest:
    def test_output_is_plain_python(self, rng):
        res = stationarity_tests(rng.standard_normal(1001), n_segments=3)
        assert res["segment_length"] == 333 and res["n_dropped"] == 2
        assert res["ks_pairs"] == [[0, 1], [1, 2]]
        assert res["ks_alpha"] == pytest.approx(0.025)

        def plain(v):
            if isinstance(v, dict):
                return all(plain(u) for u in v.values())
            if isinstance(v, list):
                return all(plain(u) for u in v)
            return type(v) in (int, float, bool, str)

        assert plain(res)
        yaml = pytest.importorskip("yaml")
        assert yaml.safe_load(yaml.safe_dump(res)) == res

    def test_matches_scipy_on_halves(self, rng):
        x = rng.standard_normal(2000)
        res = stationarity_tests(x)
        lev = scipy.stats.levene(x[:1000], x[1000:], center="median")
        ks = scipy.stats.ks_2samp(x[:1000], x[1000:])
        assert res["levene_p"] == lev.pvalue and res["ks_p"] == [ks.pvalue]
        assert res["stationary"] == (lev.pvalue > 0.05 and ks.pvalue > 0.05)

    def test_white_noise_passes_at_nominal_rate(self, rng):
        # iid data: each test rejects with probability 0.05; the AND verdict with prob.
        # 1 - 0.95^2 = 0.0975 (the two tests are nearly independent). 300 records.
        rejected = [not stationarity_tests(rng.standard_normal(1000))["stationary"] for _ in range(300)]
        lo, hi = binomial_band(1 - 0.95**2, 300)
        assert lo < np.mean(rejected) < hi

    def test_variance_step_fails(self, rng):
        x = rng.standard_normal(4000)
        x[2000:] *= 1.3
        res = stationarity_tests(x)
        assert not res["stationary"] and not res["levene_pass"]

    def test_mean_step_fails_in_the_right_pair(self, rng):
        x = rng.standard_normal(3000)
        x[2000:] += 0.5
        res = stationarity_tests(x, n_segments=3)
        assert not res["stationary"]
        assert res["ks_p"][1] < 1e-6 and res["ks_p"][0] > 1e-3  # the step is between segments 1 and 2

    def test_errors(self, rng):
        with pytest.raises(ValueError, match="n_segments"):
            stationarity_tests(rng.standard_normal(100), n_segments=1)
        with pytest.raises(ValueError, match="alpha"):
            stationarity_tests(rng.standard_normal(100), alpha=0.0)
        with pytest.raises(ValueError, match="too short"):
            stationarity_tests(np.zeros(5), n_segments=2)
        with pytest.raises(ValueError, match="NaN or inf"):
            stationarity_tests(np.array([1.0, np.nan, 2.0, 3.0, 4.0, 5.0, 6.0]))

    def test_constant_record(self):
        with pytest.warns(UserWarning, match="constant record"):
            res = stationarity_tests(np.full(100, 9.81))
        assert res["levene_p"] == 1.0 and res["ks_p"] == [1.0] and res["stationary"]


# ---------------------------------------------------------------------------------------------
class TestCalibrated:
    def test_correlated_noise_paper_rejects_calibrated_does_not(self, rng):
        # docs/method.md, section "Stationarity": on stationary white + GM noise at 1 Hz the paper's KS on halves
        # rejects far more often than 5 % (serially correlated samples), the calibrated test
        # ~5 %. 100 records of 2000 s (GM sigma = white std, T = 50 s), 39 null draws each
        # ((39 + 1) * 0.05 = 2: an exact-level Monte Carlo test). Binomial sd at 5 %: 2.2 %.
        gen = white_plus_gm(1.0, 1.0, 50.0)
        paper_ks, paper, calibrated = [], [], []
        for _ in range(100):
            x = gen(2000, rng)
            res = calibrated_stationarity(x, 1.0, gen, n_sim=39, rng=rng)
            paper_ks.append(not res["paper"]["ks_pass"])
            paper.append(not res["paper"]["stationary"])
            calibrated.append(not res["stationary"])
        assert np.mean(paper_ks) > 0.5 and np.mean(paper) > 0.5
        lo, hi = binomial_band(0.05, 100)
        assert max(lo, 0.0) <= np.mean(calibrated) < hi

    def test_variance_step_fails(self, rng):
        gen = white_plus_gm(1.0, 0.5, 20.0)
        x = gen(4000, rng)
        x[2000:] *= 1.5
        res = calibrated_stationarity(x, 1.0, gen, n_sim=99, rng=rng)
        assert not res["stationary"]
        assert res["levene_p"] == pytest.approx(0.01) and res["p_value"] <= 0.02

    def test_p_value_formula_and_output(self, rng):
        # a null that can never reach the observed statistics: p = 1/(1 + n_sim)
        x = np.concatenate([rng.standard_normal(500), 10 + 5 * rng.standard_normal(500)])
        res = calibrated_stationarity(x, 2.0, lambda n, g: g.standard_normal(n), n_sim=19, rng=1, n_sim_max=None)
        assert res["levene_p"] == res["ks_p"] == res["p_value"] == pytest.approx(1 / 20)
        assert res["rate_hz"] == 2.0 and res["n_sim"] == 19 and not res["extended"]
        assert res["paper"]["stationary"] is False
        yaml = pytest.importorskip("yaml")
        assert yaml.safe_load(yaml.safe_dump(res)) == res

    def test_early_stop_keeps_the_full_verdict(self, rng):
        # Same null draws (a callable null draws record by record from the same generator): the verdict with
        # stop_early must equal the full n_sim test's on every record -- it is a certainty, not a statistical
        # statement -- and stationary records stop early. A variance step makes some records non-stationary.
        gen = white_plus_gm(1.0, 1.0, 30.0)
        runs = []
        for i in range(40):
            x = gen(2000, rng)
            if i % 4 == 0:
                x[1000:] *= 1.3
            full = calibrated_stationarity(x, 1.0, gen, n_sim=39, rng=i, stop_early=False, n_sim_max=None)
            fast = calibrated_stationarity(x, 1.0, gen, n_sim=39, rng=i, stop_early=True, n_sim_max=None)
            assert fast["stationary"] == full["stationary"]
            assert full["n_sim_run"] == 39 and not full["stopped_early"]
            # the lemma the stopping rule rests on: the calibrated p-value is at least the observed min-p
            assert full["p_value"] >= min(full["levene_p"], full["ks_p"])
            runs.append(fast["n_sim_run"])
            if fast["stopped_early"]:
                assert fast["stationary"]
        assert np.median(runs) < 39

    def test_reproducible_with_seed(self, rng):
        gen = white_plus_gm(1.0, 1.0, 30.0)
        x = gen(1000, rng)
        a = calibrated_stationarity(x, 1.0, gen, n_sim=20, rng=7)
        b = calibrated_stationarity(x, 1.0, gen, n_sim=20, rng=7)
        assert a == b

    def test_bad_model_and_simulator_shape(self, rng):
        with pytest.raises(TypeError, match="NoiseModel or a callable"):
            calibrated_stationarity(rng.standard_normal(100), 1.0, 3.0, n_sim=5)
        with pytest.raises(ValueError, match="shape"):
            calibrated_stationarity(
                rng.standard_normal(100), 1.0, lambda n, g: g.standard_normal(n + 1), n_sim=5
            )

    def test_with_noise_model(self, rng):
        models = pytest.importorskip("imupipe.models")
        pytest.importorskip("imupipe.simulate")
        model = models.NoiseModel(white=1.0, gauss_markov=((1.0, 50.0),))
        x = white_plus_gm(1.0, 1.0, 50.0)(2000, rng)
        res = calibrated_stationarity(x, 1.0, model, n_sim=19, rng=rng)
        assert 0.0 < res["p_value"] <= 1.0 and "NoiseModel" in res["null"]

    @pytest.mark.slow
    def test_ten_hour_records(self, rng):
        # paper scale: 10 h at 1 Hz, white + GM (sigma = white std, T = 300 s); 100 records,
        # 99 null draws each
        gen = white_plus_gm(1.0, 1.0, 300.0)
        paper, calibrated = [], []
        for _ in range(100):
            res = calibrated_stationarity(gen(36000, rng), 1.0, gen, n_sim=99, rng=rng)
            paper.append(not res["paper"]["stationary"])
            calibrated.append(not res["stationary"])
        assert np.mean(paper) > 0.5
        lo, hi = binomial_band(0.05, 100)
        assert max(lo, 0.0) <= np.mean(calibrated) < hi


# ---------------------------------------------------------------------------------------------
class TestBlockBootstrap:
    def test_white_noise_near_nominal(self, rng):
        # iid data, blocks of 1 sample = the ordinary bootstrap. 100 records, 39 draws.
        rejected = []
        for _ in range(100):
            res = bootstrap_stationarity(rng.standard_normal(1000), 1.0, block_s=1.0, n_boot=39, rng=rng)
            rejected.append(not res["stationary"])
        lo, hi = binomial_band(0.05, 100)
        assert max(lo, 0.0) <= np.mean(rejected) < hi

    def test_variance_step_fails(self, rng):
        x = rng.standard_normal(4000)
        x[2000:] *= 1.5
        res = bootstrap_stationarity(x, 1.0, block_s=20.0, n_boot=99, rng=rng)
        assert not res["stationary"] and res["block_length"] == 20

    def test_correlated_noise_long_blocks(self, rng):
        # white + GM (T = 10 s) with blocks of 20 T: far fewer false rejections than the paper's
        # test (the bootstrap is only approximately calibrated: a loose upper limit)
        gen = white_plus_gm(1.0, 1.0, 10.0)
        boot, paper = [], []
        for _ in range(60):
            res = bootstrap_stationarity(gen(4000, rng), 1.0, block_s=200.0, n_boot=39, rng=rng)
            boot.append(not res["stationary"])
            paper.append(not res["paper"]["stationary"])
        assert np.mean(boot) < 0.2 < np.mean(paper)

    def test_errors(self, rng):
        with pytest.raises(ValueError, match="block_s"):
            bootstrap_stationarity(rng.standard_normal(100), 1.0, block_s=0.1)
        with pytest.raises(ValueError, match="block_s"):
            bootstrap_stationarity(rng.standard_normal(100), 1.0, block_s=200.0)


class TestStableVerdicts:
    def test_same_record_on_three_axes_same_verdict(self, rng):
        # common random numbers: the default seed comes from the record, so copies of one record (three axes
        # of identical data) get bit-identical null draws and results, whatever generator state surrounds them
        gen = white_plus_gm(1.0, 1.0, 30.0)
        x = gen(3000, rng)
        res = [calibrated_stationarity(x.copy(), 1.0, gen, n_sim=39) for _ in range(3)]
        assert res[0] == res[1] == res[2] and res[0]["seed"] == "data"
        # a different record gets different draws (the seed is not a constant)
        other = calibrated_stationarity(gen(3000, rng), 1.0, gen, n_sim=39, stop_early=False)
        full = calibrated_stationarity(x, 1.0, gen, n_sim=39, stop_early=False)
        assert other["levene_p"] != full["levene_p"] or other["ks_p"] != full["ks_p"]

    def test_close_verdicts_draw_more(self):
        # A null that never reaches the observed statistics: the p-value falls like 1/(1 + n) with the number
        # of draws n. At n_sim = 19 it sits within 2 Monte Carlo standard errors of alpha = 0.05 (a close
        # verdict), so the draws double (19, 39, 79, ...) until p is more than 2 se from alpha.
        x = np.concatenate([np.random.default_rng(3).standard_normal(500),
                            10 + np.random.default_rng(4).standard_normal(500)])
        null = lambda n, g: g.standard_normal(n)  # noqa: E731
        fixed = calibrated_stationarity(x, 1.0, null, n_sim=19, n_sim_max=None)
        assert abs(fixed["closeness"]) <= 2 and not fixed["extended"]
        res = calibrated_stationarity(x, 1.0, null, n_sim=19, n_sim_max=1000)
        assert res["extended"] and res["n_sim_run"] in (39, 79, 159, 319, 639) and abs(res["closeness"]) > 2
        half = calibrated_stationarity(x, 1.0, null, n_sim=19, n_sim_max=(res["n_sim_run"] - 1) // 2)
        assert abs(half["closeness"]) <= 2  # the stage before was still close: no draw was wasted
        p, n = res["p_value"], res["n_sim_run"] + 1
        assert res["p_value_mc_se"] == pytest.approx(math.sqrt(p * (1 - p) / n))
        assert res["p_value"] < fixed["p_value"]
        # a verdict far from the level is not extended
        far = calibrated_stationarity(x, 1.0, null, n_sim=199, n_sim_max=1000)
        assert not far["extended"] and far["n_sim_run"] == 199


class TestNullWithLines:
    """The calibrated null holds the axis's spectral lines (imupipe.stages.stationarity): a steady line is part of a
    stationary record. Outside evaluations saw every axis with a line flagged (a null of white, GM, flicker and
    random walk only, whose fit also absorbed the line's Allan variance)."""

    @staticmethod
    def line(f0, power, width_hz, resolution_hz=0.002):
        from imupipe.lines import _line

        return _line(f0, power, width_hz, peak_ratio=50.0, f_lo_hz=f0 - 0.004, f_hi_hz=f0 + 0.004,
                     resolution_hz=resolution_hz)

    def test_terms_at_the_alias_with_the_block_average_gain(self):
        from imupipe.stages.stationarity import NULL_COHERENCE_RECORDS, null_line_sets

        resolved = self.line(0.08, 4e-6, 0.01)  # wider than the resolution: its width is measured
        folded = self.line(1.3, 1e-6, 0.02)  # above the 1 Hz record's Nyquist: at |1.3 - 1| Hz
        on_dc = self.line(2.0, 1e-6, 0.02)  # a multiple of the rate: the block average removes it
        (terms,) = null_line_sets([resolved, folded, on_dc], 1.0, 5400.0)
        assert len(terms) == 2
        (s0, f0, z0), (s1, f1, z1) = terms
        assert (s0, f0) == pytest.approx((2e-3 * abs(np.sinc(0.08)), 0.08), rel=1e-12)
        assert z0 == pytest.approx(0.01 / (2 * 0.08), rel=1e-12)  # Gamma kept: zeta = Gamma / (2 f)
        assert (s1, f1) == pytest.approx((1e-3 * abs(np.sinc(1.3)), 0.3), rel=1e-12)
        assert z1 == pytest.approx(0.02 / (2 * 0.3), rel=1e-12)
        # an unresolved line (width at the resolution) is also tried at longer coherence times
        sets = null_line_sets([self.line(0.08, 4e-6, 0.002)], 1.0, 5400.0)
        assert len(sets) == 1 + len(NULL_COHERENCE_RECORDS)
        for (_, fa, z), c in zip((s[0] for s in sets[1:]), NULL_COHERENCE_RECORDS):
            assert 1.0 / (2 * math.pi * fa * z) == pytest.approx(c * 5400.0, rel=1e-12)  # tau_c = 1/(2 pi zeta f)
        assert null_line_sets([], 1.0, 5400.0) == []

    def test_a_steady_line_is_stationary(self):
        """White noise + GM + a line at 0.08 Hz of damping 0.001 (coherence 2000 s, unresolved at 0.002 Hz), 1.5 h
        at 10 Hz decimated to 1 Hz: the null without the line flags it (its fit absorbs the line); with the axis's
        lines found by the workflow's search, the verdict is stationary. One record of a fixed seed; the rates over
        20 records each are in docs/performance.md."""
        from imupipe.allan import allan_variance
        from imupipe.lines import find_lines
        from imupipe.models import NoiseModel
        from imupipe.simulate import simulate
        from imupipe.spectra import decimate
        from imupipe.stages.stationarity import stationarity_stage

        truth = NoiseModel(white=1e-3, gauss_markov=((2e-4, 300.0),), narrowband=((3e-3, 0.08, 0.001),))
        x = simulate(truth, 54_000, 10.0, np.random.default_rng(1))
        av = allan_variance(x, 10.0)
        found = find_lines(x, 10.0, resolution_hz=0.002).lines
        assert len(found) == 1 and found[0].frequency_hz == pytest.approx(0.08, abs=0.002)
        y, r = decimate(x, 10.0, 1.0)
        allan = (av.tau, av.avar, av.edf)
        without = stationarity_stage(y, r, allan=allan)
        with_lines = stationarity_stage(y, r, allan=allan, lines=found)
        assert not without["stationary"] and "null_lines" not in without["calibrated"]
        assert with_lines["stationary"] and with_lines["calibrated"]["null_lines"]["tried"]
        assert with_lines["calibrated"]["null_model"]["narrowband"]
        (lo, hi), = with_lines["calibrated"]["null_lines"]["notch_hz"]
        found_width = found[0].f_hi_hz - found[0].f_lo_hz  # the line's interval, plus 25 bins of 1/5400 Hz each side
        assert lo < 0.08 < hi and hi - lo == pytest.approx(found_width + 50 / 5400.0, rel=1e-9)
        # the white noise's sd stepping by sqrt(1 + 0.6^2) = 1.17x halfway under the same line: still seen (the
        # notch leaves the broadband noise)
        z = x.copy()
        z[27_000:] += 0.6 * 1e-3 * np.sqrt(10.0) * np.random.default_rng(2).standard_normal(27_000)
        av = allan_variance(z, 10.0)
        y, r = decimate(z, 10.0, 1.0)
        stepped = stationarity_stage(y, r, allan=(av.tau, av.avar, av.edf),
                                     lines=find_lines(z, 10.0, resolution_hz=0.002).lines)
        assert not stepped["stationary"]
        # the nulls are tried in order until one does not reject: the stationary record ran the first (its line as
        # measured) only; the rejected one ran all five (the measured width and four coherence times) and reports
        # the largest p-value, below the level
        from imupipe.stages.stationarity import NULL_COHERENCE_RECORDS

        assert len(with_lines["calibrated"]["null_lines"]["tried"]) == 1
        assert with_lines["p_value"] > 0.05
        tried = stepped["calibrated"]["null_lines"]["tried"]
        assert len(tried) == 1 + len(NULL_COHERENCE_RECORDS)
        assert stepped["p_value"] == max(t["p_value"] for t in tried) <= 0.05

    def test_the_null_beside_strong_lines_keeps_the_slow_gm(self):
        """Lines 400 and 900 times the decimated white variance (0.3 Hz and 2.45 Hz, which folds to 0.45 Hz at 1 Hz)
        beside white noise and a GM of 200 s, 1.5 h at 20 Hz: the null fitted to the full-rate curve with the lines'
        Allan variance known took white noise 0.3-2.5x the truth's, a random walk, or no GM (the lines' known part is
        inexact at short tau; an outside evaluation saw a GM of 0.05 s and 2 of 3 stationary axes flagged). Fitted
        to the notched decimated record itself, each of three records keeps a GM of tens to hundreds of seconds and
        is stationary (benchmarks/stationarity_lines.py --case strong: 0 of 60 flagged)."""
        from imupipe.allan import allan_variance
        from imupipe.lines import find_lines
        from imupipe.models import NoiseModel
        from imupipe.simulate import simulate
        from imupipe.spectra import decimate
        from imupipe.stages.stationarity import stationarity_stage

        truth = NoiseModel(white=1e-3, gauss_markov=((3e-4, 200.0),),
                           narrowband=((2e-2, 0.3, 0.001), (3e-2, 2.45, 0.001)))
        rng = np.random.default_rng(5)
        for _ in range(3):
            x = simulate(truth, 108_000, 20.0, rng)
            av = allan_variance(x, 20.0)
            found = find_lines(x, 20.0, resolution_hz=0.002).lines
            y, r = decimate(x, 20.0, 1.0)
            v = stationarity_stage(y, r, allan=(av.tau, av.avar, av.edf), lines=found)
            null = v["calibrated"]["null_model"]
            assert v["stationary"] and null["white"] > 0, null
            assert [g for g in null["gauss_markov"] if 30.0 <= g["T"] <= 3000.0], null

    def test_a_line_broadband_in_the_record_is_not_notched(self):
        # an outside evaluation's resonance: 40 Hz, 0.24 Hz wide (damping 0.003), block-averaged to 1 Hz folds onto
        # 0 Hz; its notch (10 half-power widths each side) would take the whole 0-0.5 Hz band, leaving the test no
        # record to read: it is not notched (the null carries it). A line at 0.3 Hz, 0.004 Hz wide, is.
        from imupipe.lines import _line
        from imupipe.stages.stationarity import NOTCH_MAX_SHARE, notch_bands

        wide = _line(40.2, 1e-4, 0.24, peak_ratio=50.0, f_lo_hz=39.9, f_hi_hz=40.5, resolution_hz=0.128)
        narrow = self.line(0.3, 1e-6, 0.004)
        bands = notch_bands([wide, narrow], 1.0, 7200)
        assert len(bands) == 1 and bands[0][0] < 0.3 < bands[0][1]
        assert bands[0][1] - bands[0][0] <= NOTCH_MAX_SHARE * 0.5

    def test_notch_removes_the_band_only(self):
        from imupipe.stationarity import notch

        n, rate = 1000, 1.0
        t = np.arange(n) / rate
        rng = np.random.default_rng(3)
        other = rng.standard_normal(n)
        line = 5.0 * np.sin(2 * np.pi * 0.1 * t + 0.3)  # on the bin k = 100
        out = notch(np.stack([line + other, other]), rate, [(0.095, 0.105)])
        np.testing.assert_allclose(out[0], out[1], atol=1e-12)  # the line gone, linear in the record
        X, Y = np.fft.rfft(other - other.mean()), np.fft.rfft(out[1])
        keep = np.abs(np.fft.rfftfreq(n) - 0.1) > 0.0051
        keep[0] = False
        np.testing.assert_allclose(Y[keep], X[keep], atol=1e-10)  # every other coefficient as it was
        assert np.all(np.abs(Y[~keep]) < 1e-10)
