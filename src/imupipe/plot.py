r"""Figures of the PSD-overbounding method (Gallon, Joerger, Pervan, ION GNSS+ 2021, Figures 5-8).

Every function returns a :class:`matplotlib.figure.Figure` built directly (no pyplot state, no GUI
backend) that labels itself: title naming the sensor (and the bound's mode where known), axis labels
with units, a legend, log-log axes. Write it with :func:`save_figure` (atomic).

=====================================  ==============================================================
function                               what it shows
=====================================  ==============================================================
:func:`plot_psd_bound`                 Figure 5: sample PSDs, spec PSD, bound PSD and its components
:func:`plot_allan_components`          Figure 6: sample ADEVs, identified and bound components
:func:`plot_inflation_effect`          Figure 7: PSD change when one parameter is inflated (Table 3)
:func:`plot_inflation_steps`           Figure 8: the hand inflation, model after each phase
:func:`plot_plan_check`                `imupipe plan`: predicted half-widths of N, B, K against record length
=====================================  ==============================================================

Conventions (docs/architecture.md): data and models are SI (gyro rad/s, accel m/s^2); every PSD is
**two-sided** :math:`S_2` (u^2/Hz, listed for f >= 0; DC is not drawn). Model PSDs are
``model.psd_sampled(f, dt)`` (block-averaged, aliased) when the sample interval `dt` of the averaged
data is given, else the continuous ``model.psd(f)``. Allan deviations are
:math:`\sqrt{\mathrm{AVAR}}` in the rate unit.

matplotlib is imported inside the functions: ``import imupipe.plot`` costs nothing.

References
----------
.. [1] E. Gallon, M. Joerger, B. Pervan, "Development of Stochastic IMU Error Models for INS/GNSS
       Integration", ION GNSS+ 2021, Figures 5-8, Tables 2-3, Appendix A.
"""

from __future__ import annotations

import functools
import math
import os
import sys
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from imupipe.units import SI_UNITS, STANDARD_GRAVITY

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from imupipe.models import NoiseModel

__all__ = [
    "PSD_UNITS",
    "READOFF_UNITS",
    "allan_readoffs",
    "plot_allan_deviation",
    "RATE_UNITS",
    "plot_allan_components",
    "plot_inflation_effect",
    "plot_inflation_steps",
    "plot_plan_check",
    "plot_psd_bound",
    "save_figure",
    "table3_model",
]

#: SI rate unit of each sensor.
RATE_UNITS = SI_UNITS
#: SI two-sided PSD unit of each sensor.
PSD_UNITS = {sensor: f"({unit})^2/Hz" for sensor, unit in SI_UNITS.items()}
#: Spec-sheet rate units used by ``display_unit="spec"``.
SPEC_RATE_UNITS = {"gyro": "deg/h", "accel": "mg"}

#: Display name and colour of each model component (one colour per component in every figure).
_COMPONENT_STYLE = {
    "white": ("white noise", "C0"),
    "gauss_markov": ("Gauss-Markov", "C1"),
    "random_walk": ("random walk", "C2"),
    "flicker": ("flicker", "C3"),
    "quantization": ("quantization", "C4"),
    "ramp": ("ramp", "C5"),
}
_EXTRA_GM_COLOURS = ("C1", "C6", "C8", "C9", "C7")
_SAMPLE_COLOUR = "0.6"
_SPEC_COLOUR = "tab:red"
_BOUND_COLOUR = "tab:green"

# ---------------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------------
#: Fixed margins per (grid, figure size), in figure fractions: room for the suptitle, small axes titles,
#: log-axis tick labels such as 10⁻¹⁴ and axis labels. Fixed rather than constrained layout: constrained
#: layout measures every tick label's extent at each save (two layout passes; half the time of the 2 x 2
#: figure, a quarter of a single-axes one). Other grids and sizes use constrained layout.
_FIXED_MARGINS = {
    ((1, 1), (7.5, 5.0)): dict(left=0.095, right=0.98, bottom=0.1, top=0.885),
    ((2, 2), (11.0, 8.0)): dict(left=0.07, right=0.985, bottom=0.065, top=0.89, wspace=0.2, hspace=0.3),
}


def _new_figure(nrows=1, ncols=1, figsize=(7.5, 5.0)):
    """A pyplot-free Figure and an (nrows, ncols) grid of axes: fixed margins for the grids and sizes of
    :data:`_FIXED_MARGINS`, constrained layout otherwise."""
    from matplotlib.figure import Figure

    margins = _FIXED_MARGINS.get(((nrows, ncols), tuple(float(v) for v in figsize)))
    if margins is not None:
        fig = Figure(figsize=figsize)
        fig.subplots_adjust(**margins)
    else:
        fig = Figure(figsize=figsize, layout="constrained")
    axes = fig.subplots(nrows, ncols, squeeze=False)
    return fig, axes


_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


@functools.cache
def _unicode_log_formatter_class():
    """LogFormatterSciNotation with plain Unicode labels: 10⁻³ and, where matplotlib labels minor ticks
    (an axis spanning less than about a decade), 2×10⁻³.

    matplotlib decides which ticks carry a label (the parent class, so the choice is the same); only the
    text differs: its mathtext labels are parsed by a typesetting engine, ~10 ms per distinct label in
    every fresh process, a fifth of a figure job. Built once, on first use (matplotlib imported lazily).
    """
    from matplotlib.ticker import LogFormatterSciNotation

    class UnicodeLogFormatter(LogFormatterSciNotation):
        def __call__(self, x, pos=None):
            if not super().__call__(x, pos) or not (x > 0 and math.isfinite(x)):
                return ""
            e = math.floor(math.log10(x) + 1e-9)
            c = x / 10.0**e
            power = "10" + str(e).translate(_SUPERSCRIPT)
            return power if abs(c - 1.0) < 1e-6 else f"{c:.2g}×{power}"

    return UnicodeLogFormatter


def _check_sensor(sensor):
    if sensor not in RATE_UNITS:
        raise ValueError(f"sensor must be one of {sorted(RATE_UNITS)}, got {sensor!r}")
    return sensor


def _as_curves(curves, n, dim):
    """(C, n) float64 array and per-curve labels from an array or an xarray.DataArray.

    A DataArray must have the dimension `dim` (``frequency`` or ``tau``); all its other dimensions
    (e.g. ``dataset``, ``axis``) are stacked into curves, labelled ``dataset=..., axis=...``.
    """
    if curves is None:
        return None, []
    if hasattr(curves, "dims") and hasattr(curves, "stack"):  # xarray.DataArray
        from imupipe.labelled import stack_curves

        if dim not in curves.dims:
            raise ValueError(f"an xarray argument needs a {dim!r} dimension, got dims {curves.dims}")
        arr, labels = stack_curves(curves, dim)
    else:
        arr = np.asarray(curves, dtype=np.float64)
        if arr.ndim == 1:
            arr = arr[None, :]
        labels = [f"curve {i}" for i in range(arr.shape[0])] if arr.ndim == 2 else []
    if arr.ndim != 2 or arr.shape[1] != n:
        raise ValueError(f"curves must have shape (n_curves, {n}) on the {dim} grid, got {arr.shape}")
    return arr, labels


