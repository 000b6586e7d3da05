"""The earlier integrity truths (tactical white + GM + random walk, MEMS white + two GMs + random walk, white + GM:
the truths of tests/test_verify.py) end to end through the one-call pipeline (imupipe.api.noise_model: the KF file
with its verified P0), judged by the independent exact covariance analysis of tests/exact_kf.py, with the truth's
GM terms started at their stationary variance.

The fast tests check the analysis itself on identities: a filter whose model IS the truth (the harness's own
discrete truth, or the project's export of the truth model) has MSE/P = 1 at every step. The slow test runs the
earlier cases; run as a script for the table (worst MSE/P over fixes + outage and over the outage, mean P/MSE over the outage):
``OPENBLAS_NUM_THREADS=1 python tests/test_integrity_cases.py [seed ...]`` (default seeds 101 and 202, the ones
of tests/test_verify.py: 1 dataset on the first, 5 on the second).
"""

from __future__ import annotations

import sys

import numpy as np
import pytest

from exact_kf import FIX_S, OUTAGE_S, kf_against_truth, truth_discrete
from imupipe.models import NoiseModel
from imupipe.specsheet import parse_spec

RATE_HZ, RECORD_S = 10.0, 36000.0
TRUTHS = {  # as in tests/test_verify.py (SI: m/s^2 units, used for both sensor kinds)
    "tactical": NoiseModel(white=3e-5, gauss_markov=((2e-5, 300.0),), random_walk=3e-7),
    "mems": NoiseModel(white=6e-4, gauss_markov=((3e-4, 30.0), (2e-4, 900.0)), random_walk=2e-6),
    "no_rw": NoiseModel(white=1e-4, gauss_markov=((6e-5, 500.0),)),
}
UNITS = {"accel": ("m/s^2/sqrt(Hz)", "m/s^2", "m/s^2/sqrt(s)"), "gyro": ("rad/s/sqrt(Hz)", "rad/s", "rad/s/sqrt(s)")}


def optimistic_spec(t: NoiseModel, sensor: str):
    """The earlier work's unflated datasheet: N x 0.8, sigma x 0.7, K x 0.5 (every parameter below the truth)."""
    wu, su, ku = UNITS[sensor]
    body = {"white": {"value": 0.8 * t.white, "unit": wu},
            "gauss_markov": [{"sigma": {"value": 0.7 * s, "unit": su}, "T": {"value": T, "unit": "s"}}
                             for s, T in t.gauss_markov]}
    if t.random_walk > 0:
        body["random_walk"] = {"value": 0.5 * t.random_walk, "unit": ku}
    return parse_spec({"name": "optimistic", sensor: body})


def run_case(name: str, sensor: str, n_data: int, seed: int) -> dict:
    from imupipe.api import noise_model
    from imupipe.simulate import simulate

    truth = TRUTHS[name]
    X = simulate(truth, int(RECORD_S * RATE_HZ), RATE_HZ, rng=np.random.default_rng(seed), n_records=n_data)
    curves = {f"d{i}/x": X[i] for i in range(n_data)}
    res = noise_model(curves, RATE_HZ, sensor, optimistic_spec(truth, sensor), window_s=25200.0, step_s=36000.0,
                      outage_s=OUTAGE_S, fix_s=FIX_S, n_boot=50, n_gm=len(truth.gauss_markov))
    ver = res.verification["verification"]
    out = kf_against_truth(res.kf, truth, sensor)
    return {"case": name, "sensor": sensor, "n_data": n_data, "seed": seed,
            "bounded": res.bounded, **out}


@pytest.mark.parametrize("sensor", ["accel", "gyro"])
@pytest.mark.parametrize("name", list(TRUTHS))
def test_exact_analysis_of_the_truth_itself_is_one(name, sensor):
    truth = TRUTHS[name]
    Phi, Qd, P0 = truth_discrete(truth, sensor, 1.0)
    r = kf_against_truth({"dt_s": 1.0, "Phi": Phi, "Qd": Qd, "P0": P0}, truth, sensor)
    # the same model in truth and filter: MSE = P at every step up to round-off, which the joint form magnifies
    # by its cancellation (MSE = var + var - 2 cov) and accumulates over the steps (a random walk of errors)
    tol = 10 * np.finfo(float).eps * r["cancellation"] * np.sqrt(r["n_steps"])
    assert abs(r["worst"] - 1.0) < tol and abs(r["end_p_over_mse"] - 1.0) < tol, (r, tol)


