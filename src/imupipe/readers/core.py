"""The reader: one record from any format, converted to SI and validated."""

from __future__ import annotations

import dataclasses
import itertools
import math
import re
import warnings
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from imupipe.readers._common import *  # noqa: F403
from imupipe.readers._common import _ROS_FIELDS, _Raw, _blank, _chname, _default_specs, _resolve, _time_factor, Key, SI_UNITS, _cell, _example_unit, _normalise_channels, _normalise_units, _unit_factor, _EXTENSIONS


from imupipe.readers.arrays import _load_npy, _load_npz
from imupipe.readers.netcdf import _load_netcdf
from imupipe.readers.rdata import _load_rdata
from imupipe.readers.rosbag import _load_rosbag
from imupipe.readers.text import _load_text
from imupipe.readers.checks import check_file, check_unchanged, check_values
from imupipe.readers.intervals import (
    count_zero, interval, intervals, intervals_above, median_interval, nonpositive, sum_between,
)

#: ``{sensor}_unit`` value that takes the unit from the file's own attribute (netCDF ``units``).
FROM_FILE = "from_file"
#: Longest gap ``gap_policy="fill"`` fills when neither fill_max_samples nor fill_max_s is given.
DEFAULT_FILL_MAX_SAMPLES = 10
#: Largest share of the record ``gap_policy="fill"`` may insert in all (inserted samples over the file's
#: samples) when ``fill_max_fraction`` is not given: 1 %. By the estimate in docs/inputs.md (relative
#: change of the Allan variance of order 2 n_filled / N) this bounds the filling's effect to a few % at worst.
DEFAULT_FILL_MAX_FRACTION = 0.01
#: relative agreement the sheet's rate_hz must have with the timestamps' mean rate (read_dataset's rate_rtol)
RATE_RTOL = 0.01


def sheet_row_to_kwargs(row: Mapping[str, Any], base_dir: str | Path | None = None) -> dict[str, Any]:
    """Keyword arguments of :func:`read_dataset` from one dataset-sheet row.

    Parameters
    ----------
    row : mapping
        One row of the dataset sheet, column name -> cell (str, number, None or NaN); the columns
        are those of :data:`SHEET_COLUMNS`, all optional but ``path``. Unknown columns are ignored.
    base_dir : str or Path, optional
        Directory that relative ``path`` cells are relative to. Defaults to None (the working
        directory).

    Returns
    -------
    dict
        Arguments for :func:`read_dataset` (without ``min_duration_s``, which the workflow gives).
    """
    r = {k: _cell(v) for k, v in row.items()}
    name = r.get("dataset") or "<row>"
    if r.get("path") is None:
        raise DataError(f"dataset {name!r}: column 'path' is empty")
    path = Path(str(r["path"]))
    if base_dir is not None and not path.is_absolute():
        path = Path(base_dir) / path
    rate = r.get("rate_hz")
    if rate is not None:
        try:
            rate = float(rate)
        except ValueError:
            raise DataError(f"dataset {name!r}: rate_hz = {rate!r} is not a number (Hz)") from None
    channels = {(s, a): r[f"{s}_{a}"] for s in SENSORS for a in AXES if r.get(f"{s}_{a}") is not None}
    units = {s: r[f"{s}_unit"] for s in SENSORS if r.get(f"{s}_unit") is not None}
    kwargs: dict[str, Any] = {
        "path": path,
        "format": r.get("format") or "auto",
        "rate_hz": rate,
        "channels": channels or None,
        "units": units or None,
    }
    for key in ("time_column", "time_unit", "delimiter", "variable", "topic", "axis_map", "gap_policy"):
        if r.get(key) is not None:
            kwargs[key] = r[key]
    for key, kind, what in (
        ("fill_max_samples", int, "an integer number of samples"),
        ("fill_max_s", float, "a number of s"),
        ("fill_max_fraction", float, "a number (fraction of the record, dimensionless)"),
    ):
        if r.get(key) is not None:
            try:
                value = kind(r[key])
                if kind is int and float(r[key]) != value:
                    raise ValueError
            except (TypeError, ValueError):
                raise DataError(
                    f"dataset {name!r}: {key} = {r[key]!r} is not {what}"
                ) from None
            kwargs[key] = value
    if r.get("long_gap_policy") is not None:
        kwargs["long_gap_policy"] = r["long_gap_policy"]
    return kwargs


def read_dataset_row(
    row: Mapping[str, Any],
    *,
    base_dir: str | Path | None = None,
    min_duration_s: float | None = None,
    min_duration_key: str = "min_duration_s",
) -> Recording:
    """Read the record described by one dataset-sheet row (see :data:`SHEET_COLUMNS`).

    Parameters
    ----------
    row : mapping
        Column name -> cell; see :func:`sheet_row_to_kwargs`.
    base_dir : str or Path, optional
        Directory of relative paths. Defaults to None (the working directory).
    min_duration_s : float, optional
        Shortest usable record (s), e.g. what the largest Allan tau or PSD window needs.
        Defaults to None (no check).
    min_duration_key : str, optional
        Setting quoted when the record is too short (e.g. ``"psd.window_s"``). Defaults to ``"min_duration_s"``.

    Returns
    -------
    Recording
        The channels in SI units, as :func:`read_dataset` returns them.
    """
    return read_dataset(
        **sheet_row_to_kwargs(row, base_dir), min_duration_s=min_duration_s, min_duration_key=min_duration_key
    )