def _grid(x, curves, dim):
    """The 1-D grid `x`, or the `dim` coordinate of an xarray `curves` when `x` is None."""
    if x is None:
        if hasattr(curves, "coords") and dim in getattr(curves, "coords", {}):
            x = curves.coords[dim].values
        else:
            raise ValueError(f"{dim} is required (or pass an xarray DataArray with a {dim!r} coordinate)")
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 1:
        raise ValueError(f"{dim} must be one-dimensional, got shape {x.shape}")
    return x


def _positive_frequency_curves(frequency, curves):
    """Frequency grid (Hz) and PSD curves (C, F) without the DC bin (a PSD plot is log-log), and the
    curve labels of :func:`_as_curves`."""
    f_all = _grid(frequency, curves, "frequency")
    arr, labels = _as_curves(curves, f_all.size, "frequency")
    keep = f_all > 0
    return f_all[keep], arr[:, keep], labels


def _unwrap_bound(bound_model):
    """(NoiseModel, mode or None) from a NoiseModel or a :class:`imupipe.bound.BoundResult`."""
    if bound_model is not None and hasattr(bound_model, "model") and hasattr(bound_model, "mode"):
        return bound_model.model, bound_model.mode
    return bound_model, None


def _model_psd(model, f, dt):
    """Two-sided model PSD on f (Hz, > 0), u^2/Hz: sampled if dt is given, else continuous."""
    if dt is not None:
        return np.asarray(model.psd_sampled(f, dt), dtype=np.float64)
    return np.asarray(model.psd(f), dtype=np.float64)


def _psd_scale(display_unit, sensor):
    """(factor from SI PSD to the display PSD, PSD unit string)."""
    if display_unit is None or display_unit in ("SI", "si"):
        return 1.0, PSD_UNITS[sensor]
    from imupipe.units import from_si

    rate = SPEC_RATE_UNITS[sensor] if display_unit == "spec" else str(display_unit)
    c = float(from_si(1.0, rate, "rate", sensor, key="display_unit"))
    return c * c, f"({rate})^2/Hz"


def _component_style(name):
    """(display name, colour) of a component key from ``NoiseModel.components()``."""
    if name.startswith("gauss_markov_"):
        i = int(name.rsplit("_", 1)[1])
        return f"Gauss-Markov {i + 1}", _EXTRA_GM_COLOURS[i % len(_EXTRA_GM_COLOURS)]
    return _COMPONENT_STYLE.get(name, (name, "k"))


#: Log-x columns of the min/max envelope of long sample curves when the axes' width is not known (about one
#: per pixel of the 7.5 in axes at 150 dpi, whose data area is ~990 pixels wide).
_ENVELOPE_BINS = 1024
#: Resolution of :func:`save_figure`, dots per inch.
_DPI = 150


def _pixel_columns(ax) -> int:
    """Pixel columns of the axes' data area at :data:`_DPI` (its position as laid out so far: a constrained
    layout only shrinks it, so the count is never too small), at least 64."""
    width_in = ax.get_position().width * ax.get_figure().get_figwidth()
    return max(64, math.ceil(width_in * _DPI))


def _envelope(x, y, n_bins=_ENVELOPE_BINS):
    """Indices of the points that draw like the whole curve on a log-x axis (min/max decimation).

    x > 0 sorted ascending. The x range is cut into `n_bins` equal log-width columns; each column keeps
    its first, last, lowest and highest point, in order. Columns narrower than a pixel drawn with
    these 4 points look exactly like the full polyline; sparse columns (low frequencies) keep every
    point. Curves of up to 4 `n_bins` points are returned whole.
    """
    n = x.size
    if n <= 4 * n_bins:
        return np.arange(n)
    lx = np.log(x)
    col = np.minimum(((lx - lx[0]) / (lx[-1] - lx[0]) * n_bins).astype(np.int64), n_bins - 1)
    starts = np.flatnonzero(np.r_[True, col[1:] != col[:-1]])
    ends = np.r_[starts[1:], n] - 1
    seg = np.repeat(np.arange(starts.size), ends - starts + 1)  # column number of each point, 0..
    finite = np.isfinite(y)
    low = np.where(finite, y, np.inf)
    high = np.where(finite, y, -np.inf)

    def where_extreme(v, reduce, first):
        # index of the first (or last) point of each column equal to the column's extreme
        idx = np.flatnonzero(v == reduce.reduceat(v, starts)[seg])
        s = seg[idx]
        pick = np.r_[True, s[1:] != s[:-1]] if first else np.r_[s[1:] != s[:-1], True]
        return idx[pick]

    lowest, highest = where_extreme(low, np.minimum, True), where_extreme(high, np.maximum, False)
    return np.unique(np.concatenate([starts, ends, lowest, highest]))


def _draw_samples(ax, x, arr, labels, what, lw=0.6):
    """Sample curves: grey with one legend entry, or coloured and labelled one by one.

    Long curves on a log-x axis are drawn through their min/max envelope (:func:`_envelope`): the same
    picture, a fraction of the drawing time.
    """
    if arr is None:
        return
    x = np.asarray(x)
    if labels is None:
        plural = "" if arr.shape[0] == 1 else "s"
        labels_iter = [f"sample {what} ({arr.shape[0]} curve{plural})"] + ["_nolegend_"] * (arr.shape[0] - 1)
        style = {"color": _SAMPLE_COLOUR, "alpha": 0.7}
    else:
        if len(labels) != arr.shape[0]:
            raise ValueError(f"{len(labels)} labels for {arr.shape[0]} curves")
        labels_iter = [str(lab) for lab in labels]
        style = {"alpha": 0.8}
    columns = _pixel_columns(ax)  # one envelope column per pixel: a 2x2 panel needs half of a full figure's
    for i, (y, lab) in enumerate(zip(arr, labels_iter)):
        y = np.asarray(y)
        keep = _envelope(x, y, columns) if x.size > 1 and np.all(x > 0) else np.arange(x.size)
        ax.plot(x[keep], y[keep], lw=lw, zorder=1, gid=f"sample:{i}", label=lab, **style)


#: Log-frequency bins per decade of the sample envelope and smoothed median (:func:`_draw_envelope`).
_ENVELOPE_BINS_PER_DECADE = 40


def _log_bins(x, per_decade):
    """(start index of each bin, counts) of sorted x > 0 cut into bins of 1/per_decade decade."""
    b = np.floor(np.log10(x) * per_decade).astype(np.int64)
    starts = np.flatnonzero(np.r_[True, b[1:] != b[:-1]])
    return starts, np.diff(np.r_[starts, x.size])


def _draw_envelope(ax, x, arr, what, per_decade=_ENVELOPE_BINS_PER_DECADE):
    """Shaded min-max band over the curves and their median, both per log-x bin (two legend entries).

    In each bin of 1/per_decade decade: the band spans the lowest and the highest value of any curve (the
    extremes the bound must lie above are all inside the band), the line is the mean over the bin of the
    per-frequency median over curves (a smoothed "typical" curve). Bins holding one point keep it as is.
    Returns (x_bin, low, high, median).
    """
    x = np.asarray(x, dtype=np.float64)
    a = np.asarray(arr, dtype=np.float64)
    with np.errstate(all="ignore"):
        lo = np.nanmin(a, axis=0)
        hi = np.nanmax(a, axis=0)
        med = np.nanmedian(a, axis=0)
    ok = np.isfinite(lo) & np.isfinite(hi) & (x > 0)
    x, lo, hi, med = x[ok], lo[ok], hi[ok], med[ok]
    starts, counts = _log_bins(x, per_decade)
    xb = np.exp(np.add.reduceat(np.log(x), starts) / counts)
    lob = np.minimum.reduceat(lo, starts)
    hib = np.maximum.reduceat(hi, starts)
    medb = np.add.reduceat(med, starts) / counts
    ax.fill_between(xb, lob, hib, color=_SAMPLE_COLOUR, alpha=0.45, lw=0, zorder=1, gid="samples:envelope",
                    label=f"sample {what}: min-max of {a.shape[0]} curves")
    ax.plot(xb, medb, color="0.25", lw=1.0, zorder=2, gid="samples:median", label=f"sample {what}: median (smoothed)")
    return xb, lob, hib, medb


