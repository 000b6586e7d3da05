r"""The noisiest stretch of a record: how far the PSD of its worst part stands above the whole record's.

A bound over a record's average PSD covers a filter that meets the record's average noise. Where the noise level
changes along the record (white noise 2.5x over its last third: an average PSD 2.75x the quiet level, the noisy
stretch's 6.25x), a filter running through the noisy stretch under-states its error there (MSE/P 1.5 under a bound
of the average). The bound of a record that fails the stationarity test therefore also covers its noisiest stretch
(docs/method.md, "Stationarity"): its PSD raised, band by band, by the gain this module measures.

Scan (:func:`stretch_levels`). The decimated record of n samples at rate :math:`f_s` is cut into stretches of
:math:`L = \lfloor n / S \rfloor` samples (:data:`STRETCHES_PER_RECORD` = S), one every L/2 samples (a change that
lasts 1.5 L fills one stretch whatever its phase). Each stretch's PSD is the Welch average of its Hann windows of
:math:`w = \lfloor L / W \rfloor` samples (:data:`WINDOWS_PER_STRETCH` = W) at 50 % overlap, mean removed; the whole
record's is the average of every such window. Over log bands of the window's bins (5 per decade, merged from the
lowest until each holds at least :data:`MIN_EDF` degrees of freedom per stretch) the band means give

.. math::

    r_b = \max_s \frac{\bar P_{s,b}}{\bar P_{b}},

the gain of band b and the stretch s that sets it. Degrees of freedom of a band: counted as :math:`M n_b` for M
windows of a stretch and :math:`n_b` bins (half the nominal :math:`2 M n_b`, a lower figure for Hann's correlated
neighbours and overlapping windows). For a stationary record :math:`r_b` exceeds 1 by chance only: the largest of
about 2S - 1 band means, each with relative sd about :math:`\sqrt{2/\nu}` (about 0.14 at :math:`\nu` = 100, so a
chance gain near 1.3 in the lowest band, less above); the bound applies gains only to records that fail the
stationarity test beyond chance (:func:`imupipe.stages.stationarity.summary_stage`).

The gain on a PSD grid (:meth:`StretchLevels.gain`): at least :math:`\max(1, r_b)` over band b (from its lowest
bin to the next band's; the top band's to every higher f), and below each band a log-linear ramp over one decade,
:math:`r_b^{1 + \log_{10}(f/f_b)}` for :math:`f_b/10 \le f < f_b` (:math:`f_b` the band's lowest bin); the largest
of these, and 1 where none reaches. The gain only falls abruptly as f rises, never rises: a bound built from band
means (the ``smoothed``, ``confidence`` and ``pooled`` modes) of a target that stepped up inside one of its bands
lay under the target's upper bins (an outside-case record: the data check failed three of four candidates at the
step from 2.68 to 3.12). Below the scan's lowest band the ramp raises the decade a stretch does not resolve
partly; lower, the variation at longer times is what the whole record's spectrum already holds.

Units: frequencies Hz, durations s, gains dimensionless (ratios of PSDs in the record's u^2/Hz).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["MIN_EDF", "STRETCHES_PER_RECORD", "WINDOWS_PER_STRETCH", "StretchLevels", "stretch_levels"]

#: Stretch length: the record's length over this (s = n / this / rate).
STRETCHES_PER_RECORD = 8

#: Welch window of a stretch: the stretch's length over this.
WINDOWS_PER_STRETCH = 8

#: Least degrees of freedom of a band of one stretch (module docstring).
MIN_EDF = 100.0

#: Log bands per decade before merging.
BANDS_PER_DECADE = 5

#: Fewest samples of a Welch window: a shorter record gives no scan.
MIN_WINDOW_SAMPLES = 16


@dataclass(frozen=True)
class StretchLevels:
    """The scan's result (module docstring): per band its edges ``f_lo_hz``, ``f_hi_hz`` (Hz, the band's lowest
    and highest bin), the gain ``ratio`` (dimensionless, not floored) and ``start_s`` (s from the record's start) of
    the stretch that sets it; ``stretch_s`` (s), ``n_stretches`` and ``edf_min`` (the least band's degrees of
    freedom of one stretch)."""

    f_lo_hz: tuple
    f_hi_hz: tuple
    ratio: tuple
    start_s: tuple
    stretch_s: float
    n_stretches: int
    edf_min: float

    def gain(self, frequency) -> np.ndarray:
        r""":math:`g(f)` on `frequency` (Hz), module docstring: :math:`\max(1, \max_b g_b(f))` with
        :math:`g_b = r_b` from the band's lowest bin :math:`f_b` to the next band's (the top band's to every higher
        f) and :math:`r_b^{1 + \log_{10}(f / f_b)}` over the decade below :math:`f_b`."""
        f = np.asarray(frequency, dtype=np.float64)
        g = np.ones_like(f)
        lo = np.asarray(self.f_lo_hz, dtype=np.float64)
        tops = np.append(lo[1:], np.inf)
        with np.errstate(divide="ignore", invalid="ignore"):
            for f_b, top, r in zip(lo, tops, self.ratio):
                if r <= 1.0:
                    continue
                x = np.log10(np.where(f > 0, f, np.nan) / f_b)
                g_b = np.where((x >= 0) & (f < top), r, np.where((x < 0) & (x >= -1), r ** (1.0 + x), 1.0))
                g = np.maximum(g, np.nan_to_num(g_b, nan=1.0))
        return g

    @property
    def max_gain(self) -> float:
        """The largest gain over the bands (at least 1)."""
        return float(max([1.0, *self.ratio]))

    def to_dict(self) -> dict:
        return {"stretch_s": float(self.stretch_s), "n_stretches": int(self.n_stretches),
                "edf_min": float(self.edf_min), "max_gain": self.max_gain,
                "bands": [{"f_lo_hz": float(a), "f_hi_hz": float(b), "ratio": float(r), "start_s": float(s)}
                          for a, b, r, s in zip(self.f_lo_hz, self.f_hi_hz, self.ratio, self.start_s)],
                "units": "Hz, s; ratio: the stretch's band PSD over the whole record's"}

    @classmethod
    def from_dict(cls, d: dict) -> "StretchLevels":
        bands = d.get("bands") or []
        return cls(f_lo_hz=tuple(float(b["f_lo_hz"]) for b in bands), f_hi_hz=tuple(float(b["f_hi_hz"]) for b in bands),
                   ratio=tuple(float(b["ratio"]) for b in bands), start_s=tuple(float(b["start_s"]) for b in bands),
                   stretch_s=float(d["stretch_s"]), n_stretches=int(d["n_stretches"]), edf_min=float(d["edf_min"]))


def _periodograms(v: np.ndarray, w: int, hop: int) -> np.ndarray:
    """Hann periodograms (unnormalised: only ratios are used) of the windows of `v` at `hop`, mean removed:
    (n_windows, w // 2) over bins 1 .. w // 2."""
    n_win = (v.size - w) // hop + 1
    idx = np.arange(w)[None, :] + hop * np.arange(n_win)[:, None]
    seg = v[idx]
    seg = seg - seg.mean(axis=1, keepdims=True)
    taper = np.hanning(w + 2)[1:-1]
    return np.abs(np.fft.rfft(seg * taper, axis=1)[:, 1:w // 2 + 1]) ** 2


def _bands(n_bins: int, windows: int) -> list[tuple[int, int]]:
    """Log bands of bins 1 .. n_bins (index 0 .. n_bins - 1), merged from the lowest until each has
    :data:`MIN_EDF` degrees of freedom (`windows` x bins); the top band absorbs a short remainder."""
    k = np.arange(1, n_bins + 1)
    edges = np.unique(np.floor(BANDS_PER_DECADE * np.log10(k)).astype(int), return_index=True)[1]
    edges = list(edges) + [n_bins]
    need = int(math.ceil(MIN_EDF / windows))
    out, lo = [], 0
    for hi in edges[1:]:
        if hi - lo >= need:
            out.append((lo, hi))
            lo = hi
    if lo < n_bins:
        if out:
            out[-1] = (out[-1][0], n_bins)
        elif n_bins >= need:
            out.append((0, n_bins))
    return out


def stretch_levels(x, rate: float, views=None) -> StretchLevels | None:
    """The noisiest-stretch scan (module docstring) of the decimated record `x` (u) at `rate` (Hz), or of its
    segments `views` (arrays: the record cut at events; stretches and windows lie inside one segment, the stretch
    length is that of the whole record). None when the record is too short for the scan (a window of fewer than
    :data:`MIN_WINDOW_SAMPLES` samples, or too few bins for one band)."""
    parts = [np.asarray(v, dtype=np.float64) for v in (views if views is not None else [x])]
    n = sum(p.size for p in parts)
    L = n // STRETCHES_PER_RECORD
    w = L // WINDOWS_PER_STRETCH
    if w < MIN_WINDOW_SAMPLES:
        return None
    hop = w // 2
    per_stretch = (L - w) // hop + 1  # windows inside one stretch
    bands = _bands(w // 2, per_stretch)
    if not bands:
        return None
    stretch_hop = L // 2
    record_sum, n_windows, best, where = 0.0, 0, None, None
    offset = 0.0
    for p in parts:
        if p.size < w:
            offset += p.size / rate
            continue
        P = _periodograms(p, w, hop)
        B = np.stack([P[:, lo:hi].mean(axis=1) for lo, hi in bands], axis=1)  # (windows, bands)
        record_sum = record_sum + B.sum(axis=0)
        n_windows += B.shape[0]
        for s0 in range(0, p.size - L + 1, stretch_hop):
            first = -(-s0 // hop)
            level = B[first:first + per_stretch].mean(axis=0)
            if best is None:
                best, where = level.copy(), np.full(level.size, offset + s0 / rate)
            else:
                up = level > best
                best[up], where[up] = level[up], offset + s0 / rate
        offset += p.size / rate
    if best is None:
        return None
    ratio = best / (record_sum / n_windows)
    f_bin = np.arange(1, w // 2 + 1) * rate / w
    return StretchLevels(f_lo_hz=tuple(float(f_bin[lo]) for lo, _ in bands),
                         f_hi_hz=tuple(float(f_bin[hi - 1]) for _, hi in bands),
                         ratio=tuple(float(r) for r in ratio), start_s=tuple(float(s) for s in where),
                         stretch_s=L / rate, n_stretches=int(sum(max(0, (p.size - L) // stretch_hop + 1)
                                                                 for p in parts)),
                         edf_min=float(per_stretch * min(hi - lo for lo, hi in bands)))