def read_dataset(
    path: str | Path, format: str = "auto", rate_hz: float | None = None, channels: Mapping[Any, Any] | None = None,
    units: Mapping[Any, Any] | None = None, *, time_column: str | int | None = None, time_unit: str | None = None,
    delimiter: str | None = None, variable: str | None = None, topic: str | None = None,
    axis_map: str | Mapping[str, str] | None = None, gap_policy: str = "fail", min_duration_s: float | None = None,
    rate_rtol: float = RATE_RTOL, gap_factor: float = 1.5, fill_max_samples: int | None = None,
    fill_max_s: float | None = None, long_gap_policy: str = "fail",
    fill_max_fraction: float = DEFAULT_FILL_MAX_FRACTION, min_duration_key: str = "min_duration_s",
) -> Recording:
    r"""Read, convert to SI and validate one static IMU record.

    The steps are: read the channels (and timestamps) in file units; check every sample is finite;
    check the timestamps (strictly increasing, rate within ``rate_rtol`` of ``rate_hz``, no
    interval longer than ``gap_factor / rate_hz``); handle gaps per ``gap_policy``; check the
    duration against ``min_duration_s`` and that no channel is constant; convert to SI
    (:math:`x_\mathrm{SI} = c_u\,x`, e.g. :math:`c = \pi/180` for deg/s and :math:`c = g_0 =
    9.80665` m/s^2 for g); apply the axis map.

    Parameters
    ----------
    path : str or Path
        File to read (a rosbag2 directory for ROS 2 bags).
    format : str, optional
        One of :data:`FORMATS` (``csv``, ``netcdf``, ``npy``, ``npz``, ``rda``/``rds``, ``rosbag``/``mcap``,
        ...). Defaults to ``"auto"``: by the file extension (a directory is a rosbag2 bag).
    rate_hz : float, optional
        Nominal sample rate (Hz) from the dataset sheet. Checked against the timestamps and against
        a rate stored in the file (R attribute ``freq``/``tsp``); a relative difference above
        ``rate_rtol`` is an error. Defaults to None: the file's rate, else the timestamps' mean rate.
    channels : mapping, optional
        ``{(sensor, axis) or "sensor_axis": column}`` with sensor ``gyro``/``accel`` and axis
        ``x``/``y``/``z``; ``column`` is a column / variable / array name, a 0-based index, or for
        bags a message field such as ``"angular_velocity.x"``. A dataset may hold one sensor only.
        Defaults to None: columns named ``gyro_x`` ... ``accel_z`` (bags: all six Imu fields).
    units : mapping, optional
        Stored unit per sensor, ``{"gyro": "deg/s", "accel": "g"}`` (keys ``(sensor, axis)``
        also accepted). Any rate unit :func:`imupipe.units.rate_factor` accepts: rad/s, mrad/s,
        deg/s, dps, °/s, mdeg/s, deg/h, rad s-1 (CF); m/s^2, m s-2, mm/s^2, g, mg, ug, µg
        (``g`` = 9.80665 m/s^2); table in docs/inputs.md. ``"from_file"``: the file's own unit
        attribute (netCDF ``units``), which must then exist. A unit the file states must parse and
        agree with the sheet's. Defaults to None: the file's unit, SI for ROS bags, an error otherwise.
    time_column : str or int, optional
        Column / variable / array of timestamps. For bags ``"header"`` (``header.stamp``, the
        default) or ``"bag"`` (recording time). Defaults to None: no timestamps, uniform sampling
        at ``rate_hz`` assumed.
    time_unit : str, optional
        Unit of ``time_column``: ``s``, ``ms``, ``us`` or ``ns``. Defaults to None: seconds (netCDF:
        from the variable's ``units`` attribute).
    delimiter : str, optional
        Text files: ``","``, ``"tab"``, ``"semicolon"``, ``"space"`` (runs of whitespace), ... .
        Defaults to None: tab, comma, semicolon or whitespace, whichever the header line shows.
        Lines starting with ``#`` are comments; a first line of numbers means no header.
    variable : str, optional
        R ``.rda``: name of the object (needed when the file holds several). ``.npz`` / netCDF: a
        2-D array / variable ``(samples, columns)`` that the channel indices refer to. Defaults to None.
    topic : str, optional
        Bags: topic of the ``sensor_msgs/Imu`` messages. Defaults to None: the only Imu topic.
    axis_map : str or mapping, optional
        Body axis <- signed file axis, e.g. ``"x:-y,y:x,z:z"`` (see :func:`parse_axis_map`), applied
        to both sensors after the SI conversion. Defaults to None (identity).
    gap_policy : {"fail", "split", "fill"}, optional
        What a timestamp gap does: ``"fail"`` raises :class:`DataError` naming the first gap;
        ``"split"`` keeps the longest contiguous segment in ``channels``, lists every segment in
        ``Recording.segments`` (data via ``Recording.segment(i)``) and warns (:class:`GapWarning`)
        naming the gaps. ``"fill"`` fills every gap of at most ``fill_max_samples`` missing samples
        (or ``fill_max_s`` seconds) by linear interpolation between its two neighbours (timestamps
        and every channel), lists them in ``Recording.filled`` and handles longer gaps by
        ``long_gap_policy``. Duplicated or decreasing timestamps are always an error. Defaults to ``"fail"``.
    min_duration_s : float, optional
        Shortest usable record (s), e.g. ``2 * tau_max`` for the largest Allan tau or the PSD
        window length; the (selected) record must last at least this long (``n / rate_hz``).
        Defaults to None (no check).
    rate_rtol : float, optional
        Relative tolerance between the sheet's rate and the file's or timestamps' rate.
        Defaults to 0.01 (1 %).
    gap_factor : float, optional
        A timestamp interval longer than ``gap_factor / rate_hz`` is a gap when it lies beyond the stamps'
        own jitter (:func:`_gap_mask`: the stamps after it sit later on the sample grid, or the interval
        itself is longer than the intervals' jitter allows; a late or early stamp is jitter); shorter positive
        ones are sample steps (jitter and clock quantisation, e.g. integer-ms stamps at 300 Hz, are accepted).
        Defaults to 1.5.
    fill_max_samples : int, optional
        ``gap_policy="fill"``: longest gap filled, in missing samples. Defaults to None: 10 samples
        unless ``fill_max_s`` is given.
    fill_max_s : float, optional
        ``gap_policy="fill"``: longest gap filled, in s of missing data (``fill_max_s * rate`` samples,
        rounded down). Defaults to None.
    long_gap_policy : {"fail", "split"}, optional
        ``gap_policy="fill"``: what a longer gap does. Defaults to ``"fail"``.
    fill_max_fraction : float, optional
        ``gap_policy="fill"``: most samples filling may insert in all, as a fraction of the file's
        samples (dimensionless, in [0, 1]); more is an error naming ``fill_max_fraction``. Defaults to
        :data:`DEFAULT_FILL_MAX_FRACTION` (0.01).
    min_duration_key : str, optional
        Name of the setting ``min_duration_s`` comes from, quoted in the error (the workflow passes
        ``"psd.window_s"``). Defaults to ``"min_duration_s"``.

    Returns
    -------
    Recording
        Mapping ``{(sensor, axis): float64 ndarray}`` in rad/s (gyro) and m/s^2 (accel), with
        ``rate_hz`` (Hz), ``source``, ``units``, ``file_units``, ``columns`` and ``segments``.

    Raises
    ------
    DataError
        Missing, empty, truncated or malformed file; unknown column, object, topic, format, unit
        or axis map; non-finite samples; bad timestamps or rate; too short; constant channel.

    Examples
    --------
    >>> rec = read_dataset("imu.csv", "csv", rate_hz=100.0,  # doctest: +SKIP
    ...                    channels={"gyro_x": "wx", "gyro_y": "wy", "gyro_z": "wz"},
    ...                    units={"gyro": "deg/s"}, time_column="t", axis_map="x:-y,y:x,z:z")
    >>> rec["gyro", "x"]  # rad/s  # doctest: +SKIP
    """
    path = Path(path)
    where = str(path)
    fmt = _format_of(path, format)
    _check_arguments(where, gap_policy, long_gap_policy, fill_max_samples, fill_max_s, fill_max_fraction, rate_hz,
                     min_duration_s)
    before = check_file(path, fmt)
    specs = _normalise_channels(channels)
    _check_specs(specs, where)
    sheet_units = _normalise_units(units)
    amap = parse_axis_map(axis_map)
    _check_sheet_units(specs, sheet_units, where)
    raw = _load(fmt, path, specs, delimiter, variable, topic, time_column, time_unit, where, before)
    row_text = _RowText(raw)
    n = _check_samples(raw, where, row_text)
    rate, segments, filled = _rate_and_segments(
        raw, n, fmt, rate_hz, time_unit, gap_policy, long_gap_policy, fill_max_samples, fill_max_s, fill_max_fraction,
        rate_rtol, gap_factor, where, row_text)
    selected = max(range(len(segments)), key=lambda i: segments[i].n)
    seg = segments[selected]
    _check_duration(raw, seg, len(segments), rate, min_duration_s, min_duration_key, where)
    si, file_units = _to_si(raw, sheet_units, where, row_text)
    mapped, columns, mapped_units = _apply_axis_map(si, file_units, raw, amap, axis_map, where)
    keys = [(s, a) for s in SENSORS for a in AXES if (s, a) in mapped]
    full = {k: mapped[k] for k in keys}
    if len(segments) > 1:
        chans = {k: v[seg.start : seg.stop] for k, v in full.items()}
    else:
        chans, full = full, {}
    detail = raw.detail or (f"variable {variable!r}" if fmt in ("npz", "netcdf") and variable else "")
    source = f"{where} ({fmt}{', ' + detail if detail else ''})"
    return Recording(channels=chans, rate_hz=float(rate), source=source, units={k: SI_UNITS[k[0]] for k in keys},
                     file_units={k: mapped_units[k] for k in keys}, columns={k: columns[k] for k in keys},
                     segments=tuple(segments), selected=selected, filled=filled, _full=full)


