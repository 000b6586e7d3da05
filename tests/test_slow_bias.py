"""Slow-bias truths end to end (a bias slower than the records): simulate -> the one-call pipeline
(imupipe.api.noise_model: identification, bound, verification, KF export) -> an exact covariance analysis of the
exported KF file (its own Phi, Qd and P0) against the truth, the truth's GM started at its stationary variance as a
sensor's bias is at turn-on.

Truth: white noise + one GM of T = factor x the record (10 h at 10 Hz; factor 0.5, 1, 3, 10), spec sheet = the
truth scaled by 1, 2 or 0.5 (N and sigma; T kept). Integrity asks: with the spec = truth or 2x truth, bounded and
worst MSE/P <= 1 over fixes + horizon; with the spec halved, no bounded export with worst MSE/P > 1.5.

Run the table: ``OPENBLAS_NUM_THREADS=1 python tests/test_slow_bias.py [seed]`` (48 cases, ~10 min on one core).
The default suite runs two cases; ``pytest -m slow -k slow_bias`` a larger subset.
"""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest

from imupipe.models import NoiseModel
from imupipe.specsheet import parse_spec

RATE_HZ = 10.0
RECORD_S = 36000.0
FIX_S, HORIZON_S = 600.0, 3600.0
BASE = {"accel": (1e-4, 3e-4), "gyro": (1e-5, 1e-5)}  # (N u/sqrt(Hz), GM sigma u), SI
UNITS = {"accel": ("m/s^2/sqrt(Hz)", "m/s^2"), "gyro": ("rad/s/sqrt(Hz)", "rad/s")}


def truth_of(sensor: str, factor: float) -> NoiseModel:
    n, s = BASE[sensor]
    return NoiseModel(white=n, gauss_markov=((s, factor * RECORD_S),))


def spec_of(sensor: str, truth: NoiseModel, scale: float):
    (s, T), = truth.gauss_markov
    wu, su = UNITS[sensor]
    return parse_spec({"name": f"truth x{scale:g}", sensor: {
        "white": {"value": scale * truth.white, "unit": wu},
        "gauss_markov": [{"sigma": {"value": scale * s, "unit": su}, "T": {"value": T, "unit": "s"}}]}})


def kf_against_truth(kf: dict, truth: NoiseModel, sensor: str) -> tuple[float, float]:
    """Worst true MSE / P of the position (angle) over fixes + outage for the filter of the KF file `kf` (its
    Phi, Qd, P0 at dt = 1 s) when the error is `truth` (started stationary); and the time of the first ratio > 1.

    The truth's discrete model is built here from its parameters (exact for white + GM at dt: the white noise
    integrated over a step, the GM's phi and driving variance), not from the project's state-space code."""
    dt = float(kf["dt_s"])
    Phi_f, Qd_f, P0_f = (np.array(kf[k], dtype=float) for k in ("Phi", "Qd", "P0"))
    (s, T), = truth.gauss_markov
    phi = math.exp(-dt / T)
    q_b = s * s * (1 - phi * phi)
    N2 = truth.white**2
    # truth states: kinematic (x, v) or theta, then b; e_k = -(white + b) enters the rate
    if sensor == "accel":
        # exact integrals of a constant-over-step b would need its own Van Loan; the GM is slow (T >> dt) so the
        # continuous model is discretised by the matrix exponential below instead
        from scipy.linalg import expm

        F = np.array([[0, 1, 0], [0, 0, -1], [0, 0, -1 / T]], dtype=float)
        G = np.array([[0, 0], [-1, 0], [0, 1]], dtype=float)
        Qc = np.diag([N2, 2 * s * s / T])
    else:
        from scipy.linalg import expm

        F = np.array([[0, -1], [0, -1 / T]], dtype=float)
        G = np.array([[-1, 0], [0, 1]], dtype=float)
        Qc = np.diag([N2, 2 * s * s / T])
    n = F.shape[0]
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n], M[:n, n:], M[n:, n:] = -F * dt, G @ Qc @ G.T * dt, F.T * dt
    E = expm(M)
    Phi_t = E[n:, n:].T
    Qd_t = Phi_t @ E[:n, n:]
    Qd_t = 0.5 * (Qd_t + Qd_t.T)
    assert abs(Phi_t[-1, -1] - phi) < 1e-12 and abs(Qd_t[-1, -1] - q_b) < 1e-9 * q_b
    sigma_fix = 0.5 if sensor == "accel" else math.radians(0.1)
    R = sigma_fix**2
    P0_t = np.zeros((n, n))
    P0_t[0, 0] = R
    if sensor == "accel":
        P0_t[1, 1] = 1.0
    P0_t[-1, -1] = s * s
    # the KF file's P0 carries the noise states; the kinematic initial variances are the scenario's (the same
    # as the truth's: fix sigma^2, and 1 (m/s)^2 for the velocity)
    P0_f = P0_f.copy()
    P0_f[0, 0] = R
    if sensor == "accel":
        P0_f[1, 1] = 1.0
    nt, nf = n, Phi_f.shape[0]
    Ht, Hf = np.zeros(nt), np.zeros(nf)
    Ht[0] = Hf[0] = 1.0
    A = np.zeros((nt + nf, nt + nf))
    A[:nt, :nt], A[nt:, nt:] = Phi_t, Phi_f
    Qa = np.zeros_like(A)
    Qa[:nt, :nt] = Qd_t
    C = np.zeros_like(A)
    C[:nt, :nt] = P0_t
    P = P0_f.copy()
    c = np.zeros(nt + nf)
    c[0], c[nt] = -1.0, 1.0
    worst, first = 0.0, None
    n_fix, n_all = int(FIX_S / dt), int((FIX_S + HORIZON_S) / dt)
    for k in range(n_all):
        C = A @ C @ A.T + Qa
        P = Phi_f @ P @ Phi_f.T + Qd_f
        if k < n_fix:
            K = P @ Hf / (Hf @ P @ Hf + R)
            IKH = np.eye(nf) - np.outer(K, Hf)
            P = IKH @ P @ IKH.T + R * np.outer(K, K)
            B = np.eye(nt + nf)
            B[nt:, :nt] = np.outer(K, Ht)
            B[nt:, nt:] -= np.outer(K, Hf)
            C = B @ C @ B.T
            C[nt:, nt:] += R * np.outer(K, K)
        r = float(c @ C @ c) / P[0, 0]
        if r > 1 + 1e-6 and first is None:
            first = (k + 1) * dt
        worst = max(worst, r)
    return worst, first


