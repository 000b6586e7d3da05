r"""Kalman-filter export of a noise model: continuous and exactly discretised state-space models.

One axis of the paper's navigation example (Gallon, Joerger, Pervan, ION GNSS+ 2021, eq. 17), for
an accelerometer measuring :math:`q_m = (1 + s_f) q_t + b + p + \nu_s`:

.. math::

    \frac{d}{dt}\begin{bmatrix} x \\ v \\ b_i \\ p \\ s_f \end{bmatrix} =
    \begin{bmatrix} 0 & 1 & 0 & 0 & 0 \\ 0 & 0 & -1 & -1 & -q_m^* \\ 0 & 0 & -1/T_i & 0 & 0 \\
    0 & 0 & 0 & 0 & 0 \\ 0 & 0 & 0 & 0 & 0 \end{bmatrix}
    \begin{bmatrix} x \\ v \\ b_i \\ p \\ s_f \end{bmatrix}
    + \begin{bmatrix} 0 \\ 1 \\ 0 \\ 0 \\ 0 \end{bmatrix} q_m
    + \begin{bmatrix} 0 & 0 & 0 \\ -1 & 0 & 0 \\ 0 & 1 & 0 \\ 0 & 0 & 1 \\ 0 & 0 & 0 \end{bmatrix}
    \begin{bmatrix} \nu_s \\ \nu_{b,i} \\ \nu_p \end{bmatrix},

with white-noise intensities (two-sided PSDs) :math:`Q_c = \operatorname{diag}(N^2,\ 2\sigma_i^2/T_i,\
K^2)`: :math:`N^2` for the velocity random walk, :math:`2\sigma^2/T` for a GM of steady-state
variance :math:`\sigma^2`, :math:`K^2` for the acceleration random walk. The reduced model (eq. 19)
drops :math:`p`; the scale-factor state :math:`s_f` has no driving noise. A gyro axis has the same
structure with the attitude angle :math:`\theta` in place of :math:`(x, v)`.

Discretisation is exact (Van Loan 1978): with :math:`M = \begin{bmatrix} -F & G Q_c G^T \\ 0 &
F^T\end{bmatrix}\Delta t`, :math:`e^{M} = \begin{bmatrix} \cdot & \Phi^{-1} Q_d \\ 0 &
\Phi^T\end{bmatrix}`. Closed forms it reproduces (tests): GM :math:`\Phi = e^{-\Delta t/T}`,
:math:`Q_d = \sigma^2(1 - e^{-2\Delta t/T})`; random walk :math:`Q_d = K^2 \Delta t` (driving
standard deviation :math:`K\sqrt{\Delta t}`, **not** the paper's :math:`\sigma_p = K \Delta t`,
which agrees only at :math:`\Delta t = 1` s: docs/method.md, section "Slip: discrete driving noise"); velocity random walk
:math:`Q_{d,vv} = N^2 \Delta t`; white rate noise as a discrete measurement/input noise
:math:`N^2/\Delta t` per sample.

References
----------
.. [1] E. Gallon, M. Joerger, B. Pervan, "Development of Stochastic IMU Error Models for INS/GNSS
       Integration", ION GNSS+ 2021, eqs. 14-19.
.. [2] C. F. Van Loan, "Computing integrals involving the matrix exponential", IEEE Trans.
       Automatic Control 23(3), 395-404, 1978.
.. [3] Kalibr wiki, "IMU Noise Model" (ethz-asl/kalibr): noise density and bias random walk
       convention of ``imu.yaml``.
.. [4] IEEE Std 952-1997, Annex C (angle random walk N, rate random walk K).
"""

from __future__ import annotations

import math
import warnings
from typing import NamedTuple

import numpy as np

from imupipe.units import SI_UNITS

__all__ = [
    "ContinuousModel",
    "export_scope",
    "dropped_by_reduction",
    "inflation_scope",
    "continuous_model",
    "discretize",
    "initial_covariance",
    "export_kf",
]

_RATE_UNIT = SI_UNITS