class _RowText:
    """Where row `row` of the record is, for error messages (helper of :func:`read_dataset`): its 0-based row,
    the line of a text file, and after gap filling (``file_row``: filled row -> file row, -1 for an inserted
    sample) the row of the file or that it was inserted."""

    def __init__(self, raw: _Raw) -> None:
        self.raw = raw
        self.file_row: Callable[[int], int] | None = None

    def __call__(self, row: int) -> str:
        if self.file_row is not None:
            in_file = self.file_row(row)
            if in_file < 0:
                return f"row {row} of the gap-filled record (an inserted sample)"
            row = in_file
        text = f"row {row} (0-based)"
        if self.raw.line_of_row is not None:
            text += f", line {self.raw.line_of_row(row)}"
        return text


def _check_arguments(where, gap_policy, long_gap_policy, fill_max_samples, fill_max_s, fill_max_fraction, rate_hz,
                     min_duration_s) -> None:
    """:class:`DataError` naming the file (`where`) and the argument of :func:`read_dataset` out of its range."""
    if gap_policy not in GAP_POLICIES:
        raise DataError(f"{where}: gap_policy {gap_policy!r} not one of {GAP_POLICIES}")
    if long_gap_policy not in ("fail", "split"):
        raise DataError(f"{where}: long_gap_policy {long_gap_policy!r} not one of ('fail', 'split')")
    for name, value in (("fill_max_samples", fill_max_samples), ("fill_max_s", fill_max_s)):
        if value is not None and not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
            raise DataError(f"{where}: {name} = {value!r}; expected a non-negative number")
    if not (isinstance(fill_max_fraction, (int, float)) and 0 <= fill_max_fraction <= 1):
        raise DataError(
            f"{where}: fill_max_fraction = {fill_max_fraction!r}; expected a fraction of the record in [0, 1]"
        )
    if rate_hz is not None and not (np.isfinite(rate_hz) and rate_hz > 0):
        raise DataError(f"{where}: rate_hz = {rate_hz!r}; expected a positive number of Hz")
    if min_duration_s is not None and not (min_duration_s >= 0):
        raise DataError(f"{where}: min_duration_s = {min_duration_s!r}; expected a non-negative number of s")


def _check_specs(specs, where) -> None:
    """The channel columns of :func:`read_dataset`: at least one, no column named twice."""
    if specs is not None and not specs:
        raise DataError(f"{where}: no channel given (all of gyro_x ... accel_z are empty)")
    if specs is not None:
        seen: dict[str, Key] = {}
        for key, spec in specs.items():
            other = seen.setdefault(str(spec), key)
            if other != key:
                raise DataError(
                    f"{where}: {_chname(other)} and {_chname(key)} both name column {spec!r}; expected one column "
                    "per channel (a duplicated or mistyped dataset-sheet column?)"
                )


def _check_sheet_units(specs, sheet_units, where) -> None:
    """The sheet's units of the channels read, checked before a large file is read."""
    if specs is not None:
        for key in specs:
            if sheet_units.get(key) is not None and sheet_units[key] != FROM_FILE:
                _unit_factor(sheet_units[key], key[0], f"{where}: {key[0]}_unit")


def _load(fmt, path, specs, delimiter, variable, topic, time_column, time_unit, where, before) -> _Raw:
    """The channels (and timestamps) of `path` in file units by the reader of format `fmt`; a file changed while
    it was read (against `before`, :func:`imupipe.readers.checks.check_file`) is named as such."""
    try:
        if fmt == "csv":
            raw = _load_text(path, specs, delimiter, time_column, time_unit, where)
        elif fmt == "npy":
            raw = _load_npy(path, specs, time_column, time_unit, where)
        elif fmt == "npz":
            raw = _load_npz(path, specs, variable, time_column, time_unit, where)
        elif fmt == "netcdf":
            raw = _load_netcdf(path, specs, variable, time_column, time_unit, where)
        elif fmt == "rdata":
            raw = _load_rdata(path, specs, variable, time_column, time_unit, where)
        else:
            raw = _load_rosbag(path, specs, topic, time_column, where)
    except DataError as exc:
        # a file rewritten during the read ends in a torn row or a short table: say that it changed (the
        # parse error that followed is chained), not that its row N is malformed
        try:
            check_unchanged(path, before)
        except DataError as changed:
            raise changed from exc
        raise
    check_unchanged(path, before)
    return raw


def _check_samples(raw: _Raw, where, row_text) -> int:
    """The number of samples, every channel (and the timestamps) of that length and every sample finite."""
    lengths = {len(v) for v in raw.data.values()} | ({len(raw.time)} if raw.time is not None else set())
    if len(lengths) != 1:
        detail = ", ".join(f"{_chname(k)}: {len(v)}" for k, v in raw.data.items())
        raise DataError(f"{where}: channels differ in length ({detail})")
    n = lengths.pop()
    if n == 0:
        raise DataError(f"{where}: no samples")
    for key, x in raw.data.items():
        if np.isfinite(x.min()) and np.isfinite(x.max()):  # NaN propagates: no temporary array when all is well
            continue
        finite = np.isfinite(x)
        if not finite.all():
            row = int(np.argmin(finite))
            raise DataError(
                f"{where}: {_chname(key)} (column {raw.names[key]}) has a non-finite sample ({float(x[row])}) at "
                f"{row_text(row)}; {int(np.count_nonzero(~finite))} in all"
            )
    return n


def _rate_and_segments(raw, n, fmt, rate_hz, time_unit, gap_policy, long_gap_policy, fill_max_samples, fill_max_s,
                       fill_max_fraction, rate_rtol, gap_factor, where, row_text):
    """The record's rate (Hz), its contiguous segments and the gaps filled (:func:`read_dataset`'s timestamp
    steps: the sheet's rate against the file's, gap filling per `gap_policy`, the timestamp checks); frees
    ``raw.time`` once checked. `row_text` learns the filled-to-file row map."""
    rate = rate_hz
    if raw.file_rate is not None and rate_hz is not None:
        if abs(raw.file_rate - rate_hz) > rate_rtol * rate_hz:
            raise DataError(
                f"{where}: rate_hz = {rate_hz:g} Hz in the sheet but the file says {raw.file_rate:g} Hz "
                f"({raw.file_rate_from})"
            )
    elif rate is None:
        rate = raw.file_rate
    segments = [Segment(0, n)]
    # the unit the stamps were read in, for the time_unit hint (netCDF without time_unit: the file's, not known here)
    stamp_unit = str(time_unit).strip() if not _blank(time_unit) else None if fmt in ("netcdf", "rosbag") else "s"
    filled: tuple[FilledGap, ...] = ()
    policy, max_missing = gap_policy, None
    if raw.time is not None and gap_policy == "fill":
        if not (np.isfinite(raw.time.min()) and np.isfinite(raw.time.max())) or len(raw.time) < 2:
            pass  # _check_time names the bad value
        else:
            if fill_max_samples is not None:
                max_missing = fill_max_samples
            elif fill_max_s is not None:
                # the median interval needs increasing time (the check _fill_gaps makes first)
                _order_stamps(raw, where, row_text)
                guess = rate if rate is not None else _nominal_rate(raw.time, None, gap_factor)[1]
                max_missing = int(math.floor(fill_max_s * guess))
            else:
                max_missing = DEFAULT_FILL_MAX_SAMPLES
            filled, row_text.file_row = _fill_gaps(
                raw, rate, rate_hz, rate_rtol, gap_factor, max_missing, fill_max_fraction, where, row_text, stamp_unit
            )
        policy = long_gap_policy
    elif raw.time is None and gap_policy == "fill":
        pass  # no timestamps: no gaps to see
    if raw.time is not None:
        segments, rate = _check_time(raw, rate, rate_hz, policy, rate_rtol, gap_factor, where, row_text, stamp_unit,
                                     after_fill=max_missing)
        raw.time = None  # checked: its memory is free for the unit conversion below
    if rate is None:
        raise DataError(f"{where}: sample rate unknown: give rate_hz (no timestamps and no rate in the file)")
    return rate, segments, filled