@pytest.mark.parametrize("sensor", ["accel", "gyro"])
def test_exact_analysis_of_the_projects_export_of_the_truth_is_one(sensor):
    """The project's KF export of a white + GM truth (P0 of the GM its stationary sigma^2) against the independent
    discrete truth: the two discretisations agree, so MSE/P = 1 to the accuracy of the matrix exponentials."""
    from imupipe.kf import export_kf

    truth = TRUTHS["no_rw"]
    r = kf_against_truth(export_kf(truth, 1.0, sensor=sensor), truth, sensor)
    assert abs(r["worst"] - 1.0) < 1e-6 and abs(r["end_p_over_mse"] - 1.0) < 1e-6, r


@pytest.mark.slow
@pytest.mark.parametrize("name", list(TRUTHS))
def test_earlier_integrity_cases(name):
    for sensor in ("accel", "gyro"):
        for n_data, seed in ((1, 101), (5, 202)):
            r = run_case(name, sensor, n_data, seed)
            assert r["bounded"] and r["worst"] <= 1.0 + 1e-6, r


if __name__ == "__main__":
    seeds = [int(s) for s in sys.argv[1:]] or [101, 202]
    print("| truth | sensor | datasets | seed | bounded | worst MSE/P, fixes + outage (first > 1, s) | worst MSE/P, "
          "outage | mean P/MSE, outage |")
    print("|---|---|---|---|---|---|---|")
    for name in TRUTHS:
        for sensor in ("accel", "gyro"):
            for n_data, seed in zip((1, 5), seeds) if len(seeds) == 2 else ((1, s) for s in seeds):
                r = run_case(name, sensor, n_data, seed)
                fe = "" if r["first_exceed_s"] is None else f" ({r['first_exceed_s']:.0f})"
                print(f"| {name} | {sensor} | {n_data} | {seed} | {r['bounded']} | {r['worst']:.3f}{fe} | "
                      f"{r['worst_outage']:.3f} | {r['mean_p_over_mse_outage']:.2f} |", flush=True)


def test_a_bias_ten_times_the_record_that_the_spec_omits():
    """An outside evaluation's case: gyro white 4.4e-5 rad/s/sqrt(Hz) + a GM of sigma 1.5e-5 rad/s at T = 54 000 s
    (10x the 1.5 h record at 10 Hz), spec sheet N x 1 with a GM of 2e-6 rad/s at 100 s (it omits the slow bias).
    Without the bootstrap (n_boot = 0) the envelope was the point fit, the export was marked bounded and the true
    error reached 26x the filter's variance; now n_boot = 0 fails the contract's identification_intervals check,
    and the default (100 replicates) exports a filter that holds against the truth (exact analysis)."""
    from imupipe.api import noise_model
    from imupipe.simulate import simulate

    truth = NoiseModel(white=4.4e-5, gauss_markov=((1.5e-5, 54000.0),))
    spec = parse_spec({"name": "omits the slow bias", "gyro": {
        "white": {"value": 4.4e-5, "unit": "rad/s/sqrt(Hz)"},
        "gauss_markov": [{"sigma": {"value": 2e-6, "unit": "rad/s"}, "T": {"value": 100.0, "unit": "s"}}]}})
    x = simulate(truth, int(1.5 * 3600 * 10.0), 10.0, rng=np.random.default_rng(1071))
    quick = noise_model({"a/x": x}, 10.0, "gyro", spec, n_boot=0)
    assert not quick.bounded
    assert any(f["check"] == "identification_intervals" for f in quick.contract["failed_checks"])
    res = noise_model({"a/x": x}, 10.0, "gyro", spec)
    r = kf_against_truth(res.kf, truth, "gyro")
    assert res.bounded and r["worst"] <= 1.0 + 1e-6, (res.contract["failed_checks"], r)  # 0.999 (seeds 5, 6 too)