class ContinuousModel(NamedTuple):
    r"""Continuous-time model :math:`\dot X = F X + G w`, :math:`E[w(t) w(s)^T] = Q_c \delta(t-s)`."""

    F: np.ndarray  #: system matrix (n, n), 1/s
    G: np.ndarray  #: noise input matrix (n, m)
    Qc: np.ndarray  #: noise intensities (m, m): u^2/Hz (white), u^2/s (GM, random walk)
    states: list  #: state names
    noises: list  #: noise names


def _resolve_reduced(model, reduced):
    if reduced is None:
        return model.random_walk == 0
    if reduced and model.random_walk > 0:
        warnings.warn(
            f"reduced model (eq. 19) requested for a model with random walk K = {model.random_walk:.3g}: "
            "the random walk is dropped, which the paper allows only when the AV shows none",
            UserWarning,
            stacklevel=3,
        )
    return bool(reduced)


def _lines(model) -> tuple:
    """The model's narrowband terms (sigma, f0_hz, zeta) with sigma > 0 (a zero term, e.g. a line column the
    bound did not need, has no state)."""
    return tuple(t for t in getattr(model, "narrowband", ()) if t[0] > 0)


def _narrowband_names(n: int) -> list:
    """State names of the narrowband terms: ``nb`` (one term) or ``nb_1``, ``nb_2``, ... (its rate is
    ``<name>_dot``)."""
    return ["nb"] if n == 1 else [f"nb_{i + 1}" for i in range(n)]