def run_case(sensor: str, factor: float, n_data: int, scale: float, seed: int) -> dict:
    from imupipe.api import noise_model
    from imupipe.simulate import simulate

    truth = truth_of(sensor, factor)
    X = simulate(truth, int(RECORD_S * RATE_HZ), RATE_HZ, rng=np.random.default_rng(seed), n_records=n_data)
    curves = {f"d{i}/x": X[i] for i in range(n_data)}
    res = noise_model(curves, RATE_HZ, sensor, spec_of(sensor, truth, scale), window_s=25200.0, step_s=36000.0,
                      horizon_s=HORIZON_S, fix_s=FIX_S, n_boot=0)
    ver = res.verification
    checks = ver["verification"]["checks"]
    bounded = bool(res.bound.bounded and ver["verification"]["passed"])
    worst, first = kf_against_truth(res.kf, truth, sensor)
    bi = ver["exported"]["bias_initialisation"]
    return {"sensor": sensor, "T_factor": factor, "n_data": n_data, "spec_scale": scale, "seed": seed,
            "bounded": bounded, "psd_bounded": bool(res.bound.bounded),
            "failed": [k for k, c in checks.items() if not c["passed"]], "worst": worst, "first_exceed_s": first,
            "rests_on": bi["rests_on"], "checked_by_records": bi["checked_by_records"],
            "required_std_over_truth": bi["required_std"] / BASE[sensor][1]}


def acceptable(r: dict) -> bool:
    """The issue's criterion for one case."""
    if r["spec_scale"] >= 1.0:
        return r["bounded"] and r["worst"] <= 1.0 + 1e-6
    return (not r["bounded"]) or r["worst"] <= 1.5


@pytest.mark.parametrize("sensor,factor,n_data,scale", [("accel", 3.0, 1, 0.5), ("gyro", 10.0, 1, 1.0)])
def test_slow_bias_case(sensor, factor, n_data, scale):
    r = run_case(sensor, factor, n_data, scale, seed=911)
    assert acceptable(r), r
    assert not r["checked_by_records"]  # a bias slower than the records: the summary must say so


@pytest.mark.slow
@pytest.mark.parametrize("factor", [0.5, 1.0, 3.0, 10.0])
@pytest.mark.parametrize("sensor", ["accel", "gyro"])
def test_slow_bias_cases_slow(sensor, factor):
    for n_data in (1, 5):
        for scale in (1.0, 2.0, 0.5):
            r = run_case(sensor, factor, n_data, scale, seed=977)
            assert acceptable(r), r


if __name__ == "__main__":
    seed = int(sys.argv[1]) if len(sys.argv) > 1 else 4242
    print("| sensor | T / record | datasets | spec / truth | bounded | failed checks | worst MSE/P (first > 1, s) "
          "| initial bias std / truth sigma, rests on | ok |")
    print("|---|---|---|---|---|---|---|---|---|")
    for sensor in ("accel", "gyro"):
        for factor in (0.5, 1.0, 3.0, 10.0):
            for n_data in (1, 5):
                for scale in (1.0, 2.0, 0.5):
                    r = run_case(sensor, factor, n_data, scale, seed + n_data)
                    fe = "" if r["first_exceed_s"] is None else f" ({r['first_exceed_s']:.0f})"
                    print(f"| {sensor} | {factor:g} | {n_data} | {scale:g} | {r['bounded']} | "
                          f"{', '.join(r['failed']) or '-'} | {r['worst']:.3f}{fe} | "
                          f"{r['required_std_over_truth']:.2f}, {r['rests_on']} | "
                          f"{'yes' if acceptable(r) else 'NO'} |", flush=True)