def test_a_random_walk_the_fit_gave_to_a_ramp_stays_in_each_axis_model():
    """An outside evaluation's truth (gyro N 0.2 deg/sqrt(h), GM 1 deg/h at 1200 s, K 0.08 (deg/h)/sqrt(s)), one
    2 h record of three axes at 20 Hz, x 2x the others (the pooling test rejects one model: each axis gets its own),
    spec sheet at half, ``mode="auto"`` with the joint envelope, 600 s of fixes + 1800 s of outage. On this seed
    axis x's fit gave its random walk's rise to a rate ramp (K fitted 0, its upper limit 0.71x the truth's): the
    per-axis model on it under-stated x's error 2.03x under ``bounded: true``. The envelope now carries the ramp as
    the random walk it stands for (imupipe.bound.allan_check.ramp_random_walk), and every exported model holds
    against the truth of its axis (exact analysis; 0.98 here)."""
    import math

    from imupipe.api import noise_model
    from imupipe.simulate import simulate

    sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parents[1] / "benchmarks"))
    from bound_modes import halved_spec

    d2r = math.pi / 180.0
    truth = NoiseModel(white=0.2 * d2r / 60, gauss_markov=((1.0 * d2r / 3600, 1200.0),), random_walk=0.08 * d2r / 3600)
    rng, n, scale = np.random.default_rng(699), 2 * 3600 * 20, {"x": 2.0, "y": 1.0, "z": 1.0}
    curves = {f"r/{ax}": scale[ax] * simulate(truth, n, 20.0, rng) for ax in "xyz"}
    res = noise_model(curves, 20.0, "gyro", halved_spec(truth, "gyro"), outage_s=1800.0, fix_s=600.0, mode="auto",
                      envelope="joint", lines_policy="model", stationarity=False, events=False)
    assert res.bounded and not res.records["identify"]["pooling"]["consistent"]
    per = res.kf.get("per_axis") or {}
    for ax in "xyz":
        t_ax = NoiseModel(white=scale[ax] * truth.white, random_walk=scale[ax] * truth.random_walk,
                          gauss_markov=tuple((scale[ax] * s, T) for s, T in truth.gauss_markov))
        kf = {**res.kf, **per[ax]} if per.get(ax, {}).get("model") == "own" else res.kf
        r = kf_against_truth(kf, t_ax, "gyro", 600.0, 1800.0)
        assert r["worst"] <= 1.0 + 1e-6, (ax, per.get(ax, {}).get("model"), r)


@pytest.mark.parametrize("sensor", ["accel", "gyro"])
def test_exact_analysis_carries_a_narrowband_truth(sensor):
    """tests/exact_kf.py's damped oscillator (the slow oscillation of benchmarks/line_integrity.py): its stationary
    covariance diag(sigma^2, w0^2 sigma^2) is invariant under the discrete step (Phi P0 Phi' + Qd = P0 to round-off),
    and the project's KF export of the same truth (imupipe.kf: its own oscillator discretisation) gives MSE/P = 1 to
    the accuracy of the matrix exponentials, as for a GM above."""
    from imupipe.kf import export_kf
    from imupipe.models import NoiseModel

    truth = NoiseModel(white=2e-4, gauss_markov=((3e-5, 30.0),), random_walk=5e-8, narrowband=((2e-5, 3e-4, 0.02),))
    Phi, Qd, P0 = truth_discrete(truth, sensor, 1.0)
    j = (2 if sensor == "accel" else 1) + 1  # after the kinematic states and the GM
    b = slice(j, j + 2)
    step = Phi[b, b] @ P0[b, b] @ Phi[b, b].T + Qd[b, b]
    assert np.allclose(step, P0[b, b], rtol=1e-9, atol=1e-12 * P0[j + 1, j + 1])
    # the truth's random walk starts at 0 in the exact analysis: the export's initial variance of it 0 too
    r = kf_against_truth(export_kf(truth, 1.0, sensor=sensor, p0_random_walk=0.0), truth, sensor)
    assert abs(r["worst"] - 1.0) < 1e-6 and abs(r["end_p_over_mse"] - 1.0) < 1e-6, r