def continuous_model(model, reduced: bool | None = None, q_m: float = 0.0, sensor: str = "accel",
                     scale_factor: bool = True) -> ContinuousModel:
    r"""One-axis continuous model of Gallon et al. 2021, eq. 17 (eq. 19 when `reduced`).

    States (accelerometer): ``x`` (m), ``v`` (m/s), ``b`` (GM bias, m/s^2; ``b_1``, ``b_2``, ...
    for several GM terms), ``p`` (random-walk bias, m/s^2; absent when reduced), ``s_f`` (scale
    factor, 1). Gyro: ``theta`` (rad) instead of ``x, v``. The linearised measurement (eq. 16)
    :math:`q_t = q_m - b - p - \nu_s - q_m^* s_f` gives the velocity (angle) row
    :math:`-1, -1, -q_m^*`.

    Narrowband terms (``model.narrowband``, damped oscillators :math:`\ddot n + 2\zeta\omega_0\dot n +
    \omega_0^2 n = \nu_n`, :math:`\omega_0 = 2\pi f_0`): two states each, ``nb`` (u) and ``nb_dot`` (u/s)
    (``nb_1``, ``nb_1_dot``, ... for several), placed after the GM states, with the block
    :math:`F = [[0, 1], [-\omega_0^2, -2\zeta\omega_0]]`; ``nb`` enters the velocity (angle) row with -1 like a
    bias, and the noise ``nu_nb`` drives ``nb_dot`` with intensity :math:`4\zeta\omega_0^3\sigma^2`
    (u^2/s^3), so that the steady-state variance of ``nb`` is :math:`\sigma^2` (models.narrowband_psd).
    Terms with sigma = 0 get no state.

    Noises: ``nu_s`` (white rate noise, intensity :math:`N^2`, enters with -1), ``nu_b``
    (:math:`2\sigma^2/T` per GM term, so the GM's steady-state variance is :math:`\sigma^2`),
    ``nu_nb`` (per narrowband term, above), ``nu_p`` (:math:`K^2`).

    Parameters
    ----------
    model : imupipe.models.NoiseModel
        SI noise model (white, gauss_markov, random_walk used; flicker, quantization and ramp are
        not states and are ignored with a warning).
    reduced : bool or None, optional
        Drop the random-walk state (eq. 19). None (default): reduced iff the model has no random
        walk. True with a random walk present warns.
    q_m : float, optional
        Nominal measured rate :math:`q_m^*` (u) multiplying the scale-factor state. Default 0.
    sensor : {"accel", "gyro"}, optional
        Default ``"accel"``.
    scale_factor : bool, optional
        Include ``s_f``. Default True.

    Returns
    -------
    ContinuousModel
        ``(F, G, Qc, states, noises)``.
    """
    if sensor not in _RATE_UNIT:
        raise ValueError(f"sensor must be 'accel' or 'gyro', got {sensor!r}")
    for name in ("flicker", "quantization", "ramp"):
        if getattr(model, name, 0.0):
            warnings.warn(f"{name} is not a Kalman-filter state and is left out of the state-space model",
                          UserWarning, stacklevel=2)
    reduced = _resolve_reduced(model, reduced)
    gm = sorted(model.gauss_markov, key=lambda st: st[1])
    nb = _lines(model)
    states = ["x", "v"] if sensor == "accel" else ["theta"]
    kin = len(states)
    i_rate = kin - 1  # the row receiving the rate error (v for accel, theta for gyro)
    b_names = ["b"] if len(gm) == 1 else [f"b_{i + 1}" for i in range(len(gm))]
    states += b_names
    nb_names = _narrowband_names(len(nb))
    for nm in nb_names:
        states += [nm, nm + "_dot"]
    if not reduced:
        states.append("p")
    if scale_factor:
        states.append("s_f")
    n = len(states)
    idx = {s: i for i, s in enumerate(states)}
    F = np.zeros((n, n))
    if sensor == "accel":
        F[idx["x"], idx["v"]] = 1.0
    for bn, (_, T) in zip(b_names, gm):
        F[i_rate, idx[bn]] = -1.0
        F[idx[bn], idx[bn]] = -1.0 / T
    for nm, (_, f0, zeta) in zip(nb_names, nb):
        w0 = 2.0 * math.pi * f0
        i, j = idx[nm], idx[nm + "_dot"]
        F[i_rate, i] = -1.0  # the line is part of the rate error
        F[i, j] = 1.0
        F[j, i] = -w0 * w0
        F[j, j] = -2.0 * zeta * w0
    if not reduced:
        F[i_rate, idx["p"]] = -1.0
    if scale_factor:
        F[i_rate, idx["s_f"]] = -float(q_m)
    noises = ["nu_s"] + (["nu_b"] if len(gm) == 1 else [f"nu_b_{i + 1}" for i in range(len(gm))])
    q = [model.white**2] + [2.0 * s**2 / T for s, T in gm]
    noises += ["nu_" + nm for nm in nb_names]
    q += [4.0 * zeta * (2.0 * math.pi * f0) ** 3 * s**2 for s, f0, zeta in nb]
    if not reduced:
        noises.append("nu_p")
        q.append(model.random_walk**2)
    m = len(noises)
    G = np.zeros((n, m))
    G[i_rate, 0] = -1.0
    for j, bn in enumerate(b_names):
        G[idx[bn], 1 + j] = 1.0
    for j, nm in enumerate(nb_names):
        G[idx[nm + "_dot"], 1 + len(b_names) + j] = 1.0
    if not reduced:
        G[idx["p"], m - 1] = 1.0
    return ContinuousModel(F, G, np.diag(np.asarray(q, dtype=np.float64)), states, noises)


