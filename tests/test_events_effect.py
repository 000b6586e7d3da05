"""What an event kept in the data (events.policy warn) does to the model (imupipe.events.event_effect) and the
FLAG that says so. An outside evaluation saw a knock set the white noise N about 6x high under ``warn`` while the
summary only said "kept in the analysis"."""

import numpy as np
import pytest

from imupipe.allan import allan_variance
from imupipe.events import event_effect, event_flags


def test_a_step_adds_the_allan_variance_of_a_random_walk_k_equal_d_over_sqrt_t():
    """A pure step d at mid-record, no noise: the overlapping AV at tau = m / f_s is d^2 m / (3 (n - 2m + 1)) up to
    the triangle's discreteness (sum of squares 2m/3 + 1/(3m)): relative 1/(2 m^2) <= 5e-3 at m >= 10. The
    closed form K = d / sqrt(T) gives d^2 tau / (3 T), n / (n - 2m + 1) below it: at m / n <= 1/360 that is
    <= 0.6 %, so 1.5 % covers both."""
    rate, n, d = 10.0, 36000, 0.03
    x = np.where(np.arange(n) >= n // 2, d, 0.0)
    eff = event_effect(x, rate, {"kind": "step", "size": d, "index": n // 2}, sensor="accel")
    T = n / rate
    assert eff["record_s"] == T and np.isclose(eff["random_walk_equivalent"], d / np.sqrt(T), rtol=1e-12)
    av = allan_variance(x, rate, taus=np.array([1.0, 4.0, 10.0]))
    k2 = eff["random_walk_equivalent"] ** 2
    np.testing.assert_allclose(av["avar"].values, k2 * av["tau"].values / 3.0, rtol=0.015)
    # 0.03 m/s^2 / 9.80665e-3 = 3.06 mg; / sqrt(3600 s) = 0.051 mg/sqrt(s)
    assert eff["display"]["unit"] == "mg/sqrt(s)" and np.isclose(eff["display"]["random_walk_equivalent"], 0.051, rtol=1e-2)


def test_a_burst_raises_the_allan_deviation_at_tau0_by_its_energy():
    """White noise sigma plus a deterministic burst b: (1/2) mean over pairs of (dx)^2 has expectation sigma^2 with
    the burst left out and sigma^2 + (1/2) sum (db)^2 / (n - 1) with it (the cross term has mean 0). The estimate's
    relative sd is about sqrt(3 / n) (dx^2 has variance 2 (2 sigma^2)^2, adjacent differences correlate -1/2) =
    0.0055 at n = 1e5: 4 sd = 2.2 % on the AV ratio, 1.1 % on its square root."""
    rng = np.random.default_rng(7)
    n, rate, sigma = 100_000, 100.0, 1.0
    x = sigma * rng.standard_normal(n)
    i0, L = 50_000, 50
    b = 30.0 * sigma * (-1.0) ** np.arange(L)  # a ringing knock: |db| = 60 sigma inside it
    x[i0:i0 + L] += b
    db = np.diff(np.concatenate([[0.0], b, [0.0]]))
    expected = np.sqrt(1.0 + 0.5 * np.sum(db ** 2) / ((n - 1) * sigma ** 2))
    eff = event_effect(x, rate, {"kind": "burst", "index": i0, "stop_index": i0 + L}, guard=100)
    assert abs(eff["white_noise_ratio"] / expected - 1.0) < 0.011
    assert expected > 1.3  # the case tests something: the knock raises N read at tau0 by over 30 %


def test_the_flag_of_an_event_kept_under_warn_says_what_it_does_to_the_model():
    from imupipe.stages.outliers import outliers_stage

    rng = np.random.default_rng(3)
    rate, n, sigma, d = 50.0, 90_000, 0.003, 0.03  # 30 min at 50 Hz, white noise, a 3 mg step at 20 min
    x = sigma * rng.standard_normal(n) + np.where(np.arange(n) >= 60_000, d, 0.0)
    report, _ = outliers_stage(x, rate, units="m/s^2", dataset="r1", sensor="accel", axis="x", policy="warn")
    (step,) = [e for e in report["events"] if e["kind"] == "step"]
    assert np.isclose(step["effect"]["random_walk_equivalent"], abs(step["size"]) / np.sqrt(n / rate))
    (text,) = [t for _, t in event_flags([step])]
    assert "kept in the analysis (events.policy warn): in the Allan variance a step in this 1800 s record acts as a " \
           "random walk K = " in text and "it can inflate K" in text
    # exclude / split take the event out of the analysis: no effect stated
    report, _ = outliers_stage(x, rate, units="m/s^2", dataset="r1", sensor="accel", axis="x", policy="warn",
                               events={"policy": "exclude"})
    assert all("effect" not in e for e in report["events"])


def test_event_effects_of_a_record_equal_each_events_own():
    # the record's sum of squared differences taken once for all its bursts: the same numbers as one call per event
    from imupipe.events import event_effects

    rng = np.random.default_rng(7)
    x = rng.normal(0.0, 1e-3, 60_000)
    x[10_000:10_050] += rng.normal(0.0, 0.05, 50)
    x[40_000:] += 5e-3
    events = [{"kind": "burst", "index": 10_000, "stop_index": 10_050}, {"kind": "step", "size": 5e-3, "index": 40_000},
              {"kind": "burst", "index": 20_000, "stop_index": 20_010}]
    got = event_effects(x, 100.0, events, guard=100, sensor="accel")
    for g, e in zip(got, events):
        want = event_effect(x, 100.0, e, guard=100, sensor="accel")
        assert g.keys() == want.keys()
        for k in want:
            assert g[k] == pytest.approx(want[k], rel=1e-12) if isinstance(want[k], float) else g[k] == want[k]