def _resolve_labels(labels, auto):
    if labels is True:
        return auto
    if labels is None or labels is False:
        return None
    return [str(s) for s in labels]


def _axes_title(ax, text, **kwargs):
    """An axes title at its default place (just above the axes) given explicitly: matplotlib then skips
    its automatic placement, which measures every tick label of both axes at each save (for titles above
    axes whose tick labels are below and left, it never moves them; half of the 2 x 2 figure's time)."""
    ax.set_title(text, y=1.0, **kwargs)


def _finish_loglog(ax, xlabel, ylabel, legend_loc="best", ncol=1):
    """Log-log axes with Unicode tick labels, a grid and the legend. Minor ticks at 2 and 5 times each power
    of ten rather than at 2, 3, ..., 9: over the 5-12 decades of these figures the finer grid is clutter, and
    each tick is a matplotlib artist (a 2 x 2 figure then draws ~350 of them, ~0.15 s of a figure job).
    Where an axis spans so little that at most one tick (major or minor) falls in view, matplotlib's
    LogLocator falls back to linear ticks."""
    from matplotlib.ticker import LogLocator

    ax.set_xscale("log")
    ax.set_yscale("log")
    for axis in (ax.xaxis, ax.yaxis):
        axis.set_minor_locator(LogLocator(base=10.0, subs=(2.0, 5.0)))
        axis.set_major_formatter(_unicode_log_formatter_class()(base=10.0))
        axis.set_minor_formatter(_unicode_log_formatter_class()(base=10.0))
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(True, which="major", alpha=0.4)
    ax.grid(True, which="minor", alpha=0.15)
    ax.legend(loc=legend_loc, fontsize="small", ncol=ncol, framealpha=0.85)


def _fmt(x):
    return f"{x:.3g}"


# ---------------------------------------------------------------------------------------------
# Figure 5
# ---------------------------------------------------------------------------------------------
def plot_psd_bound(frequency, curves, spec_model, bound_model, *, sensor, dt=None, labels=None, title=None,
                   display_unit=None, samples="lines") -> "Figure":
    r"""Sample PSDs of one sensor type with the spec-sheet PSD and the bounding model (paper Figure 5).

    Parameters
    ----------
    frequency : array_like or None
        Frequency grid, Hz, shape (n_freq,). f = 0 is not drawn (a random walk is infinite there).
        None takes the ``frequency`` coordinate of an xarray `curves`.
    curves : array_like or xarray.DataArray
        Two-sided sample PSDs, u^2/Hz (SI): shape (n_curves, n_freq), or a DataArray with dims
        (dataset, axis, frequency) (any dims besides ``frequency`` are stacked into curves).
    spec_model : imupipe.models.NoiseModel or None
        Spec-sheet model, SI.
    bound_model : imupipe.models.NoiseModel or imupipe.bound.BoundResult or None
        The bound; each of its components is drawn dashed. A BoundResult also names the mode in
        the title.
    sensor : {"gyro", "accel"}
        Sensor type (unit labels).
    dt : float, optional
        Sample interval of the (block-averaged) data, s: models drawn as ``psd_sampled(f, dt)``,
        the spectrum the sample PSDs estimate; else the continuous ``psd(f)``.
    labels : sequence of str or True, optional
        One label per curve (curves then drawn in colour, one legend entry each); True uses the
        DataArray's coordinates. Default: thin grey lines with a single legend entry.
    title : str, optional
        Figure title; default names the sensor, the model PSD convention and the bound's mode.
    display_unit : None, "spec" or str, optional
        None (default): SI, y label ``two-sided PSD [(rad/s)^2/Hz]`` or ``[(m/s^2)^2/Hz]``.
        ``"spec"``: (deg/h)^2/Hz for a gyro, (mg)^2/Hz for an accelerometer. Any other string is
        taken as a rate unit (``"deg/s"``, ``"ug"``) and the PSD is shown in (unit)^2/Hz.
    samples : {"lines", "envelope"}, optional
        ``"lines"`` (default): every sample curve drawn. ``"envelope"``: the min-max envelope over the
        curves as one shaded band (gid ``samples:envelope``; per log-frequency bin of 1/40 decade the
        lowest and highest value of any curve, so no extreme is hidden) and the median over the curves,
        averaged in the same bins, as one line (gid ``samples:median``); `labels` is then ignored. Two
        legend entries whatever the number of curves.

    Returns
    -------
    matplotlib.figure.Figure
        One log-log axes. Lines carry gids ``sample:i``, ``spec``, ``bound``, ``bound:<component>``.
    """
    sensor = _check_sensor(sensor)
    f, arr, auto = _positive_frequency_curves(frequency, curves)
    scale, unit = _psd_scale(display_unit, sensor)
    bound, mode = _unwrap_bound(bound_model)

    fig, axes = _new_figure()
    ax = axes[0, 0]
    if samples == "envelope":
        _draw_envelope(ax, f, arr * scale if scale != 1.0 else arr, "PSDs")
    elif samples == "lines":
        _draw_samples(ax, f, arr * scale if scale != 1.0 else arr, _resolve_labels(labels, auto), "PSDs")
    else:
        raise ValueError(f"samples: expected 'lines' or 'envelope', got {samples!r}")

    def y(model):
        s = _model_psd(model, f, dt)
        return s * scale if scale != 1.0 else s

    if spec_model is not None:
        ax.plot(f, y(spec_model), color=_SPEC_COLOUR, lw=2.0, zorder=3, gid="spec", label="spec sheet")
    if bound is not None:
        ax.plot(f, y(bound), color=_BOUND_COLOUR, lw=2.0, zorder=4, gid="bound",
                label="bound" + (f" ({mode})" if mode else ""))
        for name, comp in bound.components().items():
            if name == "ramp":  # no PSD
                continue
            disp, colour = _component_style(name)
            ax.plot(f, y(comp), color=colour, lw=1.2, ls="--", zorder=3, gid=f"bound:{name}",
                    label=f"bound: {disp}")
    conv = f"sampled, dt = {_fmt(dt)} s" if dt is not None else "continuous"
    if title is None:
        title = f"{sensor}: sample PSDs, spec and bound" + (f" (mode {mode})" if mode else "")
    fig.suptitle(title)
    _axes_title(ax, f"two-sided PSDs; model PSDs {conv}", fontsize="small")
    _finish_loglog(ax, "frequency [Hz]", f"two-sided PSD [{unit}]", legend_loc="lower left")
    return fig


