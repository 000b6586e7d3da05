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
- ramp: the deterministic R t.
"""

from __future__ import annotations

import numpy as np

try:  # optional compiled kernel; scipy.signal.lfilter does the same recursion
    from imupipe import _kernels
except ImportError:  # pragma: no cover
    _kernels = None

__all__ = ["simulate"]


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
    if x is None:
        x = np.zeros(shape)
    if model.quantization:
        e = model.quantization * rng.standard_normal(shape[:-1] + (n + 1,))
        x += np.diff(e, axis=-1) / dt
    if model.ramp:
        x += model.ramp * dt * np.arange(n)
    return x.astype(dtype, copy=False)