def _check_duration(raw, seg, n_segments, rate, min_duration_s, min_duration_key, where) -> None:
    """The selected segment `seg` lasts at least `min_duration_s` s and no channel is constant on it."""
    duration = seg.n / rate
    if min_duration_s is not None and duration < min_duration_s:
        part = "longest contiguous segment" if n_segments > 1 else "record"
        raise DataError(
            f"{where}: {part} lasts {duration:.6g} s ({seg.n} samples at {rate:g} Hz), shorter than the "
            f"{min_duration_s:g} s needed ({min_duration_key})"
        )
    for key, x in raw.data.items():
        part = x[seg.start : seg.stop]
        if part.size and part.min() == part.max():
            raise DataError(
                f"{where}: {_chname(key)} (column {raw.names[key]}) is constant ({part[0]:g} in all {part.size} "
                "samples): a dead or saturated channel, or the wrong column"
            )


def _to_si(raw, sheet_units, where, row_text):
    """Every channel in SI (rad/s, m/s^2) from the sheet's unit or the file's (which must agree where both are
    given), its values checked; returns (channels, unit each was read in)."""
    si: dict[Key, np.ndarray] = {}
    file_units: dict[Key, str] = {}
    for key, x in raw.data.items():
        sensor = key[0]
        unit = sheet_units.get(key)
        origin = f"{where}: {sensor}_unit"
        stored_unit = raw.file_units.get(key)
        if stored_unit is not None and not _blank(stored_unit):  # a unit the file states must be readable
            try:
                stored_factor = _unit_factor(stored_unit, sensor, f"{where}: variable {raw.names[key]} units attribute")
            except DataError as exc:
                raise DataError(
                    f"{exc}; the file's own unit must parse (and agree with {sensor}_unit, or set "
                    f"{sensor}_unit: {FROM_FILE})"
                ) from None
        if unit == FROM_FILE:
            if stored_unit is None or _blank(stored_unit):
                raise DataError(
                    f"{where}: {sensor}_unit = {FROM_FILE!r} but {_chname(key)} (variable {raw.names[key]}) has no "
                    "units attribute; give the unit in the sheet"
                )
            unit = None
        if unit is None:
            unit = raw.file_units.get(key) or raw.default_units.get(sensor)
            origin = f"{where}: {_chname(key)} unit (from the file)"
            if unit is None:
                raise DataError(
                    f"{where}: {sensor}_unit missing for {_chname(key)} (the file does not say); "
                    f"expected e.g. {SI_UNITS[sensor]!r} or {_example_unit(sensor)!r}"
                )
        elif raw.file_units.get(key):
            if not math.isclose(stored_factor, _unit_factor(unit, sensor, origin), rel_tol=1e-9):
                raise DataError(
                    f"{where}: {sensor}_unit = {unit!r} in the sheet but {raw.names[key]} states "
                    f"{raw.file_units[key]!r} (its column header or units attribute); the two must agree: correct "
                    f"the sheet's {sensor}_unit, or leave it empty to take the file's"
                )
        factor = _unit_factor(unit, sensor, origin)
        # x * factor is a new array; in SI already, a fresh array is kept as it is and only a read-only view
        # (a .npy opened as a memory map) is copied (a 36 MB copy costs ~50 ms, mostly page faults)
        si[key] = x * factor if factor != 1.0 else (x if x.flags.writeable else np.array(x, dtype=np.float64))
        file_units[key] = unit
        check_values(si[key], sensor, f"{_chname(key)} (column {raw.names[key]})", where, row_text)
    return si, file_units


def _apply_axis_map(si, file_units, raw, amap, axis_map, where):
    """The channels, their column names and file units under the axis map `amap` (body axis <- signed file
    axis; all three axes of a sensor needed unless it is the identity)."""
    mapped: dict[Key, np.ndarray] = {}
    columns: dict[Key, str] = {}
    mapped_units: dict[Key, str] = {}
    identity = all(sign == 1 and src == a for a, (sign, src) in amap.items())
    for sensor in SENSORS:
        present = [a for a in AXES if (sensor, a) in si]
        if not present:
            continue
        if not identity and len(present) != 3:
            raise DataError(
                f"{where}: axis_map {axis_map!r} needs all three {sensor} axes; have {', '.join(present)}"
            )
        for a in AXES:
            sign, src = amap[a]
            if (sensor, src) not in si:
                continue
            x = si[(sensor, src)]
            mapped[(sensor, a)] = -x if sign < 0 else x
            columns[(sensor, a)] = ("-" if sign < 0 else "") + raw.names[(sensor, src)]
            mapped_units[(sensor, a)] = file_units[(sensor, src)]
    return mapped, columns, mapped_units


def format_of(path: str | Path, format: str | None = "auto") -> str:
    """The reader format (a value of :data:`FORMATS`: csv, netcdf, npy, npz, rdata, rosbag) of `path` given as
    `format`; ``"auto"`` (or blank) picks by the extension, a directory is a ROS 2 bag. Raises
    :class:`DataError` for an unknown format or extension."""
    return _format_of(Path(path), format)


def _format_of(path: Path, format: str | None) -> str:
    key = "auto" if _blank(format) else str(format).strip().lower()
    if key not in FORMATS:
        raise DataError(f"{path}: unknown format {format!r}; expected one of {', '.join(sorted(FORMATS))}")
    fmt = FORMATS[key]
    if fmt == "auto":
        if path.is_dir():
            return "rosbag"
        fmt = _EXTENSIONS.get(path.suffix.lower())
        if fmt is None:
            raise DataError(
                f"{path}: cannot tell the format from the extension {path.suffix!r}; give `format`"
            )
    return fmt


#: Stamps on each side of a long interval whose median grid phase tells a gap from a late or early stamp
#: (:func:`grid_shift`).
GAP_PHASE_STAMPS = 8


def grid_shift(t: np.ndarray, at: np.ndarray, period: float, stamps: int = GAP_PHASE_STAMPS,
               through: np.ndarray | None = None) -> np.ndarray:
    r"""How many sample periods the stamps after each interval ``at[g]`` (t[i] -> t[i+1], ascending indices) sit
    later on the sample grid than those before it (dimensionless; about the samples missing there).

    .. math:: s_i = \frac{\operatorname{med}_{j \in A} \phi_j - \operatorname{med}_{j \in B} \phi_j}{T},
              \qquad \phi_j = t_j - t_i - (j - i)\,T,

    with B the up to `stamps` stamps before i and A those after i + 1 (the interval's own two stamps, which sit
    early and late where the interval is long by jitter, only where no other stamp remains), neither reaching past
    the neighbouring intervals of `at`. Stamp jitter moves a stamp about its grid point: a late stamp makes one
    interval long and the next short and leaves the phases around it in place (s near 0), while k missing samples
    move every later stamp by k T (s near k). With independent jitter of rms sigma per stamp, s has an sd of about
    0.65 sigma (two medians of eight). Simulated (10 h at 10 Hz, 20 records each, 20 drops each): at sigma = T/10,
    8.8 intervals per record longer than 1.5 T and no false gap, every drop found; at T/5, 1390 long intervals and
    0.05 false gaps per record, 7 % of the drops missed (their interval below 1.5 T); uniform +-0.35 T (2 h): no
    false gap, the mean rate exact. A clock whose intervals themselves jitter (a random-walk phase) moves s by the
    walk over about `stamps` intervals.

    `through` (optional, one per `at`, ascending, ``through[g] >= at[g]``): the shift across the run of intervals
    ``at[g] .. through[g]`` instead (the stamps after ``through[g] + 1`` against those before ``at[g]``): a drop
    beside a jittered stamp makes two neighbouring intervals long and splits its shift between them.
    """
    at = np.asarray(at, dtype=np.int64)
    end = at if through is None else np.asarray(through, dtype=np.int64)
    n = len(t)
    out = np.empty(at.size, dtype=np.float64)
    for g, i in enumerate(at):
        i, k = int(i), int(end[g])
        first = max(i - stamps, int(end[g - 1]) + 1 if g else 0)
        last = min(k + 1 + stamps, int(at[g + 1]) if g + 1 < at.size else n - 1)
        # the interval's own two stamps are left out where others remain: a long interval is long because they
        # sit early and late, which would pull both medians apart
        j_before = np.arange(first, i) if i > first else np.array([i])
        j_after = np.arange(k + 2, last + 1) if last > k + 1 else np.array([k + 1])
        before = np.median(t[j_before] - t[i] - (j_before - i) * period)
        after = np.median(t[j_after] - t[i] - (j_after - i) * period)
        out[g] = (after - before) / period
    return out