# ---------------------------------------------------------------------------------------------
# Figure 6
# ---------------------------------------------------------------------------------------------
def plot_allan_components(tau, avar, identified_model, bound_model, *, sensor, avar_lower=None, avar_upper=None,
                          labels=None, title=None, dropped=(), display_unit=None) -> "Figure":
    r"""Sample Allan deviations with the identified model's and the bound's components (paper Figure 6).

    Each component (white, Gauss-Markov, random walk, flicker, quantization, ramp) has one colour:
    the identified model's solid, the bound's dashed; the totals are black (solid / dashed). The
    paper's check is that each bound component lies above its identified counterpart (a bound GM
    standing in for flicker).

    Parameters
    ----------
    tau : array_like or None
        Averaging times, s, shape (n_tau,) (> 0). None takes the ``tau`` coordinate of an xarray `avar`.
    avar : array_like or xarray.DataArray
        Sample Allan variances, u^2 (SI): shape (n_curves, n_tau), or a DataArray with dims
        (dataset, axis, tau). Drawn as ADEV = sqrt(avar), u.
    identified_model : imupipe.models.NoiseModel or None
        Model fitted to the Allan variances (:func:`imupipe.identify.fit_allan`), SI.
    bound_model : imupipe.models.NoiseModel or imupipe.bound.BoundResult or None
        The PSD bound, SI.
    sensor : {"gyro", "accel"}
        Sensor type (unit labels: rad/s or m/s^2).
    avar_lower, avar_upper : array_like or xarray.DataArray, optional
        Confidence limits of `avar`, u^2, same shape; drawn as a shaded band.
    labels : sequence of str or True, optional
        Per-curve labels (coloured curves), True for the DataArray's coordinates; default grey.
    title : str, optional
        Figure title; default names the sensor (and the bound's mode).
    dropped : iterable of str, optional
        Components of `identified_model` that model selection left out of the error model
        (``selection.dropped`` of ``results/identify/{sensor}.yaml``): drawn dotted and thin, labelled
        "(dropped)", so that the figure does not suggest a state the filter does not carry.
    display_unit : None, "spec" or str, optional
        None (default): SI (rad/s, m/s^2). ``"spec"``: deg/h (gyro) or mg (accel). Any other string is
        taken as a rate unit (``"deg/s"``, ``"ug"``).

    Returns
    -------
    matplotlib.figure.Figure
        One log-log axes. Lines carry gids ``sample:i``, ``identified``, ``identified:<component>``,
        ``bound``, ``bound:<component>``.
    """
    sensor = _check_sensor(sensor)
    dropped = set(dropped)
    unknown = dropped - set(_COMPONENT_STYLE)
    if unknown:
        raise ValueError(f"dropped: unknown component(s) {sorted(unknown)} (known: {sorted(_COMPONENT_STYLE)})")
    tau = _grid(tau, avar, "tau")
    if np.any(tau <= 0):
        raise ValueError("tau must be > 0 s")
    arr, auto = _as_curves(avar, tau.size, "tau")
    bound, mode = _unwrap_bound(bound_model)
    scale2, psd_unit = _psd_scale(display_unit, sensor)  # (display/SI)^2 and "(unit)^2/Hz"
    unit = RATE_UNITS[sensor] if scale2 == 1.0 and display_unit in (None, "SI", "si") else psd_unit[1:-len(")^2/Hz")]
    c = math.sqrt(scale2)

    def sq(v):
        v = np.sqrt(v)
        return v * c if c != 1.0 else v

    fig, axes = _new_figure()
    ax = axes[0, 0]
    if avar_lower is not None and avar_upper is not None:
        lo, _ = _as_curves(avar_lower, tau.size, "tau")
        hi, _ = _as_curves(avar_upper, tau.size, "tau")
        if lo.shape != arr.shape or hi.shape != arr.shape:
            raise ValueError("avar_lower and avar_upper must have the shape of avar")
        for i in range(arr.shape[0]):
            ax.fill_between(tau, sq(np.clip(lo[i], 0, None)), sq(np.clip(hi[i], 0, None)),
                            color=_SAMPLE_COLOUR, alpha=0.15, lw=0, zorder=0, gid=f"band:{i}",
                            label="confidence interval" if i == 0 else "_nolegend_")
    _draw_samples(ax, tau, sq(np.clip(arr, 0, None)), _resolve_labels(labels, auto), "ADEVs", lw=0.8)

    for model, who, ls in ((identified_model, "identified", "-"), (bound, "bound", "--")):
        if model is None:
            continue
        for name, comp in model.components().items():
            disp, colour = _component_style(name)
            if who == "identified" and ("gauss_markov" if name.startswith("gauss_markov") else name) in dropped:
                ax.plot(tau, sq(comp.avar(tau)), color=colour, lw=1.0, ls=":", alpha=0.8, zorder=3,
                        gid=f"{who}:{name}", label=f"{who}: {disp} (dropped)")
                continue
            ax.plot(tau, sq(comp.avar(tau)), color=colour, lw=1.5, ls=ls, zorder=3, gid=f"{who}:{name}",
                    label=f"{who}: {disp}")
        ax.plot(tau, sq(model.avar(tau)), color="k", lw=2.0, ls=ls, zorder=4, gid=who,
                label=f"{who}: total")
    if title is None:
        title = f"{sensor}: Allan deviation, identified and bound components" + (f" (mode {mode})" if mode else "")
    fig.suptitle(title)
    _axes_title(ax, "solid: identified model; dashed: bound", fontsize="small")
    _finish_loglog(ax, "averaging time τ [s]", f"Allan deviation [{unit}]", ncol=2)
    return fig


# ---------------------------------------------------------------------------------------------
# Figure 7
# ---------------------------------------------------------------------------------------------
def table3_model(dt: float = 1.0) -> "NoiseModel":
    r"""The paper's Appendix Table 3 example accelerometer model, SI.

    sigma_bs = 1e-2 g = 9.80665e-2 m/s^2, T = 1e3 s, velocity random walk 0.1 m/s/sqrt(h)
    (N = 0.1/60 m/s^2/sqrt(Hz)), K = 1e-4 m/s^2/sqrt(s) (the unit of K the paper's values imply,
    docs/method.md, section "Slip: units of K"), sample interval `dt` (1 s in the paper).
    """
    from imupipe.models import NoiseModel

    return NoiseModel(white=0.1 / 60.0, gauss_markov=((1e-2 * STANDARD_GRAVITY, 1e3),), random_walk=1e-4, dt=dt)


def _factor_text(k):
    return f"{k:g}"


