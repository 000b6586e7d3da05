r"""Exact discrete simulation of the noise components of a :class:`~imupipe.models.NoiseModel`.

Each component is simulated as point samples of the continuous process every dt = 1/rate:

- white: :math:`N/\sqrt{dt}\,\epsilon_k` (its AV is exactly N^2/tau at tau = m dt);
- Gauss-Markov: the exact AR(1) recursion :math:`x_{k+1} = \phi x_k + \sigma\sqrt{1-\phi^2}\,\epsilon_k`,
  :math:`\phi = e^{-dt/T}`, started at steady state :math:`x_0 \sim N(0, \sigma^2)`;
- random walk: :math:`K\sqrt{dt}` times the cumulative sum of unit normals (the paper's :math:`K\,dt` is a slip);
- flicker: white noise shaped in the frequency domain to :math:`S_2 = B^2/(2\pi |f|)` over the record
  (DC bin set to zero, so no component below 1/(n dt));
- quantization: rate :math:`(e_{k+1} - e_k)/dt` of an i.i.d. angle error of standard deviation Q
  (its AV is 3 Q^2/tau^2);
- ramp: the deterministic R t;
- narrowband (damped oscillator, state [x, x']): the exact discretisation of
  :math:`\dot s = F s + G w`, :math:`F = [[0, 1], [-\omega_0^2, -2\zeta\omega_0]]`, G = [0, 1]^T, white w of
  two-sided PSD :math:`q = 4\zeta\omega_0^3\sigma^2`: :math:`\Phi = e^{F dt}` and :math:`Q_d` from Van Loan's block
  exponential (C. F. Van Loan, IEEE TAC 23(3), 1978), started at the steady state
  :math:`P_\infty = \mathrm{diag}(\sigma^2, \omega_0^2\sigma^2)`. The recursion is run on the complex modal
  coordinate of :math:`\Phi` (one complex first-order recursion; x = 2 Re(v s)), which is the same linear map.
"""

from __future__ import annotations

import numpy as np

try:  # optional compiled kernel; scipy.signal.lfilter does the same recursion
    from imupipe import _kernels
except ImportError:  # pragma: no cover
    _kernels = None

__all__ = ["simulate", "narrowband_discrete"]