#: Robust standard deviations above its jitter that a long interval's evidence must lie to be a gap
#: (:func:`_gap_mask`): of the grid shift, and of the interval itself.
GAP_SHIFT_SDS, GAP_INTERVAL_SDS = 4.0, 5.0


def _robust_sd(x: np.ndarray) -> float:
    """1.4826 x the median absolute deviation: the sd of a normal sample, unmoved by a few outliers (gaps)."""
    x = np.asarray(x, dtype=np.float64)
    return float(1.4826 * np.median(np.abs(x - np.median(x)))) if x.size else 0.0


def _gap_mask(t: np.ndarray, long: np.ndarray, period: float, gap_factor: float, where: str | None = None
              ) -> tuple[np.ndarray, np.ndarray]:
    r"""(which of the long intervals `long` are gaps, the samples each misses). Gaps are the long intervals
    (longer than `gap_factor` periods of `period` s) whose
    stamps after them sit later on the sample grid by more than the stamps' own jitter shows, or that are
    themselves longer than the intervals' jitter allows:

    .. math:: s_i \ge \max(1/2,\ 4\,\hat\sigma_s) \quad\text{or}\quad
              \Delta t_i - T \ge \max((g - 1) T,\ 5\,\hat\sigma_{\Delta t}),

    :math:`s_i` the :func:`grid_shift`, :math:`\hat\sigma_s` its robust sd at up to 2000 ordinary intervals,
    :math:`\hat\sigma_{\Delta t}` the robust sd of up to 100 000 intervals, g = `gap_factor`. Stamp jitter (each
    stamp about its grid point) leaves the grid shift small and is read by the first test; a clock whose intervals
    themselves jitter (its phase wanders) moves the grid shift by the walk and is read by the second, where a
    20 % interval jitter made a long interval of every 160th and ``gap_policy: fill`` filled each. A gap of fewer
    samples than either test can see at such jitter is not found, and `where` (the file, for the warning) is told
    how many samples the stamps resolve. The samples missed: :math:`\mathrm{round}(s_i)` where the grid reads to
    a half sample at four sds (:math:`\hat\sigma_s \le 1/8`), else :math:`\mathrm{round}(\Delta t_i / T) - 1`;
    at least 1. A run of neighbouring long intervals none of which passes is tested as one (its grid shift across
    the run, :func:`grid_shift`'s `through`): a drop beside a jittered stamp splits its shift between two intervals;
    the gap is placed at the run's longest."""
    n = len(t)
    shift, dt = grid_shift(t, long, period), intervals(t, long)
    ordinary = np.setdiff1d(np.linspace(0, n - 2, min(2000, max(n - 1, 1))).astype(np.int64), long)
    sd_s = _robust_sd(grid_shift(t, ordinary, period)) if ordinary.size >= 20 else 0.0
    sample = np.linspace(0, n - 2, min(100_000, max(n - 1, 1))).astype(np.int64)
    sd_dt = _robust_sd(intervals(t, sample))
    gap = (shift >= max(0.5, GAP_SHIFT_SDS * sd_s)) | (
        dt - period >= max((gap_factor - 1.0) * period, GAP_INTERVAL_SDS * sd_dt))
    missing = np.rint(shift) if sd_s <= 0.5 / GAP_SHIFT_SDS else np.rint(dt / period) - 1.0
    # neighbouring long intervals none of which is a gap: a drop beside a jittered stamp splits its grid shift
    # between them (0.28 + 0.39 periods in an outside evaluation's record): the run's shift is read as one, the gap
    # placed at its longest interval, the samples missed from the run's shift or its length
    runs = np.split(np.arange(long.size), np.flatnonzero(np.diff(long) > 1) + 1) if long.size else []
    runs = [r for r in runs if r.size > 1 and not gap[r].any()]
    if runs:
        across = grid_shift(t, long[[r[0] for r in runs]], period, through=long[[r[-1] for r in runs]])
        for r, s_run in zip(runs, across):
            if s_run >= max(0.5, GAP_SHIFT_SDS * sd_s):
                g = int(r[np.argmax(dt[r])])
                gap[g] = True
                missing[g] = (np.rint(s_run) if sd_s <= 0.5 / GAP_SHIFT_SDS else
                              np.rint(float(np.sum(dt[r])) / period) - r.size)
    missing = np.maximum(missing, 1).astype(np.int64)
    k_min = min(max(1, math.ceil(GAP_SHIFT_SDS * sd_s)), max(1, math.ceil(GAP_INTERVAL_SDS * sd_dt / period)))
    if k_min > 1 and where is not None:
        warnings.warn(f"{where}: the timestamps jitter (interval sd {sd_dt / period:.2g} periods, grid phase sd "
                      f"{sd_s:.2g} periods over {GAP_PHASE_STAMPS} stamps): gaps of fewer than {k_min} samples cannot "
                      "be told from jitter and are not found", GapWarning, stacklevel=4)
    return gap, missing


def _find_gaps(t: np.ndarray, nominal: float, gap_factor: float, where: str | None = None
               ) -> tuple[np.ndarray, np.ndarray]:
    """(indices i, samples missing) of the gaps: intervals t[i] -> t[i+1] longer than ``gap_factor * nominal``
    (s) that :func:`_gap_mask` finds to be gaps, not jitter (a long interval that the next short one makes up, or a
    wandering clock's long interval within its jitter), the samples missing counted as it says."""
    long = intervals_above(t, gap_factor * nominal)
    if not long.size:
        return long, np.empty(0, dtype=np.int64)
    gap, missing = _gap_mask(t, long, nominal, gap_factor, where)
    return long[gap], missing[gap]


def _nominal_rate(t: np.ndarray, rate, gap_factor: float) -> tuple[float, float]:
    """(rate in Hz used to find gaps, mean rate in Hz over the intervals that are not gaps).

    The mean interval over the record (gap-free intervals only) is the rate's estimate: jitter and a
    quantised clock (integer-millisecond stamps at 128 or 300 Hz) average out, while a median interval
    would report the clock's quantum (1/0.003 s = 333.3 Hz for 300 Hz stamped in ms). Gaps are found
    against `rate` when known, else against the median interval, then the mean is taken without them:
    ``count(ok) / sum(dt[ok])`` with ``ok = dt <= gap_factor / guess``. Computed block-wise over `t`
    (:mod:`imupipe.readers.intervals`, equal to the whole-array ``np.median`` and ``np.sum(dt, where=ok)`` to
    the last bit); when `rate` is None, `t` must increase strictly. Then the long intervals that are jitter, not
    gaps (:func:`_gap_mask` against that mean), are counted back in: a late stamp's long interval and the short one
    after it average to a period, the short one alone does not.
    """
    guess = 1.0 / median_interval(t) if rate is None else rate

    def mean_rate_below(limit: float, default: float) -> float:
        count, total = sum_between(t, intervals_above(t, limit))
        return float(count / total) if count else default

    mean_rate = mean_rate_below(gap_factor / guess, guess)
    if rate is None:  # second pass against the mean: the median of a quantised clock may be off by a quantum
        mean_rate = mean_rate_below(gap_factor / mean_rate, mean_rate)
    # a long interval that is jitter, not a gap (_gap_mask), is a sample step: left out, its
    # short partner kept, the mean would be biased high (uniform jitter of +-0.35 periods: 10 Hz read as 10.31)
    # (twice: the grid's period from a biased mean drifts by a few % per stamp)
    for _ in range(2):
        long = intervals_above(t, gap_factor / mean_rate)
        if not long.size:
            break
        jitter = ~_gap_mask(t, long, 1.0 / mean_rate, gap_factor)[0]
        if not jitter.any():
            break
        count, total = sum_between(t, long[~jitter])
        mean_rate = float(count / total) if count else mean_rate
    return (rate if rate is not None else mean_rate), mean_rate


