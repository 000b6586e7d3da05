"""The reader: one record from any format, converted to SI and validated."""

from __future__ import annotations

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
from imupipe.readers._common import _Raw, _blank, _chname, _default_specs, _resolve, _time_factor, Key, _SI_UNITS, _cell, _example_unit, _normalise_channels, _normalise_units, _unit_factor, _EXTENSIONS


from imupipe.readers.arrays import _load_npy, _load_npz
from imupipe.readers.netcdf import _load_netcdf
from imupipe.readers.rdata import _load_rdata
from imupipe.readers.rosbag import _load_rosbag
from imupipe.readers.text import _load_text


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
    return kwargs


def read_dataset_row(
    row: Mapping[str, Any], *, base_dir: str | Path | None = None, min_duration_s: float | None = None
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

    Returns
    -------
    Recording
        The channels in SI units, as :func:`read_dataset` returns them.
    """
    return read_dataset(**sheet_row_to_kwargs(row, base_dir), min_duration_s=min_duration_s)


def read_dataset(
    path: str | Path,
    format: str = "auto",
    rate_hz: float | None = None,
    channels: Mapping[Any, Any] | None = None,
    units: Mapping[Any, Any] | None = None,
    *,
    time_column: str | int | None = None,
    time_unit: str | None = None,
    delimiter: str | None = None,
    variable: str | None = None,
    topic: str | None = None,
    axis_map: str | Mapping[str, str] | None = None,
    gap_policy: str = "fail",
    min_duration_s: float | None = None,
    rate_rtol: float = 0.01,
    gap_factor: float = 1.5,
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
        also accepted). Gyro units: rad/s, mrad/s, rad/h, deg/s, mdeg/s, deg/min, deg/h; accel
        units: m/s^2, mm/s^2, g, mg, ug (``g`` = 9.80665 m/s^2). Defaults to None: the netCDF
        ``units`` attribute, SI for ROS bags, an error otherwise.
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
    gap_policy : {"fail", "split"}, optional
        What a timestamp gap does: ``"fail"`` raises :class:`DataError` naming the first gap;
        ``"split"`` keeps the longest contiguous segment in ``channels``, lists every segment in
        ``Recording.segments`` (data via ``Recording.segment(i)``) and warns (:class:`GapWarning`)
        naming the gaps. Duplicated or decreasing timestamps are always an error. Defaults to ``"fail"``.
    min_duration_s : float, optional
        Shortest usable record (s), e.g. ``2 * tau_max`` for the largest Allan tau or the PSD
        window length; the (selected) record must last at least this long (``n / rate_hz``).
        Defaults to None (no check).
    rate_rtol : float, optional
        Relative tolerance between the sheet's rate and the file's or timestamps' rate.
        Defaults to 0.01 (1 %).
    gap_factor : float, optional
        A timestamp interval longer than ``gap_factor / rate_hz`` is a gap. Defaults to 1.5.

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
    if gap_policy not in GAP_POLICIES:
        raise DataError(f"{where}: gap_policy {gap_policy!r} not one of {GAP_POLICIES}")
    if rate_hz is not None and not (np.isfinite(rate_hz) and rate_hz > 0):
        raise DataError(f"{where}: rate_hz = {rate_hz!r}; expected a positive number of Hz")
    if min_duration_s is not None and not (min_duration_s >= 0):
        raise DataError(f"{where}: min_duration_s = {min_duration_s!r}; expected a non-negative number of s")
    if not path.exists():
        raise DataError(f"{where}: file not found")
    if path.is_dir() and fmt != "rosbag":
        raise DataError(f"{where}: is a directory, not a {fmt} file")
    specs = _normalise_channels(channels)
    if specs is not None and not specs:
        raise DataError(f"{where}: no channel given (all of gyro_x ... accel_z are empty)")
    sheet_units = _normalise_units(units)
    amap = parse_axis_map(axis_map)
    if specs is not None:  # units known from the sheet are checked before reading a large file
        for key in specs:
            if sheet_units.get(key) is not None:
                _unit_factor(sheet_units[key], key[0], f"{where}: {key[0]}_unit")

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

    def row_text(row: int) -> str:
        text = f"row {row} (0-based)"
        if raw.line_of_row is not None:
            text += f", line {raw.line_of_row(row)}"
        return text

    # --- samples ---------------------------------------------------------------------------
    lengths = {len(v) for v in raw.data.values()} | ({len(raw.time)} if raw.time is not None else set())
    if len(lengths) != 1:
        detail = ", ".join(f"{_chname(k)}: {len(v)}" for k, v in raw.data.items())
        raise DataError(f"{where}: channels differ in length ({detail})")
    n = lengths.pop()
    if n == 0:
        raise DataError(f"{where}: no samples")
    for key, x in raw.data.items():
        finite = np.isfinite(x)
        if not finite.all():
            row = int(np.argmin(finite))
            raise DataError(
                f"{where}: {_chname(key)} (column {raw.names[key]}) has a non-finite sample ({float(x[row])}) at "
                f"{row_text(row)}; {int(np.count_nonzero(~finite))} in all"
            )

    # --- rate and timestamps -----------------------------------------------------------------
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
    if raw.time is not None:
        segments, rate = _check_time(raw, rate, rate_hz, gap_policy, rate_rtol, gap_factor, where, row_text)
    if rate is None:
        raise DataError(f"{where}: sample rate unknown: give rate_hz (no timestamps and no rate in the file)")
    selected = max(range(len(segments)), key=lambda i: segments[i].n)
    seg = segments[selected]

    # --- duration and constant channels --------------------------------------------------------
    duration = seg.n / rate
    if min_duration_s is not None and duration < min_duration_s:
        part = "longest contiguous segment" if len(segments) > 1 else "record"
        raise DataError(
            f"{where}: {part} lasts {duration:.6g} s ({seg.n} samples at {rate:g} Hz), shorter than the "
            f"{min_duration_s:g} s needed (min_duration_s)"
        )
    for key, x in raw.data.items():
        part = x[seg.start : seg.stop]
        if part.size and part.min() == part.max():
            raise DataError(
                f"{where}: {_chname(key)} (column {raw.names[key]}) is constant ({part[0]:g} in all {part.size} "
                "samples): a dead or saturated channel, or the wrong column"
            )

    # --- units, SI, axis map -----------------------------------------------------------------
    si: dict[Key, np.ndarray] = {}
    file_units: dict[Key, str] = {}
    for key, x in raw.data.items():
        sensor = key[0]
        unit = sheet_units.get(key)
        origin = f"{where}: {sensor}_unit"
        if unit is None:
            unit = raw.file_units.get(key) or raw.default_units.get(sensor)
            origin = f"{where}: {_chname(key)} unit (from the file)"
            if unit is None:
                raise DataError(
                    f"{where}: {sensor}_unit missing for {_chname(key)} (the file does not say); "
                    f"expected e.g. {_SI_UNITS[sensor]!r} or {_example_unit(sensor)!r}"
                )
        elif raw.file_units.get(key):
            try:
                stored = _unit_factor(raw.file_units[key], sensor, origin)
            except DataError:
                stored = None
            if stored is not None and not math.isclose(
                stored, _unit_factor(unit, sensor, origin), rel_tol=1e-9
            ):
                raise DataError(
                    f"{where}: {sensor}_unit = {unit!r} in the sheet but variable {raw.names[key]} "
                    f"has units {raw.file_units[key]!r}"
                )
        factor = _unit_factor(unit, sensor, origin)
        # x * factor is a new array; in SI already, a fresh array is kept as it is and only a read-only view
        # (a .npy opened as a memory map) is copied (a 36 MB copy costs ~50 ms, mostly page faults)
        si[key] = x * factor if factor != 1.0 else (x if x.flags.writeable else np.array(x, dtype=np.float64))
        file_units[key] = unit

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
    keys = [(s, a) for s in SENSORS for a in AXES if (s, a) in mapped]
    full = {k: mapped[k] for k in keys}
    if len(segments) > 1:
        chans = {k: v[seg.start : seg.stop] for k, v in full.items()}
    else:
        chans, full = full, {}
    detail = raw.detail or (f"variable {variable!r}" if fmt in ("npz", "netcdf") and variable else "")
    source = f"{where} ({fmt}{', ' + detail if detail else ''})"
    return Recording(
        channels=chans,
        rate_hz=float(rate),
        source=source,
        units={k: _SI_UNITS[k[0]] for k in keys},
        file_units={k: mapped_units[k] for k in keys},
        columns={k: columns[k] for k in keys},
        segments=tuple(segments),
        selected=selected,
        _full=full,
    )


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


def _check_time(raw: _Raw, rate, rate_hz, gap_policy, rtol, gap_factor, where, row_text):
    """Check timestamps; return (segments, rate in Hz)."""
    t = raw.time
    tname = raw.time_name
    finite = np.isfinite(t)
    if not finite.all():
        row = int(np.argmin(finite))
        raise DataError(
            f"{where}: time column {tname} has a non-finite value ({float(t[row])}) at {row_text(row)}"
        )
    n = len(t)
    if n < 2:
        return [Segment(0, n, float(t[0]), float(t[0]))], rate
    dt = np.diff(t)
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        i = int(bad[0])
        if dt[i] == 0:
            raise DataError(
                f"{where}: duplicate timestamp in {tname}: {row_text(i)} and {row_text(i + 1)} both have t = {float(t[i]):.9g} s "
                f"({int(np.count_nonzero(dt == 0))} duplicates in all)"
            )
        raise DataError(
            f"{where}: time in {tname} is not increasing: t = {float(t[i + 1]):.9g} s at {row_text(i + 1)} comes after "
            f"t = {float(t[i]):.9g} s at {row_text(i)}"
        )
    median_rate = 1.0 / float(np.median(dt))
    if rate_hz is not None and abs(median_rate - rate_hz) > rtol * rate_hz:
        raise DataError(
            f"{where}: rate_hz = {rate_hz:g} Hz in the sheet but the timestamps ({tname}) give {median_rate:.6g} Hz "
            f"(median interval {1.0 / median_rate:.6g} s)"
        )
    if rate is not None and rate_hz is None and abs(median_rate - rate) > rtol * rate:
        raise DataError(
            f"{where}: the file says {rate:g} Hz ({raw.file_rate_from}) but the timestamps ({tname}) "
            f"give {median_rate:.6g} Hz"
        )
    nominal = 1.0 / (rate if rate is not None else median_rate)
    gaps = np.flatnonzero(dt > gap_factor * nominal)
    if gaps.size:

        def describe(i: int) -> str:
            return (
                f"{dt[i]:.6g} s between {row_text(int(i))} (t = {t[i]:.9g} s) and {row_text(int(i) + 1)} "
                f"(t = {t[i + 1]:.9g} s)"
            )

        if gap_policy == "fail":
            raise DataError(
                f"{where}: timestamp gap of {describe(int(gaps[0]))}, expected {nominal:.6g} s "
                f"({gaps.size} gap(s) in all; gap_policy='split' keeps the longest contiguous segment)"
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
    if longest.n > 1:
        mean_rate = (longest.n - 1) / (longest.t_stop - longest.t_start)
        reference = rate_hz if rate_hz is not None else rate
        if reference is not None and abs(mean_rate - reference) > rtol * reference:
            raise DataError(
                f"{where}: rate_hz = {reference:g} Hz but the timestamps ({tname}) give a mean rate of "
                f"{mean_rate:.6g} Hz over rows {longest.start}..{longest.stop - 1}"
            )
        if rate is None:
            rate = mean_rate
    return segments, rate

