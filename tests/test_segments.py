"""Segments of a record cut at its events (imupipe.segments, events.policy split): bookkeeping, the estimators pooled
over segments against direct computation and closed forms, nothing across a cut."""

import numpy as np
import pytest

from imupipe.segments import (
    Segments,
    decimate_segments,
    pooled_allan,
    pooled_edf,
    pooled_psd,
    read_segments,
    segment_records,
    split_at_events,
)

RATE = 100.0


def _three(n=60_000):
    # a step at 20 000 and a burst over 35 000-35 300, guard 100 samples: segments [0, 19 900), [20 100, 34 900),
    # [35 400, n)
    events = [{"index": 20_000}, {"index": 35_000, "stop_index": 35_300}]
    return split_at_events(n, RATE, events, guard=100, min_samples=1000), n


class TestBookkeeping:
    def test_cuts_segments_and_times(self):
        seg, n = _three()
        assert seg.bounds == ((0, 19_900), (20_100, 34_900), (35_400, n))
        assert seg.start_s == (0.0, 201.0, 354.0) and seg.cuts == ((199.0, 201.0), (349.0, 354.0))
        assert seg.dropped == () and not seg.is_whole
        np.testing.assert_array_equal(seg.lengths, [19_900, 14_800, 24_600])

    def test_no_event_is_the_whole_record(self):
        seg = split_at_events(5000, RATE, [], guard=100, min_samples=1000)
        assert seg.is_whole and seg == Segments.whole(5000, RATE)

    def test_short_stretches_are_dropped_and_reported(self):
        seg, _ = _three()
        short = split_at_events(60_000, RATE, [{"index": 20_000}, {"index": 21_000}], guard=100, min_samples=1000)
        # 20 100-20 900 (800 samples) is shorter than the minimum
        assert short.bounds == ((0, 19_900), (21_100, 60_000)) and short.dropped == ((201.0, 209.0),)
        with pytest.raises(ValueError, match=r"imu1/accel/x: events.policy = 'split' leaves no segment of at least "
                                             r"30000 samples .* longest event-free stretch has 24600 samples"):
            split_at_events(60_000, RATE, [{"index": 20_000}, {"index": 35_000, "stop_index": 35_300}], guard=100,
                            min_samples=30_000, where="imu1/accel/x")

    def test_round_trips_through_attrs_dict_and_file(self, tmp_path):
        from imupipe.io import write_series, write_yaml_atomic

        seg, n = _three()
        assert Segments.from_dict(seg.to_dict()) == seg
        path = tmp_path / "seg.yaml"
        write_yaml_atomic(seg.to_dict(), path)
        assert read_segments(path, n, RATE) == seg
        with pytest.raises(ValueError, match="x.nc .*: 59999 samples, its segments file refers to 60000"):
            read_segments(path, n - 1, RATE, "x.nc")
        y, r, sy = decimate_segments(np.zeros(n), RATE, 1.0, seg)
        write_series(tmp_path / "d.nc", y, rate_hz=r, units="m/s^2", attrs={"dataset": "d", **sy.to_attrs()})
        from imupipe.io import read_series

        y2, r2, attrs = read_series(tmp_path / "d.nc")
        back = Segments.from_attrs(attrs, y2.size, r2)
        assert back.bounds == sy.bounds and back.start_s == sy.start_s and "record_segment_bounds" not in attrs
        assert Segments.from_attrs({"dataset": "d"}, 7, 1.0).is_whole  # a file without segments: the whole record

    def test_records_keep_the_axis_last(self):
        seg, n = _three()
        recs = segment_records(np.arange(n, dtype=float), seg, "imu1/x")
        assert list(recs) == ["imu1#1/x", "imu1#2/x", "imu1#3/x"] and recs["imu1#2/x"][0] == 20_100
        assert list(segment_records(np.zeros(5), Segments.whole(5, 1.0), "imu1/x")) == ["imu1/x"]


def test_pooled_edf_identities():
    # equal segments: K times one; non-overlapping Welch windows (edf 2K each): 2 sum K, the record's own rule
    assert pooled_edf([10, 10, 10], [7.0, 7.0, 7.0]) == pytest.approx(21.0, rel=1e-15)
    assert pooled_edf([3, 5, 1], [6.0, 10.0, 2.0]) == pytest.approx(18.0, rel=1e-15)
    assert pooled_edf([4, 0], [8.0, 1.0]) == pytest.approx(8.0, rel=1e-15)  # a zero count leaves its segment out