def discretize(F, G, Qc, dt: float):
    r"""Exact discretisation by Van Loan's method.

    .. math::

        \exp\!\left(\begin{bmatrix} -F & G Q_c G^T \\ 0 & F^T \end{bmatrix}\Delta t\right)
        = \begin{bmatrix} \cdot & \Phi^{-1} Q_d \\ 0 & \Phi^T \end{bmatrix},
        \qquad \Phi = e^{F\Delta t},\quad
        Q_d = \int_0^{\Delta t} e^{F s} G Q_c G^T e^{F^T s}\, ds .

    Parameters
    ----------
    F : array_like
        (n, n) system matrix, 1/s.
    G : array_like or None
        (n, m) noise input matrix; None for the identity (then `Qc` is (n, n)).
    Qc : array_like
        (m, m) white-noise intensities (two-sided PSDs).
    dt : float
        Step, s (> 0).

    Returns
    -------
    Phi : numpy.ndarray
        (n, n) transition matrix.
    Qd : numpy.ndarray
        (n, n) discrete process-noise covariance (symmetrised).

    References
    ----------
    .. [1] C. F. Van Loan, IEEE Trans. Automatic Control 23(3), 395-404, 1978.
    """
    from scipy.linalg import expm

    F = np.asarray(F, dtype=np.float64)
    n = F.shape[0]
    if F.shape != (n, n):
        raise ValueError(f"F must be square, got {F.shape}")
    Qc = np.atleast_2d(np.asarray(Qc, dtype=np.float64))
    G = np.eye(n) if G is None else np.asarray(G, dtype=np.float64)
    if G.shape[0] != n or G.shape[1] != Qc.shape[0] or Qc.shape[0] != Qc.shape[1]:
        raise ValueError(f"shapes do not match: F {F.shape}, G {G.shape}, Qc {Qc.shape}")
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be a positive step in s, got {dt!r}")
    Q = G @ Qc @ G.T
    # Van Loan's block holds exp(-F dt): for a stiff state (a GM with T << dt) that is e^(dt/T), and Qd is
    # lost to cancellation (measured: T = 0.01 s at dt = 1 s gave Qd ~ 1e24 u^2). So the block is evaluated
    # at h = dt / 2^k with ||F|| h <= 1/2 and doubled back: Phi(2h) = Phi(h)^2,
    # Qd(2h) = Qd(h) + Phi(h) Qd(h) Phi(h)^T (each step adds positive semi-definite terms: stable).
    # k = 0 (the plain formula) when ||F|| dt <= 1/2.
    norm = float(np.linalg.norm(F, 1)) * dt
    k = max(0, int(math.ceil(math.log2(norm / 0.5)))) if norm > 0.5 else 0
    h = dt / 2.0**k
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n] = -F
    M[:n, n:] = Q
    M[n:, n:] = F.T
    E = expm(M * h)
    Phi = E[n:, n:].T
    Qd = Phi @ E[:n, n:]
    for _ in range(k):
        Qd = Qd + Phi @ Qd @ Phi.T
        Phi = Phi @ Phi
    return Phi, 0.5 * (Qd + Qd.T)


def initial_covariance(model, states, p0_random_walk: float | None = None, var_x: float = 0.0,
                       var_v: float = 0.0, var_theta: float = 0.0, var_scale_factor: float = 0.0):
    r"""Diagonal initial covariance, GM and narrowband states at their steady state.

    The steady state of a damped oscillator (solution of :math:`F P + P F^T + G Q_c G^T = 0` for the
    block of :func:`continuous_model`) is :math:`\operatorname{diag}(\sigma^2, \omega_0^2\sigma^2)`: the
    position and rate of a stationary oscillator are uncorrelated.

    A GM bias started at its steady-state variance :math:`\sigma^2` is stationary, which the PSD
    bound's guarantee needs (docs/method.md, section "The bound"). The random walk has no steady state: its
    initial variance must be stated (e.g. the turn-on bias repeatability squared, or
    :math:`K^2 t_0` for a bias left to wander :math:`t_0` seconds before the filter starts).

    Parameters
    ----------
    model : imupipe.models.NoiseModel
        SI model (GM sigmas are read from it, in the order of increasing T).
    states : sequence of str
        State names from :func:`continuous_model`.
    p0_random_walk : float
        Initial variance of ``p``, u^2. Required when ``p`` is a state.
    var_x, var_v, var_theta, var_scale_factor : float, optional
        Initial variances of the kinematic states (m^2, (m/s)^2, rad^2) and of the scale factor
        (1). Default 0.

    Returns
    -------
    numpy.ndarray
        (n, n) diagonal covariance.
    """
    gm = sorted(model.gauss_markov, key=lambda st: st[1])
    nb = _lines(model)
    nb_of = {nm: term for nm, term in zip(_narrowband_names(len(nb)), nb)}
    d = []
    b_i = 0
    for s in states:
        if s == "x":
            d.append(var_x)
        elif s == "v":
            d.append(var_v)
        elif s == "theta":
            d.append(var_theta)
        elif s == "b" or s.startswith("b_"):
            d.append(gm[b_i][0] ** 2)
            b_i += 1
        elif s == "p":
            if p0_random_walk is None:
                raise ValueError(
                    "the random-walk state p has no steady state: give its initial variance p0_random_walk "
                    "(u^2), e.g. the turn-on bias repeatability squared"
                )
            d.append(float(p0_random_walk))
        elif s == "s_f":
            d.append(var_scale_factor)
        elif s in nb_of:  # steady state of the oscillator: var x = sigma^2, var x' = w0^2 sigma^2, uncorrelated
            d.append(nb_of[s][0] ** 2)
        elif s.endswith("_dot") and s[:-4] in nb_of:
            sg, f0, _ = nb_of[s[:-4]]
            d.append((2.0 * math.pi * f0) ** 2 * sg**2)
        else:
            raise ValueError(f"unknown state {s!r}")
    return np.diag(np.asarray(d, dtype=np.float64))


