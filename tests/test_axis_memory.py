"""The full-rate outlier and line stages work in batches: the same numbers as whole-array arithmetic, and a
peak of Python-visible allocations (tracemalloc, which sees numpy's buffers) far below one copy of the series.

Bounds: a batch is HAMPEL_BATCH / SPECTRUM_BATCH = 2**18 samples; the work arrays of one batch are a few
times its 2 MB (medians' partition copies, deviations, repeated centres and scales; segment copies and their
complex FFT), i.e. about 10 MB, plus the outputs (outlier indices, the spectrum of nperseg/2 + 1 bins). With a
series of 2**22 samples (33.5 MB) the allowed peak is half the series (16.8 MB); whole-array arithmetic (what
the stages did) needed 4-6 copies of the series."""

import tracemalloc

import numpy as np
import pytest

import imupipe.lines as lines_mod
import imupipe.outliers as outliers_mod
from imupipe.lines import find_lines
from imupipe.outliers import hampel, removal_effect, screen_outliers


def _hampel_reference(x, window, k):
    """The rule with whole-array arithmetic (module docstring of imupipe.outliers)."""
    n = x.size
    nb = max(n // window, 1)
    main = x[: nb * window].reshape(nb, window)
    med = np.median(main, axis=1)
    mad = np.median(np.abs(main - med[:, None]), axis=1)
    if n > nb * window:
        last = x[(nb - 1) * window :]
        med[-1] = np.median(last)
        mad[-1] = np.median(np.abs(last - med[-1]))
    scale = np.where(mad > 0, outliers_mod.MAD_TO_SIGMA * mad, np.inf)
    counts = np.full(nb, window)
    counts[-1] += n - nb * window
    center, sc = np.repeat(med, counts), np.repeat(scale, counts)
    return np.abs(x - center) > k * sc, center, sc


@pytest.mark.parametrize("batch", [7, 100, 1 << 18])
def test_hampel_batches_equal_whole_arrays(monkeypatch, rng, batch):
    x = rng.standard_normal(10_037)
    x[[5, 4_000, 10_030]] += 40.0  # the last one in the partial last block
    monkeypatch.setattr(outliers_mod, "HAMPEL_BATCH", batch)
    mask, center, scale = hampel(x, 100, 7.0)
    ref = _hampel_reference(x, 100, 7.0)
    np.testing.assert_array_equal(mask, ref[0])
    np.testing.assert_array_equal(center, ref[1])
    np.testing.assert_array_equal(scale, ref[2])
    assert np.flatnonzero(mask).tolist() == [5, 4_000, 10_030]
    cleaned, report = screen_outliers(x, policy="remove", k=7.0, window=100)
    np.testing.assert_array_equal(cleaned[mask], ref[1][mask])
    assert report.max_abs_deviation == pytest.approx(np.max(np.abs(x - ref[1])[mask]), rel=0, abs=0)


def test_removal_effect_in_batches(monkeypatch, rng):
    x = rng.standard_normal(1_001)
    monkeypatch.setattr(outliers_mod, "HAMPEL_BATCH", 64)
    got = removal_effect(x, x * 2.0, 10.0)
    ref = 0.5 * np.mean(np.diff(x) ** 2)
    # summation order differs: relative rounding bound ~ n * eps = 1000 * 2.2e-16
    assert got["avar_tau0_before"] == pytest.approx(ref, rel=1e-12)
    assert got["avar_ratio"] == pytest.approx(4.0, rel=1e-12)


def test_line_spectrum_batches_equal_whole_arrays(monkeypatch, rng):
    rate, n = 100.0, 100 * 1_000 + 37
    t = np.arange(n) / rate
    x = rng.standard_normal(n) + 0.5 * np.sin(2 * np.pi * 12.3 * t)
    whole = find_lines(x, rate, resolution_hz=0.1)
    monkeypatch.setattr(lines_mod, "SPECTRUM_BATCH", 1_000)  # one segment per batch
    batched = find_lines(x, rate, resolution_hz=0.1)
    # sums of K = 100 periodograms in another order: relative rounding bound ~ K * eps
    np.testing.assert_allclose(batched.psd, whole.psd, rtol=1e-13, atol=0)
    assert [ln.frequency_hz for ln in batched.lines] == pytest.approx([ln.frequency_hz for ln in whole.lines],
                                                                      rel=1e-12)
    assert len(whole.lines) == 1 and abs(whole.lines[0].frequency_hz - 12.3) < 0.1


N_BIG = 1 << 22  # samples: 33.5 MB


def _peak_bytes(fn):
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        base = tracemalloc.get_traced_memory()[0]
        fn()
        return tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()


@pytest.mark.parametrize("stage", ["outliers", "lines"])
def test_stage_peak_is_far_below_the_series(rng, stage):
    x = rng.standard_normal(N_BIG)
    if stage == "outliers":
        peak = _peak_bytes(lambda: screen_outliers(x, policy="warn", k=7.0, window=100))
    else:
        peak = _peak_bytes(lambda: find_lines(x, 125.0, resolution_hz=0.002))
    assert peak <= 0.5 * x.nbytes, f"{stage}: peak {peak / 2**20:.1f} MB for a {x.nbytes / 2**20:.1f} MB series"
