r"""The noisiest stretch of a record: how far the PSD of its worst part stands above the whole record's.

A bound over a record's average PSD covers a filter that meets the record's average noise. Where the noise level
changes along the record (white noise 2.5x over its last third: an average PSD 2.75x the quiet level, the noisy
stretch's 6.25x), a filter running through the noisy stretch under-states its error there (MSE/P 1.5 under a bound
of the average). The bound of a record that fails the stationarity test, or whose level changes by this module's
stretch test, therefore also covers its noisiest stretch (docs/method.md, "Stationarity"): its PSD raised, band by
band, by the gain this module measures.

Scan (:func:`stretch_levels`). The decimated record of n samples at rate :math:`f_s` is cut into stretches of
:math:`L = \lfloor n / S \rfloor` samples, one every L/2 samples (a change that lasts 1.5 L fills one stretch
whatever its phase), at each scale S of :data:`SCALES` (8, 4 and 2 stretches per record: the longer stretches
resolve lower frequencies, where a slow GM's level shows; each scale's bands are the scan's). Each stretch's PSD is
the Welch average of its Hann windows of :math:`w = \lfloor L / W \rfloor` samples (:data:`WINDOWS_PER_STRETCH` =
W) at 50 % overlap, mean removed; the whole record's is the average of every such window. Over log bands of the window's bins (5 per decade, merged from the
lowest until each holds at least :data:`MIN_EDF` degrees of freedom per stretch) the band means give

.. math::

    r_b = \max_s \frac{\bar P_{s,b}}{\bar P_{b}},

the gain of band b and the stretch s that sets it. Degrees of freedom of a band: counted as :math:`M n_b` for M
windows of a stretch and :math:`n_b` bins (half the nominal :math:`2 M n_b`, a lower figure for Hann's correlated
neighbours and overlapping windows). For a stationary record :math:`r_b` exceeds 1 by chance only: the largest of
about 2S - 1 band means, each with relative sd about :math:`\sqrt{2/\nu}` (about 0.14 at :math:`\nu` = 100, so a
chance gain near 1.3 in the lowest band, less above); the bound applies gains only to records that fail the
stationarity test beyond chance or whose stretch test (:func:`stretch_test`) rejects a stationary record
(:func:`imupipe.stages.stationarity.summary_stage`).

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

__all__ = ["MIN_EDF", "SCREEN", "STRETCHES_PER_RECORD", "WINDOWS_PER_STRETCH", "StretchLevels", "stretch_levels",
           "stretch_test"]

#: Stretch length: the record's length over this (s = n / this / rate), the scan's shortest scale.
STRETCHES_PER_RECORD = 8

#: The scan's scales: stretches of the record's length over each (a longer stretch resolves lower frequencies: a
#: change of a slow GM's level).
SCALES = (STRETCHES_PER_RECORD, 4, 2)

#: Welch window of a stretch: the stretch's length over this.
WINDOWS_PER_STRETCH = 8

#: Least degrees of freedom of a band of one stretch (module docstring).
MIN_EDF = 100.0

#: Log bands per decade before merging.
BANDS_PER_DECADE = 5

#: Fewest samples of a Welch window: a shorter record gives no scan.
MIN_WINDOW_SAMPLES = 16

#: The stretch test's screen: a statistic below this is not simulated (:func:`stretch_test`).
SCREEN = 3.0

#: The stretch test's simulated records: at most this many, in batches of :data:`SIM_BATCH`, stopping once
#: :data:`SIM_STOP` of them reach the record's statistic (Besag and Clifford's sequential p-value).
SIM_MAX = 999
SIM_BATCH = 100
SIM_STOP = 10


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
    statistic: float = 0.0
    band_stretch_s: tuple = ()  # each band's stretch length, s (empty: every band's is stretch_s)

    def gain(self, frequency) -> np.ndarray:
        r""":math:`g(f)` on `frequency` (Hz), module docstring: :math:`\max(1, \max_b g_b(f))` with
        :math:`g_b = r_b` from the band's lowest bin :math:`f_b` to the next band's (the top band's to every higher
        f) and :math:`r_b^{1 + \log_{10}(f / f_b)}` over the decade below :math:`f_b`."""
        f = np.asarray(frequency, dtype=np.float64)
        g = np.ones_like(f)
        lo = np.asarray(self.f_lo_hz, dtype=np.float64)
        scale = np.asarray(self.band_stretch_s or (self.stretch_s,) * lo.size, dtype=np.float64)
        tops = np.array([min([b for b, s in zip(lo, scale) if s == s_a and b > a] or [np.inf])
                         for a, s_a in zip(lo, scale)])  # the next band's lowest bin of the same scan
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
                "edf_min": float(self.edf_min), "max_gain": self.max_gain, "statistic": float(self.statistic),
                "bands": [{"f_lo_hz": float(a), "f_hi_hz": float(b), "ratio": float(r), "start_s": float(s),
                           "stretch_s": float(L)}
                          for a, b, r, s, L in zip(self.f_lo_hz, self.f_hi_hz, self.ratio, self.start_s,
                                                   self.band_stretch_s or (self.stretch_s,) * len(self.ratio))],
                "units": "Hz, s; ratio: the stretch's band PSD over the whole record's"}

    @classmethod
    def from_dict(cls, d: dict) -> "StretchLevels":
        bands = d.get("bands") or []
        return cls(f_lo_hz=tuple(float(b["f_lo_hz"]) for b in bands),
                   f_hi_hz=tuple(float(b["f_hi_hz"]) for b in bands),
                   ratio=tuple(float(b["ratio"]) for b in bands), start_s=tuple(float(b["start_s"]) for b in bands),
                   stretch_s=float(d["stretch_s"]), n_stretches=int(d["n_stretches"]), edf_min=float(d["edf_min"]),
                   statistic=float(d.get("statistic", 0.0)),
                   band_stretch_s=tuple(float(b.get("stretch_s", d["stretch_s"])) for b in bands))


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


def _scan(parts: list, rate: float, per_record: int):
    """One scale of the scan (:func:`stretch_levels`): stretches of the record's length over `per_record`. Returns
    (f_lo Hz, f_hi Hz, ratio, start s, edf per band, stretch s, stretches) or None."""
    n = sum(p.size for p in parts)
    L = n // per_record
    w = L // WINDOWS_PER_STRETCH
    if w < MIN_WINDOW_SAMPLES:
        return None
    hop = w // 2
    per_stretch = (L - w) // hop + 1  # windows inside one stretch
    bands = _bands(w // 2, per_stretch)
    if not bands:
        return None
    stretch_hop = L // 2
    record_sum, n_windows, best, where, offset = 0.0, 0, None, None, 0.0
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
    f_bin = np.arange(1, w // 2 + 1) * rate / w
    return (np.array([f_bin[lo] for lo, _ in bands]), np.array([f_bin[hi - 1] for _, hi in bands]),
            best / (record_sum / n_windows), where, per_stretch * np.array([hi - lo for lo, hi in bands], float),
            L / rate, int(sum(max(0, (p.size - L) // stretch_hop + 1) for p in parts)))


def stretch_levels(x, rate: float, views=None) -> StretchLevels | None:
    """The noisiest-stretch scan (module docstring) of the decimated record `x` (u) at `rate` (Hz), or of its
    segments `views` (arrays: the record cut at events; stretches and windows lie inside one segment, the stretch
    length is that of the whole record), at each scale of :data:`SCALES` (the shortest first): every scale's bands.
    None when the record is too short for the shortest scale (a window of fewer than :data:`MIN_WINDOW_SAMPLES`
    samples, or too few bins for one band)."""
    parts = [np.asarray(v, dtype=np.float64) for v in (views if views is not None else [x])]
    scans = [_scan(parts, rate, k) for k in SCALES]
    if scans[0] is None:
        return None
    scans = [sc for sc in scans if sc is not None]
    f_lo, f_hi, ratio, where, edf = (np.concatenate([sc[i] for sc in scans]) for i in range(5))
    return StretchLevels(f_lo_hz=tuple(map(float, f_lo)), f_hi_hz=tuple(map(float, f_hi)),
                         ratio=tuple(map(float, ratio)), start_s=tuple(map(float, where)),
                         stretch_s=float(scans[0][5]), n_stretches=scans[0][6], edf_min=float(edf.min()),
                         statistic=float(np.max(np.log(np.maximum(ratio, 1e-300)) * np.sqrt(edf / 2.0))),
                         band_stretch_s=tuple(float(sc[5]) for sc in scans for _ in sc[0]))


def _data_seed(x) -> int:
    """A seed from the record's bytes: identical records get identical null draws, whatever their axis or dataset."""
    import hashlib

    h = hashlib.blake2b(np.ascontiguousarray(x, dtype=np.float64).tobytes(), digest_size=8, person=b"stretches")
    return int.from_bytes(h.digest(), "little")