def plot_inflation_effect(base_model=None, *, duration_s: float = 36000.0, dt: float = 1.0, factors=(1, 2, 5, 10),
                          sensor: str = "accel") -> "Figure":
    r"""Effect on the model PSD of inflating one parameter at a time (paper Figure 7, Appendix A.1).

    A 2x2 grid in the paper's order: (a) white noise N, (b) random walk K, (c) Gauss-Markov sigma,
    (d) Gauss-Markov T. Each panel shows the base model's continuous two-sided PSD (red, the paper's
    equation 13) and the PSD with that one parameter multiplied by each factor; for T, also divided
    by it (dashed), since the paper deflates T. Frequencies span 1/duration_s to 1/(2 dt).

    Read as: N raises the flat high-frequency part; K the 1/f^2 low-frequency part; sigma the
    mid-band plateau (and the low end, sigma^2 T); deflating T lowers the plateau and widens the
    band it covers (the paper's text calls the right of its plots "low frequencies"; here the
    axis is frequency in Hz).

    Parameters
    ----------
    base_model : imupipe.models.NoiseModel, optional
        Model to perturb, SI. Default :func:`table3_model` (the paper's Table 3 accelerometer:
        sigma 1e-2 g, T 1e3 s, RW 0.1 m/s/sqrt(h), K 1e-4 m/s^2/sqrt(s)). With several GM terms
        the one of smallest T is perturbed.
    duration_s : float, optional
        Record length, s; the lowest frequency is 1/duration_s. Default 36000 (10 h).
    dt : float, optional
        Sample interval, s; the highest frequency is 1/(2 dt). Default 1.
    factors : sequence of float, optional
        Multipliers (> 0; 1 is the base and is drawn once). The paper's Figure 7 uses x1.5 and
        x0.5 for every parameter: ``factors=(0.5, 1.5)``. Default (1, 2, 5, 10).
    sensor : {"gyro", "accel"}, optional
        Unit labels. The default model is an accelerometer model: a gyro needs `base_model`.

    Returns
    -------
    matplotlib.figure.Figure
        Four log-log axes; the base line has gid ``base``, the others ``<param>:x<k>`` / ``T:/<k>``.
    """
    sensor = _check_sensor(sensor)
    if base_model is None:
        if sensor != "accel":
            raise ValueError("the default base model is the paper's accelerometer example (Table 3); "
                             "pass base_model for a gyro")
        base_model = table3_model(dt)
        origin = "Table 3 example"
    else:
        origin = "base model"
    if not (duration_s > 0 and dt > 0 and duration_s > 2 * dt):
        raise ValueError("need duration_s > 2 dt > 0")
    ks = sorted({float(k) for k in factors if float(k) != 1.0})
    if any(k <= 0 for k in ks):
        raise ValueError("factors must be > 0")
    if base_model.dt is None:
        base_model = replace(base_model, dt=dt)
    f = np.logspace(np.log10(1.0 / duration_s), np.log10(0.5 / dt), 400)
    gm = sorted(base_model.gauss_markov, key=lambda st: st[1])
    rest = tuple(gm[1:])

    def with_gm(sigma=None, T=None):
        s0, T0 = gm[0]
        return replace(base_model, gauss_markov=((s0 if sigma is None else sigma, T0 if T is None else T),) + rest)

    panels = [
        ("N", "(a) white noise N", base_model.white > 0, lambda k: replace(base_model, white=base_model.white * k)),
        ("K", "(b) random walk K", base_model.random_walk > 0,
         lambda k: replace(base_model, random_walk=base_model.random_walk * k)),
        ("sigma", "(c) Gauss-Markov σ", bool(gm), lambda k: with_gm(sigma=gm[0][0] * k)),
        ("T", "(d) Gauss-Markov T", bool(gm), lambda k: with_gm(T=gm[0][1] * k)),
    ]
    import matplotlib as mpl

    cmap = mpl.colormaps["viridis"]
    colours = [cmap(x) for x in np.linspace(0.15, 0.85, max(len(ks), 1))]
    fig, axes = _new_figure(2, 2, figsize=(11.0, 8.0))
    base_psd = base_model.psd(f)
    unit = PSD_UNITS[sensor]
    sym = {"N": "N", "K": "K", "sigma": "σ", "T": "T"}
    for ax, (key, name, present, make) in zip(axes.ravel(), panels):
        ax.plot(f, base_psd, color=_SPEC_COLOUR, lw=2.2, zorder=4, gid="base", label=origin)
        if present:
            for k, c in zip(ks, colours):
                ax.plot(f, make(k).psd(f), color=c, lw=1.3, zorder=3, gid=f"{key}:x{_factor_text(k)}",
                        label=f"{sym[key]} x {_factor_text(k)}")
                if key == "T":
                    ax.plot(f, make(1.0 / k).psd(f), color=c, lw=1.3, ls="--", zorder=3,
                            gid=f"T:/{_factor_text(k)}", label=f"T / {_factor_text(k)}")
        else:
            ax.text(0.5, 0.5, "component absent from the model", transform=ax.transAxes, ha="center",
                    fontsize="small")
        _axes_title(ax, name)
        _finish_loglog(ax, "frequency [Hz]", f"two-sided PSD [{unit}]", legend_loc="lower left",
                       ncol=2 if key == "T" else 1)
    p = base_model
    params = [f"N={_fmt(p.white)} {RATE_UNITS[sensor]}/sqrt(Hz)", f"K={_fmt(p.random_walk)} {RATE_UNITS[sensor]}/sqrt(s)"]
    if gm:
        params += [f"sigma={_fmt(gm[0][0])} {RATE_UNITS[sensor]}", f"T={_fmt(gm[0][1])} s"]
    fig.suptitle(f"{sensor}: effect of inflating one parameter on the model PSD ({origin}; "
                 f"{_fmt(duration_s / 3600.0)} h, dt = {_fmt(dt)} s)\n" + ", ".join(params))
    return fig


# ---------------------------------------------------------------------------------------------
# Figure 8
# ---------------------------------------------------------------------------------------------
_PHASE_NAMES = {"sigma": "sigma", "T": "T", "K": "K", "N": "N"}


def _history_rows(history):
    """History entries as (parameter, N, sigma, T, K, margin) tuples (lists, tuples or dicts)."""
    rows = []
    for h in history:
        if isinstance(h, dict):
            h = (h["parameter"], h["N"], h["sigma"], h["T"], h["K"], h.get("margin", float("nan")))
        p, N, s, T, K, m = h
        rows.append((str(p), float(N), float(s), float(T), float(K), float(m)))
    if not rows:
        raise ValueError("history is empty")
    return rows


def _phase_ends(rows):
    """Indices of the last step of each phase (a run of one parameter name), skipping the start."""
    ends = []
    for i in range(1, len(rows)):
        if i == len(rows) - 1 or rows[i + 1][0] != rows[i][0]:
            ends.append(i)
    return ends


def _spread(ends, m):
    """Indices of `m` phase ends spread evenly over the steps: the first, the last, and between."""
    ends = np.asarray(ends)
    chosen = {0, ends.size - 1}
    for t in np.linspace(ends[0], ends[-1], m)[1:-1]:
        order = np.argsort(np.abs(ends - t), kind="stable")
        chosen.add(int(next(j for j in order if int(j) not in chosen)))
    return sorted(chosen)


