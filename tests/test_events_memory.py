"""The outliers job's event scan without record-length work arrays beyond one cumulative sum: the same events,
outlier counts and steps as the whole-array scan it replaced, and a peak far below the whole-array scan's.

The expected values below were computed by the whole-array scan (events.py before the change: block deviations
of the whole record, a cleaned copy of the record for the step scan, index arrays per scale) on the same
records; the indices and counts are compared exactly, the sizes to 1e-12 relative (the same operations in the
same order give the same bits on one machine; 1e-12 leaves room for another BLAS or SIMD path, far below the
1e-2 relative width of a size interval).
"""

import tracemalloc
import warnings

import numpy as np
import pytest
from scipy.signal import lfilter

import imupipe.events as events_mod
from imupipe.events import detect_events
from imupipe.stages.outliers import outliers_stage

G = 9.80665
RATE = 100.0


def _record(seed, n=200_000):
    """White 2e-3 m/s^2/sqrt(Hz) + a GM (3e-4 m/s^2, T = 100 s) + a random walk 3e-6 m/s^2/sqrt(s) (the
    ADIS16405-like axis of tests/test_events.py, drawn with numpy alone), a knock (0.5 g at 5 Hz for 0.2 s) at
    a third, a mean step of 3.4 mg at two thirds and two single spikes of 0.2 m/s^2."""
    rng = np.random.default_rng(seed)
    dt = 1.0 / RATE
    phi = np.exp(-dt / 100.0)
    gm = lfilter([3e-4 * np.sqrt(1 - phi**2)], [1.0, -phi], rng.standard_normal(n))
    x = 2e-3 / np.sqrt(dt) * rng.standard_normal(n) + gm  # the white noise drawn before the random walk
    x += 3e-6 * np.sqrt(dt) * np.cumsum(rng.standard_normal(n))
    k0 = n // 3 + 101 * seed
    x[k0:k0 + 20] += 0.5 * G * np.sin(2 * np.pi * 5.0 * np.arange(20) / RATE)
    x[2 * n // 3 + 37 * seed:] += 3.4e-3 * G
    x[[1000 + seed, n // 2]] += 0.2
    return x


#: seed -> (outlier count, first outlier indices, events (kind, index, stop index, size in m/s^2)) of the
#: whole-array scan
BEFORE = {
    0: (20, [1000, 66667, 66668, 66669, 66670, 66671, 66672, 66673, 66674, 66675, 66677, 66678, 66679, 66680,
             66681, 66682, 66683, 66684, 66685, 100000],
        [("burst", 1000, 1001, "0x1.9eea1711e7245p-3"), ("burst", 66667, 66686, "0x1.3a147f92ee0c9p+2"),
         ("burst", 100000, 100001, "0x1.697d7989ce8dfp-3"),
         ("step", 133332, 133332, "0x1.10fee963f4b9ap-5")]),
    1: (20, [1001, 66768, 66769, 66770, 66771, 66772, 66773, 66774, 66775, 66776, 66778, 66779, 66780, 66781,
             66782, 66783, 66784, 66785, 66786, 100000],
        [("burst", 1001, 1002, "0x1.c983ee2eb1012p-3"), ("burst", 66768, 66787, "0x1.3a73d45241327p+2"),
         ("burst", 100000, 100001, "0x1.6d5e3eed61896p-3"),
         ("step", 133374, 133374, "0x1.066d3bdb9d8f6p-5")]),
    2: (20, [1002, 66869, 66870, 66871, 66872, 66873, 66874, 66875, 66876, 66877, 66879, 66880, 66881, 66882,
             66883, 66884, 66885, 66886, 66887, 100000],
        [("burst", 1002, 1003, "0x1.c2b74ad867d57p-3"), ("burst", 66869, 66888, "0x1.39582911bd650p+2"),
         ("burst", 100000, 100001, "0x1.c31a51ae7f148p-3"),
         ("step", 133407, 133407, "0x1.162bbf4b54ce1p-5")]),
}


def _check(seed, events):
    _, _, want = BEFORE[seed]
    assert [(e["kind"], e["index"], e["stop_index"]) for e in events] == [w[:3] for w in want]
    sizes = [float.fromhex(w[3]) for w in want]
    np.testing.assert_allclose([e["size"] for e in events], sizes, rtol=1e-12, atol=0)


@pytest.mark.parametrize("seed", sorted(BEFORE))
def test_events_outliers_and_steps_equal_the_whole_array_scan(seed):
    x = _record(seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the policy warn's UserWarning about the outliers
        out, _ = outliers_stage(x, RATE, units="m/s^2", sensor="accel")
    count, first, _ = BEFORE[seed]
    assert out["n_outliers"] == count and out["indices"][:25] == first
    _check(seed, detect_events(x, RATE, sensor="accel")["events"])


def test_the_burst_scan_in_batches_of_a_few_blocks_gives_the_same_events(monkeypatch):
    # 10 blocks of 1 s per batch instead of ~2600: every block's energy is computed alone, so the same bits
    monkeypatch.setattr(events_mod, "EVENTS_BATCH", 1_000)
    _check(1, detect_events(_record(1), RATE, sensor="accel")["events"])


def test_detect_events_holds_one_cumulative_sum_beyond_the_record():
    """Peak of the allocations (tracemalloc sees numpy's buffers) during detect_events on 2**22 samples
    (33.5 MB) with a knock and a step: the cumulative sum (n + 1 float64), the step scan's |D| at the shortest
    scale (one array of n / 25 positions: 0.04 n), and fixed work arrays (a batch of the burst scan, 2**18
    samples, and the 2000 blocks of its covariance estimate with their FFTs: below 12 MB). The whole-array
    scan held the block deviations of the record and a cleaned copy besides the cumulative sum (> 2 x the
    record)."""
    rng = np.random.default_rng(4)
    n = 1 << 22
    x = 0.02 * rng.standard_normal(n)
    x[n // 3:n // 3 + 20] += 0.5 * G * np.sin(2 * np.pi * 5.0 * np.arange(20) / RATE)
    x[2 * n // 3:] += 3.4e-3 * G
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        base = tracemalloc.get_traced_memory()[0]
        ev = detect_events(x, RATE)["events"]
        peak = tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()
    assert [e["kind"] for e in ev] == ["burst", "step"]
    assert abs(ev[1]["index"] - 2 * n // 3) <= RATE  # within 1 s (the events tests' requirement)
    assert peak <= 1.04 * x.nbytes + 12e6, f"peak {peak / 1e6:.1f} MB for a {x.nbytes / 1e6:.1f} MB record"


@pytest.mark.parametrize("policy, events", [("remove", "warn"), ("remove", "exclude"), ("warn", "exclude")])
def test_the_stage_returns_the_cleaned_segment_it_returned_with_a_held_copy(policy, events):
    """The stage rebuilds its cleaned series after the event scan from the replaced samples: the same values
    as the cleaned copy of :func:`imupipe.outliers.screen_outliers` (block medians at the outliers) cut to the
    segment the events leave."""
    from imupipe.outliers import screen_outliers

    x = _record(0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out, x_seg = outliers_stage(x, RATE, units="m/s^2", sensor="accel", policy=policy,
                                    events={"policy": events})
        cleaned, _ = screen_outliers(x, policy=policy)
    a, b = (round(out["events_segment"][k] * RATE) for k in ("start_s", "stop_s"))
    assert (a, b) != (0, x.size) if events == "exclude" else (a, b) == (0, x.size)
    np.testing.assert_array_equal(x_seg, cleaned[a:b])
    if events == "warn":  # the whole record: every outlier replaced by its block median
        assert int((x_seg != x).sum()) == out["n_outliers"] == 20
