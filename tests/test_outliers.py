"""Hampel/MAD outlier screening: exact counts of injected spikes, the false-detection rate, the policies."""

import math
import warnings

import numpy as np
import pytest
from scipy.stats import poisson

from imupipe.models import NoiseModel
from imupipe.outliers import expected_false_count, hampel, screen_outliers
from imupipe.simulate import simulate

RATE = 100.0
MODEL = NoiseModel(white=1e-3, gauss_markov=((2e-4, 50.0),))  # u/sqrt(Hz); u, s
SIGMA = math.sqrt(1e-6 * RATE + 4e-8)  # per-sample standard deviation, u


def _spiky(rng, n=200_000, n_spikes=50, size=50.0):
    x = simulate(MODEL, n, RATE, rng)
    idx = np.sort(rng.choice(n, n_spikes, replace=False))
    spikes = x.copy()
    spikes[idx] += size * SIGMA * rng.choice([-1.0, 1.0], n_spikes)
    return x, spikes, idx


def _white_N(x):
    """White-noise density from the overlapping AV at tau = 0.1 s (m = 10): N = sqrt(AV tau), u/sqrt(Hz)."""
    from imupipe.allan import overlapping_avar

    tau_m = np.array([10])
    return math.sqrt(float(np.asarray(overlapping_avar(x, RATE, tau_m)).ravel()[0]) * tau_m[0] / RATE)


def test_injected_spikes_counted_exactly(rng):
    clean, x, idx = _spiky(rng)
    with pytest.warns(UserWarning, match="50 outlier"):
        out, rep = screen_outliers(x, "warn", label="sim/x")
    assert rep.n_outliers == 50
    np.testing.assert_array_equal(rep.indices, idx)
    assert out is not x and np.array_equal(out, x)  # warn: values unchanged
    assert rep.to_dict()["n_outliers"] == 50


def test_remove_restores_white_noise(rng):
    # 50 spikes of 50 sigma add ~50 (50 sigma)^2/(m L) to AV(m): at m = 10, L = 2e5 about +6 % on AV(0.1 s) in
    # N; replaced by block medians the N agrees with the clean record's to ~count/L = 2.5e-4 (module
    # docstring): 1 % is the acceptance and far above that, and the spiky record must miss it
    clean, x, idx = _spiky(rng)
    out, rep = screen_outliers(x, "remove")
    n_clean, n_spiky, n_removed = _white_N(clean), _white_N(x), _white_N(out)
    assert n_spiky / n_clean > 1.05
    assert n_removed == pytest.approx(n_clean, rel=0.01)
    np.testing.assert_array_equal(np.flatnonzero(out != x), idx)


def test_clean_record_has_almost_no_detections(rng):
    # expected false detections at k = 7, W = 100 on 1e6 Gaussian samples ~0.01 (module docstring):
    # fail above the Poisson 0.999 quantile of that mean (1 detection at most)
    x = simulate(MODEL, 1_000_000, RATE, rng)
    mu = expected_false_count(x.size)
    assert mu < 0.1
    mask, _, _ = hampel(x)
    assert mask.sum() <= poisson.ppf(0.999, mu)


@pytest.mark.parametrize("k", [4.0, 4.5, 5.0])
def test_expected_false_count_matches_simulation(k):
    # at lower k the count is measurable: 2e6 Gaussian samples, Poisson scatter sqrt(mu): 4 sigma
    x = np.random.default_rng(int(10 * k)).standard_normal(2_000_000)
    mu = expected_false_count(x.size, k, 100)
    count = int(hampel(x, 100, k)[0].sum())
    assert abs(count - mu) < 4 * math.sqrt(mu) + 1


def test_fail_policy_names_the_series(rng):
    _, x, idx = _spiky(rng, n_spikes=3)
    with pytest.raises(ValueError, match=r"imu1/accel/x: 3 outlier\(s\)"):
        screen_outliers(x, "fail", label="imu1/accel/x")
    with pytest.raises(ValueError, match="policy"):
        screen_outliers(x, "drop")


def test_quantised_block_with_zero_mad():
    # coarsely quantised: most samples equal, MAD = 0; the mean-absolute-deviation scale keeps the rule sane
    x = np.zeros(1000)
    x[::7] = 1.0  # one LSB steps, 14 % of samples
    x[500] = 40.0
    mask, _, scale = hampel(x, 100, 7.0)
    assert np.flatnonzero(mask).tolist() == [500]
    assert np.all(np.isfinite(scale))