def stretch_test(x, rate: float, null_model, seed: int | None = None, levels: StretchLevels | None = None) -> dict:
    r"""Does the noise level change along the record more than a stationary record's would? A Monte Carlo test of
    the scan's statistic :math:`T = \max_b \ln(r_b) \sqrt{\nu_b / 2}` (each band's log gain over its sd for the
    counted degrees of freedom :math:`\nu_b`; :func:`stretch_levels`) on records of the same length drawn from
    `null_model` (the axis's stationary fit, :func:`imupipe.simulate.simulate` at `rate` Hz; `seed` seeds the draws,
    None: a seed from the record's bytes).

    The Levene and KS statistics of the stationarity test read the decimated samples' spread and distribution; where
    a slow GM dominates that spread, a white-noise level change moves them little (an outside evaluation: white noise
    3x over 8 % of an accelerometer record, p 0.11 to 0.66, while the scan's gains were 3.5 to 4.1). This test reads
    the band levels.

    A statistic below :data:`SCREEN` is not simulated (p-value None): for a stationary record the statistic is the
    largest of about 15 stretches' band estimates, each about N(0, 1/2) with the counted degrees of freedom (half the
    nominal); its 95th and 99th percentiles were 2.8-3.1 and 3.2-3.3 on 2 h records of white, white + GM + random
    walk and GM-dominated noise (300 each), so about five in a hundred stationary records are simulated (their test is
    then at its exact level: 7 of 400 stationary records rejected at 0.0167, each tested on its own true model).
    Otherwise up to :data:`SIM_MAX` records, stopping at :data:`SIM_STOP` exceedances; p = (1 + exceedances) / (1 +
    records drawn). `levels`: the record's scan when already made. Returns the statistic, the p-value, the records
    drawn and what was done. A whole record only (the stationarity stage does not run it on a record cut into
    segments)."""
    from imupipe.simulate import simulate

    obs = levels if levels is not None else stretch_levels(x, rate)
    if obs is None:
        return {"statistic": None, "p_value": None, "n_sim": 0, "note": "record too short for the scan"}
    out = {"statistic": float(obs.statistic), "screen": SCREEN, "p_value": None, "n_sim": 0}
    if obs.statistic < SCREEN:
        out["note"] = f"statistic below the screen {SCREEN:g}: not simulated"
        return out
    rng, n = np.random.default_rng(_data_seed(x) if seed is None else seed), int(np.asarray(x).size)
    drawn = hits = 0
    while drawn < SIM_MAX and hits < SIM_STOP:
        batch = min(SIM_BATCH, SIM_MAX - drawn)
        for y in np.atleast_2d(simulate(null_model, n, rate, rng, n_records=batch)):
            sim = stretch_levels(y, rate)
            hits += int(sim is not None and sim.statistic >= obs.statistic)
        drawn += batch
    out.update(p_value=(1 + hits) / (1 + drawn), n_sim=drawn,
               note=f"Monte Carlo on the stationary null: {hits} of {drawn} records reached the statistic")
    return out