def plot_inflation_steps(frequency, curves, spec_model, history, *, sensor: str, dt: float | None = None,
                         title: str | None = None, max_phases: int = 6, display_unit=None) -> "Figure":
    r"""The paper's hand inflation, step by step (paper Figure 8, Appendix A.2).

    Draws the sample PSDs (grey), the spec-sheet PSD (red) and the model PSD at the end of each
    phase of :func:`imupipe.bound.paper_inflation` (a phase is a run of steps on one parameter:
    inflate sigma, deflate T, inflate K, inflate N, repeated in rounds if needed), colour-coded in
    order, legend ``after sigma``, ``after T``, ... (``(round r)`` appended to a parameter's later
    phases). The last one is the final model (thick, ``final, after <p>``). When the procedure
    alternates between parameters (its no-progress rule steps one parameter at a time) and there
    are more than `max_phases` phases, `max_phases` of them are drawn: the first, the last and
    phase ends spread evenly over the steps between.

    Parameters
    ----------
    frequency : array_like or None
        Frequency grid, Hz (f = 0 not drawn); None takes the coordinate of an xarray `curves`.
    curves : array_like or xarray.DataArray
        Two-sided sample PSDs, u^2/Hz (SI), (n_curves, n_freq) or dims (dataset, axis, frequency).
    spec_model : imupipe.models.NoiseModel
        The spec model the procedure started from (its GM terms beyond the one of smallest T are
        kept fixed, as in :func:`~imupipe.bound.paper_inflation`).
    history : sequence
        ``paper_inflation(...).details["history"]``: entries (parameter, N, sigma, T, K, margin)
        in SI (N u/sqrt(Hz), sigma u, T s, K u/sqrt(s)); the first is ``"spec"``. Dict entries with
        those keys are accepted too.
    sensor : {"gyro", "accel"}
        Sensor type (unit labels).
    dt : float, optional
        Sample interval of the averaged data, s: models drawn as ``psd_sampled(f, dt)`` (pass the
        same dt as to paper_inflation).
    title : str, optional
        Figure title; default names the sensor and the procedure.
    max_phases : int, optional
        Most phase curves drawn (>= 2), the final model included. Default 6.
    display_unit : None, "spec" or str, optional
        PSD axis unit, as in :func:`plot_psd_bound`: None or ``"SI"`` (u^2/Hz), ``"spec"`` ((deg/h)^2/Hz or
        mg^2/Hz, :data:`SPEC_RATE_UNITS`) or a rate unit string.

    Returns
    -------
    matplotlib.figure.Figure
        One log-log axes; lines with gids ``sample:i``, ``spec``, ``phase:<j>`` (j = 0, 1, ...; the
        last is the final model).
    """
    from imupipe.models import NoiseModel

    sensor = _check_sensor(sensor)
    f, arr, _ = _positive_frequency_curves(frequency, curves)
    rows = _history_rows(history)
    extra_gm = tuple(sorted(spec_model.gauss_markov, key=lambda st: st[1])[1:])

    def model_of(row):
        _, N, s, T, K, _ = row
        g = ((s, T),) + extra_gm if s > 0 else extra_gm
        return NoiseModel(white=N, gauss_markov=g, random_walk=K, dt=dt)

    scale, unit = _psd_scale(display_unit, sensor)
    fig, axes = _new_figure()
    ax = axes[0, 0]
    _draw_samples(ax, f, arr * scale, None, "PSDs")
    ax.plot(f, scale * _model_psd(spec_model, f, dt), color=_SPEC_COLOUR, lw=2.0, zorder=3, gid="spec",
            label="spec sheet")
    if int(max_phases) < 2:
        raise ValueError("max_phases must be >= 2")
    ends = _phase_ends(rows)
    labels, seen = [], {}
    for i in ends:
        p = rows[i][0]
        seen[p] = seen.get(p, 0) + 1
        labels.append(f"after {_PHASE_NAMES.get(p, p)}" + (f" (round {seen[p]})" if seen[p] > 1 else ""))
    n_phases = len(ends)
    if n_phases > int(max_phases):
        pick = _spread(ends, int(max_phases))
        ends = [ends[j] for j in pick]
        labels = [labels[j] for j in pick]
    if ends:
        labels[-1] = f"final, {labels[-1]}"
    import matplotlib as mpl

    cmap = mpl.colormaps["viridis"]
    for j, (i, label) in enumerate(zip(ends, labels)):
        last = j == len(ends) - 1
        colour = cmap(0.1 + 0.8 * j / max(len(ends) - 1, 1))
        ax.plot(f, scale * _model_psd(model_of(rows[i]), f, dt), color=colour, lw=2.4 if last else 1.4,
                zorder=4 + j, gid=f"phase:{j}", label=label)
    n_steps = len(rows) - 1
    final = rows[-1][5]
    if title is None:
        title = f"{sensor}: step-by-step spec inflation (paper procedure)"
    fig.suptitle(title)
    conv = f"sampled, dt = {_fmt(dt)} s" if dt is not None else "continuous"
    shown = "" if len(ends) == n_phases else f" ({len(ends)} shown)"
    _axes_title(ax, f"{n_steps} steps in {n_phases} phases{shown}, final margin {final:.3g}; model PSDs {conv}",
                fontsize="small")
    _finish_loglog(ax, "frequency [Hz]", f"two-sided PSD [{unit}]", legend_loc="lower left")
    return fig


# ---------------------------------------------------------------------------------------------
# Allan deviation with slope lines and read-offs
# ---------------------------------------------------------------------------------------------
#: Display units of the read-offs: (rate unit of the ADEV axis, N unit, B unit, K unit) per sensor.
READOFF_UNITS = {
    "spec": {"gyro": ("deg/h", "deg/sqrt(h)", "deg/h", "(deg/h)/sqrt(s)"),
             "accel": ("ug", "m/s/sqrt(h)", "ug", "m/s^2/sqrt(s)")},
    "SI": {"gyro": ("rad/s", "rad/s/sqrt(Hz)", "rad/s", "rad/s/sqrt(s)"),
           "accel": ("m/s^2", "m/s^2/sqrt(Hz)", "m/s^2", "m/s^2/sqrt(s)")},
}


def allan_readoffs(tau, avar) -> dict:
    r"""N, B and K read off an Allan deviation by the slope lines (IEEE Std 952 Annex C), SI.

    On the median over curves of the ADEV :math:`\sigma(\tau) = \sqrt{AVAR}` (u):
    the :math:`-1/2` line :math:`\sigma = N/\sqrt{\tau}` read at :math:`\tau = 1` s gives N (u/sqrt(Hz));
    the flat line at the minimum gives :math:`B = \min\sigma/0.664` (u, flicker constant
    :math:`\sqrt{2\ln 2/\pi}`); the :math:`+1/2` line :math:`\sigma = K\sqrt{\tau/3}` read at
    :math:`\tau = 3` s gives K (u/sqrt(s)). The lines go through the points whose local slope is closest to
    -1/2 and +1/2 (:func:`imupipe.identify.slope_line`); a value is None when no part of the curve has that
    slope (within 0.25).

    Parameters
    ----------
    tau : array_like
        Averaging times, s.
    avar : array_like
        Allan variance(s), u^2, shape (n_tau,) or (n_curves, n_tau).

    Returns
    -------
    dict
        ``white`` (N), ``flicker`` (B), ``random_walk`` (K), ``adev_min`` (u), ``tau_min`` (s), ``tau`` and
        ``adev`` (the median curve read, u), ``tau_white`` and ``tau_random_walk`` (s, where the lines are
        drawn through; None without the line), ``adev_at_1s`` and ``adev_at_3s`` (the median curve itself at the
        read-off taus, interpolated in log-log, u; None outside the curve).
    """
    from imupipe.identify import slope_line

    t = np.asarray(tau, dtype=np.float64)
    a = np.atleast_2d(np.asarray(avar, dtype=np.float64))
    with np.errstate(all="ignore"):
        adev = np.sqrt(np.nanmedian(np.clip(a, 0, None), axis=0))
    ok = np.isfinite(adev) & (adev > 0) & (t > 0)
    sl = slope_line(t[ok], adev[ok])
    return {"white": sl["white"], "flicker": sl["flicker"], "random_walk": sl["random_walk"],
            "adev_min": sl["adev_min"], "tau_min": sl["tau_min"], "tau": t[ok], "adev": adev[ok],
            "tau_white": sl["tau_white"], "tau_random_walk": sl["tau_random_walk"], "adev_at_1s": sl["adev_at_1s"],
            "adev_at_3s": sl["adev_at_3s"]}


#: A slope line's read-off that departs from the curve itself at the read-off tau by more than this (relative)
#: has the curve's value beside it in the legend: the line then is not the curve there (IEEE Std 952 reads the
#: line, a user reads the curve; 10 % is well outside the ADEV's own 1-sigma scatter at 1 s of an hour's record).
READOFF_CURVE_RTOL = 0.10