class TestPooledAllan:
    def test_equals_the_direct_sums_over_segments(self, rng):
        from imupipe.allan import overlapping_avar

        seg, n = _three()
        x = rng.standard_normal(n)
        av = pooled_allan(x, RATE, seg, taus="octave")
        m = av.coords["m"][0]
        num, den = np.zeros(m.size), np.zeros(m.size)
        for a, b in seg.bounds:
            ok = m <= (b - a) // 4
            terms = (b - a) + 1 - 2 * m[ok]
            num[ok] += overlapping_avar(x[a:b], RATE, m[ok], method="direct") * terms
            den[ok] += terms
        # float64 sums of <= 6e4 terms: relative rounding <= n u ~ 1e-11
        np.testing.assert_allclose(av.data_vars["avar"][0], num / den, rtol=1e-10)
        np.testing.assert_array_equal(av.coords["n_terms"][0], den)
        assert av.attrs["n_samples"] == 24_600 and av.attrs["n_samples_analysed"] == int(seg.lengths.sum())

    def test_differences_stay_within_a_segment(self, rng):
        # per-segment offsets (the size of a tilt step) change nothing: no second difference spans a cut
        seg, n = _three()
        x = rng.standard_normal(n)
        shifted = x.copy()
        for k, (a, b) in enumerate(seg.bounds):
            shifted[a:b] += 50.0 * k
        shifted[19_900:20_100] = 1e6  # the cut-out samples are never read
        a1 = pooled_allan(x, RATE, seg)
        a2 = pooled_allan(shifted, RATE, seg)
        np.testing.assert_allclose(a2.data_vars["avar"][0], a1.data_vars["avar"][0], rtol=1e-9)

    def test_white_noise_mean_and_edf_against_the_closed_form(self, rng):
        # white rate noise of variance s2 per sample: AV(m) = s2 / m exactly; the pooled estimate's exact variance
        # from the segments' exact covariances (imupipe.avcov, independent segments) gives the exact edf
        from imupipe.allan import allan_variance_labelled
        from imupipe.avcov import avar_covariance
        from imupipe.models import NoiseModel

        seg, n = _three()
        s2 = 4.0
        x = rng.normal(scale=np.sqrt(s2), size=n)
        av = pooled_allan(x, RATE, seg)
        m = av.coords["m"][0]
        model = NoiseModel(white=np.sqrt(s2 / RATE))
        var, ratios = np.zeros(m.size), []
        total = av.coords["n_terms"][0].astype(float)
        for a, b in seg.bounds:
            ok = m <= (b - a) // 4
            c = (b - a) + 1 - 2 * m[ok]
            v = np.diag(avar_covariance(model, m[ok], b - a, RATE))
            var[ok] += (c / total[ok]) ** 2 * v
            own = allan_variance_labelled(x[a:b], RATE, taus=m[ok] / RATE)
            ratios.append(own.data_vars["edf"][0] / (2.0 * (s2 / m[ok]) ** 2 / v))
        edf_exact = 2.0 * (s2 / m) ** 2 / var
        # the pooled edf of segment edfs that are r_k x their exact values lies between min r and max r x exact
        lo = np.min([r.min() for r in ratios]) * (1 - 1e-12)
        hi = np.max([r.max() for r in ratios]) * (1 + 1e-12)
        ratio = av.data_vars["edf"][0] / edf_exact
        assert np.all((ratio >= lo) & (ratio <= hi)), (ratio, lo, hi)
        # and with the exact segment edfs the pooled formula gives the exact pooled edf (independent segments)
        exact_k = np.zeros((len(seg.bounds), m.size))
        counts = np.zeros((len(seg.bounds), m.size))
        for k, (a, b) in enumerate(seg.bounds):
            ok = m <= (b - a) // 4
            counts[k, ok] = (b - a) + 1 - 2 * m[ok]
            exact_k[k, ok] = 2.0 * (s2 / m[ok]) ** 2 / np.diag(avar_covariance(model, m[ok], b - a, RATE))
        np.testing.assert_allclose(pooled_edf(counts, np.where(counts > 0, exact_k, 1.0)), edf_exact, rtol=1e-10)
        # the estimate itself: within 4.4 exact sds of s2/m at every tau (Bonferroni over 13 points at 1e-4)
        z = (av.data_vars["avar"][0] - s2 / m) / np.sqrt(var)
        assert np.all(np.abs(z) < 4.4), z

    def test_the_whole_record_is_the_record_own_estimate(self, rng):
        from imupipe.allan import allan_variance_labelled

        x = rng.standard_normal(4000)
        a = pooled_allan(x, RATE, Segments.whole(x.size, RATE))
        b = allan_variance_labelled(x, RATE)
        np.testing.assert_array_equal(a.data_vars["avar"][0], b.data_vars["avar"][0])
        assert a.attrs == b.attrs