def _mat(a):
    return [[float(v) for v in row] for row in np.asarray(a)]


def export_kf(model, dt: float, reduced: bool | None = None, q_m: float = 0.0, sensor: str = "accel",
              p0_random_walk: float | None = None, var_scale_factor: float = 0.0, var_x: float = 0.0,
              var_v: float = 0.0, var_theta: float = 0.0) -> dict:
    r"""Continuous and discrete Kalman-filter matrices of one axis, as a YAML-ready dict.

    Parameters
    ----------
    model : imupipe.models.NoiseModel
        The (bound) noise model, SI.
    dt : float
        Filter step, s.
    reduced, q_m, sensor :
        See :func:`continuous_model`.
    p0_random_walk, var_scale_factor, var_x, var_v, var_theta :
        See :func:`initial_covariance`.

    Returns
    -------
    dict
        ``states``, ``state_units``, ``noises``, ``noise_units``, ``F``, ``G``, ``Qc`` (continuous),
        ``Phi``, ``Qd`` (discrete at `dt`), ``P0``, ``parameters`` (SI), ``discrete_noise``
        (standard deviations per filter step :math:`\Delta t` = ``step_s``, not per IMU sample: white
        ``white_std_per_step`` :math:`N/\sqrt{\Delta t}`, random walk
        :math:`K\sqrt{\Delta t}`, GM :math:`\phi` and :math:`\sigma\sqrt{1-\phi^2}`), ``equation``,
        ``notes``.
    """
    cm = continuous_model(model, reduced=reduced, q_m=q_m, sensor=sensor)
    Phi, Qd = discretize(cm.F, cm.G, cm.Qc, dt)
    P0 = initial_covariance(model, cm.states, p0_random_walk=p0_random_walk, var_x=var_x, var_v=var_v,
                            var_theta=var_theta, var_scale_factor=var_scale_factor)
    u = _RATE_UNIT[sensor]
    unit_of = {"x": "m", "v": "m/s", "theta": "rad", "p": u, "s_f": "1"}
    state_units = [f"{u}/s" if s.startswith("nb") and s.endswith("_dot") else unit_of.get(s, u) for s in cm.states]
    noise_units = [f"({u})^2/Hz" if nm == "nu_s" else f"({u})^2/s^3" if nm.startswith("nu_nb") else f"({u})^2/s"
                   for nm in cm.noises]
    gm = sorted(model.gauss_markov, key=lambda st: st[1])
    nb = _lines(model)
    is_reduced = "p" not in cm.states
    notes = [
        "two-sided intensities: E[w(t) w(s)] = Qc delta(t - s)",
        "random-walk driving std per step is K*sqrt(dt) (the paper's sigma_p = K*dt holds only at dt = 1 s)",
        "GM states start at their steady-state variance sigma^2 (stationary, as the PSD bound requires)",
    ]
    if not is_reduced and model.random_walk > 0:
        notes.append("p (random walk) is not stationary: its initial variance is a stated input")
    elif not is_reduced:  # the p state kept without a random walk (e.g. the verified reduction dropped K)
        notes.append("p is the turn-on bias, constant here (no random walk: its Qd is 0): its initial variance P0 is "
                     "the bias the filter starts with")
    if "s_f" in cm.states:
        notes.append("s_f is the scale factor (dimensionless) of the paper's model, driven by no noise: its P0 is the "
                     "filter's own scale-factor uncertainty (0 unless given); it enters the rate row as -q_m s_f, "
                     f"here with the nominal rate q_m = {q_m:g} {u}")
    if var_x or var_v or var_theta:
        notes.append("kinematic states (x, v or theta) start at the verified reference filter's variances (the fix "
                     "variance, 1 (m/s)^2 for v): a filter starts them at its own initial uncertainty, at least the "
                     "true initial error's variance (smaller ones were not verified)")
    if nb:
        notes.append("narrowband states (nb, nb_dot) are damped oscillators started at their steady state "
                     "diag(sigma^2, (2 pi f0)^2 sigma^2); their discrete Phi, Qd blocks are in Phi and Qd")
    params = {
        "white": float(model.white),
        "gauss_markov": [{"sigma": float(s), "T": float(T)} for s, T in gm],
        "random_walk": float(model.random_walk),
        "units": {"white": f"{u}/sqrt(Hz)", "sigma": u, "T": "s", "random_walk": f"{u}/sqrt(s)"},
    }
    if nb:
        params["narrowband"] = [{"sigma": float(s), "f0_hz": float(f0), "zeta": float(z)} for s, f0, z in nb]
        params["units"].update(f0_hz="Hz", zeta="1")
    return {
        "sensor": sensor,
        "equation": "Gallon et al. 2021 eq. 19 (reduced, no random-walk state)" if is_reduced
        else "Gallon et al. 2021 eq. 17",
        "dt_s": float(dt),
        "q_m_nominal": float(q_m),
        "states": list(cm.states),
        "state_units": state_units,
        "noises": list(cm.noises),
        "noise_units": noise_units,
        "F": _mat(cm.F),
        "G": _mat(cm.G),
        "Qc": _mat(cm.Qc),
        "Phi": _mat(Phi),
        "Qd": _mat(Qd),
        "P0": _mat(P0),
        "parameters": params,
        "discrete_noise": {
            # per filter step dt_s, not per IMU sample: a sensor sample at rate r has N sqrt(r) of white noise
            "step_s": float(dt),
            "white_std_per_step": float(model.white / math.sqrt(dt)),
            "random_walk_driving_std": float(model.random_walk * math.sqrt(dt)),
            "gauss_markov": [
                {"phi": float(math.exp(-dt / T)), "driving_std": float(s * math.sqrt(-math.expm1(-2 * dt / T)))}
                for s, T in gm
            ],
            "unit": u,
            "note": (f"standard deviations per filter step of {float(dt):g} s (the KF file's dt_s), not per IMU "
                     f"sample: white noise per sample of an IMU at rate r is N sqrt(r), N = parameters.white"),
        },
        "notes": notes,
    }