def _curve_note(line_value, curve_value, tau_s: float, unit: str, to_display) -> str:
    """" (the curve at tau = 1 s: X u)" when the line's read-off departs from the curve there, else ""."""
    if line_value is None or curve_value is None or line_value <= 0:
        return ""
    if abs(curve_value / line_value - 1.0) <= READOFF_CURVE_RTOL:
        return ""
    return f"; the curve at τ = {_fmt(tau_s)} s: {_fmt(to_display(curve_value))} {unit}"


def plot_allan_deviation(tau, avar, *, sensor: str, labels=None, display_unit: str = "spec", title: str | None = None,
                         max_labelled: int = 3) -> "Figure":
    r"""Allan deviations with the -1/2, 0 and +1/2 slope lines and the N, B, K read-offs marked.

    Read-offs (:func:`allan_readoffs`, on the median curve): N where the -1/2 line crosses
    :math:`\tau = 1` s, B at the minimum (:math:`\sigma_{min} = 0.664 B`, the 0 line), K where the +1/2 line
    crosses :math:`\tau = 3` s; each line and its marker share one legend entry giving the value in the
    display units. At most `max_labelled` curves get a legend entry of their own (more are drawn grey under
    one entry): at most 1 + 3 + `max_labelled` entries.

    Parameters
    ----------
    tau : array_like
        Averaging times, s, shape (n_tau,).
    avar : array_like
        Allan variances, u^2 (SI: rad^2/s^2 or m^2/s^4), shape (n_curves, n_tau) or (n_tau,).
    sensor : {"gyro", "accel"}
    labels : sequence of str, optional
        One per curve.
    display_unit : {"spec", "SI"}, optional
        ``"spec"`` (default): ADEV in deg/h (gyro) or ug (accel), N in deg/sqrt(h) or m/s/sqrt(h), B in
        deg/h or ug, K in (deg/h)/sqrt(s) or m/s^2/sqrt(s). ``"SI"``: rad/s or m/s^2 and SI read-offs.
    title : str, optional
    max_labelled : int, optional
        Default 3.

    Returns
    -------
    matplotlib.figure.Figure
        One log-log axes. Gids: ``sample:i``, ``slope:-1/2``, ``slope:0``, ``slope:+1/2``, ``readoff:N``
        (point (1 s, N)), ``readoff:B`` (point (tau_min, 0.664 B)), ``readoff:K`` (point (3 s, K)), all in
        the display rate unit. ``fig.readoffs`` holds the SI values and the displayed ones.
    """
    from imupipe.units import from_si

    sensor = _check_sensor(sensor)
    if display_unit not in READOFF_UNITS:
        raise ValueError(f"display_unit: expected 'spec' or 'SI', got {display_unit!r}")
    t = np.asarray(tau, dtype=np.float64)
    a = np.atleast_2d(np.asarray(avar, dtype=np.float64))
    if a.shape[-1] != t.size:
        raise ValueError(f"avar has {a.shape[-1]} taus, tau {t.size}")
    rate_u, n_u, b_u, k_u = READOFF_UNITS[display_unit][sensor]
    c = float(from_si(1.0, rate_u, "rate", sensor, key="display_unit"))  # display rate per SI rate
    ro = allan_readoffs(t, a)

    fig, axes = _new_figure()
    ax = axes[0, 0]
    adev = np.sqrt(np.clip(a, 0, None)) * c
    lab = list(labels) if labels is not None else None
    if lab is not None and len(lab) != a.shape[0]:
        raise ValueError(f"{len(lab)} labels for {a.shape[0]} curves")
    for i, y in enumerate(adev):
        if lab is not None and a.shape[0] <= max_labelled:
            ax.plot(t, y, lw=1.0, alpha=0.9, zorder=2, gid=f"sample:{i}", label=lab[i])
        else:
            ax.plot(t, y, lw=0.8, color=_SAMPLE_COLOUR, alpha=0.8, zorder=1, gid=f"sample:{i}",
                    label=f"sample ADEVs ({a.shape[0]} curves)" if i == 0 else "_nolegend_")
    tt = np.geomspace(t[np.isfinite(t) & (t > 0)].min(), t[np.isfinite(t) & (t > 0)].max(), 64)
    shown = {}
    if ro["white"] is not None:
        n_disp = float(from_si(ro["white"], n_u, "white", sensor, key="N"))
        shown["N"] = (n_disp, n_u)
        ax.plot(tt, ro["white"] * c / np.sqrt(tt), color="C0", lw=1.0, ls="--", zorder=3, gid="slope:-1/2",
                label=f"−1/2 line through τ = {_fmt(ro['tau_white'])} s: N = {_fmt(n_disp)} {n_u} "
                      "(read at τ = 1 s" + _curve_note(ro["white"], ro["adev_at_1s"], 1.0, n_u, lambda v: float(
                          from_si(v, n_u, "white", sensor, key="N"))) + ")")
        ax.plot([1.0], [ro["white"] * c], "o", color="C0", ms=6, zorder=5, gid="readoff:N", label="_nolegend_")
    b_disp = float(from_si(ro["flicker"], b_u, "rate", sensor, key="B"))
    shown["B"] = (b_disp, b_u)
    ax.plot(tt, np.full(tt.size, ro["adev_min"] * c), color="C3", lw=1.0, ls="--", zorder=3, gid="slope:0",
            label=f"0 line: B = min/0.664 = {_fmt(b_disp)} {b_u}")
    ax.plot([ro["tau_min"]], [ro["adev_min"] * c], "s", color="C3", ms=6, zorder=5, gid="readoff:B",
            label="_nolegend_")
    if ro["random_walk"] is not None:
        k_disp = float(from_si(ro["random_walk"], k_u, "random_walk", sensor, key="K"))
        shown["K"] = (k_disp, k_u)
        ax.plot(tt, ro["random_walk"] * c * np.sqrt(tt / 3.0), color="C2", lw=1.0, ls="--", zorder=3,
                gid="slope:+1/2",
                label=f"+1/2 line through τ = {_fmt(ro['tau_random_walk'])} s: K = {_fmt(k_disp)} {k_u} "
                      "(read at τ = 3 s" + _curve_note(ro["random_walk"], ro["adev_at_3s"], 3.0, k_u, lambda v: float(
                          from_si(v, k_u, "random_walk", sensor, key="K"))) + ")")
        ax.plot([3.0], [ro["random_walk"] * c], "^", color="C2", ms=6, zorder=5, gid="readoff:K",
                label="_nolegend_")
    lo = np.nanmin(adev[adev > 0]) if np.any(adev > 0) else 1.0
    hi = np.nanmax(adev) if np.any(np.isfinite(adev)) else 1.0
    ax.set_ylim(lo / 3.0, hi * 3.0)
    if title is None:
        title = f"{sensor}: Allan deviation with slope-line read-offs"
    fig.suptitle(title)
    _axes_title(ax, "read-offs on the median curve (IEEE Std 952 Annex C)", fontsize="small")
    _finish_loglog(ax, "averaging time τ [s]", f"Allan deviation [{rate_u}]")
    fig.readoffs = {"si": {k: ro[k] for k in ("white", "flicker", "random_walk", "adev_min", "tau_min")},
                    "display": shown, "rate_unit": rate_u}
    return fig


