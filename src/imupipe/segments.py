r"""Segments of a record cut at its events (config ``events.policy: split``), analysed as records.

A record with events (bursts, steps: :mod:`imupipe.events`) is cut at each event into event-free segments; every
per-axis modelling stage treats the segments of one dataset and axis as records of that dataset and axis, and
nothing straddles a cut.

Cuts and segments (:func:`split_at_events`)
-------------------------------------------
Event e spans samples :math:`[i_e, j_e]` (a step: :math:`i_e = j_e`, its time; a burst or a transient: its first
and last samples). Widened by the guard g (samples, one burst window: the span a block scan can misplace an event
by), it removes :math:`[i_e - g, j_e + g)` from the record. The segments are the maximal runs of samples that no
widened event touches, each :math:`[a_k, b_k)` of :math:`n_k = b_k - a_k` samples. A segment shorter than the
minimum :math:`n_{min}` (the workflow: one PSD window, ``psd.window_s`` at the full rate, the shortest record the
PSD stage accepts) is dropped and reported; when no segment is left the split is an error naming the series.

Estimators pooled over segments
-------------------------------
Every estimator below is the record's own one with its sums restricted to terms inside one segment; the sums
and the counts add over segments.

- **Decimation** (:func:`decimate_segments`): block averages of M samples within each segment
  (:func:`imupipe.spectra.decimate`, the incomplete last block of each segment dropped); the decimated
  segments are stored one after the other with their bounds (:data:`BOUNDS_ATTR`).
- **Welch PSD** (:func:`pooled_psd`): the windows of each segment (never across a cut); with :math:`K_k`
  windows and the segment's Welch PSD :math:`\hat S_k` (u^2/Hz, two-sided) of edf :math:`\nu_k`,

  .. math:: \hat S = \frac{\sum_k K_k \hat S_k}{\sum_k K_k},

  the average over all windows of all segments.
- **Allan variance** (:func:`pooled_allan`): with :math:`\theta` the integral of segment k alone and
  :math:`c_k(m) = n_k - 2m + 1` second differences at :math:`\tau = m\tau_0`,

  .. math::

      \hat\sigma^2(m\tau_0) = \frac{\sum_k \sum_{i=0}^{c_k - 1}(\theta_{k,i+2m} - 2\theta_{k,i+m} + \theta_{k,i})^2}
                                   {2 (m\tau_0)^2 \sum_k c_k(m)}
                            = \frac{\sum_k c_k \hat\sigma^2_k}{\sum_k c_k}

  (NIST SP 1065 eq. 11 on each segment; segment k contributes where :math:`m \le n_k/4`, the record's own
  rule for the named grids, or :math:`m \le n_k/2` for explicit times).

Degrees of freedom (:func:`pooled_edf`). Both pooled estimates are :math:`\hat v = \sum_k w_k \hat v_k` with
weights :math:`w_k = c_k / \sum c_k` and segment estimates that are independent (disjoint data; for noise whose
correlation time is short against the guard, exactly so for white noise). With
:math:`\mathrm{Var}\,\hat v_k = 2 v^2/\nu_k` (the definition of the edf :math:`\nu_k`),

.. math::

    \mathrm{Var}\,\hat v = \sum_k w_k^2 \frac{2 v^2}{\nu_k}
    \quad\Rightarrow\quad
    \nu = \frac{2 v^2}{\mathrm{Var}\,\hat v} = \frac{\left(\sum_k c_k\right)^2}{\sum_k c_k^2/\nu_k} .

Equal segments of edf :math:`\nu_1` give :math:`\nu = K\nu_1`; non-overlapping Welch windows
(:math:`\nu_k = 2K_k`) give :math:`\nu = 2\sum_k K_k`, the record's own rule. The chi-squared limits follow from
:math:`\nu` (:func:`imupipe.allan.chi2_limits`).

References
----------
.. [1] W. J. Riley, "Handbook of Frequency Stability Analysis", NIST SP 1065, 2008, eq. (11), section 5.3.
.. [2] P. D. Welch, IEEE Trans. Audio Electroacoust. 15(2), 70-73, 1967.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["BOUNDS_ATTR", "CURVE_ATTRS", "START_ATTR", "Segments", "decimate_segments", "pooled_allan", "pooled_edf",
           "pooled_psd", "read_segments", "segment_lines", "segment_records", "split_at_events"]

#: netCDF attribute of a series: its segments' [start, stop) sample indices, flattened (start0, stop0, start1, ...)
BOUNDS_ATTR = "record_segment_bounds"
#: netCDF attribute of a series: each segment's start, s from the record's start
START_ATTR = "record_segment_start_s"
#: global attributes of a PSD or Allan file analysed over segments (one curve's, not a stack's)
CURVE_ATTRS = ("n_samples_analysed", "n_record_segments", "record_segments", "segments_method",
               "segments_without_window")


@dataclass(frozen=True)
class Segments:
    """The segments of one series that the analysis uses.

    Attributes
    ----------
    bounds : tuple of (int, int)
        [start, stop) sample indices of each segment in the series they refer to, increasing, disjoint.
    n_samples : int
        Samples of that series.
    rate_hz : float
        Its sampling rate, Hz.
    start_s : tuple of float
        Each segment's start, s from the record's start (the series may be a concatenation of segments).
    dropped : tuple of (float, float)
        Event-free stretches left out as shorter than the minimum, (start, stop) s from the record's start.
    cuts : tuple of (float, float)
        The widened events cut out, (start, stop) s from the record's start.
    """

    bounds: tuple
    n_samples: int
    rate_hz: float
    start_s: tuple
    dropped: tuple = ()
    cuts: tuple = ()

    @classmethod
    def whole(cls, n: int, rate_hz: float) -> Segments:
        """One segment: the whole series of `n` samples at `rate_hz` Hz."""
        return cls(((0, int(n)),), int(n), float(rate_hz), (0.0,))

    @property
    def is_whole(self) -> bool:
        """True when the one segment is the whole series (the analysis is the record's own)."""
        return len(self.bounds) == 1 and self.bounds[0] == (0, self.n_samples)

    @property
    def lengths(self) -> np.ndarray:
        """Samples of each segment (int64)."""
        return np.array([b - a for a, b in self.bounds], dtype=np.int64)

    def views(self, x) -> list:
        """The segments of `x` (views, no copy); `x` must have :attr:`n_samples` samples."""
        if len(x) != self.n_samples:
            raise ValueError(f"the series has {len(x)} samples, its segments refer to {self.n_samples}")
        return [x[a:b] for a, b in self.bounds]

    def describe(self) -> str:
        """Short text: the segments in s from the record's start."""
        return ", ".join(f"{s:.1f}-{s + n / self.rate_hz:.1f} s" for s, n in zip(self.start_s, self.lengths))

    def to_attrs(self) -> dict:
        """The netCDF attributes of a series stored as its segments (:data:`BOUNDS_ATTR`, :data:`START_ATTR`)."""
        return {BOUNDS_ATTR: np.asarray(self.bounds, dtype=np.int64).ravel(),
                START_ATTR: np.asarray(self.start_s, dtype=np.float64)}

    @classmethod
    def from_attrs(cls, attrs: dict, n: int, rate_hz: float, where: str = "series") -> Segments:
        """The segments of a series of `n` samples at `rate_hz` Hz from its netCDF attributes (pops them);
        the whole series when it has none. A ValueError names `where` when they do not fit the series."""
        b = attrs.pop(BOUNDS_ATTR, None)
        s = attrs.pop(START_ATTR, None)
        if b is None:
            return cls.whole(n, rate_hz)
        b = np.atleast_1d(np.asarray(b, dtype=np.int64)).reshape(-1, 2)
        s = np.atleast_1d(np.asarray(s, dtype=np.float64))
        seg = cls(tuple((int(a), int(c)) for a, c in b), int(n), float(rate_hz), tuple(float(v) for v in s))
        seg.check(where)
        return seg

    def check(self, where: str = "series") -> None:
        """ValueError naming `where` unless the bounds are increasing, disjoint, non-empty and inside the series."""
        prev = 0
        for a, b in self.bounds:
            if not (prev <= a < b <= self.n_samples):
                raise ValueError(f"{where}: segment bounds {list(self.bounds)} do not fit a series of "
                                 f"{self.n_samples} samples (expected increasing, disjoint, non-empty [start, stop))")
            prev = b
        if len(self.start_s) != len(self.bounds):
            raise ValueError(f"{where}: {len(self.start_s)} segment start times for {len(self.bounds)} segments")

    def to_dict(self) -> dict:
        """Plain dict for YAML (samples and s from the record's start), with its units."""
        return {"n_samples": self.n_samples, "rate_hz": self.rate_hz, "n_segments": len(self.bounds),
                "segments": [{"start": a, "stop": b, "start_s": s, "stop_s": s + (b - a) / self.rate_hz}
                             for (a, b), s in zip(self.bounds, self.start_s)],
                "dropped": [{"start_s": a, "stop_s": b} for a, b in self.dropped],
                "cuts": [{"start_s": a, "stop_s": b} for a, b in self.cuts],
                "units": {"start": "sample index of the series", "stop": "sample index (exclusive)",
                          "start_s": "s from the record's start", "stop_s": "s from the record's start",
                          "rate_hz": "Hz"}}

    @classmethod
    def from_dict(cls, d: dict, where: str = "segments") -> Segments:
        """The inverse of :meth:`to_dict`; a ValueError names `where` when a key is missing."""
        try:
            seg = cls(tuple((int(s["start"]), int(s["stop"])) for s in d["segments"]), int(d["n_samples"]),
                      float(d["rate_hz"]), tuple(float(s["start_s"]) for s in d["segments"]),
                      tuple((float(s["start_s"]), float(s["stop_s"])) for s in d.get("dropped") or ()),
                      tuple((float(s["start_s"]), float(s["stop_s"])) for s in d.get("cuts") or ()))
        except (KeyError, TypeError) as exc:
            raise ValueError(f"{where}: expected keys n_samples, rate_hz and segments (start, stop, start_s); "
                             f"missing {exc}") from None
        seg.check(where)
        return seg

    def for_series(self, n: int, where: str = "series") -> Segments:
        """Self after checking that it refers to a series of `n` samples (ValueError naming `where`)."""
        if n != self.n_samples:
            raise ValueError(f"{where}: {n} samples, its segments file refers to {self.n_samples}")
        return self


def read_segments(path, n: int, rate_hz: float, where: str = "series") -> Segments:
    """The segments of the series `where` (`n` samples at `rate_hz` Hz) from the segments file `path` (YAML of
    :meth:`Segments.to_dict`), the whole series when `path` is None; a ValueError names both when they disagree."""
    if not path:
        return Segments.whole(n, rate_hz)
    from imupipe.io import read_yaml

    return Segments.from_dict(read_yaml(path), str(path)).for_series(int(n), f"{where} (segments {path})")


def split_at_events(n: int, rate_hz: float, events, *, guard: int, min_samples: int,
                    where: str = "series") -> Segments:
    """The event-free segments of an `n`-sample record at `rate_hz` Hz (module docstring, "Cuts and segments").

    `events` are :func:`imupipe.events.detect_events` events (``index``, optional ``stop_index``: samples), each
    widened by `guard` samples on both sides; segments shorter than `min_samples` are dropped (and reported in
    ``dropped``). ValueError naming `where` when every segment is shorter than `min_samples`."""
    n, rate = int(n), float(rate_hz)
    cuts = sorted((max(0, int(e["index"]) - guard), min(n, int(e.get("stop_index", e["index"])) + guard))
                  for e in events)
    free, pos = [], 0
    for a, b in cuts:
        if a > pos:
            free.append((pos, a))
        pos = max(pos, b)
    if n > pos:
        free.append((pos, n))
    keep = tuple((a, b) for a, b in free if b - a >= min_samples)
    dropped = tuple((a / rate, b / rate) for a, b in free if b - a < min_samples)
    merged = []
    for a, b in cuts:  # the widened events as stretches of time (overlapping ones merged)
        if merged and a <= merged[-1][1]:
            merged[-1] = (merged[-1][0], max(merged[-1][1], b))
        else:
            merged.append((a, b))
    if not keep:
        longest = max((b - a for a, b in free), default=0)
        raise ValueError(
            f"{where}: events.policy = 'split' leaves no segment of at least {min_samples} samples "
            f"({min_samples / rate:g} s, one psd.window_s) between {len(cuts)} event(s) widened by {guard} samples; "
            f"the longest event-free stretch has {longest} samples ({longest / rate:.1f} s); use events.policy = "
            "'warn' or a shorter psd.window_s")
    return Segments(keep, n, rate, tuple(a / rate for a, _ in keep), dropped,
                    tuple((a / rate, b / rate) for a, b in merged))


def pooled_edf(counts, edfs) -> np.ndarray:
    r"""Equivalent degrees of freedom of :math:`\sum_k c_k \hat v_k / \sum_k c_k` for independent estimates
    :math:`\hat v_k` of one variance with edf :math:`\nu_k` (module docstring):
    :math:`\nu = (\sum_k c_k)^2 / \sum_k (c_k^2/\nu_k)` (dimensionless). `counts` and `edfs` have the
    segments along axis 0; a zero count leaves its segment out."""
    c = np.asarray(counts, dtype=np.float64)
    nu = np.asarray(edfs, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        terms = np.where(c > 0, c**2 / nu, 0.0)
    return c.sum(axis=0) ** 2 / terms.sum(axis=0)


def decimate_segments(x, rate: float, target_rate: float, seg: Segments):
    """Block averages of each segment of `x` (u, at `rate` Hz) to `target_rate` Hz
    (:func:`imupipe.spectra.decimate` per segment, each segment's incomplete last block dropped), stored one after
    the other: (y, new_rate Hz, the segments of y). The whole record: exactly ``decimate(x, rate, target_rate)``.
    A segment shorter than one block is left out (listed in ``dropped``)."""
    from imupipe.spectra import decimate

    if seg.is_whole:
        y, new_rate = decimate(x, rate, target_rate)
        return y, new_rate, Segments.whole(y.size, new_rate)
    m = int(round(rate / target_rate))
    parts, bounds, starts, dropped, pos = [], [], [], list(seg.dropped), 0
    new_rate = None
    for (a, b), s in zip(seg.bounds, seg.start_s):
        if b - a < m:
            dropped.append((s, s + (b - a) / rate))
            continue
        y, new_rate = decimate(x[a:b], rate, target_rate)
        parts.append(y)
        bounds.append((pos, pos + y.size))
        starts.append(s)
        pos += y.size
    if not parts:
        raise ValueError(f"every segment ({seg.describe()}) is shorter than one decimation block of {m} samples")
    out = Segments(tuple(bounds), pos, float(new_rate), tuple(starts), tuple(dropped), seg.cuts)
    return np.concatenate(parts), new_rate, out


def segment_records(x, seg: Segments, label: str) -> dict:
    """{record label: samples} of the segments of `x`: `label` itself for the whole record, else
    ``dataset#k/axis`` (k = 1, 2, ...) for `label` = ``dataset/axis``, so that the axis stays the label's last
    part. Views, no copy."""
    if seg.is_whole:
        return {label: x}
    head, _, axis = label.rpartition("/")
    return {f"{head}#{k}/{axis}" if head else f"{label}#{k}": v for k, v in enumerate(seg.views(x), start=1)}


def pooled_psd(y, rate: float, seg: Segments, *, window_s: float, step_s: float, taper="hann", detrend="constant",
               confidence: float = 0.95, units=None):
    """Two-sided Welch PSD (u^2/Hz on Hz) over the windows of all segments of `y` (at `rate` Hz), as
    :class:`imupipe.labelled.Labelled` (module docstring: the average over all windows, its edf
    :func:`pooled_edf`, chi-squared limits). The whole record: exactly :func:`imupipe.spectra.psd_labelled`.
    Segments shorter than one window are left out and named in the attrs; a ValueError when none holds one."""
    from imupipe.allan import chi2_limits
    from imupipe.spectra import psd_labelled

    kw = dict(window_s=window_s, step_s=step_s, taper=taper, detrend=detrend, confidence=confidence, units=units)
    if seg.is_whole:
        return psd_labelled(y, rate, **kw)
    nperseg = int(round(window_s * rate))
    parts, short = [], []
    for (a, b), s in zip(seg.bounds, seg.start_s):
        if b - a >= nperseg:
            parts.append(psd_labelled(y[a:b], rate, **kw))
        else:
            short.append(f"{s:.1f}-{s + (b - a) / rate:.1f} s")
    if not parts:
        raise ValueError(f"no segment ({seg.describe()}) holds one PSD window of {window_s:g} s ({nperseg} samples "
                         f"at {rate:g} Hz); use a shorter psd.window_s")
    k = np.array([p.attrs["n_segments"] for p in parts], dtype=np.float64)
    nu_k = np.array([p.attrs["edf"] for p in parts])
    s2 = sum(kk * p.data_vars["psd"][0] for kk, p in zip(k, parts)) / k.sum()
    nu = float(pooled_edf(k, nu_k))
    edf = np.full(s2.size, nu)
    edf[0] = nu / 2.0
    if nperseg % 2 == 0:
        edf[-1] = nu / 2.0
    lower, upper = chi2_limits(s2, edf, confidence)
    base = parts[0]
    dv = dict(base.data_vars)
    for name, val in (("psd", s2), ("psd_lower", lower), ("psd_upper", upper), ("edf", edf)):
        dv[name] = (val, dv[name][1])
    attrs = dict(base.attrs)
    attrs.update({
        "n_segments": int(k.sum()), "edf": nu, "n_samples": int(seg.lengths.sum()),
        "n_samples_used": int(sum(p.attrs["n_samples_used"] for p in parts)),
        "n_record_segments": len(parts), "record_segments": seg.describe(),
        "segments_method": "the windows of every segment (none across a cut), averaged; edf (sum K)^2 / "
                           "sum(K^2 / edf_k), K_k windows of segment k (imupipe.segments)",
    })
    if short:
        attrs["segments_without_window"] = ", ".join(short)
    return base._replace(data_vars=dv, attrs=attrs)


def pooled_allan(x, rate: float, seg: Segments, *, taus="octave", confidence: float = 0.683, units=None,
                 method: str = "auto", backend: str = "auto"):
    """Overlapping Allan variance (u^2 on tau in s) pooled over the segments of `x` (at `rate` Hz), as
    :class:`imupipe.labelled.Labelled` with the variables of :func:`imupipe.allan.allan_variance_labelled`
    (module docstring: only differences within a segment; sums and counts add; edf :func:`pooled_edf`).

    The grid is the longest segment's (`taus` as there); ``n_terms`` is the pooled count; ``alpha`` (noise type)
    that of the segment with the most terms. Attrs: ``n_samples`` the longest segment's samples (the record
    length an identification may assume for the estimates' covariance: the pooled estimate varies no more than
    that segment's alone), ``n_samples_analysed`` all segments' samples. The whole record: exactly
    ``allan_variance_labelled(x, rate, ...)``."""
    from imupipe.allan import allan_variance_labelled, chi2_limits, tau_grid

    kw = dict(confidence=confidence, units=units, method=method, backend=backend)
    if seg.is_whole:
        return allan_variance_labelled(x, rate, taus=taus, **kw)
    lengths = seg.lengths
    grid = tau_grid(int(lengths.max()), rate, taus)
    explicit = not isinstance(taus, (str, int, np.integer))
    counts, avars, edfs, alphas, used = [], [], [], [], []
    base = None
    for (a, b) in seg.bounds:
        n_k = b - a
        m_k = grid.m[grid.m <= (n_k // 2 if explicit else n_k // 4)]
        c = np.zeros(grid.m.size)
        av, nu, al = np.zeros(grid.m.size), np.ones(grid.m.size), np.zeros(grid.m.size, dtype=np.int64)
        if m_k.size:
            res = allan_variance_labelled(x[a:b], rate, taus=m_k / float(rate), **kw)
            sel = np.searchsorted(grid.m, res.coords["m"][0])
            c[sel] = res.coords["n_terms"][0]
            av[sel] = res.data_vars["avar"][0]
            nu[sel] = res.data_vars["edf"][0]
            al[sel] = res.data_vars["alpha"][0]
            used.append(n_k)
            if base is None or n_k == lengths.max():
                base = res
        counts.append(c), avars.append(av), edfs.append(nu), alphas.append(al)
    c, av, nu, al = np.array(counts), np.array(avars), np.array(edfs), np.array(alphas)
    total = c.sum(axis=0)
    avar = (c * av).sum(axis=0) / total
    edf = pooled_edf(c, nu)
    alpha = al[np.argmax(c, axis=0), np.arange(grid.m.size)]
    lower, upper = chi2_limits(avar, edf, confidence)
    dv = dict(base.data_vars)
    for name, val in (("avar", avar), ("avar_lower", lower), ("avar_upper", upper), ("edf", edf),
                      ("alpha", alpha)):
        dv[name] = (val, dv[name][1])
    co = dict(base.coords)
    co["tau"] = (grid.tau, co["tau"][1])
    co["m"] = (grid.m, co["m"][1])
    co["n_terms"] = (total.astype(np.int64), co["n_terms"][1])
    attrs = dict(base.attrs)
    attrs.update({
        "n_samples": int(lengths.max()), "n_samples_analysed": int(sum(used)), "n_record_segments": len(used),
        "record_segments": seg.describe(),
        "segments_method": "pooled over segments: second differences within a segment only, sums and counts add; "
                           "edf (sum c)^2 / sum(c^2 / edf_k), c_k terms of segment k; n_samples: the longest "
                           "segment's (imupipe.segments)",
    })
    return base._replace(data_vars=dv, coords=co, attrs=attrs)


def segment_lines(x, rate: float, seg: Segments, *, resolution_hz: float, alpha: float, floor_window_bins: int,
                  units: str = "u", label: str | None = None, scales=(1,), low_band_resolution_hz=None):
    """Spectral lines of the segments of `x` (u at `rate` Hz): :func:`imupipe.lines.find_lines` on each segment
    that holds one detection segment (1/`resolution_hz` s) at level alpha/K (Bonferroni over the K searched
    segments, so the family-wise level stays `alpha`), the lines merged (:func:`imupipe.lines.merge_lines`: a
    line found on any segment is kept, with the largest power). Returns the
    :class:`imupipe.lines.LineSearch` of the longest searched segment with the merged lines and the level
    `alpha`; the whole record: exactly ``find_lines(x, rate, ...)``. `scales`, `low_band_resolution_hz`: the
    resolutions searched (:func:`imupipe.lines.find_lines`)."""
    from dataclasses import replace

    from imupipe.lines import find_lines, merge_lines

    kw = dict(resolution_hz=resolution_hz, floor_window_bins=floor_window_bins, units=units, label=label,
              scales=tuple(scales), low_band_resolution_hz=low_band_resolution_hz)
    if seg.is_whole:
        return find_lines(x, rate, alpha=alpha, **kw)
    need = int(round(rate / float(resolution_hz)))
    views = [v for v in seg.views(x) if v.size >= need]
    if not views:
        raise ValueError(f"no segment ({seg.describe()}) is as long as 1/resolution_hz = {1 / resolution_hz:g} s")
    searches = [find_lines(v, rate, alpha=alpha / len(views), **kw) for v in views]
    longest = searches[int(np.argmax([v.size for v in views]))]
    lines = merge_lines([ln for s in searches for ln in s.lines])
    return replace(longest, lines=tuple(lines), alpha=float(alpha))
