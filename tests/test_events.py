"""imupipe.events on simulated records with a known truth (white + Gauss-Markov + random walk, exact simulation:
imupipe.simulate), with and without a mean step and a burst (a knock followed by a tilt, as on a real ADIS16405
record: accel 0.5 g for 0.2 s, then the mean shifted by 3.4 mg).

Tolerances: the false-alarm rate is an upper bound alpha per record (union bound, module docstring); over R
event-free records the number of records with an event is at most binomial(R, alpha), so more than its 0.999
quantile refutes the bound with probability of error 1e-3. The step's time: the issue asks for 1 s. The size
interval is at 95 %: a miss on the one seeded record is a 5 % event, the same check over 20 records allows up to
the binomial(20, 0.05) 0.999 quantile (4 misses).
"""

import math

import numpy as np
import pytest
from scipy.stats import binom

from imupipe.allan import allan_variance
from imupipe.events import (detect_events, display_unit, event_flags, event_free_segment, find_bursts,
                            find_steps)
from imupipe.identify import fit_allan
from imupipe.models import NoiseModel
from imupipe.simulate import simulate

G = 9.80665
#: ADIS16405-like accelerometer axis (m/s^2): white 2e-3 m/s^2/sqrt(Hz) (2 mg per sample at 100 Hz), a GM of
#: 0.03 mg with T = 100 s and a random walk of 3e-6 m/s^2/sqrt(s) (the long-tau rise)
TRUTH = NoiseModel(white=2e-3, gauss_markov=((3e-4, 100.0),), random_walk=3e-6)
#: coloured noise where the random walk and a short GM dominate (the pooled real fits' T = 0.05 s GM)
TRUTH_RW = NoiseModel(white=2e-3, gauss_markov=((1e-3, 0.05),), random_walk=3e-5)
STEP = 3.4e-3 * G  # m/s^2
KNOCK = 0.5 * G  # m/s^2


def _with_events(x, rate, t_step_s, t_knock_s=None, knock_s=0.2):
    """x plus a mean step at t_step_s and, optionally, a knock (a 5 Hz oscillation of amplitude KNOCK)."""
    y = x.copy()
    i0 = int(round(t_step_s * rate))
    y[i0:] += STEP
    if t_knock_s is not None:
        k0, k1 = int(round(t_knock_s * rate)), int(round((t_knock_s + knock_s) * rate))
        y[k0:k1] += KNOCK * np.sin(2 * np.pi * 5.0 * np.arange(k1 - k0) / rate)
    return y, i0


