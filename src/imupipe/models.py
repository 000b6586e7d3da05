r"""Stochastic IMU error models: closed-form PSDs and Allan variances of the classic components.

Conventions (docs/architecture.md): SI units, **two-sided** PSDs :math:`S_2` (u^2/Hz, integrated over
:math:`-\infty..\infty`), :math:`S_1 = 2 S_2`. The Allan variance of a two-sided PSD is

.. math:: \sigma^2(\tau) = 4 \int_0^\infty S_2(f) \frac{\sin^4(\pi f \tau)}{(\pi f \tau)^2} df

(the paper's eq. 1 has the factor 2, which gives half the Allan variance with a two-sided PSD).

========================  =====================  ==============================  ==========================
component                 parameter (SI)         two-sided PSD                   Allan variance
========================  =====================  ==============================  ==========================
white (ARW / VRW)         N, u/sqrt(Hz)          N^2                             N^2 / tau
Gauss-Markov (1st order)  sigma (u), T (s)       2 sigma^2 T / (1 + (2 pi f T)^2)  :func:`gm_avar`
random walk (RRW / AcRW)  K, u/sqrt(s)           K^2 / (2 pi f)^2                K^2 tau / 3
flicker (bias instab.)    B, u                   B^2 / (2 pi f)                  (2 ln2 / pi) B^2
quantization              Q, u*s                 (2 pi f)^2 Q^2 dt, f < 1/(2 dt)   3 Q^2 / tau^2
rate ramp                 R, u/s                 (none: not stationary)          R^2 tau^2 / 2
narrowband (2nd-order GM) sigma (u), f0 (Hz),    q / ((w0^2-w^2)^2+(2 zeta w0 w)^2) :func:`narrowband_avar`
                          zeta (-)
========================  =====================  ==============================  ==========================

The narrowband term (a spectral line, e.g. a vibration or a coupled oscillation) is the damped oscillator
:math:`\ddot x + 2\zeta\omega_0\dot x + \omega_0^2 x = w`, :math:`\omega_0 = 2\pi f_0`, w white with two-sided
PSD q; :math:`\omega = 2\pi f`, variance :math:`\sigma^2 = q/(4\zeta\omega_0^3)`, 0 < zeta < 1. Its
autocovariance is :math:`R(t) = \mathrm{Re}[A e^{\lambda |t|}]` with :math:`\lambda = -\zeta\omega_0 +
i\omega_0\sqrt{1-\zeta^2}` and :math:`A = \sigma^2 (1 - i\zeta/\sqrt{1-\zeta^2})`: every closed form of the
first-order GM (autocovariance :math:`\sigma^2 e^{-|t|/T}`) holds for it with :math:`-1/T \to \lambda` and the real
part of A times the result taken, which is how :func:`narrowband_avar` and ``psd_sampled`` are written.

References
----------
.. [1] IEEE Std 952-1997, Annex C (Allan variance of each noise term).
.. [2] W. J. Riley, NIST SP 1065 (2008).
.. [3] E. Gallon, M. Joerger, B. Pervan, "Development of Stochastic IMU Error Models for INS/GNSS Integration",
       ION GNSS+ 2021, eqs. 5-13.
.. [4] A. Papoulis, S. U. Pillai, *Probability, Random Variables and Stochastic Processes*, 4th ed. (2002):
       spectra of linear systems driven by white noise (the damped oscillator).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

__all__ = ["NoiseModel", "dominating_model", "gm_avar", "narrowband_avar", "narrowband_psd", "expm1x", "FLICKER_AV", "COMPONENTS"]

#: Allan variance of flicker noise of coefficient B is FLICKER_AV * B^2 (ADEV = 0.664 B).
FLICKER_AV = 2.0 * math.log(2.0) / math.pi

#: Component names, in the order used by ``components()`` and ``to_dict()``.
COMPONENTS = ("white", "gauss_markov", "random_walk", "flicker", "quantization", "ramp", "narrowband")

# Series of the GM Allan variance: AV = -sigma^2 * sum_{n>=3} (-1)^n (2^n - 4) x^(n-2) / n!,  x = tau/T.
_GM_SERIES = np.array([-((-1.0) ** n) * (2.0**n - 4.0) / math.factorial(n) for n in range(3, 40)])
_GM_SWITCH = 0.5


def gm_avar(tau, sigma: float, T: float) -> np.ndarray:
    r"""Allan variance of a first-order Gauss-Markov process (variance sigma^2, time constant T).

    .. math::

        \sigma^2_A(\tau) = \frac{2\sigma^2 T}{\tau}\left[1 - \frac{T}{2\tau}
        \left(3 - 4 e^{-\tau/T} + e^{-2\tau/T}\right)\right]

    Evaluated directly this cancels catastrophically for small x = tau/T (all digits are gone near x = 1e-6).
    Below x = 0.5 the exact power series :math:`2\sigma^2 (x/3 - x^2/4 + 7x^3/60 - x^4/24 + \dots)`
    (general term :math:`-\sigma^2 (-1)^n (2^n - 4) x^{n-2}/n!`, n >= 3, 37 terms: truncation below 1e-30) is
    summed by Horner's rule; above it the bracket is written with ``expm1``:
    :math:`3 - 4e^{-x} + e^{-2x} = e_m (2 + e_m)` with :math:`e_m = -\mathrm{expm1}(-x)`, which loses at most
    about one digit at the switch. Relative accuracy ~1e-15 for x from 1e-9 to 1e6 (tested against mpmath).

    Parameters
    ----------
    tau : array_like
        Averaging times, s (> 0).
    sigma : float
        Standard deviation of the process, in the signal's unit u.
    T : float
        Time constant, s (> 0).

    Returns
    -------
    numpy.ndarray
        Allan variance, u^2. Peaks at ADEV = 0.6174 sigma near tau = 1.893 T.
    """
    tau = np.asarray(tau, dtype=np.float64)
    if T <= 0:
        raise ValueError(f"Gauss-Markov time constant T must be > 0 s, got {T!r}")
    x = tau / T
    out = np.empty_like(x)
    small = x < _GM_SWITCH
    xs = x[small]
    acc = np.zeros_like(xs)
    for c in _GM_SERIES[::-1]:
        acc = acc * xs + c
    out[small] = acc * xs
    xl = x[~small]
    em = -np.expm1(-xl)
    out[~small] = (2.0 / xl) * (1.0 - em * (2.0 + em) / (2.0 * xl))
    return sigma**2 * out


def expm1x(x):
    """:math:`e^{-x} - 1 + x` for :math:`x \\ge 0` (dimensionless) without cancellation near 0.

    ``expm1(-x) + x``, with the Taylor series :math:`x^2/2 - x^3/6 + x^4/24 - x^5/120` below x = 1e-3 (its
    first omitted term, :math:`x^6/720`, is below 3e-15 of :math:`x^2/2` there). Used by the sampled
    Gauss-Markov PSD (:meth:`NoiseModel.psd_sampled`, x = dt/T) and the GM term of the phase's generalised
    covariance (:func:`imupipe.avcov.phase_gencov`, x = lag/T).
    """
    x = np.asarray(x, dtype=np.float64)
    out = np.expm1(-x) + x
    small = x < 1e-3
    xs = x[small]
    out[small] = xs * xs * (0.5 - xs * (1.0 / 6.0 - xs * (1.0 / 24.0 - xs / 120.0)))
    return out


def _check_nonneg(name: str, value: float) -> float:
    value = float(value)
    if not math.isfinite(value) or value < 0:
        raise ValueError(f"NoiseModel parameter {name!r} must be a finite number >= 0, got {value!r}")
    return value


# Series in z of g(z) = (4 e^z - e^{2z} - 3 - 2z) / z^2 = sum_{n>=3} (4 - 2^n) z^(n-2) / n!  (complex z;
# the n = 2 coefficient is 0, kept so that the coefficient list starts at z^0 like the others)
_NB_AV_SERIES = np.array([(4.0 - 2.0**n) / math.factorial(n) for n in range(2, 40)])
# e1(z) = (e^z - 1)/z = sum_{n>=1} z^(n-1)/n!;  e2(z) = 2 (e^z - 1 - z)/z^2 = 2 sum_{n>=2} z^(n-2)/n!
_E1_SERIES = np.array([1.0 / math.factorial(n) for n in range(1, 40)])
_E2_SERIES = np.array([2.0 / math.factorial(n) for n in range(2, 40)])
_SERIES_SWITCH = 0.5


def _horner(coef, z):
    acc = np.zeros_like(z)
    for c in coef[::-1]:
        acc = acc * z + c
    return acc


def _complex_fn(z, series, direct):
    """Evaluate a function of complex z by its power series where |z| < 0.5 (no cancellation), else directly."""
    z = np.asarray(z, dtype=np.complex128)
    out = np.empty_like(z)
    small = np.abs(z) < _SERIES_SWITCH
    out[small] = _horner(series, z[small])
    zl = z[~small]
    out[~small] = direct(zl)
    return out


def _nb_lambda(f0_hz: float, zeta: float):
    """Pole lambda = -zeta w0 + i w0 sqrt(1 - zeta^2) (1/s) and the coefficient c = zeta/sqrt(1 - zeta^2)."""
    w0 = 2.0 * math.pi * f0_hz
    r = math.sqrt((1.0 - zeta) * (1.0 + zeta))
    return complex(-zeta * w0, w0 * r), zeta / r


def narrowband_psd(f, sigma: float, f0_hz: float, zeta: float) -> np.ndarray:
    r"""Two-sided PSD of the damped oscillator (second-order Gauss-Markov), u^2/Hz.

    .. math:: S_2(f) = \frac{q}{(\omega_0^2 - \omega^2)^2 + (2\zeta\omega_0\omega)^2},\quad
              q = 4\zeta\omega_0^3\sigma^2,\ \omega = 2\pi f,\ \omega_0 = 2\pi f_0

    The peak is near f0 with height about :math:`\sigma^2/(2\pi f_0\zeta)` and half-power width
    about :math:`2\zeta f_0` Hz (small zeta); the integral over all f is sigma^2.

    Parameters
    ----------
    f : array_like
        Frequencies, Hz.
    sigma : float
        Standard deviation, u.
    f0_hz : float
        Undamped natural frequency, Hz (> 0).
    zeta : float
        Damping ratio, 0 < zeta < 1.
    """
    f = np.asarray(f, dtype=np.float64)
    w0 = 2.0 * math.pi * f0_hz
    w = 2.0 * np.pi * f
    q = 4.0 * zeta * w0**3 * sigma**2
    return q / ((w0 * w0 - w * w) ** 2 + (2.0 * zeta * w0 * w) ** 2)


def narrowband_avar(tau, sigma: float, f0_hz: float, zeta: float) -> np.ndarray:
    r"""Allan variance of the damped oscillator (second-order Gauss-Markov), u^2.

    The AV is :math:`c_0(\tau) - c_1(\tau)` of the covariances of adjacent tau-means; with the autocovariance
    :math:`\mathrm{Re}[A e^{\lambda |t|}]` (module docstring) and :math:`z = \lambda\tau`:

    .. math:: \sigma^2_A(\tau) = \mathrm{Re}\left[A\,\frac{4e^{z} - e^{2z} - 3 - 2z}{z^2}\right]

    (with :math:`z = -\tau/T`, A = sigma^2 this is the first-order GM's :func:`gm_avar`). Below |z| = 0.5 the
    power series :math:`\sum_{n\ge3} (4 - 2^n) z^{n-2}/n!` (37 terms) avoids the cancellation. Tested against
    :meth:`NoiseModel.avar_from_psd`.

    Parameters
    ----------
    tau : array_like
        Averaging times, s (> 0).
    sigma, f0_hz, zeta : float
        Standard deviation (u), natural frequency (Hz), damping ratio (0 < zeta < 1).
    """
    tau = np.asarray(tau, dtype=np.float64)
    lam, c = _nb_lambda(f0_hz, zeta)
    z = lam * tau
    g = _complex_fn(z, _NB_AV_SERIES, lambda z: (4.0 * np.exp(z) - np.exp(2.0 * z) - 3.0 - 2.0 * z) / z**2)
    return sigma**2 * np.real((1.0 - 1j * c) * g)


def _narrowband_psd_sampled(f, dt: float, sigma: float, f0_hz: float, zeta: float) -> np.ndarray:
    """Two-sided PSD of the oscillator block-averaged over dt and sampled every dt (see NoiseModel.psd_sampled)."""
    lam, c = _nb_lambda(f0_hz, zeta)
    z = np.array([lam * dt])
    a = np.exp(z)[0]
    c0 = _complex_fn(z, _E2_SERIES, lambda z: 2.0 * (np.expm1(z) - z) / z**2)[0]
    b = _complex_fn(z, _E1_SERIES, lambda z: np.expm1(z) / z)[0] ** 2
    cw = np.cos(2.0 * np.pi * np.asarray(f, dtype=np.float64) * dt)
    val = c0 + 2.0 * b * (cw - a) / (1.0 - 2.0 * a * cw + a * a)
    return dt * sigma**2 * np.real((1.0 - 1j * c) * val)


def _check_narrowband(i: int, term) -> tuple:
    try:
        sigma, f0, zeta = term
    except (TypeError, ValueError):
        raise ValueError(f"narrowband[{i}] must be a triple (sigma, f0_hz, zeta), got {term!r}") from None
    sigma = _check_nonneg(f"narrowband[{i}].sigma", sigma)
    f0 = _check_nonneg(f"narrowband[{i}].f0_hz", f0)
    zeta = float(zeta)
    if f0 == 0:
        raise ValueError(f"narrowband[{i}].f0_hz must be > 0 Hz")
    if not 0.0 < zeta < 1.0:
        raise ValueError(f"narrowband[{i}].zeta must be in (0, 1) (a lightly damped oscillator), got {zeta!r}")
    return (sigma, f0, zeta)


_FLICKER_CACHE: dict = {}
_FLICKER_CACHE_SIZE = 8


def _flicker_alias_sum(x) -> np.ndarray:
    r""":math:`\sum_k \mathrm{sinc}^2(x+k) / (2\pi |x+k|)` for x = f dt, 1/(Hz s) units folded: times B^2 dt.

    Exact: :math:`\sin^2(\pi x)/(2\pi^3)\,[\zeta(3, x') + \zeta(3, 1 - x')]`, x' = x mod 1 (Hurwitz zeta);
    infinite at whole x (the flicker PSD at f = 0 and its aliases). The last few grids are cached by content
    (a bound job evaluates the same f dt grid for every LP): a read-only array is returned.
    """
    x = np.abs(np.asarray(x, dtype=np.float64))
    key = (x.shape, x.tobytes())
    hit = _FLICKER_CACHE.get(key)
    if hit is None:
        hit = _flicker_alias_sum_eval(x)
        hit.setflags(write=False)
        if len(_FLICKER_CACHE) >= _FLICKER_CACHE_SIZE:
            _FLICKER_CACHE.pop(next(iter(_FLICKER_CACHE)))
        _FLICKER_CACHE[key] = hit
    return hit


def _flicker_alias_sum_eval(x: np.ndarray) -> np.ndarray:
    from scipy.special import zeta

    xr = np.mod(x, 1.0)
    out = np.full_like(x, np.inf)
    ok = xr > 0
    xo = xr[ok]
    out[ok] = np.sin(np.pi * xo) ** 2 / (2.0 * np.pi**3) * (zeta(3.0, xo) + zeta(3.0, 1.0 - xo))
    return out


@dataclass(frozen=True)
class NoiseModel:
    """Sum of independent noise components of one rate signal, in SI units (see the module table).

    Parameters
    ----------
    white : float
        N, white rate noise density, u/sqrt(Hz) (= u*sqrt(s)); spec-sheet ARW/VRW in u*h^-1/2 is N*60.
    gauss_markov : sequence of (sigma, T)
        First-order Gauss-Markov terms: standard deviation sigma (u) and time constant T (s).
    random_walk : float
        K, rate random walk coefficient, u/sqrt(s).
    flicker : float
        B, flicker (bias instability) coefficient, u.
    quantization : float
        Q, quantization coefficient, u*s (angle or velocity quantization).
    ramp : float
        R, rate ramp, u/s (not stationary: no PSD).
    dt : float or None
        Sample interval, s; needed by the quantization PSD.
    narrowband : sequence of (sigma, f0_hz, zeta)
        Second-order Gauss-Markov (damped oscillator) terms: standard deviation sigma (u), the true full-rate
        natural frequency f0_hz (Hz; aliasing is done by :meth:`psd_sampled`) and the damping ratio zeta in (0, 1).
    """

    white: float = 0.0
    gauss_markov: tuple = field(default_factory=tuple)
    random_walk: float = 0.0
    flicker: float = 0.0
    quantization: float = 0.0
    ramp: float = 0.0
    dt: float | None = None
    narrowband: tuple = field(default_factory=tuple)

    def __post_init__(self):
        for name in ("white", "random_walk", "flicker", "quantization", "ramp"):
            object.__setattr__(self, name, _check_nonneg(name, getattr(self, name)))
        terms = []
        for i, term in enumerate(self.gauss_markov or ()):
            try:
                sigma, T = term
            except (TypeError, ValueError):
                raise ValueError(f"gauss_markov[{i}] must be a pair (sigma, T), got {term!r}") from None
            sigma = _check_nonneg(f"gauss_markov[{i}].sigma", sigma)
            T = _check_nonneg(f"gauss_markov[{i}].T", T)
            if T == 0:
                raise ValueError(f"gauss_markov[{i}].T must be > 0 s")
            terms.append((sigma, T))
        object.__setattr__(self, "gauss_markov", tuple(terms))
        object.__setattr__(
            self, "narrowband", tuple(_check_narrowband(i, t) for i, t in enumerate(self.narrowband or ()))
        )
        if self.dt is not None:
            dt = _check_nonneg("dt", self.dt)
            if dt == 0:
                raise ValueError("dt must be > 0 s")
            object.__setattr__(self, "dt", dt)

    # ------------------------------------------------------------------ PSD
    def psd(self, f, onesided: bool = False) -> np.ndarray:
        """Model PSD at frequencies f (Hz), u^2/Hz; two-sided unless ``onesided`` (then doubled).

        Random walk and flicker are infinite at f = 0. The ramp has no PSD and is left out.
        """
        f = np.abs(np.asarray(f, dtype=np.float64))
        w = 2.0 * np.pi * f
        with np.errstate(divide="ignore"):
            s = np.full_like(f, self.white**2)
            for sigma, T in self.gauss_markov:
                s = s + 2.0 * sigma**2 * T / (1.0 + (w * T) ** 2)
            if self.random_walk:
                s = s + self.random_walk**2 / w**2
            if self.flicker:
                s = s + self.flicker**2 / w
        for sigma, f0, zeta in self.narrowband:
            s = s + narrowband_psd(f, sigma, f0, zeta)
        if self.quantization:
            if self.dt is None:
                raise ValueError("the quantization PSD needs the sample interval: set NoiseModel(dt=...)")
            s = s + np.where(f < 0.5 / self.dt, w**2 * self.quantization**2 * self.dt, 0.0)
        return 2.0 * s if onesided else s

    def psd_sampled(self, f, dt: float) -> np.ndarray:
        r"""Two-sided PSD of the process block-averaged over dt and sampled every dt, u^2/Hz, 0 <= f <= 1/(2dt).

        This is what the sample PSD of block-averaged data estimates:
        :math:`S_d(f) = \sum_k S_2(f + k/dt)\,\mathrm{sinc}^2((f + k/dt) dt)`. Closed forms:

        - white: :math:`N^2` exactly (:math:`\sum_k \mathrm{sinc}^2(x + k) = 1`);
        - random walk: :math:`K^2 dt^2 (1/\sin^2(\pi f dt) - 2/3) / 4`
          (from :math:`\sum_k (x+k)^{-4} = \pi^4/\sin^4(\pi x) - 2\pi^4/(3 \sin^2(\pi x))`);
        - Gauss-Markov, a = exp(-dt/T), w = 2 pi f dt: from the autocovariance of the block means,
          :math:`c_0 = 2\sigma^2 (T/dt)^2 (a - 1 + dt/T)`, :math:`c_j = \sigma^2 (T/dt)^2 (1-a)^2 a^{j-1}`,
          :math:`S_d = dt\,[c_0 + 2\sigma^2 (T/dt)^2 (1-a)^2 (\cos w - a)/(1 - 2a\cos w + a^2)]`;
        - flicker: with x = f dt, :math:`\mathrm{sinc}^2(x+k) = \sin^2(\pi x)/(\pi (x+k))^2`, so
          :math:`S_d = \frac{B^2 dt}{2\pi^3}\sin^2(\pi x)\,[\zeta(3, x') + \zeta(3, 1-x')]`, x' = x mod 1, with
          the Hurwitz zeta :math:`\zeta(3, a) = \sum_{k\ge0} (k+a)^{-3}` (``scipy.special.zeta``): exact, no alias
          sum (the sum over k of :math:`|x+k|^{-3}` is split into k >= 0 and k < 0);
        - narrowband (damped oscillator): as the Gauss-Markov with :math:`a = e^{\lambda dt}` complex and the real
          part of :math:`A\,[\dots]` (module docstring):
          :math:`S_d = dt\,\mathrm{Re}\{A[e_2 + 2 e_1^2 (\cos w - a)/(1 - 2a\cos w + a^2)]\}`,
          :math:`e_1 = (e^{z}-1)/z`, :math:`e_2 = 2(e^{z}-1-z)/z^2`, :math:`z = \lambda dt` (power series below
          |z| = 0.5): the aliases of f0 above 1/(2 dt) land where block averaging folds them;
        - quantization (band-limited, no aliases): :math:`S_2(f)\,\mathrm{sinc}^2(f dt)`.
        """
        f = np.abs(np.asarray(f, dtype=np.float64))
        dt = float(dt)
        if dt <= 0:
            raise ValueError(f"dt must be > 0 s, got {dt!r}")
        s = np.full_like(f, self.white**2)
        cw = np.cos(2.0 * np.pi * f * dt) if self.gauss_markov else None
        for sigma, T in self.gauss_markov:
            x = dt / T
            a = math.exp(-x)
            r = (T / dt) ** 2
            c0 = 2.0 * sigma**2 * r * float(expm1x(np.array([x]))[0])
            b = sigma**2 * r * (-math.expm1(-x)) ** 2
            s = s + dt * (c0 + 2.0 * b * (cw - a) / (1.0 - 2.0 * a * cw + a * a))
        with np.errstate(divide="ignore"):
            if self.random_walk:
                sn = np.sin(np.pi * f * dt)
                s = s + self.random_walk**2 * dt**2 * (1.0 / sn**2 - 2.0 / 3.0) / 4.0
            if self.flicker:
                s = s + self.flicker**2 * _flicker_alias_sum(f * dt) * dt
        for sigma, f0, zeta in self.narrowband:
            s = s + _narrowband_psd_sampled(f, dt, sigma, f0, zeta)
        if self.quantization:
            s = s + NoiseModel(quantization=self.quantization, dt=dt).psd(f) * np.sinc(f * dt) ** 2
        return s

    # ------------------------------------------------------------------ Allan variance
    def avar(self, tau) -> np.ndarray:
        """Closed-form Allan variance at averaging times tau (s), u^2 (sum of the module table's forms)."""
        tau = np.asarray(tau, dtype=np.float64)
        av = self.white**2 / tau + self.random_walk**2 * tau / 3.0
        for sigma, T in self.gauss_markov:
            av = av + gm_avar(tau, sigma, T)
        av = av + FLICKER_AV * self.flicker**2 + 3.0 * self.quantization**2 / tau**2 + self.ramp**2 * tau**2 / 2.0
        for sigma, f0, zeta in self.narrowband:
            av = av + narrowband_avar(tau, sigma, f0, zeta)
        return av

    def avar_from_psd(self, tau) -> np.ndarray:
        r"""Allan variance by numerical integration of the two-sided PSD (factor 4), u^2.

        With u = f tau: :math:`\sigma^2(\tau) = (4/\tau)\int_0^\infty S_2(u/\tau) \sin^4(\pi u)/(\pi u)^2 du`.
        [0, 1] is integrated with adaptive quadrature; on [1, inf) :math:`\sin^4 = (3 - 4\cos 2\pi u +
        \cos 4\pi u)/8` turns the oscillatory integral into one plain and two Fourier integrals (QUADPACK
        QAGI and QAWF). Quantization is band-limited at 1/(2 dt), where the integral is elementary:
        :math:`16 Q^2 dt\,\tau^{-3} (3U/8 - \sin 2\pi U/(4\pi) + \sin 4\pi U/(32\pi))`, U = tau/(2 dt).
        The ramp has no PSD and is not included. With narrowband terms the head interval reaches past every
        peak u0 = f0 tau by 10 half-widths and is split at the peaks, their half-power points and every whole u
        (cost grows with f0 tau: meant for tests, not for long tau grids).
        """
        from scipy.integrate import quad

        tau = np.atleast_1d(np.asarray(tau, dtype=np.float64))
        smooth = replace(self, quantization=0.0, ramp=0.0)
        out = np.empty_like(tau)
        for i, t in enumerate(tau):

            def g(u, t=t):
                return float(smooth.psd(np.array([u / t]))[0]) / (np.pi * u) ** 2

            def head(u, t=t):
                if u == 0.0:
                    return 0.0
                return g(u) * math.sin(math.pi * u) ** 4

            # narrowband peaks (u0 = f0 tau, half-power half-width zeta u0) stay in the finite head [0, U]:
            # U = 1, or an integer beyond every peak by 10 half-widths (the rest is a smooth u^-6 tail for QAWF),
            # each piece between breakpoints
            # (peaks, their half-power points, whole numbers of oscillations) integrated separately
            U, pts = 1.0, []
            for _, f0, zeta in self.narrowband:
                u0, hw = f0 * t, zeta * f0 * t
                U = max(U, float(math.ceil(u0 + 10.0 * hw)))
                pts += [u0 - hw, u0, u0 + hw]
            edges = sorted({0.0, U, *[p for p in pts if 0.0 < p < U], *np.arange(1.0, U).tolist()})
            a = 0.0
            for lo, hi in zip(edges[:-1], edges[1:]):
                a += quad(head, lo, hi, epsabs=0.0, epsrel=1e-13, limit=200)[0]
            plain, _ = quad(g, U, np.inf, epsabs=0.0, epsrel=1e-13, limit=200)
            scale = abs(plain) + abs(a) + 1e-300
            c2, _ = quad(g, U, np.inf, weight="cos", wvar=2.0 * np.pi, epsabs=1e-12 * scale, limlst=200)
            c4, _ = quad(g, U, np.inf, weight="cos", wvar=4.0 * np.pi, epsabs=1e-12 * scale, limlst=200)
            out[i] = 4.0 / t * (a + (3.0 * plain - 4.0 * c2 + c4) / 8.0)
        if self.quantization:
            if self.dt is None:
                raise ValueError("the quantization PSD needs the sample interval: set NoiseModel(dt=...)")
            U = tau / (2.0 * self.dt)
            integral = 3.0 * U / 8.0 - np.sin(2 * np.pi * U) / (4 * np.pi) + np.sin(4 * np.pi * U) / (32 * np.pi)
            out = out + 16.0 * self.quantization**2 * self.dt / tau**3 * integral
        return out

    # ------------------------------------------------------------------ helpers
    def components(self) -> dict:
        """Name -> NoiseModel holding that component only (non-zero components; one entry per GM term)."""
        out = {}
        if self.white:
            out["white"] = NoiseModel(white=self.white, dt=self.dt)
        for i, term in enumerate(self.gauss_markov):
            key = "gauss_markov" if len(self.gauss_markov) == 1 else f"gauss_markov_{i}"
            out[key] = NoiseModel(gauss_markov=(term,), dt=self.dt)
        for name in ("random_walk", "flicker", "quantization", "ramp"):
            if getattr(self, name):
                out[name] = NoiseModel(**{name: getattr(self, name)}, dt=self.dt)
        for i, term in enumerate(self.narrowband):
            key = "narrowband" if len(self.narrowband) == 1 else f"narrowband_{i}"
            out[key] = NoiseModel(narrowband=(term,), dt=self.dt)
        return out

    def scaled(self, factor: float) -> "NoiseModel":
        """The model whose PSD and Allan variance are `factor` (> 0) times this one's at every frequency and tau:
        every squared coefficient (white, each GM and line variance, random walk, flicker, quantization, ramp) times
        `factor`, the time constants, line frequencies and damping kept."""
        if not (math.isfinite(factor) and factor > 0):
            raise ValueError(f"factor must be a positive number, got {factor!r}")
        a = math.sqrt(float(factor))
        return replace(self, white=self.white * a, random_walk=self.random_walk * a, flicker=self.flicker * a,
                       quantization=self.quantization * a, ramp=self.ramp * a,
                       gauss_markov=tuple((sg * a, T) for sg, T in self.gauss_markov),
                       narrowband=tuple((sg * a, f0, z) for sg, f0, z in self.narrowband))

    def to_dict(self) -> dict:
        """Plain-Python dict (SI) for YAML; inverse of :meth:`from_dict`.

        ``narrowband`` (sigma in u, f0_hz in Hz, zeta dimensionless) is present only when the model has such
        terms, so a model without lines writes the same dict as before.
        """
        d = {
            "white": float(self.white),
            "gauss_markov": [{"sigma": float(s), "T": float(T)} for s, T in self.gauss_markov],
            "random_walk": float(self.random_walk),
            "flicker": float(self.flicker),
            "quantization": float(self.quantization),
            "ramp": float(self.ramp),
            "dt": None if self.dt is None else float(self.dt),
        }
        if self.narrowband:
            d["narrowband"] = [
                {"sigma": float(s), "f0_hz": float(f0), "zeta": float(z)} for s, f0, z in self.narrowband
            ]
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "NoiseModel":
        """Build from :meth:`to_dict` output or the ``bound`` section of a bound YAML; unknown keys are an
        error naming the key. A scalar component given as ``None`` (YAML ``null``) is absent (0)."""
        unknown = set(d) - {"white", "gauss_markov", "random_walk", "flicker", "quantization", "ramp", "dt",
                            "narrowband"}
        if unknown:
            raise ValueError(f"unknown NoiseModel key(s): {sorted(unknown)}")
        kw = dict(d)
        for name in ("white", "random_walk", "flicker", "quantization", "ramp"):
            if name in kw and kw[name] is None:
                kw[name] = 0.0
        kw["gauss_markov"] = tuple(
            (g["sigma"], g["T"]) if isinstance(g, dict) else tuple(g) for g in kw.get("gauss_markov") or ()
        )
        nb = []
        for i, g in enumerate(kw.get("narrowband") or ()):
            if isinstance(g, dict):
                missing = {"sigma", "f0_hz", "zeta"} - set(g)
                if missing:
                    raise ValueError(f"narrowband[{i}] lacks key(s) {sorted(missing)} (expected sigma, f0_hz, zeta)")
                g = (g["sigma"], g["f0_hz"], g["zeta"])
            nb.append(tuple(g))
        kw["narrowband"] = tuple(nb)
        return cls(**kw)

    def __repr__(self) -> str:
        parts = [f"white={self.white:.6g}"] if self.white else []
        if self.gauss_markov:
            parts.append("gauss_markov=(" + ", ".join(f"({s:.6g}, {T:.6g})" for s, T in self.gauss_markov) + ")")
        for name in ("random_walk", "flicker", "quantization", "ramp"):
            if getattr(self, name):
                parts.append(f"{name}={getattr(self, name):.6g}")
        if self.narrowband:
            parts.append(
                "narrowband=(" + ", ".join(f"({s:.6g}, {f0:.6g}, {z:.6g})" for s, f0, z in self.narrowband) + ")"
            )
        if self.dt is not None:
            parts.append(f"dt={self.dt:.6g}")
        return "NoiseModel(" + ", ".join(parts) + ")"


def dominating_model(models):
    r"""The componentwise upper envelope of several noise models: one model whose PSD is >= each model's PSD at
    every frequency (for the upper envelope of curves identified separately, e.g. per axis).

    White N, flicker B, random walk K and quantization Q: the largest. Gauss-Markov terms, matched by rank of T
    (index i over the models, models with fewer terms contribute nothing to that index): the tightest single GM
    dominating all terms i. A GM (sigma_m, T_m) dominates (sigma, T) at every frequency iff
    :math:`\sigma_m^2 T_m \ge \sigma^2 T` (f -> 0) and :math:`\sigma_m^2/T_m \ge \sigma^2/T` (f -> inf) (from the
    two-sided PSD :math:`2\sigma^2 T/(1 + (2\pi f T)^2)`), so with :math:`A = \max \sigma^2 T` and
    :math:`B = \max \sigma^2/T`: :math:`T_m = \sqrt{A/B}`, :math:`\sigma_m^2 = \sqrt{A B}`. Each component of
    the result dominates the same component of every model, so the sum dominates every model's PSD
    (docs/method.md, "The bound"). Narrowband terms are not combined (ValueError if any model has one).

    Parameters
    ----------
    models : sequence of imupipe.models.NoiseModel
        SI models (same sensor type).

    Returns
    -------
    imupipe.models.NoiseModel
        SI; dt of the first model.
    """
    models = list(models)
    if not models:
        raise ValueError("dominating_model: no model given")
    if any(getattr(m, "narrowband", ()) for m in models):
        raise ValueError("dominating_model: narrowband terms are not combined")
    n_gm = max(len(m.gauss_markov) for m in models)
    gm = []
    for i in range(n_gm):
        terms = [sorted(m.gauss_markov, key=lambda st: st[1])[i] for m in models if len(m.gauss_markov) > i]
        terms = [(float(s), float(T)) for s, T in terms if s > 0 and T > 0]
        if not terms:
            continue
        a = max(s * s * T for s, T in terms)
        b = max(s * s / T for s, T in terms)
        gm.append((math.sqrt(math.sqrt(a * b)), math.sqrt(a / b)))
    return NoiseModel(
        white=max(float(m.white) for m in models),
        gauss_markov=tuple(gm),
        random_walk=max(float(m.random_walk) for m in models),
        flicker=max(float(m.flicker) for m in models),
        quantization=max(float(getattr(m, "quantization", 0.0) or 0.0) for m in models),
        dt=models[0].dt,
    )