def export_scope(exported: dict, reduction: dict | None, kf_rate_hz: float, horizon_s: float | None = None) -> dict:
    """What the exported filter model is and where its verification holds (no numerics: a statement).

    Parameters
    ----------
    exported : dict
        The ``exported`` section of a verification report (imupipe.verify.verification_stage): ``reduced``,
        ``reason``, ``model`` (SI) and ``verification`` (its ``scenario``: ``rate_hz`` of the reference filter in
        Hz, ``fix_s`` and ``horizon_s`` in s).
    reduction : dict or None
        The report's ``reduction`` (``accepted``: the drops, e.g. ``random_walk``, ``narrowband f0=0.56 Hz``).
    kf_rate_hz : float
        Rate of the exported filter, Hz (1 / the KF file's dt_s; config ``application.filter_rate_hz``).
    horizon_s : float, optional
        The configured outage horizon, s (config ``application.outage_s``); default: the verification
        scenario's (the same number: the verify rule passes it).

    Returns
    -------
    dict
        ``dropped_by_reduction`` (list of str; empty when the bound is exported whole), ``horizon_s`` (s),
        ``fix_s`` (s), ``verified_filter_rate_hz``, ``verified_fix_rate_hz`` and ``kf_rate_hz`` (Hz),
        ``verified_sigma_fix`` (with its ``verified_sigma_fix_unit``, m or rad), ``rate_mismatch`` (bool: the
        reference filter ran at another rate than the exported filter's), ``line_states`` (narrowband terms of
        the exported model with sigma > 0: sigma in the sensor's SI unit, f0_hz in Hz) and ``statement`` (one
        sentence for the summary and the files).
    """
    from imupipe.models import NoiseModel

    scen = (exported.get("verification") or {}).get("scenario") or {}
    horizon_s = scen.get("horizon_s") if horizon_s is None else horizon_s
    dropped = dropped_by_reduction(exported, reduction)
    vrate = scen.get("rate_hz")
    mismatch = vrate is not None and abs(float(vrate) - float(kf_rate_hz)) > 1e-9 * float(kf_rate_hz)
    # NoiseModel.from_dict reads the narrowband terms in either form (dicts or (sigma, f0_hz, zeta) lists)
    nb = NoiseModel.from_dict(exported.get("model") or {}).narrowband
    line_states = [{"sigma": float(s), "f0_hz": float(f0), "zeta": float(z)} for s, f0, z in nb if s > 0]
    if dropped:
        fixes = ""
        if scen.get("fix_s") is not None:
            fixes = f" after {float(scen['fix_s']):g} s of fixes"
            if scen.get("sigma_fix") is not None:
                fixes += f" of sigma {float(scen['sigma_fix']):g} {scen.get('sigma_fix_unit', '')}".rstrip()
        text = (f"reduced model: the verified reduction dropped {', '.join(dropped)}; the export is then valid for "
                f"the configured scenario only ({_num_s(horizon_s)} s of outage{fixes}), not beyond it: a longer "
                "outage or more accurate fixes need the model before the reduction (the bound file's)")
    else:
        text = "the bound's model, no state dropped"
    if mismatch:
        text += (f"; verified with a reference filter at {float(vrate):g} Hz, exported at {float(kf_rate_hz):g} Hz: "
                 "the verification (and any reduction) is not verified at the exported rate")
    return {"dropped_by_reduction": dropped, "horizon_s": None if horizon_s is None else float(horizon_s),
            "fix_s": None if scen.get("fix_s") is None else float(scen["fix_s"]),
            "verified_filter_rate_hz": None if vrate is None else float(vrate), "kf_rate_hz": float(kf_rate_hz),
            "verified_fix_rate_hz": None if scen.get("fix_rate_hz") is None else float(scen["fix_rate_hz"]),
            "verified_sigma_fix": None if scen.get("sigma_fix") is None else float(scen["sigma_fix"]),
            "verified_sigma_fix_unit": scen.get("sigma_fix_unit"),
            "rate_mismatch": bool(mismatch), "line_states": line_states, "statement": text}