def test_partial_last_block():
    x = np.random.default_rng(1).standard_normal(1050)
    x[1049] = 100.0
    mask, center, _ = hampel(x, 100, 7.0)
    assert mask[1049] and center.size == 1050


@pytest.mark.parametrize("rec", [1, 2])
def test_adis16405_counts(shared_data, rec):
    """Counts per axis on the real records (reported; the gyro axes are nearly clean, the accelerometers have
    a few tens of spikes of up to ~22 LSB)."""
    import rdata

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        raw = rdata.read_rda(str(shared_data / "adis16405" / "raw" / f"adis_16405_imu{rec}.rda"))
    x = np.asarray(raw[f"adis_16405_imu{rec}"], dtype=np.float64)
    counts = []
    for j in range(6):
        _, rep = screen_outliers(x[:, j], "remove", label=f"imu{rec}/{j}")
        counts.append(rep.n_outliers)
    # measured: imu1 [1, 0, 0, 11, 16, 19], imu2 [0, 0, 0, 5, 49, 20]; well under 1e-4 of the samples
    assert all(c < 100 for c in counts)
    assert sum(counts[3:]) > 0


# ---- stuck spans: runs of exactly repeated samples longer than chance allows (imupipe.outliers.stuck_spans) ----


def _quantised(rng, n, step=0.3):
    """Gaussian samples (sigma 1) rounded to `step` sigma: a live but coarsely quantised sensor."""
    return np.round(rng.standard_normal(n) / step) * step


def test_a_stuck_half_is_found_with_its_span_to_one_sample(rng):
    from imupipe.outliers import stuck_spans

    n, i0, i1 = 400_000, 100_000, 300_000  # samples 100000 .. 299999 stuck: half the record
    x = _quantised(rng, n)
    x[i0:i1] = x[i0]
    out = stuck_spans(x, RATE)
    assert out["n_stuck_spans"] == 1
    (span,) = out["spans"]
    assert span["start_s"] == pytest.approx(i0 / RATE, abs=1.0 / RATE)
    assert span["stop_s"] == pytest.approx((i1 - 1) / RATE, abs=1.0 / RATE)
    assert span["value"] == x[i0] and span["fraction"] == pytest.approx(0.5, abs=2.0 / n)
    # p0 and q are those of the live half (stuck samples left out): about P(two samples in one 0.3-sigma bin)
    assert out["p0"] < 0.15 and out["q"] < 0.15


def test_stuck_spans_on_float_data_at_the_record_ends_and_a_constant_record(rng):
    from imupipe.outliers import stuck_spans

    x = simulate(MODEL, 50_000, RATE, rng)  # float64 noise: no zero difference by chance
    x[-300:] = x[-300]  # the last 3 s
    x[:150] = 0.25  # the first 1.5 s
    spans = stuck_spans(x, RATE)["spans"]
    assert [(s["start_s"], s["stop_s"]) for s in spans] == [(0.0, 1.49), (497.0, 499.99)]
    assert [s["value"] for s in spans] == [0.25, x[-1]]
    assert stuck_spans(x[200:10_000], RATE)["n_stuck_spans"] == 0  # live part only
    const = stuck_spans(np.full(1000, 3.0), RATE)["spans"]
    assert len(const) == 1 and const[0]["n_samples"] == 1000 and const[0]["fraction"] == 1.0
    assert stuck_spans(x[:50], RATE)["n_stuck_spans"] == 0  # 0.5 s constant: shorter than the 1 s floor


def test_the_minimum_run_is_the_smallest_with_fewer_than_alpha_chance_runs():
    from imupipe.outliers import STUCK_ALPHA, stuck_min_run

    n, p0, q = 1_000_000, 0.3, 0.35
    r = stuck_min_run(n, p0, q, RATE, min_s=0.0)
    expected = lambda r: (n - 1) * p0 * q ** (r - 2)  # noqa: E731 (module docstring)
    assert expected(r) < STUCK_ALPHA <= expected(r - 1)
    assert stuck_min_run(n, p0, q, RATE) == 100  # the 1 s floor at 100 Hz dominates here