def snap_rate(rate_hz: float, rtol: float = 1e-3) -> float:
    """The round rate a measured mean rate stands for: the coarsest of ``round(rate_hz, d)``, d = 0..3,
    within `rtol` (relative), else `rate_hz` itself.

    Timestamps give the rate to the clock's accuracy (crystal error ~1e-5 .. 1e-4, jitter averaging out
    as 1/duration); the processing needs the nominal rate (decimation by an integer ratio), so a mean of
    2.00035 Hz stands for 2 Hz and 124.998 Hz for 125 Hz. Tolerance 1e-3 (1000 ppm, 10x a poor crystal).
    """
    for digits in range(4):
        candidate = round(rate_hz, digits)
        if candidate > 0 and abs(candidate - rate_hz) <= rtol * rate_hz:
            return float(candidate)
    return float(rate_hz)


def _check_time(raw: _Raw, rate, rate_hz, gap_policy, rtol, gap_factor, where, row_text, time_unit=None,
                after_fill: int | None = None):
    """Check timestamps; return (segments, rate in Hz). `after_fill`: the fill limit (samples) where the short gaps
    are filled already (``gap_policy: fill``); `gap_policy` is then the long-gap policy, which a refusal names, and a
    gap of at most that many samples found only now is not one (the fill's own search looked for those: it sits
    beside a filled drop among jittered stamps, which an outside evaluation saw refused as "longer than the fill
    limit").

    Tolerance: an interval in (0, gap_factor / rate] is a sample step (jitter and clock quantisation
    accepted); a longer one is a gap where it lies beyond the stamps' own jitter (:func:`_find_gaps`), else
    jitter; zero or negative is an error. The rate is the mean over the gap-free
    intervals and must agree with the sheet's (or the file's) within `rtol`.
    """
    t = raw.time
    tname = raw.time_name
    # min and max need no temporary array (a NaN propagates into both, an infinity into one of them)
    finite = np.isfinite(t) if not (np.isfinite(t.min()) and np.isfinite(t.max())) else None
    if finite is not None:
        row = int(np.argmin(finite))
        raise DataError(
            f"{where}: time column {tname} has a non-finite value ({float(t[row])}) at {row_text(row)}"
        )
    n = len(t)
    if n < 2:
        return [Segment(0, n, float(t[0]), float(t[0]))], rate
    _order_stamps(raw, where, row_text)
    t = raw.time
    if rate_hz is not None:
        _check_sheet_rate(t, rate_hz, rtol, gap_factor, tname, where, time_unit)
    nominal_rate, mean_rate = _nominal_rate(t, rate, gap_factor)
    if rate is not None and rate_hz is None and abs(mean_rate - rate) > rtol * rate:
        raise DataError(
            f"{where}: the file says {rate:g} Hz ({raw.file_rate_from}) but the timestamps ({tname}) "
            f"give {mean_rate:.6g} Hz (mean interval)"
        )
    nominal = 1.0 / nominal_rate
    # after filling, the fill's own gap search has warned already of what the stamps cannot resolve
    gaps, missing = _find_gaps(t, nominal, gap_factor, None if after_fill is not None else where)
    if after_fill is not None:
        gaps = gaps[missing > after_fill]
    if gaps.size:

        def describe(i: int) -> str:
            return (
                f"{interval(t, i):.6g} s between {row_text(int(i))} (t = {_stamp(t[i])} s) and {row_text(int(i) + 1)} "
                f"(t = {_stamp(t[i + 1])} s)"
            )

        if gap_policy == "fail":
            remedy = ("longer than the fill limit (fill_max_samples / fill_max_s) after the short ones were filled; "
                      "long_gap_policy='split' keeps the longest contiguous segment" if after_fill is not None else
                      "gap_policy='fill' fills short gaps, 'split' keeps the longest contiguous segment")
            raise DataError(
                f"{where}: timestamp gap of {describe(int(gaps[0]))} in {tname}, expected "
                f"{1.0 / float(rate_hz if rate_hz is not None else rate if rate is not None else nominal_rate):.6g} s "
                f"(at most {gap_factor:g} x); {gaps.size} gap(s) in all, {remedy}"
            )
    bounds = [0, *(int(i) + 1 for i in gaps), n]
    segments = [Segment(a, b, float(t[a]), float(t[b - 1])) for a, b in itertools.pairwise(bounds)]
    longest = max(segments, key=lambda s: s.n)
    if gaps.size:
        listed = "; ".join(describe(int(i)) for i in gaps[:5]) + ("; ..." if gaps.size > 5 else "")
        warnings.warn(
            f"{where}: {gaps.size} timestamp gap(s) (interval > {gap_factor:g} x {nominal:.6g} s): {listed}. "
            f"Kept the longest of {len(segments)} segments: rows {longest.start}..{longest.stop - 1} "
            f"({longest.n} samples)",
            GapWarning,
            stacklevel=3,
        )
    if rate is None:
        rate = snap_rate(mean_rate)
    return segments, rate


def _check_sheet_rate(t, rate_hz, rtol, gap_factor, tname, where, time_unit=None) -> None:
    """The sheet's `rate_hz` (Hz) must agree within `rtol` (relative) with the timestamps' mean rate.

    When another time unit (s, ms, us, ns) makes them agree (:func:`imupipe.readers.timeunit.infer_time_unit`
    on the stamps' interval in the unit they were read in, `time_unit`; None: not known), the message names
    ``time_unit`` and that unit instead of asking to correct ``rate_hz``.

    The mean rate is found as when ``rate_hz`` is empty (:func:`_nominal_rate` without a rate: gaps
    against the median interval, then the mean over the gap-free intervals), not against the sheet's
    rate: a 100 Hz record stated as 200 Hz would otherwise have every interval a gap (and
    ``gap_policy="fill"`` would insert a sample in each).
    """
    _, mean_rate = _nominal_rate(t, None, gap_factor)
    if abs(mean_rate - rate_hz) > rtol * rate_hz:
        from imupipe.readers.timeunit import infer_time_unit

        factor = rate_hz / mean_rate  # the stamps' interval is `factor` x what the unit read says
        if time_unit is not None:
            try:
                unit, _ = infer_time_unit(1.0 / (mean_rate * _time_factor(time_unit, where)), rate_hz, rtol=rtol)
            except DataError:
                unit = None
            if unit is not None:
                raise DataError(
                    f"{where}: rate_hz = {rate_hz:g} Hz but the timestamps ({tname}) read as {time_unit} give a mean "
                    f"rate of {mean_rate:.6g} Hz ({factor:.6g}x off); read as {unit} they give {rate_hz:g} Hz: the "
                    f"time column counts {unit}, set time_unit: {unit} (rate_hz is right)"
                )
        raise DataError(
            f"{where}: rate_hz = {rate_hz:g} Hz but the timestamps ({tname}) give a mean rate of {mean_rate:.6g} Hz "
            f"(mean interval {1.0 / mean_rate:.6g} s over the gap-free intervals, the rule used when rate_hz is "
            f"empty); expected agreement within {rtol:g} relative (rate_rtol). The sheet's rate and the timestamps "
            "disagree: correct rate_hz, or leave it empty to take the rate from the timestamps"
        )