def dropped_by_reduction(exported: dict, reduction: dict | None) -> list:
    """The states the verified reduction dropped from the exported model: the report's ``reduction.accepted`` (e.g.
    ``random_walk``, ``gauss_markov T=5 s``) when the exported model is the reduced one (``exported.reduced``), else
    none (the bound's model is exported whole)."""
    return list((reduction or {}).get("accepted") or []) if exported.get("reduced") else []


def inflation_scope(exported: dict, reduction: dict | None) -> dict:
    """What a contract's ``inflation`` (bound/spec per parameter) describes: the bound's model, before the verified
    reduction, which may have dropped some of its states from the exported model (no numerics: a statement).

    Returns
    -------
    dict
        ``of`` (``"bound"``), ``dropped_from_exported_model`` (list of str, :func:`dropped_by_reduction`) and
        ``statement`` (one sentence).
    """
    dropped = dropped_by_reduction(exported, reduction)
    if dropped:
        text = ("inflation is bound/spec of the bound's model, BEFORE the verified reduction; the exported model "
                f"(model) dropped {', '.join(dropped)}, so the inflation of those components describes no state of "
                "the exported model")
    else:
        text = "inflation is bound/spec of the bound's model, which is the exported model (no state dropped)"
    return {"of": "bound", "dropped_from_exported_model": dropped, "statement": text}


def _num_s(v) -> str:
    return "-" if v is None else f"{float(v):g}"