@pytest.mark.parametrize("correlated", [False, True])
def test_quantised_live_records_give_no_stuck_span(rng, correlated):
    # 1e6 samples at 0.3-sigma steps, white or AR(1) (phi = 0.9: runs of equal values longer than independent
    # differences give): the derived minimum alone (no 1 s floor) allows 0.01 chance runs per record, so a span
    # here is a Poisson(0.01) event (p = 0.01) or a wrong threshold
    from scipy.signal import lfilter

    from imupipe.outliers import stuck_spans

    e = rng.standard_normal(1_000_000)
    y = lfilter([1.0], [1.0, -0.9], e) * math.sqrt(1 - 0.81) if correlated else e
    x = np.round(y / 0.3) * 0.3
    out = stuck_spans(x, RATE, min_s=0.0)
    assert out["n_stuck_spans"] == 0, out["spans"][:3]
    assert out["min_run_samples"] < RATE  # the derivation, not the floor, decided
    assert stuck_spans(x, RATE)["n_stuck_spans"] == 0


class TestEventsInTheStage:
    """imupipe.stages.outliers: the events of the axis in the report, and what events.policy does with them."""

    @staticmethod
    def _record(seed=2):
        # white + GM + random walk, 2000 s at 100 Hz, a 3.4 mg step at 1234.5 s (accel, m/s^2)
        from imupipe.models import NoiseModel
        from imupipe.simulate import simulate

        x = simulate(NoiseModel(white=2e-3, gauss_markov=((3e-4, 100.0),), random_walk=3e-6), 200_000, 100.0,
                     rng=seed)
        x[123_450:] += 3.4e-3 * 9.80665
        return x

    def test_warn_reports_the_step_and_keeps_the_record(self):
        from imupipe.stages.outliers import outliers_stage

        out, x_out = outliers_stage(self._record(), 100.0, units="m/s^2", dataset="rec", sensor="accel", axis="x")
        assert x_out is None  # warn + warn: the modelling stages read the series as recorded
        [ev] = out["events"]
        assert (ev["dataset"], ev["sensor"], ev["axis"], ev["kind"]) == ("rec", "accel", "x", "step")
        assert abs(ev["time_s"] - 1234.5) <= 1.0 and ev["units"] == "m/s^2" and ev["display"]["unit"] == "mg"
        assert ev["policy"] == "warn" and out["events_segment"] == {"start_s": 0.0, "stop_s": 2000.0, "fraction": 1.0}

    def test_exclude_returns_the_longest_event_free_segment(self):
        from imupipe.stages.outliers import outliers_stage

        x = self._record()
        out, x_out = outliers_stage(x, 100.0, units="m/s^2", sensor="accel", events={"policy": "exclude"})
        seg = out["events_segment"]
        # the step at 1234.5 s: the longest side is the first 1234.5 s less the 1 s guard (within the 1 s location)
        assert seg["start_s"] == 0.0 and abs(seg["stop_s"] - 1233.5) <= 1.0
        np.testing.assert_array_equal(x_out, x[: int(round(seg["stop_s"] * 100.0))])
        with pytest.raises(ValueError, match=r"leaves 12\d\d s .* shorter than the 1800 s"):
            outliers_stage(x, 100.0, units="m/s^2", events={"policy": "exclude"}, min_segment_s=1800.0)

    def test_split_with_every_segment_too_short_names_the_axis(self):
        from imupipe.stages.outliers import outliers_stage

        # the step at 1234.5 s leaves 1233.5 s and 764.5 s: neither holds the 1800 s the analysis needs
        with pytest.raises(ValueError, match=r"rec/accel/x: events.policy = 'split' leaves no segment of at least "
                                             r"180000 samples \(1800 s"):
            outliers_stage(self._record(), 100.0, units="m/s^2", dataset="rec", sensor="accel", axis="x",
                           events={"policy": "split"}, min_segment_s=1800.0)

    def test_summary_flags_each_event(self):
        from imupipe.stages.outliers import outliers_stage
        from imupipe.summary import flags_of

        out, _ = outliers_stage(self._record(), 100.0, units="m/s^2", dataset="rec", sensor="accel", axis="x")
        flags = [f for f in flags_of("accel", bound={"events": out["events"]}) if f.check == "event"]
        assert len(flags) == 1 and flags[0].where == "rec/accel/x"
        assert flags[0].detail.startswith("mean step 0.033") and "mg) at 123" in flags[0].detail