class TestPooledPsd:
    def test_windows_never_straddle_a_cut(self, rng):
        # per-segment offsets of 1e3 noise sds: a window across a cut would see a step and raise the low bins by
        # orders of magnitude; with the windows inside segments the PSD is unchanged to rounding
        seg, n = _three()
        y = rng.standard_normal(n)
        shifted = y.copy()
        for k, (a, b) in enumerate(seg.bounds):
            shifted[a:b] += 1e3 * (k + 1)
        kw = dict(window_s=20.0, step_s=10.0, units="rad/s")
        p1, p2 = pooled_psd(y, RATE, seg, **kw), pooled_psd(shifted, RATE, seg, **kw)
        # detrending subtracts the offset first (spectra._detrend_inplace): only rounding of 1e3-sized values, ~1e-13
        np.testing.assert_allclose(p2.data_vars["psd"][0], p1.data_vars["psd"][0], rtol=1e-8)

    def test_is_the_window_weighted_average_of_the_segments(self, rng):
        from imupipe.spectra import psd_labelled, welch_edf

        seg, n = _three()
        y = rng.standard_normal(n)
        kw = dict(window_s=20.0, step_s=10.0)
        pooled = pooled_psd(y, RATE, seg, **kw)
        parts = [psd_labelled(y[a:b], RATE, **kw) for a, b in seg.bounds]
        k = np.array([p.attrs["n_segments"] for p in parts])
        expect = sum(kk * p.data_vars["psd"][0] for kk, p in zip(k, parts)) / k.sum()
        np.testing.assert_allclose(pooled.data_vars["psd"][0], expect, rtol=1e-13)
        assert pooled.attrs["n_segments"] == k.sum()
        nu = [welch_edf("hann", 2000, 1000, kk) for kk in k]
        assert pooled.attrs["edf"] == pytest.approx(k.sum() ** 2 / np.sum(k**2 / np.array(nu)), rel=1e-12)

    def test_segments_without_a_window_are_named_and_none_is_an_error(self, rng):
        seg, n = _three()
        y = rng.standard_normal(n)
        p = pooled_psd(y, RATE, seg, window_s=200.0, step_s=100.0)  # 20 000 samples: only the last segment holds one
        assert p.attrs["n_record_segments"] == 1 and "0.0-199.0 s" in p.attrs["segments_without_window"]
        with pytest.raises(ValueError, match="no segment .* holds one PSD window of 300 s"):
            pooled_psd(y, RATE, seg, window_s=300.0, step_s=100.0)


def test_decimation_blocks_stay_within_segments(rng):
    seg, n = _three()
    x = rng.standard_normal(n)
    y, r, sy = decimate_segments(x, RATE, 1.0, seg)
    assert r == 1.0 and sy.bounds == ((0, 199), (199, 347), (347, 593)) and sy.start_s == seg.start_s
    np.testing.assert_allclose(y[199], x[20_100:20_200].mean(), rtol=1e-12)  # first block of segment 2
    whole, _, sw = decimate_segments(x, RATE, 1.0, Segments.whole(n, RATE))
    assert sw.is_whole and whole.size == n // 100


def test_stationarity_tests_each_segment():
    # two segments of white noise whose means differ by 20 sds: the whole record fails the paper's test, each
    # segment passes at alpha/2 (p-value of the axis: 2 x the smallest)
    from imupipe.stages.stationarity import stationarity_stage

    rng = np.random.default_rng(5)
    x = rng.standard_normal(4000)
    x[2000:] += 20.0
    seg = Segments(((0, 2000), (2000, 4000)), 4000, 1.0, (0.0, 2100.0))
    whole = stationarity_stage(x, 1.0, test="paper")
    split = stationarity_stage(x, 1.0, test="paper", segments=seg)
    assert not whole["stationary"] and split["stationary"]
    assert [s["start_s"] for s in split["segments"]] == [0.0, 2100.0]
    assert split["p_value"] == pytest.approx(min(1.0, 2 * min(s["p_value"] for s in split["segments"])))
    assert split["paper"]["alpha"] == 0.025


def test_outliers_stage_cuts_at_the_step():
    from test_outliers import TestEventsInTheStage

    from imupipe.stages.outliers import outliers_stage

    x = TestEventsInTheStage._record()  # 2000 s at 100 Hz, a 3.4 mg step at 1234.5 s
    out, x_out = outliers_stage(x, 100.0, units="m/s^2", dataset="rec", sensor="accel", axis="x",
                                events={"policy": "split"}, min_segment_s=600.0)
    assert x_out is None  # the series as recorded; the segments travel in their own file
    seg = Segments.from_dict(out["events_segments"])
    (a0, b0), (a1, b1) = seg.bounds
    # each side of the step less the 1 s guard, the step located within 1 s
    assert a0 == 0 and b1 == x.size and abs(b0 / 100.0 - 1233.5) <= 1.0 and abs(a1 / 100.0 - 1235.5) <= 1.0
    [ev] = out["events"]
    assert ev["policy"] == "split" and ev["action"].startswith("cut: the record is analysed as 2 segment(s)")
    with pytest.raises(ValueError, match="rec/accel/x: events.policy = 'split' leaves no segment of at least"):
        outliers_stage(x, 100.0, units="m/s^2", dataset="rec", sensor="accel", axis="x", events={"policy": "split"},
                       min_segment_s=1800.0)