def narrowband_discrete(sigma: float, f0_hz: float, zeta: float, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact discrete model of the damped oscillator over dt: (Phi, Qd, P0), state [x (u), x' (u/s)].

    Phi = expm(F dt); Qd = int_0^dt e^{F s} G q G^T e^{F^T s} ds by Van Loan's method (the upper-right block
    of expm([[-F, G q G^T], [0, F^T]] dt) premultiplied by Phi); P0 = diag(sigma^2, w0^2 sigma^2) is the
    steady-state covariance (solves F P + P F^T + G q G^T = 0). Units: Qd and P0 in u^2, u^2/s, u^2/s^2.
    """
    from scipy.linalg import expm

    w0 = 2.0 * np.pi * f0_hz
    q = 4.0 * zeta * w0**3 * sigma**2
    F = np.array([[0.0, 1.0], [-w0 * w0, -2.0 * zeta * w0]])
    Qc = np.array([[0.0, 0.0], [0.0, q]])
    M = np.zeros((4, 4))
    M[:2, :2] = -F
    M[:2, 2:] = Qc
    M[2:, 2:] = F.T
    E = expm(M * dt)
    phi = E[2:, 2:].T
    Qd = phi @ E[:2, 2:]
    Qd = 0.5 * (Qd + Qd.T)
    P0 = np.diag([sigma**2, w0 * w0 * sigma**2])
    return phi, Qd, P0


def _narrowband(rng, shape, sigma: float, f0_hz: float, zeta: float, dt: float) -> np.ndarray:
    """Samples of x of the damped oscillator (steady state), exact in distribution; see the module docstring."""
    from scipy.signal import lfilter

    phi, Qd, P0 = narrowband_discrete(sigma, f0_hz, zeta, dt)
    mu, V = np.linalg.eig(phi)
    k = int(np.argmax(mu.imag)) if np.any(mu.imag != 0) else 0
    Vinv = np.linalg.inv(V)
    # real driving noise eta ~ N(0, Qd) and initial state ~ N(0, P0), mapped to the modal coordinate
    L = _psd_sqrt(Qd)  # L L^T = Qd (symmetric square root: Qd is near-singular for small w0 dt)
    e = rng.standard_normal(shape + (2,))
    eta = e @ L.T
    x0 = rng.standard_normal(shape[:-1] + (2,)) * np.sqrt(np.diag(P0))
    drive = np.empty(shape, dtype=np.complex128)
    drive[..., 1:] = eta[..., :-1, :] @ Vinv[k]
    drive[..., 0] = x0 @ Vinv[k]
    if np.iscomplexobj(mu) and abs(mu[k].imag) > 0:
        s = lfilter([1.0], [1.0, -mu[k]], drive, axis=-1)
        return 2.0 * np.real(V[0, k] * s)
    # real eigenvalues (not reached for 0 < zeta < 1): the plain two-state recursion
    out = np.empty(shape)
    st = x0
    for i in range(shape[-1]):
        out[..., i] = st[..., 0]
        st = st @ phi.T + eta[..., i, :]
    return out


def _psd_sqrt(Q: np.ndarray) -> np.ndarray:
    w, U = np.linalg.eigh(Q)
    return U * np.sqrt(np.clip(w, 0.0, None))


def _ar1(e: np.ndarray, phi: float) -> np.ndarray:
    """x[0] = e[0], x[i] = phi x[i-1] + e[i] along the last axis, in place: the compiled kernel
    (``imupipe._kernels.ar1``, no scipy.signal import in the job) or ``scipy.signal.lfilter``, the same
    operations in the same order (tested bit-identical)."""
    if _kernels is not None and e.flags.c_contiguous and e.dtype == np.float64:
        _kernels.ar1(e, float(phi), e.shape[-1])
        return e
    from scipy.signal import lfilter

    return lfilter([1.0], [1.0, -phi], e, axis=-1)


def simulate(model, n: int, rate: float, rng=None, dtype=np.float64, n_records: int | None = None) -> np.ndarray:
    """Simulate n samples at ``rate`` Hz of a rate signal with the model's noise (SI units of the model).

    Parameters
    ----------
    model : imupipe.models.NoiseModel
    n : int
        Number of samples (> 1).
    rate : float
        Sampling rate, Hz.
    rng : numpy.random.Generator or int or None
        Random generator or seed (fixed seeds make runs reproducible).
    dtype : numpy dtype
        Output dtype; the simulation itself is float64.
    n_records : int, optional
        Simulate this many independent records at once, shape (n_records, n) (vectorised: a Monte
        Carlo null of 99 records costs about one tenth of 99 calls). Default: one record, shape (n,).
    """
    n = int(n)
    if n < 2:
        raise ValueError(f"simulate needs n >= 2 samples, got {n}")
    if not rate > 0:
        raise ValueError(f"rate must be > 0 Hz, got {rate!r}")
    rng = np.random.default_rng(rng)
    dt = 1.0 / float(rate)
    shape = (n,) if n_records is None else (int(n_records), n)
    # each component is drawn into a fresh array and scaled in place (no temporaries: a Monte Carlo batch
    # is tens of MB); the values are those of the plain expressions, operation for operation
    x = None

    def add(term):
        nonlocal x
        if x is None:
            x = term
        else:
            x += term

    if model.white:
        w = rng.standard_normal(shape)
        w *= model.white / np.sqrt(dt)
        add(w)
    for sigma, T in model.gauss_markov:
        phi = np.exp(-dt / T)
        e = rng.standard_normal(shape)
        e *= sigma * np.sqrt(-np.expm1(-2.0 * dt / T))
        e[..., 0] = sigma * rng.standard_normal(shape[:-1])
        add(_ar1(e, phi))
    if model.random_walk:
        w = rng.standard_normal(shape)
        np.cumsum(w, axis=-1, out=w)
        w *= model.random_walk * np.sqrt(dt)
        add(w)
    if model.flicker:
        m = 2 * n
        f = np.fft.rfftfreq(m, dt)
        spec = np.zeros(f.size)
        spec[1:] = np.sqrt(model.flicker**2 / (2.0 * np.pi * f[1:]))
        fshape = shape[:-1] + (f.size,)
        z = np.empty(fshape, dtype=np.complex128)
        z.real = rng.standard_normal(fshape)
        z.imag = rng.standard_normal(fshape)
        # two-sided density S2 -> amplitude: x = irfft(Z * sqrt(S2 * m / dt) / sqrt(2)) with E|Z|^2 = 2
        z *= spec
        z *= np.sqrt(m / dt / 2.0)
        add(np.fft.irfft(z, n=m, axis=-1)[..., :n])
    for sigma, f0, zeta in getattr(model, "narrowband", ()):
        add(_narrowband(rng, shape, sigma, f0, zeta, dt))
    if x is None:
        x = np.zeros(shape)
    if model.quantization:
        e = model.quantization * rng.standard_normal(shape[:-1] + (n + 1,))
        x += np.diff(e, axis=-1) / dt
    if model.ramp:
        x += model.ramp * dt * np.arange(n)
    return x.astype(dtype, copy=False)
