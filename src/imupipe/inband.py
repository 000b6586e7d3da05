r"""Effective in-band inflation of a whole noise model against a spec sheet's model.

A table of parameter ratios (bound N / spec N, bound K / spec K, ...) does not say what a model does in the band an
application uses: a Gauss-Markov term whose corner :math:`1/(2\pi T)` lies above the band adds a flat PSD
:math:`2\sigma^2 T` there and acts as white noise, one whose corner lies below the band falls as :math:`f^{-2}` there
and acts as a random walk (a constant over the horizon). This module gives the ratio of the whole model's PSD to the
spec sheet's over the application band, in amplitude,

.. math:: r(f) = \sqrt{S_{model}(f) / S_{spec}(f)}, \qquad f \in [f_{lo}, f_{hi}] = [1/\text{horizon}, f_s/2],

with :math:`f_s` the reference filter's rate, and the same ratio against the spec sheet's white noise alone,
:math:`r_N(f) = \sqrt{S_{model}(f)} / N_{spec}`. Both PSDs are imupipe's two-sided PSDs (docs/method.md, "Conventions:
the PSD"), **as sampled**: :meth:`imupipe.models.NoiseModel.psd_sampled` at :math:`dt = 1/f_s` (block means sampled
every dt), as the bound compares a model with the data; for :math:`f \ll f_s/2` it equals the continuous PSD. The
spec's white noise sampled is exactly :math:`N^2`. The ratios are dimensionless (the units of the two PSDs, u^2/Hz
with u = rad/s or m/s^2, cancel).

The median is taken over a log-uniform frequency grid (``per_decade`` points a decade, both ends of the band
included): the median over log-frequency. The maximum is over the same grid with the model's and the spec's corner
frequencies added, and is reported with its frequency.

Each component of the model is labelled with what it acts as in the band (:func:`acts_as`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from imupipe.models import NoiseModel

__all__ = ["acts_as", "application_band", "band_grid", "corner_frequencies", "inband_inflation", "inband_line"]

#: Grid density of the median and maximum, points per decade (log-uniform).
PER_DECADE = 200


def application_band(horizon_s: float, filter_rate_hz: float) -> tuple[float, float]:
    """The application band [1/horizon_s, filter_rate_hz/2], Hz: the slowest frequency an outage of horizon_s s
    sees, and the reference filter's Nyquist frequency.

    Raises
    ------
    ValueError
        When the band is empty (horizon shorter than two filter samples) or an argument is not positive.
    """
    h, r = float(horizon_s), float(filter_rate_hz)
    if not (h > 0 and r > 0 and math.isfinite(h) and math.isfinite(r)):
        raise ValueError(f"application band: horizon_s = {horizon_s!r} s and filter_rate_hz = {filter_rate_hz!r} Hz "
                         "must be positive numbers")
    lo, hi = 1.0 / h, 0.5 * r
    if not lo < hi:
        raise ValueError(f"application band: 1/horizon_s = {lo:g} Hz is not below filter_rate_hz/2 = {hi:g} Hz")
    return lo, hi


def corner_frequencies(model: NoiseModel) -> list[float]:
    r"""The model's corner frequencies, Hz: :math:`1/(2\pi T)` of each GM term, f0 of each line, where the
    random walk meets the white noise, :math:`K/(2\pi N)` (where both are present), and just below the Nyquist
    frequency :math:`1/(2\,dt)` of a quantization term, where its band-limited PSD is largest and then drops to 0."""
    out = [1.0 / (2.0 * math.pi * T) for s, T in model.gauss_markov if s > 0]
    if model.quantization > 0 and model.dt:
        out.append(0.5 / model.dt * (1.0 - 1e-9))
    out += [f0 for s, f0, _ in model.narrowband if s > 0]
    if model.white > 0 and model.random_walk > 0:
        out.append(model.random_walk / (2.0 * math.pi * model.white))
    if model.white > 0 and model.flicker > 0:  # B^2/(2 pi f) = N^2
        out.append(model.flicker**2 / (2.0 * math.pi * model.white**2))
    return out


def band_grid(band_hz, per_decade: int = PER_DECADE, extra=()) -> np.ndarray:
    """Log-uniform grid over [lo, hi] Hz with both ends, ``per_decade`` points a decade at least, plus the
    frequencies of `extra` that fall inside the band; sorted, unique."""
    lo, hi = float(band_hz[0]), float(band_hz[1])
    n = max(2, int(math.ceil(per_decade * math.log10(hi / lo))) + 1)
    f = np.geomspace(lo, hi, n)
    add = [x for x in extra if lo < x < hi]
    return np.unique(np.concatenate([f, np.asarray(add, dtype=np.float64)]))


def acts_as(model: NoiseModel, band_hz) -> list[dict]:
    r"""Each non-zero component of `model` with what it acts as over the band [lo, hi] Hz.

    - white noise, random walk, flicker, quantization: themselves;
    - a GM of corner :math:`f_c = 1/(2\pi T)`: ``white noise`` when :math:`f_c > hi` (PSD flat,
      :math:`2\sigma^2 T`, within a factor :math:`1 + (hi/f_c)^2` over the band), ``random walk`` (a constant over
      the horizon) when :math:`f_c < lo` (PSD :math:`\approx 2\sigma^2/(T (2\pi f)^2)`, a random walk of
      :math:`K = \sigma\sqrt{2/T}`), else ``Gauss-Markov`` (its corner in band);
    - a line of f0: ``white noise`` when f0 > hi (flat below its resonance), ``f^-4 (line below the band)`` when
      f0 < lo, else ``line`` (in band).

    Returns
    -------
    list of dict
        ``component``, its parameters (SI), ``corner_hz`` (None where it has none) and ``acts_as``.
    """
    lo, hi = float(band_hz[0]), float(band_hz[1])
    out = []
    if model.white > 0:
        out.append({"component": "white", "N": float(model.white), "corner_hz": None, "acts_as": "white noise"})
    for s, T in model.gauss_markov:
        if s <= 0:
            continue
        fc = 1.0 / (2.0 * math.pi * T)
        what = "white noise" if fc > hi else "random walk" if fc < lo else "Gauss-Markov"
        entry = {"component": "gauss_markov", "sigma": float(s), "T": float(T), "corner_hz": fc, "acts_as": what}
        if what == "white noise":
            entry["as_N"] = math.sqrt(2.0 * s * s * T)  # u/sqrt(Hz): its flat in-band level
        elif what == "random walk":
            entry["as_K"] = s * math.sqrt(2.0 / T)  # u/sqrt(s): its f^-2 asymptote
        out.append(entry)
    if model.random_walk > 0:
        out.append({"component": "random_walk", "K": float(model.random_walk), "corner_hz": None,
                    "acts_as": "random walk"})
    if model.flicker > 0:
        out.append({"component": "flicker", "B": float(model.flicker), "corner_hz": None, "acts_as": "flicker"})
    if model.quantization > 0:
        out.append({"component": "quantization", "Q": float(model.quantization), "corner_hz": None,
                    "acts_as": "quantization"})
    for s, f0, z in model.narrowband:
        if s <= 0:
            continue
        what = "white noise" if f0 > hi else "f^-4 (line below the band)" if f0 < lo else "line"
        out.append({"component": "narrowband", "sigma": float(s), "f0_hz": float(f0), "zeta": float(z),
                    "corner_hz": float(f0), "acts_as": what})
    return out


def _stats(r: np.ndarray, f: np.ndarray, median_mask: np.ndarray) -> dict:
    i = int(np.argmax(r))
    return {"median": float(np.median(r[median_mask])), "max": float(r[i]), "max_frequency_hz": float(f[i]),
            "min": float(np.min(r))}


def inband_inflation(model: NoiseModel | Mapping, spec: NoiseModel | Mapping, band_hz, *,
                     per_decade: int = PER_DECADE) -> dict:
    r"""Effective in-band inflation of `model` against `spec` over `band_hz` (module docstring).

    Parameters
    ----------
    model, spec : NoiseModel or its to_dict()
        SI (u = rad/s or m/s^2). The ramp has no PSD and is left out of both.
    band_hz : (float, float)
        [lo, hi] Hz, hi the Nyquist frequency of the sampling the comparison uses (:func:`application_band`).
    per_decade : int, optional
        Log-uniform grid density (default :data:`PER_DECADE`).

    Returns
    -------
    dict
        ``band_hz``; ``psd`` (the convention: two-sided, sampled at dt = 1/(2 hi) s); ``vs_spec_psd``:
        median, max, max_frequency_hz, min of :math:`\sqrt{S_{model}/S_{spec}}`; ``vs_spec_white``: the same of
        :math:`\sqrt{S_{model}}/N_{spec}` (None when the spec has no white noise); ``components``: :func:`acts_as`;
        ``units``: "ratio of amplitudes (sqrt of a PSD ratio), dimensionless; frequencies Hz".

    Raises
    ------
    ValueError
        When the spec's PSD is not positive somewhere in the band (no ratio to give).
    """
    m = model if isinstance(model, NoiseModel) else NoiseModel.from_dict(dict(model))
    s = spec if isinstance(spec, NoiseModel) else NoiseModel.from_dict(dict(spec))
    lo, hi = float(band_hz[0]), float(band_hz[1])
    if not 0 < lo < hi:
        raise ValueError(f"band_hz = {band_hz!r}: expected 0 < lo < hi (Hz)")
    dt = 0.5 / hi
    f_med = band_grid((lo, hi), per_decade)
    f = band_grid((lo, hi), per_decade, extra=corner_frequencies(m) + corner_frequencies(s))
    on_grid = np.isin(f, f_med)
    sm = np.asarray(m.psd_sampled(f, dt), dtype=np.float64)
    ss = np.asarray(s.psd_sampled(f, dt), dtype=np.float64)
    if not np.all(ss > 0):
        raise ValueError("in-band inflation: the spec sheet's PSD is zero somewhere in the band; no ratio")
    out = {"band_hz": [lo, hi],
           "psd": f"two-sided, as sampled (block means every dt = {dt:.6g} s, the reference filter's interval; "
                  "NoiseModel.psd_sampled), as the bound compares",
           "grid": f"log-uniform, {per_decade} points a decade (median over it), plus the corner frequencies (max)",
           "units": "ratio of amplitudes (sqrt of a PSD ratio), dimensionless; frequencies Hz",
           "vs_spec_psd": _stats(np.sqrt(sm / ss), f, on_grid),
           "vs_spec_white": _stats(np.sqrt(sm) / s.white, f, on_grid) if s.white > 0 else None,
           "components": acts_as(m, (lo, hi))}
    return out


def inband_line(inf: Mapping | None) -> str | None:
    """One summary line of an :func:`inband_inflation` result: "in-band: median Xx, max Yx at f Hz the spec's PSD;
    Zx the spec's white noise", then each component that acts as another."""
    if not inf:
        return None
    p, w = inf.get("vs_spec_psd") or {}, inf.get("vs_spec_white")
    lo, hi = inf.get("band_hz") or (float("nan"), float("nan"))
    text = (f"in-band ({lo:.3g} to {hi:.3g} Hz): median {p.get('median', float('nan')):.3g}x, max "
            f"{p.get('max', float('nan')):.3g}x at {p.get('max_frequency_hz', float('nan')):.3g} Hz the spec's PSD")
    if w:
        text += (f"; {w['median']:.3g}x the spec's white noise (median; max {w['max']:.3g}x at "
                 f"{w['max_frequency_hz']:.3g} Hz)")
    moved = [c for c in inf.get("components") or () if c.get("component") == "gauss_markov"
             and c.get("acts_as") != "Gauss-Markov"
             or c.get("component") == "narrowband" and c.get("acts_as") != "line"]
    for c in moved:
        what = f"GM of T {c['T']:.3g} s" if c["component"] == "gauss_markov" else f"line of f0 {c['f0_hz']:.3g} Hz"
        text += f"; {what} (corner {c['corner_hz']:.3g} Hz) acts as {c['acts_as']}"
    return text