def _stamp(t) -> str:
    """A timestamp (s) for a message, with the digits that tell neighbouring stamps apart at epoch scale
    (1.70000187e+09 s at 9 digits hid the 10 ms between two rows)."""
    return f"{float(t):.15g}"


def _check_increasing(t, tname, where, row_text, i: int, why: str = "") -> None:
    """Time must increase strictly: refuses interval `i` (<= 0: a duplicate or a step back that
    :func:`_order_stamps` does not read as jitter), naming both rows and `why`."""
    if interval(t, i) == 0:
        raise DataError(
            f"{where}: duplicate timestamp in {tname}: {row_text(i)} and {row_text(i + 1)} both have "
            f"t = {_stamp(t[i])} s ({count_zero(t)} duplicates in all){why}"
        )
    raise DataError(
        f"{where}: time in {tname} is not increasing: t = {_stamp(t[i + 1])} s at {row_text(i + 1)} comes "
        f"after t = {_stamp(t[i])} s at {row_text(i)} ({t[i] - t[i + 1]:.6g} s back){why}"
    )


#: Robust sds of the stamps' own jitter about their sample grid within which a stamp that steps back (or repeats
#: its neighbour) is read as jitter (:func:`_order_stamps`).
STEP_BACK_SDS = 6.0


def _grid_residual(t: np.ndarray, j: int, period: float, skip: tuple[int, ...] = (),
                   stamps: int = GAP_PHASE_STAMPS) -> float:
    r"""How late stamp `j` sits (s) on the sample grid of its neighbours:
    :math:`t_j - \operatorname{med}_k (t_k + (j - k) T)` over up to `stamps` stamps on each side, `j` and `skip`
    left out."""
    k = np.arange(max(0, j - stamps), min(len(t), j + stamps + 1))
    k = k[~np.isin(k, (j, *skip))]
    return float(t[j] - np.median(t[k] + (j - k) * period))


def _order_stamps(raw: _Raw, where, row_text) -> None:
    r"""Stamps that step back (or repeat) within the stamps' own jitter are set to their grid times; any other
    interval <= 0 is refused (:func:`_check_increasing`). Warns (:class:`GapWarning`) of those read as jitter.

    An interval :math:`t_i \to t_{i+1}` of at most 0 is jitter when both its stamps lie within
    :math:`6\,\hat\sigma` of the grid their 8 neighbours on each side give (:func:`_grid_residual`,
    :math:`\hat\sigma` the robust sd of that residual over up to 2000 stamps, T the median interval) and the stamps
    after it sit no earlier on the grid than those before (:func:`grid_shift` above -1/2, or above -4 of its robust
    sds where the stamps jitter more, as :func:`_gap_mask` reads a gap; a later grid is a gap beside it, which the
    gap search finds). Stamp jitter of rms :math:`\sigma` makes an interval <= 0 wherever two neighbours' errors
    differ by a period (Gaussian jitter of 0.15 T: about once in 2 h at 10 Hz; beyond 6 sds: one stamp in 5e8). Two rows swapped on a clean clock (each a
    period off, :math:`\hat\sigma` 0), a repeated row (the stamps after it a period early) or a clock set back
    stay errors. The stamps are only read for the rate and the gaps: the samples the record holds do not change.
    """
    t = raw.time
    bad = nonpositive(t)
    if not bad.size:
        return
    n = len(t)
    period = float(np.median(intervals(t, np.linspace(0, n - 2, min(100_000, n - 1)).astype(np.int64))))
    if not period > 0 or n < 2 * GAP_PHASE_STAMPS + 2 or bad.size > 0.01 * n:
        _check_increasing(t, raw.time_name, where, row_text, int(bad[0]))
    sample = np.setdiff1d(np.linspace(0, n - 1, min(2000, n)).astype(np.int64), np.concatenate([bad, bad + 1]))
    sd = _robust_sd(np.array([_grid_residual(t, int(j), period) for j in sample]))
    limit = STEP_BACK_SDS * sd
    ordinary = np.setdiff1d(sample[:-1], np.concatenate([bad - 1, bad, bad + 1]))
    shift_limit = max(0.5, GAP_SHIFT_SDS * _robust_sd(grid_shift(t, ordinary, period)))  # as _gap_mask's
    if not t.flags.writeable:
        t = raw.time = t.copy()
    read: dict[int, float] = {}
    for _ in range(4):  # a stamp set to its grid time may now sit before a jittered neighbour: another pass
        for i in (int(i) for i in bad):
            if t[i + 1] > t[i]:
                continue  # an earlier repair set it right
            late = np.array([_grid_residual(t, i, period, (i + 1,)), _grid_residual(t, i + 1, period, (i,))])
            shift, off = float(grid_shift(t, np.array([i]), period)[0]), float(np.max(np.abs(late)))
            if shift <= -shift_limit:  # later: a gap beside it, which the gap search then finds
                _check_increasing(t, raw.time_name, where, row_text, i, (
                    f"; the stamps after it sit {-shift:.2f} periods earlier on the sample grid than those before (a "
                    "clock set back, or rows repeated or out of order)"))
            if off >= limit:
                _check_increasing(t, raw.time_name, where, row_text, i, (
                    f"; not read as stamp jitter: a stamp {off / period:.2g} periods off the grid its neighbours "
                    f"give, the stamps' own jitter {sd / period:.2g} periods sd"))
            read.setdefault(i, float(t[i] - t[i + 1]))
            t[[i, i + 1]] -= late
        bad = nonpositive(t)
        if not bad.size:
            break
    if bad.size:
        _check_increasing(t, raw.time_name, where, row_text, int(bad[0]),
                          "; at their grid times the stamps would still not increase")
    if read:
        i, back = next(iter(read.items()))
        warnings.warn(f"{where}: {len(read)} timestamp(s) in {raw.time_name} step back or repeat within the stamps' "
                      f"jitter (sd {sd / period:.2g} periods): read at their grid times, the samples kept; the first "
                      f"at {row_text(i + 1)}, {back:.6g} s back", GapWarning, stacklevel=4)


@dataclass(frozen=True)
class FilledGap:
    """A timestamp gap filled by ``gap_policy="fill"``.

    Attributes
    ----------
    row : int
        0-based row (in the file) of the last sample before the gap.
    n_missing : int
        Samples inserted, ``round(dt * rate) - 1``.
    t_start, dt_s : float
        File time (s) of that sample and the gap's interval (s).
    """

    row: int
    n_missing: int
    t_start: float
    dt_s: float


