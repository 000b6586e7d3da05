"""Tests of imupipe.spectra: decimation, Welch PSD (two-sided), confidence limits, band smoothing.

References are scipy.signal (welch, get_window) on the same settings, exact discrete identities
(Parseval), and chi-squared statistics of white-noise periodograms with tolerances derived from
the estimator's spread.
"""

import math
import warnings

import numpy as np
import pytest
import scipy.signal
import scipy.stats
import xarray as xr

from imupipe.spectra import (
    TAPERS,
    chi2_upper,
    decimate,
    get_taper,
    psd,
    smooth_log_bands,
    welch_edf,
)


def parseval_weights(nperseg):
    """c_k of the discrete Parseval identity on rfft bins: 1 at DC and (even N) Nyquist, else 2."""
    c = np.full(nperseg // 2 + 1, 2.0)
    c[0] = 1.0
    if nperseg % 2 == 0:
        c[-1] = 1.0
    return c


# ---------------------------------------------------------------------------------------------
class TestDecimate:
    def test_hand_example(self):
        y, rate = decimate([1.0, 2.0, 3.0, 4.0, 5.0], rate=2.0, target_rate=1.0)
        np.testing.assert_array_equal(y, [1.5, 3.5])  # incomplete last block [5.0] dropped
        assert rate == 1.0

    def test_integer_input_and_dtype(self):
        y, rate = decimate(np.arange(12, dtype=np.int16), 4.0, 1.0)
        assert y.dtype == np.float64
        np.testing.assert_array_equal(y, [1.5, 5.5, 9.5])
        assert rate == 1.0

    def test_drops_incomplete_block(self):
        x = np.arange(125 * 3 + 124, dtype=float)
        y, _ = decimate(x, 125.0, 1.0)
        assert y.shape == (3,)
        np.testing.assert_allclose(y, [62.0, 187.0, 312.0])

    def test_last_axis_of_2d(self):
        x = np.arange(2 * 10, dtype=float).reshape(2, 10)
        y, rate = decimate(x, 10.0, 2.0)
        np.testing.assert_array_equal(y, [[2.0, 7.0], [12.0, 17.0]])
        assert rate == 2.0

    @pytest.mark.parametrize("rate, target", [(125.0, 3.0), (100.0, 30.0), (1.0, 2.0)])
    def test_non_integer_ratio_names_both_rates(self, rate, target):
        with pytest.raises(ValueError, match=rf"rate={rate:g} Hz.*target_rate={target:g} Hz"):
            decimate(np.zeros(1000), rate, target)

    def test_too_short(self):
        with pytest.raises(ValueError, match="shorter than one block"):
            decimate(np.zeros(100), 125.0, 1.0)

    def test_float32_accumulates_in_float64(self, rng):
        # an accelerometer axis: 9.81 m/s^2 with 1e-6 noise, stored in float32
        x = (9.81 + 1e-6 * rng.standard_normal(125 * 200)).astype(np.float32)
        y, _ = decimate(x, 125.0, 1.0)
        ref = x.astype(np.float64).reshape(200, 125).mean(axis=1)
        np.testing.assert_allclose(y, ref, rtol=1e-15)

    def test_white_noise_density_preserved(self, rng):
        # white noise of density N (u/sqrt(Hz)) at fs: sample std N*sqrt(fs). Its 1 s block
        # average has variance N^2 * 1 Hz, i.e. the two-sided PSD stays N^2.
        n_density, fs = 0.3, 50.0
        x = n_density * math.sqrt(fs) * rng.standard_normal(int(fs) * 20000)
        y, rate = decimate(x, fs, 1.0)
        ds = psd(y, rate, window_s=500.0, step_s=500.0, taper="boxcar")
        interior = ds.psd.values[1:-1]
        # mean of M independent chi2_nu/nu ordinates: relative std sqrt(2/(nu*M))
        rel_sd = math.sqrt(2.0 / (ds.attrs["edf"] * interior.size))
        assert abs(interior.mean() / n_density**2 - 1.0) < 4 * rel_sd


# ---------------------------------------------------------------------------------------------
class TestGetTaper:
    @pytest.mark.parametrize("name", sorted(TAPERS))
    @pytest.mark.parametrize("n", [1, 2, 7, 64, 1001])
    def test_equals_scipy_periodic_window(self, name, n):
        np.testing.assert_allclose(get_taper(name, n), scipy.signal.get_window(name, n), rtol=0, atol=1e-15)

    def test_unknown_name(self):
        with pytest.raises(ValueError, match="unknown taper 'kaiser'"):
            get_taper("kaiser", 16)

    def test_explicit_weights(self):
        w = np.linspace(0.0, 1.0, 8)
        np.testing.assert_array_equal(get_taper(w, 8), w)
        with pytest.raises(ValueError, match=r"shape \(9,\)"):
            get_taper(w, 9)


# ---------------------------------------------------------------------------------------------
class TestWelchEdf:
    @pytest.mark.parametrize("name", sorted(TAPERS))
    def test_non_overlapping_is_2k(self, name):
        assert welch_edf(name, 100, 100, 7) == 14.0
        assert welch_edf(name, 100, 150, 3) == 6.0

    def test_hann_half_overlap_by_hand(self):
        # rho(1) = (sum w_n w_{n+N/2} / sum w_n^2)^2 = (1/6)^2 for the periodic Hann taper
        k = 5
        expected = 2 * k / (1 + 2 * (1 - 1 / k) / 36)
        assert welch_edf("hann", 1000, 500, k) == pytest.approx(expected, rel=1e-12)

    def test_overlapped_hann_edf_by_simulation(self, rng):
        # nu = 2 mean^2 / var of the ordinates; 40 records x ~1000 interior bins each.
        # The estimate's relative sd is ~sqrt(2/n_eff) with n_eff ~ 40*1000/2 (hann: correlated
        # neighbours), i.e. ~1 %: a 6 % tolerance leaves room for the formula's flat-spectrum
        # assumption.
        fs, nper, step, n = 1.0, 2000, 1000, 20000
        vals = []
        for _ in range(40):
            ds = psd(rng.standard_normal(n), fs, window_s=nper, step_s=step, taper="hann")
            vals.append(ds.psd.values[5:-5])
        vals = np.concatenate(vals)
        nu_emp = 2 * vals.mean() ** 2 / vals.var()
        assert nu_emp == pytest.approx(ds.attrs["edf"], rel=0.06)
        assert ds.attrs["edf"] < 2 * ds.attrs["n_segments"]


# ---------------------------------------------------------------------------------------------
class TestPsdAgainstScipy:
    @pytest.mark.parametrize("taper", sorted(TAPERS))
    @pytest.mark.parametrize("detrend", ["constant", "linear", None])
    @pytest.mark.parametrize(
        "nperseg, step",
        [(1000, 500), (1000, 1500), (999, 333), (1024, 1024), (10001, 10001)],
        ids=["overlap", "gaps", "odd", "adjacent", "single"],
    )
    def test_equals_welch(self, taper, detrend, nperseg, step):
        rng = np.random.default_rng(nperseg + step)
        fs = 4.0
        x = 5.0 + 2.0 * rng.standard_normal(10001) + np.cumsum(rng.standard_normal(10001)) * 0.01
        kwargs = dict(window_s=nperseg / fs, step_s=step / fs, taper=taper, detrend=detrend)
        ours1 = psd(x, fs, onesided=True, **kwargs)
        ours2 = psd(x, fs, **kwargs)
        sp_det = detrend if detrend is not None else False
        f1, p1 = scipy.signal.welch(x, fs, window=taper, nperseg=nperseg, noverlap=nperseg - step,
                                    detrend=sp_det, scaling="density", return_onesided=True)
        _, p2 = scipy.signal.welch(x, fs, window=taper, nperseg=nperseg, noverlap=nperseg - step,
                                   detrend=sp_det, scaling="density", return_onesided=False)
        np.testing.assert_array_equal(ours1.frequency.values, f1)
        start = 0
        if taper == "boxcar" and detrend is not None:
            # DC of a detrended boxcar segment is zero: both values are rounding noise
            start = 1
            assert abs(ours1.psd.values[0]) < 1e-25 * p1.max()
        np.testing.assert_allclose(ours1.psd.values[start:], p1[start:], rtol=1e-12)
        # scipy's two-sided output on the rfft bins (the Nyquist bin of even N is listed as -fs/2)
        np.testing.assert_allclose(ours2.psd.values[start:], p2[start : f1.size], rtol=1e-12)
        assert ours1.attrs["n_segments"] == (x.size - nperseg) // step + 1

    def test_twenty_decades_without_loss(self, rng):
        # a bin-centred tone (amplitude A) and white noise of std s = A / 2e8: the Hann periodogram
        # puts the tone into 3 bins (peak two-sided S2 = A^2 N / (6 fs)) and leaves the white
        # floor s^2/fs elsewhere: 20 decades below the peak.
        fs, n = 1.0, 25200
        a_tone, s = 1.0e3, 1.0e3 / 2e8
        k0 = 2520
        t = np.arange(n)
        x = a_tone * np.cos(2 * np.pi * k0 * t / n) + s * rng.standard_normal(n)
        ds = psd(x, fs, window_s=n, step_s=n)
        s2 = ds.psd.values
        peak = a_tone**2 * n / (6 * fs)
        assert s2[k0] == pytest.approx(peak, rel=1e-6)
        floor = np.delete(s2, [0, 1, k0 - 1, k0, k0 + 1, s2.size - 1])
        assert peak / (s**2 / fs) > 1e20
        # floor level: mean of ~12600 hann ordinates (nu = 2, neighbours correlated, n_eff ~ M/2),
        # relative sd ~ sqrt(2/M) ~ 1.3 %; 5 % tolerance
        assert floor.mean() / (s**2 / fs) == pytest.approx(1.0, rel=0.05)
        # against float64 scipy: FFT rounding is an absolute error ~eps times the tone's amplitude,
        # ~1e-16 * (A N/4) / (s sqrt(3N/8)) ~ 1e-6 of the floor's amplitude, i.e. at most a few
        # 1e-6 of the floor level in power (relative to the floor, not to each small ordinate)
        _, p2 = scipy.signal.welch(x, fs, window="hann", nperseg=n, noverlap=0, return_onesided=False)
        np.testing.assert_allclose(s2, p2[: s2.size], rtol=1e-5, atol=1e-5 * s**2 / fs)
        np.testing.assert_allclose(s2[k0 - 1 : k0 + 2], p2[k0 - 1 : k0 + 2], rtol=1e-12)
        # stored in float32, the rounding of the tone (ulp 6.1e-5 at 1e3, white, std ulp/sqrt(12))
        # makes a floor 12x above the true one: the information is lost at storage
        ds32 = psd(x.astype(np.float32), fs, window_s=n, step_s=n)
        floor32 = np.delete(ds32.psd.values, [0, 1, k0 - 1, k0, k0 + 1, s2.size - 1])
        assert floor32.mean() > 5 * s**2 / fs

    def test_random_walk_over_twenty_decades(self, rng):
        # 1/f^2 random walk (K) + tiny white noise over 0.5 mHz..0.5 Hz, two-sided, vs scipy
        n, fs = 36000, 1.0
        x = 1e3 * np.cumsum(rng.standard_normal(n)) + 1e-6 * rng.standard_normal(n)
        ds = psd(x, fs, window_s=n, step_s=n)
        _, p2 = scipy.signal.welch(x, fs, window="hann", nperseg=n, noverlap=0, return_onesided=False)
        s2 = ds.psd.values
        assert s2[1:].max() / s2[1:].min() > 1e10
        np.testing.assert_allclose(s2, p2[: s2.size], rtol=1e-9)


# ---------------------------------------------------------------------------------------------
class TestPsdIdentities:
    @pytest.mark.parametrize("nperseg", [1000, 999])
    def test_white_noise_level(self, nperseg, rng):
        # std s at fs: two-sided S2 = s^2/fs, one-sided 2 s^2/fs (style.md)
        s, fs = 0.7, 10.0
        x = s * rng.standard_normal(100 * nperseg)
        ds2 = psd(x, fs, window_s=nperseg / fs, step_s=nperseg / fs, taper="boxcar")
        ds1 = psd(x, fs, window_s=nperseg / fs, step_s=nperseg / fs, taper="boxcar", onesided=True)
        interior = slice(1, -1) if nperseg % 2 == 0 else slice(1, None)
        m = ds2.psd.values[interior].size
        # each ordinate ~ S chi2_nu/nu with nu = 200, independent (boxcar, white)
        rel_sd = math.sqrt(2.0 / (ds2.attrs["edf"] * m))
        assert ds2.psd.values[interior].mean() == pytest.approx(s**2 / fs, rel=4 * rel_sd)
        assert ds1.psd.values[interior].mean() == pytest.approx(2 * s**2 / fs, rel=4 * rel_sd)

    def test_paper_defaults_on_a_ten_hour_record(self, rng):
        ds = psd(rng.standard_normal(36000), 1.0)
        assert ds.attrs["window_s"] == 25200.0 and ds.attrs["step_s"] == 36000.0
        assert ds.attrs["n_segments"] == 1 and ds.attrs["edf"] == 2.0
        assert ds.attrs["n_samples_used"] == 25200
        assert ds.attrs["taper"] == "hann" and ds.attrs["detrend"] == "constant"
        assert ds.frequency.size == 12601 and ds.frequency.values[-1] == 0.5

    @pytest.mark.parametrize("nperseg", [64, 63])
    def test_one_two_sided_relation(self, nperseg, rng):
        x = rng.standard_normal(1000)
        kw = dict(window_s=nperseg, step_s=nperseg // 2, detrend=None)
        s1 = psd(x, 1.0, onesided=True, **kw).psd.values
        s2 = psd(x, 1.0, **kw).psd.values
        c = parseval_weights(nperseg)
        np.testing.assert_allclose(s1, c * s2, rtol=1e-15)
        assert s1[0] == s2[0]
        if nperseg % 2 == 0:
            assert s1[-1] == s2[-1]

    @pytest.mark.parametrize("nperseg", [500, 499])
    @pytest.mark.parametrize("detrend", ["constant", "linear", None])
    def test_parseval_boxcar_exact(self, nperseg, detrend, rng):
        # df * sum_k c_k S2(f_k) = mean over segments of mean(d_j^2): exact for the boxcar
        fs = 8.0
        x = 3.0 + rng.standard_normal(nperseg * 6 + 17)
        ds = psd(x, fs, window_s=nperseg / fs, step_s=nperseg / fs, taper="boxcar", detrend=detrend)
        segs = x[: 6 * nperseg].reshape(6, nperseg)
        if detrend is not None:
            segs = scipy.signal.detrend(segs, axis=-1, type=detrend)
        expected = np.mean(segs**2)
        df = fs / nperseg
        assert df * np.sum(parseval_weights(nperseg) * ds.psd.values) == pytest.approx(expected, rel=1e-12)
        if detrend == "constant":  # the variance of the (segment-demeaned) record
            assert expected == pytest.approx(np.mean(np.var(segs, axis=1)), rel=1e-12)

    def test_parseval_tapered_overlapped(self, rng):
        # with a taper: the taper-weighted mean square of the detrended segments, averaged
        fs, nperseg, step = 1.0, 400, 150
        x = rng.standard_normal(3000)
        ds = psd(x, fs, window_s=nperseg, step_s=step, taper="hann")
        w = scipy.signal.get_window("hann", nperseg)
        starts = range(0, x.size - nperseg + 1, step)
        segs = np.array([x[i : i + nperseg] - x[i : i + nperseg].mean() for i in starts])
        expected = np.mean((segs**2 * w**2).sum(axis=1) / (w**2).sum())
        total = fs / nperseg * np.sum(parseval_weights(nperseg) * ds.psd.values)
        assert total == pytest.approx(expected, rel=1e-12)

    def test_float32_equals_float64(self, rng):
        x = rng.standard_normal(5000).astype(np.float32)
        a = psd(x, 1.0, window_s=1000, step_s=500)
        b = psd(x.astype(np.float64), 1.0, window_s=1000, step_s=500)
        xr.testing.assert_identical(a, b)


# ---------------------------------------------------------------------------------------------
class TestPsdConfidence:
    def test_limits_formula(self, rng):
        ds = psd(rng.standard_normal(4000), 1.0, window_s=1000, step_s=500, confidence=0.9)
        nu = ds.edf.values
        np.testing.assert_allclose(ds.psd_lower, nu * ds.psd / scipy.stats.chi2.ppf(0.95, nu), rtol=1e-12)
        np.testing.assert_allclose(ds.psd_upper, nu * ds.psd / scipy.stats.chi2.ppf(0.05, nu), rtol=1e-12)
        assert nu[0] == nu[-1] == ds.attrs["edf"] / 2  # DC and Nyquist: half the degrees of freedom
        assert np.all(nu[1:-1] == ds.attrs["edf"])

    def test_coverage_of_white_noise_level(self, rng):
        # boxcar periodograms of Gaussian white noise: interior ordinates are independent
        # chi2_nu/nu, so the fraction of (record, bin) pairs whose 95 % band holds the true level
        # is binomial(0.95, n): 300 records x 3 segments x 63 bins -> n = 18900, sd = 0.16 %
        fs, s, nper = 2.0, 1.5, 128
        true = s**2 / fs
        inside, inside_nyq = [], []
        for _ in range(300):
            ds = psd(s * rng.standard_normal(3 * nper), fs, window_s=nper / fs, step_s=nper / fs,
                     taper="boxcar", detrend=None)
            lo, hi = ds.psd_lower.values, ds.psd_upper.values
            inside.append((lo[1:-1] <= true) & (true <= hi[1:-1]))
            inside_nyq.append(lo[-1] <= true <= hi[-1])
        frac = np.mean(inside)
        sd = math.sqrt(0.95 * 0.05 / np.size(inside))
        assert abs(frac - 0.95) < 4 * sd
        # Nyquist ordinate: nu/2 degrees of freedom; 300 records, sd 1.26 %
        assert abs(np.mean(inside_nyq) - 0.95) < 4 * math.sqrt(0.95 * 0.05 / 300)

    def test_coverage_overlapped_hann(self, rng):
        # Welch's edf for 50 %-overlapped Hann: one mid bin per record, 400 records, sd 1.1 %
        true = 1.0
        inside = []
        for _ in range(400):
            ds = psd(rng.standard_normal(1200), 1.0, window_s=200, step_s=100)
            inside.append(ds.psd_lower.values[50] <= true <= ds.psd_upper.values[50])
        assert abs(np.mean(inside) - 0.95) < 4 * math.sqrt(0.95 * 0.05 / 400)


# ---------------------------------------------------------------------------------------------
class TestPsdInputs:
    def test_nan_and_inf(self):
        x = np.ones(100)
        x[7] = np.nan
        with pytest.raises(ValueError, match="non-finite.*index 7"):
            psd(x, 1.0, window_s=10, step_s=10)
        x[7] = np.inf
        with pytest.raises(ValueError, match="non-finite"):
            psd(x, 1.0, window_s=10, step_s=10)

    def test_record_shorter_than_window(self):
        match = r"window_s=25200 s .*longer than the record \(18000 samples = 18000 s"
        with pytest.raises(ValueError, match=match):
            psd(np.zeros(18000), 1.0)

    @pytest.mark.parametrize(
        "kwargs, match",
        [
            (dict(confidence=1.0), "confidence"),
            (dict(window_s=-1.0), "window_s"),
            (dict(step_s=0.0), "step_s"),
            (dict(taper="kaiser"), "unknown taper"),
            (dict(detrend="quadratic"), "detrend"),
        ],
    )
    def test_bad_settings(self, kwargs, match, rng):
        with pytest.raises(ValueError, match=match):
            psd(rng.standard_normal(100), 1.0, **{"window_s": 10, "step_s": 10, **kwargs})

    def test_bad_rate(self):
        with pytest.raises(ValueError, match="rate"):
            psd(np.zeros(100), 0.0)

    @pytest.mark.parametrize("value", [0.0, 9.81, -3e7])
    @pytest.mark.parametrize("detrend", ["constant", "linear"])
    def test_constant_channel(self, value, detrend):
        with pytest.warns(UserWarning, match="constant record"):
            ds = psd(np.full(3000, value), 1.0, window_s=1000, step_s=500, detrend=detrend)
        for name in ("psd", "psd_lower", "psd_upper"):
            assert np.all(ds[name].values == 0.0)

    def test_metadata_and_netcdf_round_trip(self, rng, tmp_path):
        x = xr.DataArray(rng.standard_normal(3000), dims="time", attrs={"units": "rad/s"})
        ds = psd(x, 2.0, window_s=500.0, step_s=250.0, taper="hamming", detrend="linear")
        assert ds.psd.attrs["units"] == "(rad/s)^2/Hz"
        assert ds.psd.attrs["sidedness"] == "two-sided" == ds.attrs["sidedness"]
        for name in ("psd", "psd_lower", "psd_upper", "edf", "frequency"):
            assert ds[name].attrs["long_name"] and ds[name].attrs["units"]
        assert ds.frequency.attrs["units"] == "Hz"
        expected = dict(window_s=500.0, step_s=250.0, nperseg=1000, step_samples=500, taper="hamming",
                        detrend="linear", n_segments=5, rate_hz=2.0, confidence=0.95, n_samples=3000)
        assert {k: ds.attrs[k] for k in expected} == expected
        assert ds.attrs["edf"] == pytest.approx(welch_edf("hamming", 1000, 500, 5))
        assert psd(np.arange(100.0), 1.0, window_s=10, step_s=10, units="m/s^2").psd.attrs["units"] == (
            "(m/s^2)^2/Hz"
        )
        assert psd(np.arange(100.0), 1.0, window_s=10, step_s=10).psd.attrs["units"] == "1/Hz"
        path = tmp_path / "psd.nc"
        ds.to_netcdf(path)
        with xr.open_dataset(path) as back:
            xr.testing.assert_identical(back.load(), ds)


# ---------------------------------------------------------------------------------------------
class TestSmoothLogBands:
    def test_constant_psd_and_band_layout(self):
        f = np.arange(0, 1001) * 0.01  # 0 .. 10 Hz
        s = np.full(f.size, 3.0)
        bands = smooth_log_bands(f, s, bands_per_decade=5, edf=2.0)
        np.testing.assert_allclose(bands.psd, 3.0)
        assert bands.n_bins.sum() == 1000  # DC dropped, every positive bin used once
        b = np.floor(5 * np.log10(bands.f_low) + 1e-9)
        # each band lies within its decade-aligned edges 10^(b/5) .. 10^((b+1)/5)
        assert np.all(bands.f_low >= 10 ** (b / 5) * (1 - 1e-12))
        assert np.all(bands.f_high < 10 ** ((b + 1) / 5))
        np.testing.assert_allclose(bands.edf, 2.0 * bands.n_bins)
        assert np.all(np.diff(bands.frequency) > 0)

    def test_hand_example(self):
        f = np.array([0.0, 1.0, 2.0, 3.0, 10.0, 20.0])
        s = np.array([9.0, 1.0, 2.0, 3.0, 4.0, 6.0])
        bands = smooth_log_bands(f, s, bands_per_decade=1, edf=[1, 2, 2, 2, 2, 1])
        np.testing.assert_allclose(bands.frequency, [2.0, 15.0])
        np.testing.assert_allclose(bands.psd, [2.0, 5.0])
        np.testing.assert_allclose(bands.edf, [6.0, 3.0])
        np.testing.assert_array_equal(bands.n_bins, [3, 2])

    def test_stacked_curves(self):
        f = np.arange(0, 101) * 0.1
        s = np.vstack([np.full(101, 1.0), np.full(101, 2.0)])
        bands = smooth_log_bands(f, s)
        assert bands.psd.shape == (2, bands.frequency.size)
        np.testing.assert_allclose(bands.psd[1], 2.0)

    def test_hann_bin_correlation(self):
        # r_1 = 4/9, r_2 = 1/36 for the periodic Hann taper
        f = np.arange(0, 1001) * 1.0
        bands = smooth_log_bands(f, np.ones(f.size), bands_per_decade=1, edf=2.0, taper="hann")
        m = bands.n_bins
        factor = 1 + 2 * ((1 - 1 / m) * 4 / 9 + np.where(m > 2, (1 - 2 / m) / 36, 0.0))
        factor = np.where(m > 1, factor, 1.0)
        np.testing.assert_allclose(bands.edf, 2.0 * m / factor, rtol=1e-12)

    def test_band_edf_by_simulation(self, rng):
        # nu_band = 2 mean^2 / var over 400 single-window Hann periodograms of white noise, for the
        # band with ~ 100 bins; the formula with r_j should match within sampling error
        # (relative sd of the variance estimate ~ sqrt(2/400) = 7 %; tolerance 25 %), while the
        # independent-bins count (2 M) would be off by a factor 1.9.
        n = 2048
        vals = []
        for _ in range(400):
            ds = psd(rng.standard_normal(n), 1.0, window_s=n, step_s=n)
            vals.append(smooth_log_bands(ds.frequency, ds.psd, bands_per_decade=10, taper="hann"))
        psds = np.array([v.psd for v in vals])
        j = int(np.argmin(np.abs(vals[0].n_bins - 100)))
        nu_emp = 2 * psds[:, j].mean() ** 2 / psds[:, j].var()
        assert nu_emp == pytest.approx(vals[0].edf[j], rel=0.25)
        assert vals[0].edf[j] < 0.6 * 2 * vals[0].n_bins[j]

    def test_errors(self):
        with pytest.raises(ValueError, match="must match"):
            smooth_log_bands(np.arange(5.0), np.ones(4))
        with pytest.raises(ValueError, match="positive frequency"):
            smooth_log_bands(np.zeros(1), np.ones(1))


# ---------------------------------------------------------------------------------------------
class TestChi2Upper:
    def test_single_test_equals_chi2(self):
        s = np.array([1.0, 2.0, 0.0])
        nu = np.array([2.0, 10.0, 4.0])
        expected = nu * s / scipy.stats.chi2.ppf(0.05, nu)
        np.testing.assert_allclose(chi2_upper(s, nu, 0.95), expected, rtol=1e-12)

    def test_corrections(self):
        bonf = chi2_upper(1.0, 2.0, 0.95, n_tests=1000)
        sidak = chi2_upper(1.0, 2.0, 0.95, n_tests=1000, correction="sidak")
        assert bonf == pytest.approx(2.0 / scipy.stats.chi2.ppf(0.05 / 1000, 2), rel=1e-12)
        q_sidak = -math.expm1(math.log(0.95) / 1000)  # 1 - 0.95**(1/n) without cancellation
        assert sidak == pytest.approx(2.0 / scipy.stats.chi2.ppf(q_sidak, 2), rel=1e-12)
        assert chi2_upper(1.0, 2.0, 0.95) < sidak < bonf

    def test_family_wise_coverage(self, rng):
        # 400 families of 15 curves x 64 independent chi2_2 ordinates (boxcar periodograms of
        # white noise): with the Sidak correction the whole family lies under the limit with
        # probability 0.95 (sd 1.1 %)
        n_fam, n_curves, nper = 400, 15, 130
        x = rng.standard_normal((n_fam, n_curves, nper))
        per = np.abs(np.fft.rfft(x, axis=-1)[..., 1:-1]) ** 2 / nper  # true level 1, nu = 2
        n_tests = n_curves * per.shape[-1]
        up = chi2_upper(per, 2.0, 0.95, n_tests=n_tests, correction="sidak")
        covered = np.all(up >= 1.0, axis=(1, 2))
        assert abs(covered.mean() - 0.95) < 4 * math.sqrt(0.95 * 0.05 / n_fam)

    def test_raw_maximum_overshoot(self, rng):
        # docs/method.md, section "Estimators": the maximum of 15 raw single-window periodograms of white noise
        # overshoots the true PSD about ln(15 * 12600) ~ 12x (chi2_2/2 is exponential)
        maxima = [psd(rng.standard_normal(36000), 1.0).psd.values[2:-1].max() for _ in range(15)]
        assert 8 < max(maxima) < 20

    def test_errors(self):
        with pytest.raises(ValueError, match="confidence"):
            chi2_upper(1.0, 2.0, 1.5)
        with pytest.raises(ValueError, match="n_tests"):
            chi2_upper(1.0, 2.0, 0.95, n_tests=0)
        with pytest.raises(ValueError, match="correction"):
            chi2_upper(1.0, 2.0, 0.95, correction="holm")
        with pytest.raises(ValueError, match="edf"):
            chi2_upper(1.0, 0.0)


def test_shared_band_helpers_match_closed_forms():
    from imupipe.spectra import band_edf_factor, bin_correlation, log_band_index

    r = bin_correlation("hann", 5)
    # Hann: r_1 = 4/9, r_2 = 1/36, zero beyond (Percival & Walden 1993, section 6.7)
    np.testing.assert_allclose(r, [1.0, 4 / 9, 1 / 36, 0.0, 0.0, 0.0], rtol=1e-12, atol=1e-15)
    assert band_edf_factor(r, 3) == pytest.approx(1 + 2 * ((2 / 3) * 4 / 9 + (1 / 3) / 36), rel=1e-15)
    assert list(bin_correlation(None, 2)) == [1.0, 0.0, 0.0] and band_edf_factor(bin_correlation(None, 4), 4) == 1.0
    # decade edges belong to the upper band, also where log10 rounds just below the integer
    assert list(log_band_index(np.array([0.1, 0.99, 1.0, 1.2589254117941673, 10.0]), 10)) == [-10, -1, 0, 1, 10]


def test_chi2_sf_closed_form_against_scipy():
    """chi2_sf(k, x) against scipy.special.chdtrc for k = 1..200 over 12 decades of x. Tolerance: each term is
    exp(A) with |A| <= x/2 + k log(x/2) + lgamma(k) < 2000 here, so a relative error of about |A| eps = 4e-13
    per term; the terms are positive, so the sum keeps that relative error: 1e-12."""
    from scipy.special import chdtrc

    from imupipe.spectra import chi2_sf

    for k in range(1, 201):
        for x in np.concatenate([np.geomspace(1e-6, 1500.0, 60), [k - 0.5, float(k), k + 0.5]]):
            ref = float(chdtrc(k, x))
            if ref > 1e-290:
                assert chi2_sf(k, x) == pytest.approx(ref, rel=1e-12, abs=0.0), (k, x)
    # exact values: k = 2 is exp(-x/2); k = 1 is erfc(sqrt(x/2)); the edges
    assert chi2_sf(2, 3.0) == pytest.approx(math.exp(-1.5), rel=1e-15)
    assert chi2_sf(1, 3.0) == pytest.approx(math.erfc(math.sqrt(1.5)), rel=1e-15)
    assert chi2_sf(5, 0.0) == 1.0 and chi2_sf(5, -1.0) == 1.0 and chi2_sf(5, math.inf) == 0.0
    with pytest.raises(ValueError, match="integer number of degrees of freedom"):
        chi2_sf(2.5, 1.0)
    with pytest.raises(ValueError, match="integer number of degrees of freedom"):
        chi2_sf(0, 1.0)
