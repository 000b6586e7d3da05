"""An exact covariance analysis of an exported KF file against a known truth, written independently of the
project's state-space code (the truth's discrete model is built here from its parameters by Van Loan's matrix
exponential), for the integrity tables of tests/test_slow_bias.py and tests/test_integrity_cases.py.

Reference filter: position (accelerometer: x, v) or angle (gyro: theta) fixed every dt (sigma 0.5 m or 0.1 deg)
for ``fix_s``, then an outage of ``outage_s`` with no fixes. The filter runs on the KF file's own Phi, Qd and P0
(its kinematic initial variances set to the truth's: the fix variance, and 1 (m/s)^2 for the velocity); the truth
is white noise + Gauss-Markov terms (each started at its stationary variance sigma^2, as a sensor's bias is at
turn-on) + an optional random walk (started at 0). The true error covariance of the filter (the truth and the
filter's estimate propagated jointly) is compared with the filter's own P of the first state at every step:
MSE/P <= 1 everywhere means the filter does not under-state its error.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import expm

FIX_S, OUTAGE_S = 600.0, 3600.0
SIGMA_FIX = {"accel": 0.5, "gyro": math.radians(0.1)}  # m, rad


def truth_discrete(truth, sensor: str, dt: float):
    """(Phi, Qd, P0) of the truth's error state at step dt: kinematic states, one per GM term, the random walk.

    Continuous model: the rate error e = -(w + sum_i b_i + r + sum_j n_j) with w white (PSD N^2, one-sided
    convention of the project: N in u/sqrt(Hz)), db_i/dt = -b_i/T_i + sqrt(2 sigma_i^2/T_i) xi_i, dr/dt = K xi_r,
    and per narrowband term (sigma, f0, zeta) a damped oscillator n'' + 2 zeta w0 n' + w0^2 n = sqrt(q) xi,
    w0 = 2 pi f0, q = 4 zeta w0^3 sigma^2 (its stationary variance is sigma^2; started at its stationary covariance
    diag(sigma^2, w0^2 sigma^2)); Qd by Van Loan (C. F. Van Loan, "Computing integrals involving the matrix
    exponential", IEEE TAC 23(3), 1978)."""
    left_out = [k for k in ("flicker", "quantization", "ramp") if float(getattr(truth, k, 0.0) or 0.0) > 0]
    if left_out:  # no finite state model here: leaving them out would judge a filter against a smaller truth
        raise ValueError(f"truth_discrete: the truth's {', '.join(left_out)} has no state model in this analysis "
                         "(expected white, gauss_markov, random_walk, narrowband; a flicker floor can be carried as "
                         "GM terms, one per decade of T, as benchmarks/bound_modes.py's flicker_like)")
    n_kin = 2 if sensor == "accel" else 1
    gms = list(truth.gauss_markov)
    has_rw = truth.random_walk > 0
    nbs = list(getattr(truth, "narrowband", ()) or ())
    n = n_kin + len(gms) + int(has_rw) + 2 * len(nbs)
    F = np.zeros((n, n))
    if sensor == "accel":
        F[0, 1] = 1.0
    rate_row = n_kin - 1  # the state the rate error drives (v or theta)
    noises = [truth.white**2]
    G_cols = [np.eye(n)[:, rate_row] * -1.0]
    for i, (s, T) in enumerate(gms):
        j = n_kin + i
        F[rate_row, j] = -1.0
        F[j, j] = -1.0 / T
        noises.append(2.0 * s * s / T)
        G_cols.append(np.eye(n)[:, j])
    for i, (s, f0, z) in enumerate(nbs):
        j = n_kin + len(gms) + 2 * i
        w0 = 2.0 * math.pi * f0
        F[rate_row, j] = -1.0
        F[j, j + 1] = 1.0
        F[j + 1, j], F[j + 1, j + 1] = -w0 * w0, -2.0 * z * w0
        noises.append(4.0 * z * w0**3 * s * s)
        G_cols.append(np.eye(n)[:, j + 1])
    if has_rw:
        j = n - 1
        F[rate_row, j] = -1.0
        noises.append(truth.random_walk**2)
        G_cols.append(np.eye(n)[:, j])
    G = np.column_stack(G_cols)
    Qc = np.diag(noises)
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n], M[:n, n:], M[n:, n:] = -F * dt, G @ Qc @ G.T * dt, F.T * dt
    E = expm(M)
    Phi = E[n:, n:].T
    Qd = Phi @ E[:n, n:]
    Qd = 0.5 * (Qd + Qd.T)
    R = SIGMA_FIX[sensor] ** 2
    P0 = np.zeros((n, n))
    P0[0, 0] = R
    if sensor == "accel":
        P0[1, 1] = 1.0
    for i, (s, _T) in enumerate(gms):
        P0[n_kin + i, n_kin + i] = s * s
    for i, (s, f0, _z) in enumerate(nbs):
        j = n_kin + len(gms) + 2 * i
        P0[j, j], P0[j + 1, j + 1] = s * s, (2.0 * math.pi * f0 * s) ** 2
    return Phi, Qd, P0