class TestEventsInTheWorkflow:
    """The events of the tiny run's reports and what events.policy does to the DAG (tests/configs/tiny.yaml)."""

    @staticmethod
    def _changed(work, config, name, **sections):
        import yaml

        cfg = yaml.safe_load(config.read_text())
        for key, value in sections.items():
            cfg[key] = {**(cfg.get(key) or {}), **value}
        path = work / f"changed_{name}.yaml"
        path.write_text(yaml.safe_dump(cfg))
        return path

    def test_event_free_simulation_reports_no_more_than_the_false_alarm_rate(self, tiny_run):
        # 12 simulated event-free axes at alpha = 0.01 each (an upper bound): more than the 0.999 binomial
        # quantile of events-bearing axes refutes the bound
        import yaml
        from scipy.stats import binom

        from workflow_helpers import RES

        work, _ = tiny_run
        reports = sorted((work / RES / "outliers").glob("*/*/*.yaml"))
        assert len(reports) == 12
        hit = 0
        for path in reports:
            rep = yaml.safe_load(path.read_text())
            assert rep["events_policy"] == "warn" and rep["n_events"] == len(rep["events"])
            assert rep["events_scan"]["false_alarm_rate_per_record"] == 0.01
            hit += rep["n_events"] > 0
        assert hit <= binom.ppf(0.999, 12, 0.01)

    def test_exclude_feeds_the_segment_and_split_the_segments(self, tiny_run):
        pytest.importorskip("snakemake")
        from workflow_helpers import RES, snakemake

        work, config = tiny_run
        changed = self._changed(work, config, "exclude", events={"policy": "exclude"})
        out = snakemake(work, "-n", config=changed, snakefile=work / "Snakefile").stdout
        for rule in ("allan", "decimate", "lines"):
            block = out.split(f"rule {rule}:", 1)[1].split("\n\n", 1)[0]
            assert f"input: {RES}/cleaned/" in block, (rule, block)
        # split: the full-rate stages read the series as recorded and the axis's segments file
        split = self._changed(work, config, "split", events={"policy": "split"})
        out = snakemake(work, "-n", config=split, snakefile=work / "Snakefile").stdout
        for rule in ("allan", "decimate", "lines"):
            block = out.split(f"rule {rule}:", 1)[1].split("\n\n", 1)[0]
            assert f"{RES}/series/" in block and f"{RES}/segments/" in block, (rule, block)

    def test_summary_script_flags_the_events_of_the_outliers_files(self, tmp_path):
        # the rule summary reads the outliers files (SUMMARY_INPUTS): each event becomes one FLAG line naming
        # dataset/sensor/axis, time and size
        import yaml

        from imupipe.stages.outliers import outliers_stage
        from imupipe.stages.summary import summary_text
        from imupipe.summary import first_screen

        x = TestEventsInTheStage._record()
        paths = []
        for axis in ("x", "y"):
            out, _ = outliers_stage(x, 100.0, units="m/s^2", dataset="rec", sensor="accel", axis=axis)
            paths.append(tmp_path / f"{axis}.yaml")
            paths[-1].write_text(yaml.safe_dump(out))
        text = summary_text({"outliers": [str(p) for p in paths]}, ["gyro", "accel"], ["spec"], "run")
        flags = [line for line in first_screen(text).splitlines() if line.startswith("- FLAG event")]
        assert [f.split("]")[0] for f in flags] == ["- FLAG event [rec/accel/x", "- FLAG event [rec/accel/y"]
        assert all("mean step 0.033" in f and " mg) at 123" in f for f in flags), flags

    def test_events_section_reruns_the_reports_alone_under_warn(self, tiny_run):
        # warn: the events are a report, which the run summary reads (and the run verdict, the last job), but for the
        # bursts the line search fills (its own scan, with events.alpha, burst_window_s and burst_k as params:
        # tests/test_workflow_stages.py); nor does psd.window_s (the shortest segment `exclude` accepts) reach the
        # outliers jobs under warn
        from workflow_helpers import dry_run_jobs

        work, config = tiny_run
        jobs = dry_run_jobs(work, config=self._changed(work, config, "ev_scale", events={"min_scale_s": 2.0}))
        assert jobs == {"outliers": 12, "summary": 1, "integrity": 1, "all": 1}
        jobs = dry_run_jobs(work, config=self._changed(work, config, "ev_psd", psd={"window_s": 1200.0}))
        assert "outliers" not in jobs and "psd" in jobs