def _fill_gaps(raw: _Raw, rate, rate_hz, rtol, gap_factor, max_missing, max_fraction, where, row_text,
               time_unit=None):
    """Fill gaps of at most `max_missing` samples by linear interpolation; return (filled gaps, row map), the
    row map (a function) None when no gap is filled.

    The sheet's `rate_hz` (when given) is first checked against the timestamps (:func:`_check_sheet_rate`),
    and the samples inserted in all may be at most `max_fraction` of the file's samples
    (``fill_max_fraction``), else :class:`DataError`.

    Method: the k missing samples of a gap between rows i and i+1 are placed at t_i + j dt/(k+1),
    j = 1..k, with values on the straight line between samples i and i+1 (every channel). Longer gaps
    are left for the long-gap policy. The row map gives, for each row of the filled record, its 0-based
    row in the file (-1 for an inserted sample). The timestamps and channels grow in place where they own
    their memory (:func:`_insert_filled`): no second record-length array.
    """
    _order_stamps(raw, where, row_text)
    t = raw.time
    if rate_hz is not None:
        _check_sheet_rate(t, rate_hz, rtol, gap_factor, raw.time_name, where, time_unit)
    nominal_rate, _ = _nominal_rate(t, rate, gap_factor)
    gaps, missing = _find_gaps(t, 1.0 / nominal_rate, gap_factor, where)
    gap_dt = intervals(t, gaps)  # s
    fill = missing <= max_missing
    gaps, gap_dt, missing = gaps[fill], gap_dt[fill], missing[fill]
    inserted = int(missing.sum())
    if inserted > max_fraction * len(t):
        raise DataError(
            f"{where}: gap_policy fill would insert {inserted} samples in {gaps.size} gap(s), "
            f"{inserted / len(t):.3g} of the file's {len(t)} samples; at most fill_max_fraction = {max_fraction:g} "
            f"may be made up. Check the timestamps and rate_hz, or raise fill_max_fraction (sheet column) knowingly"
        )
    if not gaps.size:
        return (), None
    filled = tuple(FilledGap(int(i), int(k), float(t[i]), float(d)) for i, k, d in zip(gaps, missing, gap_dt))
    grown: dict[int, np.ndarray] = {}  # one growth per array object

    def grow(x: np.ndarray) -> np.ndarray:
        if id(x) not in grown:
            grown[id(x)] = _insert_filled(x, gaps, missing)
        return grown[id(x)]

    raw.time = grow(t)
    del t
    raw.data = {key: grow(x) for key, x in raw.data.items()}
    return filled, _filled_row_map(gaps, missing)


#: Samples moved per step when a record grows in place (:func:`_insert_filled`).
MOVE_BLOCK = 1 << 16


def _insert_filled(x: np.ndarray, gaps: np.ndarray, missing: np.ndarray) -> np.ndarray:
    """`x` with ``missing[g]`` samples inserted after row ``gaps[g]`` (ascending), on the straight line between
    ``x[i]`` and ``x[i+1]`` at the fractional rows ``i + j / (k + 1)``, j = 1..k.

    Equal to the last bit to ``np.interp(pos, np.arange(n, dtype=float), x)`` over the positions ``pos`` of the
    whole filled record (a file row at its own integer position gives ``x[i]`` itself; an inserted sample is
    interpolated between the same two neighbours and positions), without ``pos`` and a second record: an
    array owning its memory is resized in place and its rows moved to their new places from the end,
    :data:`MOVE_BLOCK` samples at a time; any other array (a view) is copied into a new one.
    """
    n = len(x)
    total = n + int(missing.sum())
    ends = np.stack([x[gaps], x[gaps + 1]], axis=1)  # each gap's two neighbours, before anything moves
    if x.dtype == np.float64 and x.flags.owndata and x.base is None and x.flags.c_contiguous and x.flags.writeable:
        x.resize(total, refcheck=False)  # the caller holds no view of x
        out, src = x, x
    else:
        out, src = np.empty(total, dtype=np.float64), x
    shift = total - n  # samples inserted before the rows being placed
    stop = n
    for g in range(len(gaps) - 1, -1, -1):
        i, k = int(gaps[g]), int(missing[g])
        _move(out, src, i + 1, stop, shift)
        shift -= k
        pos = i + np.arange(1, k + 1) / (k + 1)
        out[i + 1 + shift : i + 1 + shift + k] = np.interp(pos, np.array([i, i + 1], dtype=np.float64), ends[g])
        stop = i + 1
    _move(out, src, 0, stop, 0)
    return out


def _move(out: np.ndarray, src: np.ndarray, a: int, b: int, shift: int) -> None:
    """``out[a + shift : b + shift] = src[a:b]``, blocks from the end first (so that moving rows to the right
    within one array never overwrites a row not yet moved)."""
    if out is src and shift == 0:
        return
    for c in range(b, a, -MOVE_BLOCK):
        lo = max(a, c - MOVE_BLOCK)
        out[lo + shift : c + shift] = src[lo:c]


def _filled_row_map(gaps: np.ndarray, missing: np.ndarray) -> Callable[[int], int]:
    """Row of the filled record -> 0-based file row, -1 for an inserted sample."""
    after = np.cumsum(missing)  # samples inserted up to and including gap g
    starts = gaps + 1 + after - missing  # filled row of each gap's first inserted sample

    def file_row(row: int) -> int:
        g = int(np.searchsorted(starts, row, side="right")) - 1
        if g < 0:
            return int(row)
        if row < starts[g] + missing[g]:
            return -1
        return int(row - after[g])

    return file_row


def read_channel(key: Key | str, path: str | Path, format: str = "auto", **kwargs: Any) -> Recording:
    """Read one channel of a record (for ingest with a memory peak of about one channel).

    Reads only the file column that body channel `key` comes from (through the axis map) and returns
    a :class:`Recording` holding that channel alone, with the same checks as :func:`read_dataset`.
    Memory per format: netCDF reads one variable; ``.npy`` is memory-mapped and copies one column; ``.npz``
    decompresses one named array (the whole 2-D array when ``variable`` is given); text files, R files and
    bags are parsed whole (their layout has no per-column access), so for them reading all channels at
    once with :func:`read_dataset` is cheaper.

    Parameters
    ----------
    key : (sensor, axis) or "sensor_axis"
        Body channel, e.g. ``("gyro", "x")``.
    path, format, **kwargs
        As :func:`read_dataset` (``channels``, ``units``, ``axis_map``, ``time_column``, ...).

    Returns
    -------
    Recording
        One channel, in SI, after the axis map's sign.
    """
    sensor, _, axis = key.partition("_") if isinstance(key, str) else (key[0], "_", key[1])
    if sensor not in SENSORS or axis not in AXES:
        raise DataError(f"channel {key!r}: expected (sensor, axis) with sensor in {SENSORS}, axis in {AXES}")
    path = Path(path)
    fmt = _format_of(path, format)
    amap = parse_axis_map(kwargs.pop("axis_map", None))
    sign, src = amap[axis]
    specs = _normalise_channels(kwargs.pop("channels", None))
    if specs is None:
        spec = _ROS_FIELDS[(sensor, src)] if fmt == "rosbag" else f"{sensor}_{src}"
    elif (sensor, src) in specs:
        spec = specs[(sensor, src)]
    else:
        raise DataError(f"{path}: {sensor}_{src} (body {sensor}_{axis} via the axis map) not given in the channels")
    rec = read_dataset(path, fmt, channels={(sensor, src): spec}, **kwargs)
    x = rec.channels[(sensor, src)]
    k = (sensor, axis)
    return dataclasses.replace(
        rec,
        channels={k: -x if sign < 0 else x},
        units={k: rec.units[(sensor, src)]},
        file_units={k: rec.file_units[(sensor, src)]},
        columns={k: ("-" if sign < 0 else "") + rec.columns[(sensor, src)]},
        _full={k: -v if sign < 0 else v for v in rec._full.values()} if rec._full else {},
    )


def missing_channel_columns(row: Mapping[str, Any], sensors: tuple[str, ...] | list[str] = SENSORS) -> list[str]:
    """Sheet columns ``{sensor}_{axis}`` a row must fill for `sensors`, given the format's defaults.

    A ROS bag / MCAP row may leave all six empty (``sensor_msgs/Imu`` has them: ``angular_velocity.x`` ...);
    a row of another format may leave all of a sensor's empty when the file has columns named
    ``gyro_x`` ... (checked when the file is read). A sensor given partly is missing the empty ones.

    Parameters
    ----------
    row : mapping
        One dataset-sheet row.
    sensors : sequence of str
        Sensors the config processes. Defaults to both.

    Returns
    -------
    list of str
        Column names to fill (empty: nothing missing).
    """
    r = {k: _cell(v) for k, v in row.items()}
    missing = []
    for sensor in sensors:
        cols = [f"{sensor}_{a}" for a in AXES]
        given = [c for c in cols if r.get(c) is not None]
        if given and len(given) != len(cols):
            missing += [c for c in cols if c not in given]
    return missing
