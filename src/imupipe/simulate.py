r"""Exact discrete simulation of the noise components of a :class:`~imupipe.models.NoiseModel`.

Each component is simulated as point samples of the continuous process every dt = 1/rate:

- white: :math:`N/\sqrt{dt}\,\epsilon_k` (its AV is exactly N^2/tau at tau = m dt);
- Gauss-Markov: the exact AR(1) recursion :math:`x_{k+1} = \phi x_k + \sigma\sqrt{1-\phi^2}\,\epsilon_k`,
  :math:`\phi = e^{-dt/T}`, started at steady state :math:`x_0 \sim N(0, \sigma^2)`;
- random walk: :math:`K\sqrt{dt}` times the cumulative sum of unit normals (the paper's :math:`K\,dt` is a slip);
- flicker: one white sequence through a bank of first-order recursions (:func:`flicker_bank`), the exact
  discrete process whose two-sided PSD approximates :math:`S_2 = B^2/(2\pi |f|)` from about 1/(2 n dt) up
  (1.5 poles per decade, started at the bank's steady state; no FFT, cost linear in n; accuracy there);
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
# (flicker_bank and sim_piece are looked up by name: an extension built before them falls back to NumPy)

__all__ = ["flicker_bank", "simulate", "simulate_chunks", "narrowband_discrete"]

#: Poles per decade of the flicker bank (:func:`flicker_bank`): 3 poles per 2 decades keep the bank's PSD within
#: 0.25 dB of B^2/(2 pi f) over the band for any record length (2 per decade: 0.22 dB with a third more branches;
#: the band's edges, not the ladder's ripple, set the error), with 11 branches for 10 h at 125 Hz.
FLICKER_POLES_PER_DECADE = 1.5
# samples per pass of the flicker bank (about 256 KB of float64: each branch's pass stays in cache)
_FLICKER_CHUNK = 1 << 15
# branches the compiled flicker bank holds (IMUPIPE_MAX_BRANCHES of _kernels.c; 11 for 10 h at 125 Hz)
_FLICKER_MAX_BRANCHES = 64


def flicker_bank(n: int, dt: float, poles_per_decade: float = FLICKER_POLES_PER_DECADE):
    r"""Design of the flicker draw of :func:`simulate`: poles ``p`` and residues ``res`` of a bank of first-order
    recursions, ``c`` its direct term and ``gain`` (u per unit flicker coefficient B, per unit white draw).

    The record ``y = B gain (c w + sum_i res_i s_i)`` with ``s_i[k] = p_i s_i[k-1] + w[k]`` and ``w`` i.i.d.
    N(0, 1) is the partial-fraction form of the pole-zero cascade

    .. math:: H(z) = \prod_i \frac{1 - z_i z^{-1}}{1 - p_i z^{-1}}, \quad p_i = e^{-2\pi f_i dt},
              \ z_i = e^{-2\pi f_i \sqrt{r} dt}, \ f_i = f_a r^i, \ r = 10^{1/\text{poles\_per\_decade}},

    with :math:`f_a = 1/(2 n dt \sqrt r)` (half a spacing below the lowest frequency of the record's
    circulant embedding, 1/(2 n dt)) and poles up to the Nyquist frequency (J. A. Barnes, S. Jarvis, "Efficient
    numerical and analog modeling of flicker noise processes", NBS Technical Note 604, 1971; M. S. Keshner,
    "1/f noise", Proc. IEEE 70(3), 1982). Two-sided PSD of y: :math:`(B\,gain)^2\,dt\,|H(e^{2\pi i f dt})|^2`;
    ``gain`` makes its log-mean over 4/(2 n dt) <= f <= rate/8 equal to that of :math:`B^2/(2\pi f)`. The
    exact PSD (:func:`flicker_bank_psd`) lies within +-0.25 dB (+-6 %) of :math:`B^2/(2\pi f)` there at 1.5 poles
    per decade (:data:`FLICKER_POLES_PER_DECADE`) for any n (0.08 dB for 10 h at 125 Hz), at most 0.25 dB below it
    at 1/(2 n dt) (it flattens below, where the record's AV does not look) and up to 2.8 dB above it between rate/8
    and the Nyquist frequency (the matched pole mapping), where the white noise of an IMU exceeds its flicker by
    orders of magnitude (STIM-300-like gyro: 1e5 at 15 Hz). tests/test_simulate.py checks these bounds. The residues are all
    positive (no cancellation). Steady-state start: the branch states before the first sample are drawn from
    their stationary covariance :math:`C_{ij} = 1/(1 - p_i p_j)`.
    """
    n = int(n)
    r = 10.0 ** (1.0 / poles_per_decade)
    f_a = 1.0 / (2.0 * n * dt * np.sqrt(r))
    n_poles = max(1, int(np.ceil(np.log10(0.5 / dt / f_a) * poles_per_decade)))
    f_p = f_a * r ** np.arange(n_poles)
    p = np.exp(-2.0 * np.pi * f_p * dt)
    z = np.exp(-2.0 * np.pi * f_p * np.sqrt(r) * dt)
    c = float(np.prod(z / p))
    res = np.array([np.prod(1.0 - z / p[i]) / np.prod(np.delete(1.0 - p / p[i], i)) for i in range(n_poles)])
    f_hi = 1.0 / (8.0 * dt)
    f = np.geomspace(min(4.0 / (2.0 * n * dt), f_hi / 2.0), f_hi, 64 * n_poles)  # (a short record: an octave)
    h2 = flicker_bank_psd(f, dt, p, res, c)  # per unit B gain: dt |H|^2
    gain = float(np.exp(-0.5 * np.mean(np.log(2.0 * np.pi * f * h2))))
    return p, res, c, gain


def flicker_bank_psd(f, dt: float, p, res, c) -> np.ndarray:
    """Two-sided PSD (u^2/Hz per unit B gain, i.e. dt |H|^2) of the bank ``c + sum res_i/(1 - p_i z^-1)`` at f (Hz)."""
    zinv = np.exp(-2j * np.pi * np.asarray(f, dtype=float) * dt)
    h = c + sum(ri / (1.0 - pi * zinv) for pi, ri in zip(p, res))
    return dt * np.abs(h) ** 2


def _flicker_start(rng, lead: tuple, n: int, B: float, dt: float):
    """The bank of :func:`flicker_bank` for records of n samples, started at steady state: (poles, weights,
    direct weight, states). Weights carry B gain (u per unit white draw): branch u_i = B gain res_i s_i, so
    u_i[k] = p_i u_i[k-1] + B gain res_i w[k]. The states (the u_i before the first sample, shape lead + (J,)) are
    drawn from the stationary covariance C_ij = 1/(1 - p_i p_j) of the s_i (unit white drive)."""
    p, res, c, gain = flicker_bank(n, dt)
    scale = B * gain
    weights = scale * res
    ev, U = np.linalg.eigh(1.0 / (1.0 - np.outer(p, p)))
    state = (rng.standard_normal(lead + (p.size,)) @ (U * np.sqrt(np.clip(ev, 0.0, None))).T) * weights
    return p, weights, scale * c, state


def _flicker_run(w: np.ndarray, p, weights, direct: float, state: np.ndarray, out: np.ndarray | None = None
                 ) -> np.ndarray:
    """Flicker samples driven by the white draws w (shape (rows, m)), the branch states (rows, J) updated in place:
    y[k] = direct w[k] + u_0[k] + ... + u_{J-1}[k], u_i[k] = p_i u_i[k-1] + weights_i w[k], the branches added
    in their order. The compiled kernel (``imupipe._kernels.flicker_bank``) does it in one pass over the samples,
    all branches at once, into `out` (may be w; default a new array); without it, :func:`_flicker_passes`, the
    same operations branch by branch."""
    if (hasattr(_kernels, "flicker_bank") and w.dtype == np.float64 and w.flags.c_contiguous and state.flags.c_contiguous
            and state.dtype == np.float64 and 1 <= p.size <= _FLICKER_MAX_BRANCHES):
        y = np.empty_like(w) if out is None else out
        _kernels.flicker_bank(w, np.ascontiguousarray(p, dtype=float), np.ascontiguousarray(weights, dtype=float),
                              float(direct), state, y, w.shape[-1])
        return y
    y = _flicker_passes(w, p, weights, direct, state)
    if out is not None:
        out[...] = y
        return out
    return y


def _flicker_passes(w: np.ndarray, p, weights, direct: float, state: np.ndarray) -> np.ndarray:
    """:func:`_flicker_run` in NumPy, branch by branch: per branch a multiply, the AR(1) recursion
    (:func:`_ar1`), an add; blocks of whole records when a record fits a cache-sized chunk (contiguous copies),
    else chunks of one record, so that each branch's pass over a block stays in cache."""
    rows, m = w.shape
    y = w * direct
    n_rows, step = (max(1, _FLICKER_CHUNK // m), m) if m <= _FLICKER_CHUNK else (1, _FLICKER_CHUNK)
    for r0 in range(0, rows, n_rows):
        r1 = min(rows, r0 + n_rows)
        for a in range(0, m, step):
            b = min(m, a + step)
            block = w[r0:r1, a:b]
            chunk = np.empty(block.shape)
            for i in range(p.size):
                np.multiply(block, weights[i], out=chunk)
                chunk[:, 0] += p[i] * state[r0:r1, i]
                u = _ar1(chunk, p[i])  # in place with the kernel (chunk is contiguous)
                state[r0:r1, i] = u[:, -1]
                y[r0:r1, a:b] += u
    return y


def _flicker(rng, shape, B: float, dt: float) -> np.ndarray:
    """Flicker samples of coefficient B (u), shape `shape`, by :func:`flicker_bank` (one white draw)."""
    n = shape[-1]
    p, weights, direct, state = _flicker_start(rng, shape[:-1], n, B, dt)
    rows = int(np.prod(shape[:-1], dtype=np.int64))
    w = rng.standard_normal(shape)
    return _flicker_run(w.reshape(rows, n), p, weights, direct, state.reshape(rows, p.size)).reshape(shape)


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
    _modal_drive(eta[..., :-1, :], Vinv[k], drive[..., 1:])
    drive[..., 0] = x0 @ Vinv[k]
    if np.iscomplexobj(mu) and abs(mu[k].imag) > 0:
        return 2.0 * np.real(V[0, k] * _complex_ar1(drive, complex(mu[k])))
    # real eigenvalues (not reached for 0 < zeta < 1): the plain two-state recursion
    out = np.empty(shape)
    st = x0
    for i in range(shape[-1]):
        out[..., i] = st[..., 0]
        st = st @ phi.T + eta[..., i, :]
    return out


def _modal_drive(eta: np.ndarray, v: np.ndarray, out: np.ndarray) -> None:
    """out = eta @ v for real `eta` (..., 2) and complex `v` (2,), into complex `out` (...), in real arithmetic:
    Re = eta_0 Re v_0 + eta_1 Re v_1, Im likewise (a real times a complex number has no cross terms), without the
    complex copy of `eta` that ``@`` makes."""
    for part, w in ((out.real, v.real), (out.imag, v.imag)):
        np.multiply(eta[..., 0], w[0], out=part)
        part += eta[..., 1] * w[1]


def _complex_ar1(z: np.ndarray, mu: complex) -> np.ndarray:
    """s[0] = z[0], s[i] = mu s[i-1] + z[i] along the last axis of complex128 ``z``, in place where it can: the
    compiled kernel (``imupipe._kernels.car1`` on z's float64 pairs, no scipy.signal import in the job) or
    ``scipy.signal.lfilter([1], [1, -mu], z, axis=-1)``, the same operations in the same order (tested
    bit-identical)."""
    if _kernels is not None and hasattr(_kernels, "car1") and z.flags.c_contiguous and z.dtype == np.complex128:
        _kernels.car1(z.view(np.float64), mu.real, mu.imag, z.shape[-1])
        return z
    from scipy.signal import lfilter

    return lfilter([1.0], [1.0, -mu], z, axis=-1)


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
        add(_flicker(rng, shape, model.flicker, dt))
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


#: Gauss-Markov terms the compiled piece (``imupipe._kernels.sim_piece``) holds (IMUPIPE_MAX_GM of _kernels.c)
_PIECE_MAX_GM = 16


def _linear_piece(rng, m: int, first: bool, sw, gms, gm_last: list, krw, rw_sum: float):
    """The white, Gauss-Markov and random-walk terms of one piece of :func:`simulate_chunks` (m samples), their
    sum: x = ((0 + sw w) + g_0 + ... + g_{G-1}) + krw (cumsum(v) + rw_sum) from unit normal draws taken in that
    order (white, each GM, random walk; m each), g_j[k] = phi_j g_j[k-1] + scale_j e_j[k] (``gms`` the (phi,
    scale) pairs) started from ``gm_last`` (the first piece: g_j[0] = gm_last[j], the steady-state x_0); sw or
    krw None: no such term. ``gm_last`` receives each g_j's last value; returns (x, the random walk's running sum).
    The compiled kernel does it in one pass, the NumPy passes below term by term: the same operations in the same
    order (one draw of all the piece's normals is the same stream as one draw per term)."""
    if hasattr(_kernels, "sim_piece") and len(gms) <= _PIECE_MAX_GM:
        k = (sw is not None) + len(gms) + (krw is not None)
        draws = rng.standard_normal((k, m))
        x = np.empty(m)
        g0 = int(sw is not None)
        phis = np.array([phi for phi, _ in gms], dtype=float)
        scales = np.array([scale for _, scale in gms], dtype=float)
        last = np.array(gm_last, dtype=float)
        rw_sum = _kernels.sim_piece(x, draws[0] if sw is not None else None, float(sw or 0.0),
                                    draws[g0:g0 + len(gms)], phis, scales, last, bool(first),
                                    draws[-1] if krw is not None else None, float(krw or 0.0), float(rw_sum))
        gm_last[:] = last.tolist()
        return x, rw_sum
    x = np.zeros(m)
    if sw is not None:
        w = rng.standard_normal(m)
        w *= sw
        x += w
    for j, (phi, scale) in enumerate(gms):
        e = rng.standard_normal(m)
        e *= scale
        if first:
            e[0] = gm_last[j]  # x_0 itself
        else:
            e[0] += phi * gm_last[j]
        e = _ar1(e, phi)
        gm_last[j] = float(e[-1])
        x += e
    if krw is not None:
        w = rng.standard_normal(m)
        np.cumsum(w, out=w)
        w += rw_sum
        rw_sum = float(w[-1])
        w *= krw
        x += w
    return x, rw_sum


#: Samples per piece of :func:`simulate_chunks` (2 MB of float64): part of the definition of its random stream.
SIM_CHUNK = 1 << 18


def simulate_chunks(model, n: int, rate: float, rng=None, chunk: int = SIM_CHUNK):
    """One record of :func:`simulate`'s process in consecutive pieces: yields (first sample index, samples) with
    pieces of `chunk` samples (the last shorter), so that a record is written without holding it whole (memory:
    a few pieces, whatever n).

    The components are those of :func:`simulate` (same definitions and units), each continued exactly from piece to
    piece: the Gauss-Markov recursion and the flicker bank carry their states, the random walk its last value, the
    quantization term its last angle error, the ramp its time. The random stream differs from :func:`simulate`'s
    (the initial states first, then piece by piece: white, each GM, random walk, flicker, quantization), so the
    values differ but not their distribution; the same seed and `chunk` give the same values. A narrowband
    component is drawn over the whole record (one piece).
    """
    n = int(n)
    if n < 2:
        raise ValueError(f"simulate needs n >= 2 samples, got {n}")
    if not rate > 0:
        raise ValueError(f"rate must be > 0 Hz, got {rate!r}")
    chunk = int(chunk)
    if chunk < 1:
        raise ValueError(f"chunk must be >= 1 sample, got {chunk}")
    if getattr(model, "narrowband", ()):
        yield 0, simulate(model, n, rate, rng)
        return
    rng = np.random.default_rng(rng)
    dt = 1.0 / float(rate)
    gms = [(np.exp(-dt / T), sigma * np.sqrt(-np.expm1(-2.0 * dt / T))) for sigma, T in model.gauss_markov]
    gm_last = [sigma * rng.standard_normal() for sigma, _ in model.gauss_markov]  # steady state x_0
    rw_sum = 0.0
    sw, krw = model.white / np.sqrt(dt), model.random_walk * np.sqrt(dt)  # u per unit draw
    flk = _flicker_start(rng, (1,), n, model.flicker, dt) if model.flicker else None
    q_last = model.quantization * rng.standard_normal() if model.quantization else 0.0
    for a in range(0, n, chunk):
        m = min(chunk, n - a)
        x, rw_sum = _linear_piece(rng, m, a == 0, sw if model.white else None, gms, gm_last,
                                  krw if model.random_walk else None, rw_sum)
        if flk is not None:
            p, weights, direct, state = flk
            w = rng.standard_normal((1, m))
            x += _flicker_run(w, p, weights, direct, state, out=w)[0]
        if model.quantization:
            e = np.empty(m + 1)
            e[0] = q_last
            e[1:] = model.quantization * rng.standard_normal(m)
            q_last = float(e[-1])
            x += np.diff(e) / dt
        if model.ramp:
            x += model.ramp * dt * np.arange(a, a + m)
        yield a, x