def kf_against_truth(kf: dict, truth, sensor: str, fix_s: float = FIX_S, outage_s: float = OUTAGE_S,
                     fix_every: int = 1) -> dict:
    """Worst true MSE / P of the first state over fixes + outage for the filter of the KF file `kf` (its dt_s,
    Phi, Qd, P0) when the error is `truth` (``worst``; ``worst_outage`` over the outage alone); the time of the
    first ratio > 1 (None if none); the conservatism P / MSE averaged over the outage's steps and at its end. A fix
    every `fix_every` filter steps (at the steps k < fix_s/dt with (k + 1) % fix_every == 0). Joseph-form updates;
    the joint (truth, filter estimate) covariance is
    propagated exactly (no Monte Carlo). ``cancellation``: the largest (var(truth) + var(estimate)) / MSE of the
    first state, the factor by which round-off in the joint form is magnified in MSE = var + var - 2 cov."""
    dt = float(kf["dt_s"])
    Phi_f, Qd_f, P0_f = (np.array(kf[k], dtype=float) for k in ("Phi", "Qd", "P0"))
    Phi_t, Qd_t, P0_t = truth_discrete(truth, sensor, dt)
    R = SIGMA_FIX[sensor] ** 2
    P0_f = P0_f.copy()
    P0_f[0, 0] = R
    if sensor == "accel":
        P0_f[1, 1] = 1.0
    nt, nf = Phi_t.shape[0], Phi_f.shape[0]
    Ht, Hf = np.zeros(nt), np.zeros(nf)
    Ht[0] = Hf[0] = 1.0
    A = np.zeros((nt + nf, nt + nf))
    A[:nt, :nt], A[nt:, nt:] = Phi_t, Phi_f
    Qa = np.zeros_like(A)
    Qa[:nt, :nt] = Qd_t
    C = np.zeros_like(A)
    C[:nt, :nt] = P0_t  # the filter's estimate starts at 0: its error is the truth's state
    P = P0_f
    c = np.zeros(nt + nf)
    c[0], c[nt] = -1.0, 1.0
    worst, first, ratio, cancel = 0.0, None, float("nan"), 1.0
    worst_out, sum_p_over_mse = 0.0, 0.0
    n_fix, n_all = int(round(fix_s / dt)), int(round((fix_s + outage_s) / dt))
    for k in range(n_all):
        C = A @ C @ A.T + Qa
        P = Phi_f @ P @ Phi_f.T + Qd_f
        if k < n_fix and (k + 1) % fix_every == 0:
            K = P @ Hf / (Hf @ P @ Hf + R)
            IKH = np.eye(nf) - np.outer(K, Hf)
            P = IKH @ P @ IKH.T + R * np.outer(K, K)
            B = np.eye(nt + nf)
            B[nt:, :nt] = np.outer(K, Ht)
            B[nt:, nt:] -= np.outer(K, Hf)
            C = B @ C @ B.T
            C[nt:, nt:] += R * np.outer(K, K)
        mse = float(c @ C @ c)
        ratio = mse / P[0, 0]
        cancel = max(cancel, (C[0, 0] + C[nt, nt]) / mse)
        if ratio > 1 + 1e-6 and first is None:
            first = (k + 1) * dt
        worst = max(worst, ratio)
        if k >= n_fix:
            worst_out = max(worst_out, ratio)
            sum_p_over_mse += 1.0 / ratio
    return {"worst": worst, "first_exceed_s": first, "worst_outage": worst_out,
            "mean_p_over_mse_outage": sum_p_over_mse / (n_all - n_fix), "end_p_over_mse": 1.0 / ratio, "n_steps": n_all,
            "cancellation": cancel}
