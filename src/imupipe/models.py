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
========================  =====================  ==============================  ==========================

References
----------
.. [1] IEEE Std 952-1997, Annex C (Allan variance of each noise term).
.. [2] W. J. Riley, NIST SP 1065 (2008).
.. [3] E. Gallon, M. Joerger, B. Pervan, "Development of Stochastic IMU Error Models for INS/GNSS Integration",
       ION GNSS+ 2021, eqs. 5-13.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

__all__ = ["NoiseModel", "gm_avar", "FLICKER_AV", "COMPONENTS"]

#: Allan variance of flicker noise of coefficient B is FLICKER_AV * B^2 (ADEV = 0.664 B).
FLICKER_AV = 2.0 * math.log(2.0) / math.pi

#: Component names, in the order used by ``components()`` and ``to_dict()``.
COMPONENTS = ("white", "gauss_markov", "random_walk", "flicker", "quantization", "ramp")

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


def _expm1x(x):
    """exp(-x) - 1 + x without cancellation (x >= 0)."""
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
    """

    white: float = 0.0
    gauss_markov: tuple = field(default_factory=tuple)
    random_walk: float = 0.0
    flicker: float = 0.0
    quantization: float = 0.0
    ramp: float = 0.0
    dt: float | None = None

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
        - flicker: the alias sum truncated at |k| <= 2000 with the integral tail added;
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
            c0 = 2.0 * sigma**2 * r * float(_expm1x(np.array([x]))[0])
            b = sigma**2 * r * (-math.expm1(-x)) ** 2
            s = s + dt * (c0 + 2.0 * b * (cw - a) / (1.0 - 2.0 * a * cw + a * a))
        with np.errstate(divide="ignore"):
            if self.random_walk:
                sn = np.sin(np.pi * f * dt)
                s = s + self.random_walk**2 * dt**2 * (1.0 / sn**2 - 2.0 / 3.0) / 4.0
            if self.flicker:
                x = f * dt
                k = np.arange(-2000, 2001)[:, None]
                u = np.abs(x[None, :] + k)
                terms = np.where(u > 0, np.sinc(u) ** 2 / (2.0 * np.pi * u / dt), 0.0)
                # tail |k| > 2000: sinc^2 averages 1/(2 pi^2 u^2); sum_{|k|>M} 1/u^3 ~ 1/M^2
                tail = dt / (2.0 * np.pi) * (np.sin(np.pi * x) ** 2 / np.pi**2) / 2000.5**2
                fl = self.flicker**2 * (terms.sum(axis=0) + tail)
                s = s + np.where(x > 0, fl, np.inf)
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
        return av

    def avar_from_psd(self, tau) -> np.ndarray:
        r"""Allan variance by numerical integration of the two-sided PSD (factor 4), u^2.

        With u = f tau: :math:`\sigma^2(\tau) = (4/\tau)\int_0^\infty S_2(u/\tau) \sin^4(\pi u)/(\pi u)^2 du`.
        [0, 1] is integrated with adaptive quadrature; on [1, inf) :math:`\sin^4 = (3 - 4\cos 2\pi u +
        \cos 4\pi u)/8` turns the oscillatory integral into one plain and two Fourier integrals (QUADPACK
        QAGI and QAWF). Quantization is band-limited at 1/(2 dt), where the integral is elementary:
        :math:`16 Q^2 dt\,\tau^{-3} (3U/8 - \sin 2\pi U/(4\pi) + \sin 4\pi U/(32\pi))`, U = tau/(2 dt).
        The ramp has no PSD and is not included.
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

            a, _ = quad(head, 0.0, 1.0, epsabs=0.0, epsrel=1e-13, limit=200)
            plain, _ = quad(g, 1.0, np.inf, epsabs=0.0, epsrel=1e-13, limit=200)
            scale = abs(plain) + abs(a) + 1e-300
            c2, _ = quad(g, 1.0, np.inf, weight="cos", wvar=2.0 * np.pi, epsabs=1e-12 * scale, limlst=200)
            c4, _ = quad(g, 1.0, np.inf, weight="cos", wvar=4.0 * np.pi, epsabs=1e-12 * scale, limlst=200)
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
        return out

    def to_dict(self) -> dict:
        """Plain-Python dict (SI) for YAML; inverse of :meth:`from_dict`."""
        return {
            "white": float(self.white),
            "gauss_markov": [{"sigma": float(s), "T": float(T)} for s, T in self.gauss_markov],
            "random_walk": float(self.random_walk),
            "flicker": float(self.flicker),
            "quantization": float(self.quantization),
            "ramp": float(self.ramp),
            "dt": None if self.dt is None else float(self.dt),
        }

    @classmethod
    def from_dict(cls, d: dict) -> "NoiseModel":
        """Build from :meth:`to_dict` output; unknown keys are an error naming the key."""
        unknown = set(d) - {"white", "gauss_markov", "random_walk", "flicker", "quantization", "ramp", "dt"}
        if unknown:
            raise ValueError(f"unknown NoiseModel key(s): {sorted(unknown)}")
        kw = dict(d)
        kw["gauss_markov"] = tuple(
            (g["sigma"], g["T"]) if isinstance(g, dict) else tuple(g) for g in kw.get("gauss_markov") or ()
        )
        return cls(**kw)

    def __repr__(self) -> str:
        parts = [f"white={self.white:.6g}"] if self.white else []
        if self.gauss_markov:
            parts.append("gauss_markov=(" + ", ".join(f"({s:.6g}, {T:.6g})" for s, T in self.gauss_markov) + ")")
        for name in ("random_walk", "flicker", "quantization", "ramp"):
            if getattr(self, name):
                parts.append(f"{name}={getattr(self, name):.6g}")
        if self.dt is not None:
            parts.append(f"dt={self.dt:.6g}")
        return "NoiseModel(" + ", ".join(parts) + ")"