class TestFalseAlarms:
    def test_a_white_noise_level_change_is_not_a_train_of_mean_steps(self):
        # an outside evaluation: white noise 3x its sd over the second half read as about 20 mean excursions per
        # axis (every fluctuation of the noisier half against the whole record's scale). Against the larger of the
        # record's and the neighbourhood's scale: 1.75 per record over 20 records (benchmarks/events_level_change.py;
        # 20 before, the most reported); a mean step of 2 sigma_D(1 s) beside it is still found
        rate, n = 20.0, 144_000
        truth = NoiseModel(white=1e-3, gauss_markov=((2e-4, 200.0),))
        rng = np.random.default_rng(4402)
        x = simulate(truth, n, rate, rng)
        x[n // 2:] += np.sqrt(8.0) * truth.white * np.sqrt(rate) * rng.standard_normal(n - n // 2)
        steps = [e for e in detect_events(x, rate)["events"] if e["kind"] != "burst"]
        assert len(steps) <= 5, [(e["kind"], e["time_s"]) for e in steps]
        t0 = n // 4
        x[t0:] += 3e-3
        found = [e for e in detect_events(x, rate)["events"] if abs(e["index"] - t0) <= 2 * rate]
        assert found and found[0]["kind"] == "step"

    @pytest.mark.parametrize("truth", [TRUTH, TRUTH_RW], ids=["white+gm+rw", "rw+short-gm"])
    def test_rate_at_most_alpha_on_event_free_coloured_records(self, truth):
        # alpha = 0.2 so that the bound is measurable with 100 records of 1000 s at 100 Hz (the union bound holds at
        # any alpha); the 0.999 binomial quantile of 100 records at 0.2 is 33
        R, alpha, rate, n = 100, 0.2, 100.0, 100_000
        hits = 0
        for r in range(R):
            x = simulate(truth, n, rate, rng=5000 + r)
            hits += bool(detect_events(x, rate, alpha=alpha)["events"])
        assert hits <= binom.ppf(0.999, R, alpha), hits

    def test_thresholds_follow_the_union_bound(self):
        # each scan's threshold is the t quantile at alpha / (2 S K) (steps, two-sided) and alpha / K (bursts)
        from scipy.stats import t as student

        x = simulate(TRUTH, 200_000, 100.0, rng=3)
        res = detect_events(x, 100.0, alpha=0.01)
        scales = res["step_scan"]["scales"]
        S = len(scales)
        for row in scales:
            m = row["tau_s"] * 100.0
            nu = 0.37 * (200_000 - 2 * m) / (2 * m)
            assert row["threshold_z"] == pytest.approx(student.isf(0.005 / (2 * S * row["positions"]), nu), rel=1e-9)
        K = res["burst_scan"]["blocks"]
        assert res["burst_scan"]["threshold_z"] == pytest.approx(student.isf(0.005 / K, 0.37 * K), rel=1e-9)


class TestKnockAndTilt:
    def test_step_and_burst_found_located_and_sized(self):
        rate, n = 100.0, 400_000
        x = simulate(TRUTH, n, rate, rng=21)
        assert detect_events(x, rate, alpha=0.01, sensor="accel")["events"] == []  # the same record, no event
        y, i0 = _with_events(x, rate, t_step_s=2345.67, t_knock_s=2344.0)
        ev = detect_events(y, rate, alpha=0.01, sensor="accel")["events"]
        steps = [e for e in ev if e["kind"] == "step"]
        bursts = [e for e in ev if e["kind"] == "burst"]
        assert len(steps) == 1 and len(bursts) == 1, ev
        s = steps[0]
        assert abs(s["time_s"] - i0 / rate) <= 1.0, s
        assert s["size_low"] <= STEP <= s["size_high"], s
        assert s["display"]["unit"] == "mg" and s["display"]["size"] == pytest.approx(s["size"] / (1e-3 * G))
        b = bursts[0]
        assert 2343.9 <= b["start_s"] <= 2344.2 and 2344.0 <= b["stop_s"] <= 2344.3, b
        assert b["size"] == pytest.approx(KNOCK, rel=0.1)  # the knock's peak over the local median
        assert b["display"]["unit"] == "g"

    def test_an_events_p_value_is_the_level_at_which_the_scan_would_stop_finding_it(self):
        """p_value inverts the thresholds' rule (Bonferroni over the scan's positions and scales, alpha split between
        the burst and step scans): the scan finds the event at every alpha above its p_value and none below it, so
        an event with p_value < alpha / n is beyond the scan's level over n axes (the summary's chance verdict)."""
        rate = 100.0
        x = simulate(TRUTH, 400_000, rate, rng=21)
        y, _ = _with_events(x, rate, t_step_s=2345.67, t_knock_s=2344.0)
        ev = detect_events(y, rate, alpha=0.01, sensor="accel")["events"]
        assert {e["kind"] for e in ev} == {"step", "burst"}
        assert all(0.0 <= e["p_value"] < 1e-20 for e in ev), ev  # a 0.5 g knock and a 3.4 mg step: far beyond
        # a step near the threshold: the scan at alpha just above its p_value finds it, just below does not (the
        # thresholds' quantiles are exact down to p ~ 1e-12, where 1 - p still holds p's digits)
        z = x + np.where(np.arange(x.size) >= 200_000, 0.6e-3 * G, 0.0)
        (weak,) = detect_events(z, rate, alpha=0.01)["events"]
        assert weak["kind"] == "step" and 1e-8 < weak["p_value"] < 0.01, weak
        kinds = [[f["kind"] for f in detect_events(z, rate, alpha=a)["events"]]
                 for a in (1.05 * weak["p_value"], 0.95 * weak["p_value"])]
        assert kinds == [["step"], []], (weak, kinds)

    def test_location_and_interval_over_records(self):
        # 20 records (1000 s at 100 Hz), a step alone at a random time: every one found within 1 s; its 95 %
        # size interval misses the truth on at most binom.ppf(0.999, 20, 0.05) = 4 records
        rate, n, R = 100.0, 100_000, 20
        rng = np.random.default_rng(8)
        misses = 0
        for r in range(R):
            x = simulate(TRUTH_RW, n, rate, rng=700 + r)
            y, i0 = _with_events(x, rate, t_step_s=float(rng.uniform(200.0, 800.0)))
            steps = find_steps(y, rate, alpha=0.005)["steps"]
            assert len(steps) >= 1
            s = min(steps, key=lambda s: abs(s["index"] - i0))
            assert abs(s["index"] - i0) / rate <= 1.0, (r, s, i0)
            misses += not (s["size_low"] <= STEP <= s["size_high"])
        assert misses <= binom.ppf(0.999, R, 0.05)

    def test_undetectable_step_is_not_reported(self):
        # a step of 0.5 sigma_D at the best scale cannot pass a threshold of ~5.5 sigma_D: nothing reported
        rate = 100.0
        x = simulate(TRUTH, 200_000, rate, rng=4)
        sd = min(r["sigma_d"] for r in find_steps(x, rate)["scales"])
        y = x.copy()
        y[100_000:] += 0.5 * sd
        assert find_steps(y, rate)["steps"] == []

    @pytest.mark.parametrize("decay_s", [0.4, 2.0, 5.0, 8.0])
    def test_a_ringing_knock_is_no_step(self, decay_s):
        # an outside evaluation's 7.3 Hz knock decaying over 5 s rang 4-5 sds beyond its span: the step scan's fill
        # levels (medians of a tenth of a window beside the span) differed and a 129 deg/h "step" was reported, in 3
        # of 3 records at each decay 0.4-8 s (11.1 Hz here, other records). The fill now spans the burst's tail and
        # takes its medians over a window: a step at the knock is then a chance one (alpha / 2 per record)
        rate = 100.0
        for seed in (31, 32):
            x = simulate(TRUTH, 360_000, rate, rng=seed + int(10 * decay_s))
            t = np.arange(int(8 * decay_s * rate)) / rate
            i0 = 123_456
            x[i0:i0 + t.size] += 100 * TRUTH.white * math.sqrt(rate) * np.exp(-t / decay_s) * np.sin(
                2 * np.pi * 11.1 * t)
            kinds = [e["kind"] for e in detect_events(x, rate, alpha=0.01)["events"]]
            assert kinds == ["burst"], (seed, kinds)

    @pytest.mark.parametrize("offset_s", [-1.0, 3.0, 12.0])
    def test_a_step_inside_a_ringing_knock_keeps_its_size_and_names_the_stretch(self, offset_s):
        # a straight-line fill made a tilt inside a ringing knock's 20-30 s stretch a ramp: sized 0.83x, its 95 %
        # interval missing the truth in every record (an outside evaluation). The two flat halves keep the size: the
        # levels either side, read over half the stretch; its time is the stretch's middle, and the event names the
        # range it lies in (the stretch and the samples its levels come from)
        rate = 100.0
        for seed in (41, 42):
            x = simulate(TRUTH, 360_000, rate, rng=seed)
            t = np.arange(int(30 * rate)) / rate
            i_knock = 150_000
            x[i_knock:i_knock + t.size] += 80 * TRUTH.white * math.sqrt(rate) * np.exp(-t / 3.0) * np.sin(
                2 * np.pi * 13.3 * t)
            t_step = i_knock / rate + offset_s
            x[int(t_step * rate):] += STEP
            (s,) = [e for e in detect_events(x, rate, alpha=0.01)["events"] if e["kind"] == "step"]
            a, c = s["within_burst_s"]
            assert a <= t_step <= c and a <= s["time_s"] <= c, (s, t_step)
            half = (s["size_high"] - s["size_low"]) / 2  # 95 %: 1.96 sd of the size; 3 sd: 0.3 % per record
            assert abs(s["size"] - STEP) <= 3 * half / 1.96, (seed, s)

    def test_burst_alone(self):
        rate = 100.0
        x = simulate(TRUTH, 100_000, rate, rng=6)
        y = x.copy()
        y[50_000:50_020] += 0.5 * G
        b = find_bursts(y, rate)["bursts"]
        assert [(e["start"], e["stop"]) for e in b] == [(50_000, 50_020)]


class TestExclude:
    def test_random_walk_of_the_event_free_segment_matches_the_record_without_the_step(self):
        # 10 h at 10 Hz, the random walk dominating the Allan variance beyond ~100 s; the step at 7 h multiplies
        # the random walk identified on the whole record (by ~40 on this seed); the longest event-free segment
        # (the first 7 h) gives a K inside the 95 % interval of the record without the step
        rate, n = 10.0, 360_000
        x = simulate(TRUTH, n, rate, rng=31)
        y, i0 = _with_events(x, rate, t_step_s=25_200.0)
        ev = detect_events(y, rate, alpha=0.01, sensor="accel")["events"]
        assert any(e["kind"] == "step" and abs(e["index"] - i0) <= rate for e in ev), ev
        a, b = event_free_segment(n, ev, guard=int(rate))
        assert a == 0 and abs(b - i0) <= 2 * rate  # the first 7 h, up to the step and its guard

        def fit(z, n_boot=0):
            av = allan_variance(z, rate, taus="octave")
            return fit_allan(av.tau.values, av.avar.values, av.edf.values,
                             components=("white", "gauss_markov", "random_walk"), n_boot=n_boot, rng=1,
                             record_rate_hz=rate, n_samples=z.size)

        ref = fit(x, n_boot=100)
        lo, hi = ref.intervals["random_walk"]
        k_seg = fit(y[a:b]).params["random_walk"]
        k_step = fit(y).params["random_walk"]
        assert lo <= TRUTH.random_walk <= hi  # the reference's interval holds the truth (else the check is void)
        assert lo <= k_seg <= hi, (k_seg, lo, hi)
        assert k_step > hi, (k_step, hi)  # the step left in inflates K beyond the interval: the check can fail


class TestReportHelpers:
    def test_segment_of_no_event_is_the_record(self):
        assert event_free_segment(1000, []) == (0, 1000)
        assert event_free_segment(1000, [{"index": 300, "stop_index": 310}], guard=5) == (315, 1000)
        assert event_free_segment(1000, [{"index": 700}, {"index": 100}]) == (100, 700)

    def test_flag_text_names_where_when_and_size(self):
        item = {"dataset": "rec", "sensor": "accel", "axis": "x", "kind": "step", "time_s": 2345.6,
                "start_s": 2345.6, "stop_s": 2345.6, "size": 0.0333, "size_low": 0.032, "size_high": 0.0345,
                "units": "m/s^2", "display": {"unit": "mg", "size": 3.40}, "action": "kept in the analysis"}
        [(where, text)] = event_flags([item])
        assert where == "rec/accel/x"
        assert text == ("mean step 0.0333 m/s^2 [0.032, 0.0345] (3.4 mg) at 2345.6 s from the record's start; "
                        "kept in the analysis")
        assert display_unit("gyro", "step")[0] == "deg/h" and display_unit("gyro", "burst")[0] == "deg/s"

    def test_the_first_screen_form_keeps_the_effect_as_its_number(self):
        """An outside evaluation: the first screen's event FLAG left its effect on the model to the details, and a
        user saw the bound inflated without the reason. The short form keeps the number: the random walk K a step
        acts as (display unit), N's factor at the shortest tau for a burst; the full form keeps the sentence."""
        step = {"dataset": "rec", "sensor": "accel", "axis": "z", "kind": "step", "time_s": 5400.0, "size": 0.0097,
                "units": "m/s^2", "display": {"unit": "mg", "size": 0.989}, "action": "kept in the analysis",
                "effect": {"kind": "step", "random_walk_equivalent": 9.33e-5, "record_s": 10800.0,
                           "display": {"unit": "mg/sqrt(s)", "random_walk_equivalent": 0.00952}}}
        burst = {"dataset": "rec", "sensor": "accel", "axis": "x", "kind": "burst", "start_s": 10.0, "stop_s": 10.2,
                 "size": 4.9, "units": "m/s^2", "action": "kept in the analysis",
                 "effect": {"tau_s": 0.01, "white_noise_ratio": 1.37}}
        (_, short), (_, short_b) = event_flags([step, burst], short=True)
        assert short.endswith("kept in the analysis: acts as a random walk K = 0.00952 mg/sqrt(s), which can inflate "
                              "the bound")
        assert short_b.endswith("kept in the analysis: its samples raise N 1.37x at the shortest tau")
        (_, full), _ = event_flags([step, burst])
        assert "acts as a random walk K = 9.33e-05 m/s^2/sqrt(s) (0.00952 mg/sqrt(s)) (d^2 tau / (3 T))" in full

    def test_transient_flag_says_when_it_was_over(self):
        item = {"dataset": "rec", "sensor": "accel", "axis": "y", "kind": "transient", "time_s": 7846.9,
                "start_s": 7846.9, "stop_s": 7878.9, "size": 0.0188, "size_low": 0.0127, "size_high": 0.0249,
                "units": "m/s^2"}
        [(_, text)] = event_flags([item])
        assert text == ("mean excursion 0.0188 m/s^2 [0.0127, 0.0249] at 7846.9 s (back by 7878.9 s) from the "
                        "record's start")

    def test_many_events_of_one_record_make_one_flag_each_few_their_own(self):
        # a record with more than MAX_EVENT_FLAGS events (the shipped ADIS16405 accels have 3-11 per axis) gives one
        # line per record and sensor naming the counts and the largest step; another record's 1 event keeps its own
        from imupipe.events import MAX_EVENT_FLAGS

        def step(axis, t, mg, dataset="a"):
            return {"dataset": dataset, "sensor": "accel", "axis": axis, "kind": "step", "time_s": t,
                    "size": mg * 9.80665e-3, "units": "m/s^2", "display": {"size": mg, "unit": "mg"}}

        many = [step("x", 10.0 * i, 1.0 + i) for i in range(MAX_EVENT_FLAGS)] + [
            step("y", 500.0, -9.0), {"dataset": "a", "sensor": "accel", "axis": "z", "kind": "burst", "start_s": 3.0,
                                     "stop_s": 4.0, "size": 0.5, "units": "m/s^2"}]
        flags = event_flags(many + [step("x", 7.0, 2.0, dataset="b")])
        assert [w for w, _ in flags] == ["a/accel", "b/accel/x"]
        text = flags[0][1]
        assert text.startswith(f"{MAX_EVENT_FLAGS + 2} events ({MAX_EVENT_FLAGS} on x, 1 on y, 1 on z; "
                               f"{MAX_EVENT_FLAGS + 1} mean steps, 1 bursts)"), text
        assert "the largest, on axis y: mean step" in text and "(-9 mg) at 500.0 s" in text
        assert len(event_flags(many[:MAX_EVENT_FLAGS])) == MAX_EVENT_FLAGS  # up to the limit: one line each
        # the first screen's form: the same FLAGs in the same order, the largest's size kept, the pointer to the
        # outliers reports and each event's effect on the model left to the full text
        short = event_flags(many + [step("x", 7.0, 2.0, dataset="b")], short=True)
        assert [w for w, _ in short] == ["a/accel", "b/accel/x"]
        assert short[0][1] == text.removesuffix("; each is listed in the outliers report of its axis")

    def test_excursion_edges_are_two_steps_and_a_decaying_kick_a_transient(self):
        rate = 100.0
        x = simulate(TRUTH, 200_000, rate, rng=9)
        # +3.4 mg for 20 s: both edges are steps, each sized within the 20 s between them
        y = x.copy()
        y[100_000:102_000] += STEP
        steps = find_steps(y, rate)["steps"]
        assert [s["kind"] for s in steps] == ["step", "step"], steps
        for s, (i0, size) in zip(steps, [(100_000, STEP), (102_000, -STEP)]):
            assert abs(s["index"] - i0) <= rate and s["size_low"] <= size <= s["size_high"], s
        # a kick of 6 mg decaying in 0.3 s: its rising edge stands out at 1 s (mean of the next second 0.29 x 6 mg =
        # 1.7 mg, z ~ 6 against a threshold of 5.7), its lasting shift (integral 1.8 mg s over the size window of
        # 64 s on a 10 000 s record: 0.03 mg) lies inside that window's 95 % noise (+/- 0.09 mg): one transient,
        # sized at its detecting scale (the seed fixes the noise)
        x = simulate(TRUTH, 1_000_000, rate, rng=9)
        y = x.copy()
        y[100_000:] += 6e-3 * G * np.exp(-np.arange(900_000) / (0.3 * rate))
        [s] = find_steps(y, rate)["steps"]
        assert s["kind"] == "transient" and abs(s["index"] - 100_000) <= rate and s["size_low"] > 0, s
        # its span is the scale it is sized at (an outside evaluation: sized over 1 s but said to last 64 s)
        assert s["size_scale"] == s["scale"] and s["stop"] - s["index"] == s["scale"], s


class TestStepLocalisation:
    def test_change_point_is_the_least_squares_one_on_white_noise(self):
        """On white noise with one step the least-squares change point of the whole record (the CUSUM maximiser,
        Hinkley 1970) is the maximum-likelihood one (error sd sqrt(26) sigma_1^2 / delta^2 samples: the argmax of a
        two-sided Brownian motion with drift -|s|/2 has variance 26). The scan's refinement must reach it: its means
        either side come from the detecting window (1280 samples a side on these 4 h records at 10 Hz), which differ
        from the whole record's by ~sigma_1 / sqrt(1280) = 0.03 delta, less than the step's CUSUM slope changes over
        one sample (delta / 2). Refining in ever narrower windows (20 samples a side at the end, the two means then
        resting on 20 samples) put 3 of these 20 records 2, 9 and 14 samples off it (measured; issue 28)."""
        from imupipe.events import _cusum_argmax

        rate, n, sigma1 = 10.0, 144_000, 1e-3 * np.sqrt(10.0)
        delta = sigma1  # least-squares error sd sqrt(26) = 5 samples
        rng = np.random.default_rng(28)
        off = []
        for r in range(20):
            x = rng.standard_normal(n) * sigma1
            i0 = int(rng.integers(n // 4, 3 * n // 4))
            x[i0:] += delta
            steps = find_steps(x, rate, alpha=0.005)["steps"]
            assert steps, r
            s = min(steps, key=lambda s: abs(s["index"] - i0))
            off.append(abs(s["index"] - _cusum_argmax(x)))
        assert max(off) <= 1, off