# ---------------------------------------------------------------------------------------------
# output
# ---------------------------------------------------------------------------------------------
def save_figure(fig: "Figure", path: str | os.PathLike) -> None:
    """Write `fig` to `path` atomically (temporary file in the same directory, then :func:`os.replace`).

    The format comes from the suffix (``.png``, ``.pdf``, ``.svg``, ...), at 150 dpi (PNG: fast
    compression). The figure is closed afterwards (released from pyplot if pyplot manages it). On an
    error the temporary file is removed and `path` is left untouched.
    """
    from imupipe.io import atomic_path

    path = Path(path)
    fmt = path.suffix.lstrip(".").lower()
    if not fmt:
        raise ValueError(f"{path}: no suffix to take the figure format from")
    try:
        with atomic_path(path) as tmp:
            # PNG: zlib level 1 instead of 6, a third of the encoding time for files ~5 % larger
            extra = {"pil_kwargs": {"compress_level": 1}} if fmt == "png" else {}
            fig.savefig(os.fspath(tmp), format=fmt, dpi=_DPI, **extra)
    finally:
        plt = sys.modules.get("matplotlib.pyplot")
        if plt is not None:
            plt.close(fig)


# ---------------------------------------------------------------------------------------------
# verification
# ---------------------------------------------------------------------------------------------
def plot_verification(results: dict, unit: str | None = None, scale: float = 1.0, fix_s: float | None = None,
                      title: str | None = None, quantity: str | None = None):
    """sqrt(P) of the reference filter against the true or empirical RMS error, over fixes and outage.

    The y axis is the error itself (``quantity`` in ``unit``); each RMS curve's legend gives the worst MSE/P over
    the OUTAGE and its time (``worst_outage_ratio``, ``worst_outage_t_s``), the informative number, and the
    check's pass/FAIL.

    Parameters
    ----------
    results : dict
        Label -> :class:`imupipe.verify.Verification` (e.g. ``{"truth": ..., "replay": ...}``); all of
        one filter, so ``P`` is drawn once (from the first).
    unit : str, optional
        Display unit of the position (angle) error, e.g. ``"m"`` or ``"deg"``; ``scale`` converts from SI
        (m or rad) to it (``math.degrees(1)`` for deg). Default: SI, labelled ``SI``.
    fix_s : float, optional
        End of the fix period, s (a vertical line marks the outage start).
    title : str, optional
    quantity : str, optional
        What the filter estimates, for the y label: ``"position error"`` (accel filter, paper eq. 17) or ``"angle
        error"`` (gyro filter). Default ``"position / angle error"``.

    Returns
    -------
    matplotlib.figure.Figure
    """
    if not results:
        raise ValueError("plot_verification needs at least one verification result")
    fig, axes = _new_figure()
    ax = axes[0, 0]
    first = next(iter(results.values()))
    u = unit or "SI"
    ax.plot(first.t_s, np.sqrt(first.P) * scale, color="k", lw=1.6, label="filter sqrt(P)")
    for label, v in results.items():
        at = "" if v.worst_outage_t_s is None else f" at t = {v.worst_outage_t_s:.0f} s"
        ax.plot(v.t_s, np.sqrt(np.maximum(v.mse, 0.0)) * scale, lw=1.0,
                label=f"{label} RMS (worst MSE/P over the outage {v.worst_outage_ratio:.3g}{at}; "
                      f"{'pass' if v.passed else 'FAIL'})")
    if fix_s is not None:
        ax.axvline(fix_s, color="0.5", ls=":", lw=1.0)
    ax.set_yscale("log")
    ax.set_xlabel("time since start [s]")
    ax.set_ylabel(f"{quantity or 'position / angle error'}: RMS and filter sqrt(P) [{u}]")
    if title:
        ax.set_title(title)
    ax.legend(loc="upper left", fontsize="small")
    return fig


# ---------------------------------------------------------------------------------------------
# recording plan (imupipe.plan)
# ---------------------------------------------------------------------------------------------
def plot_plan_check(predicted: dict, simulated=(), *, sensor: str, units: dict | None = None,
                    title: str | None = None) -> "Figure":
    r"""The plan's predicted interval half-widths of N, B (GM sigma) and K against record length, one panel each,
    with simulated medians as points (their inter-quartile range as bars).

    Parameters
    ----------
    predicted : dict
        ``{label: {"hours": array (h), "half_width": [{"N", "B", "K"} (SI), one per hour]}}``, e.g. one label per
        truth (:func:`imupipe.plan.predict` at each length).
    simulated : sequence of dict
        Rows ``{"truth": label, "hours", "param": "N" | "B" | "K", "simulated", "q25", "q75"}`` (SI), as
        benchmarks/plan_check.py writes them; may be empty.
    sensor : {"gyro", "accel"}
    units : dict, optional
        Display unit per quantity ``white``, ``gm_sigma``, ``random_walk`` (default: deg/sqrt(h), deg/h,
        (deg/h)/sqrt(s) for a gyro; m/s/sqrt(h), mg, m/s^2/sqrt(s) for an accelerometer).
    title : str, optional

    Returns
    -------
    matplotlib.figure.Figure
    """
    from imupipe.units import from_si

    _check_sensor(sensor)
    if not predicted:
        raise ValueError("plot_plan_check needs at least one predicted curve")
    units = units or ({"white": "deg/sqrt(h)", "gm_sigma": "deg/h", "random_walk": "(deg/h)/sqrt(s)"}
                      if sensor == "gyro" else
                      {"white": "m/s/sqrt(h)", "gm_sigma": "mg", "random_walk": "m/s^2/sqrt(s)"})
    params = (("N", "white", "white noise N"), ("B", "gm_sigma", "GM sigma B"), ("K", "random_walk",
                                                                                  "random walk K"))
    fig, axes = _new_figure(1, 3, figsize=(13.0, 4.6))
    for j, (p, q, name) in enumerate(params):
        ax = axes[0, j]
        for i, (label, cur) in enumerate(predicted.items()):
            colour = f"C{i}"
            hw = np.array([h[p] for h in cur["half_width"]], dtype=float)
            ok = np.isfinite(hw)
            if ok.any():
                y = np.array([float(from_si(v, units[q], q, sensor)) for v in hw[ok]])
                ax.plot(np.asarray(cur["hours"], dtype=float)[ok], y, color=colour, lw=1.4,
                        label=f"{label}: predicted")
            pts = [r for r in simulated if r["truth"] == label and r["param"] == p and np.isfinite(r["simulated"])]
            if pts:
                h = np.array([r["hours"] for r in pts], dtype=float)
                conv = [[float(from_si(r[k], units[q], q, sensor)) for r in pts] for k in ("simulated", "q25", "q75")]
                med, lo, hi = (np.array(c) for c in conv)
                ax.errorbar(h, med, yerr=[med - lo, hi - med], fmt="o", color=colour, ms=5, capsize=3,
                            label=f"{label}: simulated median (IQR)")
        _axes_title(ax, name)
        if ax.lines:
            _finish_loglog(ax, "record length [h]", f"interval half-width [{units[q]}]", legend_loc="best")
        else:  # the model has no such term: nothing to predict
            ax.text(0.5, 0.5, f"no {p} in the model", ha="center", va="center", transform=ax.transAxes)
            ax.set_xlabel("record length [h]")
            ax.set_ylabel(f"interval half-width [{units[q]}]")
    fig.suptitle(title or f"{sensor}: expected interval half-width against record length (imupipe plan)")
    return fig
