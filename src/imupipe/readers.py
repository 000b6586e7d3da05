"""Read a static IMU record from a file into SI arrays, with checks that name the culprit.

One entry point, :func:`read_dataset`, reads the gyro and/or accelerometer channels of one
recording from any of the supported formats, converts them once to SI (gyro rad/s, accel m/s^2),
applies an optional axis/sign map and validates the record: missing or empty file, truncated
rows, unknown columns, NaN/inf samples, timestamps (gaps, duplicates, non-monotonic, rate
disagreeing with the sheet), a record too short for the requested analysis, constant channels
and unknown units. Every failure raises :class:`DataError` with the file, the channel or column,
the row (and for text files the line) and what was expected.

Supported formats (``format`` argument; ``"auto"`` picks by file extension):

========  ==========================  ==============================================================
format    extensions                  channels are ...
========  ==========================  ==============================================================
csv       .csv .txt .tsv .dat         column names of the header line, or 0-based column indices
netcdf    .nc .nc4 .cdf               names of 1-D variables, or indices into the 2-D ``variable``
npy       .npy                        0-based column indices of a 2-D array (field names if structured)
npz       .npz                        names of 1-D arrays, or indices into the 2-D array ``variable``
rdata     .rda .rdata .rds            column names of an R matrix / data.frame / named list
rosbag    .bag .mcap .db3, bag dir    ``sensor_msgs/Imu`` fields (default ``angular_velocity.x`` ...)
========  ==========================  ==============================================================

:func:`read_dataset_row` maps one row of the workflow's dataset sheet (``config/datasets.tsv``)
onto :func:`read_dataset`; :data:`SHEET_COLUMNS` documents the columns it reads.
"""

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

__all__ = [
    "AXES",
    "FORMATS",
    "GAP_POLICIES",
    "SENSORS",
    "SHEET_COLUMNS",
    "DataError",
    "GapWarning",
    "Recording",
    "Segment",
    "parse_axis_map",
    "read_dataset",
    "read_dataset_row",
    "sheet_row_to_kwargs",
]

SENSORS = ("gyro", "accel")
AXES = ("x", "y", "z")
GAP_POLICIES = ("fail", "split")

#: Accepted ``format`` values (and the sheet's ``format`` column) -> reader used.
FORMATS = {
    "auto": "auto",
    "csv": "csv",
    "txt": "csv",
    "tsv": "csv",
    "netcdf": "netcdf",
    "nc": "netcdf",
    "npy": "npy",
    "npz": "npz",
    "rda": "rdata",
    "rds": "rdata",
    "rdata": "rdata",
    "rosbag": "rosbag",
    "bag": "rosbag",
    "ros1": "rosbag",
    "ros2": "rosbag",
    "mcap": "rosbag",
}

_EXTENSIONS = {
    ".csv": "csv",
    ".txt": "csv",
    ".tsv": "csv",
    ".dat": "csv",
    ".nc": "netcdf",
    ".nc4": "netcdf",
    ".cdf": "netcdf",
    ".npy": "npy",
    ".npz": "npz",
    ".rda": "rdata",
    ".rdata": "rdata",
    ".rds": "rdata",
    ".bag": "rosbag",
    ".mcap": "rosbag",
    ".db3": "rosbag",
}

#: Columns of the dataset sheet read by :func:`read_dataset_row` (empty cell = not given).
SHEET_COLUMNS = {
    "dataset": "name of the dataset (wildcard value); not used by the reader",
    "path": "file (or rosbag2 directory), relative to the sheet's base directory",
    "format": f"one of {sorted(FORMATS)}; 'auto' or empty: by extension",
    "rate_hz": "nominal sample rate in Hz; may be empty when timestamps or the file give it",
    "gyro_unit": "unit of the gyro channels as stored: rad/s, deg/s, deg/h, ... (empty: from the file or SI)",
    "accel_unit": "unit of the accel channels as stored: m/s^2, g, mg, ... (empty: from the file or SI)",
    **{
        f"{s}_{a}": f"column / variable / field holding {s} {a} (name or 0-based index); empty: absent"
        for s in SENSORS
        for a in AXES
    },
    "time_column": "column / variable of timestamps (rosbag: 'header' (default) or 'bag'); empty: none",
    "time_unit": "unit of the time column: s (default), ms, us, ns",
    "delimiter": "text files: ',' or comma, tab, semicolon, space (runs of whitespace); empty: sniffed",
    "variable": "rda: object name; npz / netCDF: name of a 2-D array whose columns the channels index",
    "topic": "rosbag: topic of the sensor_msgs/Imu messages; empty: the only Imu topic",
    "axis_map": "body axis <- signed file axis, e.g. 'x:-y,y:x,z:z'; empty: identity",
    "gap_policy": "fail (default) or split (keep the longest contiguous segment, warn)",
}

_SI_UNITS = {"gyro": "rad/s", "accel": "m/s^2"}
_TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
_TIME_ALIASES = {  # CF / UDUNITS spellings of the same units
    **dict.fromkeys(("sec", "secs", "second", "seconds"), "s"),
    **dict.fromkeys(("msec", "msecs", "millisecond", "milliseconds"), "ms"),
    **dict.fromkeys(("µs", "usec", "usecs", "microsecond", "microseconds"), "us"),
    **dict.fromkeys(("nsec", "nsecs", "nanosecond", "nanoseconds"), "ns"),
}
_DELIMITERS = {
    "comma": ",",
    ",": ",",
    "tab": "\t",
    "\\t": "\t",
    "\t": "\t",
    "semicolon": ";",
    ";": ";",
    "pipe": "|",
    "|": "|",
    "space": None,
    "whitespace": None,
    " ": None,
}
_ROS_FIELDS = {("gyro", a): f"angular_velocity.{a}" for a in AXES} | {
    ("accel", a): f"linear_acceleration.{a}" for a in AXES
}

Key = tuple[str, str]


class DataError(ValueError):
    """An input record that cannot be used: the message names the file, channel, row or key."""


class GapWarning(UserWarning):
    """Timestamp gaps were found and ``gap_policy="split"`` kept the longest contiguous segment."""


@dataclass(frozen=True)
class Segment:
    """A contiguous stretch of samples (no timestamp gap) of a record.

    Attributes
    ----------
    start, stop : int
        0-based sample indices in the file, ``start`` inclusive, ``stop`` exclusive.
    t_start, t_stop : float or None
        File time (s) of the first and of the last sample; None without a time column.
    """

    start: int
    stop: int
    t_start: float | None = None
    t_stop: float | None = None

    @property
    def n(self) -> int:
        """Number of samples."""
        return self.stop - self.start


@dataclass(frozen=True, eq=False)
class Recording:
    """Channels of one IMU record in SI units, read and checked by :func:`read_dataset`.

    Behaves as a read-only mapping ``{(sensor, axis): ndarray}`` (sensor ``"gyro"`` or ``"accel"``,
    axis ``"x"``, ``"y"``, ``"z"``), each a 1-D float64 array in rad/s (gyro) or m/s^2 (accel),
    all of the same length.

    Attributes
    ----------
    channels : dict
        ``{(sensor, axis): ndarray}``, SI, after the axis map; the selected segment only.
    rate_hz : float
        Sample rate (Hz): the sheet's value, else the file's or the timestamps'.
    source : str
        Human-readable origin: path, format, object or topic.
    units : dict
        ``{(sensor, axis): "rad/s" | "m/s^2"}``.
    file_units : dict
        ``{(sensor, axis): unit}`` as stored in the file (before conversion).
    columns : dict
        ``{(sensor, axis): description}`` of the file column each channel comes from, with the sign
        of the axis map, e.g. ``"-'Gyro. Y'"``.
    segments : tuple of Segment
        All contiguous segments of the record (one unless ``gap_policy="split"`` found gaps).
    selected : int
        Index in ``segments`` of the segment held in ``channels`` (the longest).
    """

    channels: dict[Key, np.ndarray]
    rate_hz: float
    source: str
    units: dict[Key, str]
    file_units: dict[Key, str]
    columns: dict[Key, str]
    segments: tuple[Segment, ...]
    selected: int = 0
    _full: dict[Key, np.ndarray] = field(default_factory=dict, repr=False)

    def __getitem__(self, key: Key) -> np.ndarray:
        return self.channels[key]

    def __iter__(self) -> Iterator[Key]:
        return iter(self.channels)

    def __len__(self) -> int:
        return len(self.channels)

    def __contains__(self, key: object) -> bool:
        return key in self.channels

    def keys(self):
        """Channel keys ``(sensor, axis)``."""
        return self.channels.keys()

    def values(self):
        """Channel arrays (SI)."""
        return self.channels.values()

    def items(self):
        """``((sensor, axis), array)`` pairs."""
        return self.channels.items()

    @property
    def sensors(self) -> tuple[str, ...]:
        """Sensors present, in the order ``gyro``, ``accel``."""
        return tuple(s for s in SENSORS if any(k[0] == s for k in self.channels))

    @property
    def n_samples(self) -> int:
        """Number of samples per channel in ``channels``."""
        return len(next(iter(self.channels.values())))

    @property
    def duration_s(self) -> float:
        """Duration (s) of ``channels``: ``n_samples / rate_hz``."""
        return self.n_samples / self.rate_hz

    def segment(self, index: int) -> dict[Key, np.ndarray]:
        """Return the channels of one contiguous segment.

        Parameters
        ----------
        index : int
            Index into ``segments``.

        Returns
        -------
        dict
            ``{(sensor, axis): ndarray}`` in SI units (rad/s, m/s^2): views into the full record.
        """
        seg = self.segments[index]
        if not self._full:
            return dict(self.channels)
        return {k: v[seg.start : seg.stop] for k, v in self._full.items()}


# ----------------------------------------------------------------------------------------------
# sheet row -> keyword arguments
# ----------------------------------------------------------------------------------------------
def _blank(value: Any) -> bool:
    if value is None:
        return True
    if isinstance(value, float) and math.isnan(value):
        return True
    return isinstance(value, str) and value.strip() == ""


def _cell(value: Any) -> Any:
    """Normalise one sheet cell: blank -> None, integral float -> int, strings stripped."""
    if _blank(value):
        return None
    if isinstance(value, str):
        return value.strip()
    if isinstance(value, (float, np.floating)) and float(value).is_integer():
        return int(value)
    if isinstance(value, np.integer):
        return int(value)
    return value


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


# ----------------------------------------------------------------------------------------------
# units, axis map, channel specifications
# ----------------------------------------------------------------------------------------------
_G0 = 9.80665  # standard gravity, m/s^2 (CGPM 1901)
_LOCAL_UNITS = {
    "gyro": {
        "rad/s": 1.0,
        "mrad/s": 1e-3,
        "rad/h": 1.0 / 3600.0,
        "deg/s": math.pi / 180.0,
        "mdeg/s": math.pi / 180.0e3,
        "deg/min": math.pi / 180.0 / 60.0,
        "deg/h": math.pi / 180.0 / 3600.0,
    },
    "accel": {
        "m/s^2": 1.0,
        "mm/s^2": 1e-3,
        "g": _G0,
        "mg": _G0 * 1e-3,
        "ug": _G0 * 1e-6,
    },
}
_UNIT_ALIASES = {
    "rad/sec": "rad/s",
    "rad s-1": "rad/s",
    "rad s^-1": "rad/s",
    "rad/hr": "rad/h",
    "dps": "deg/s",
    "°/s": "deg/s",
    "deg/sec": "deg/s",
    "deg s-1": "deg/s",
    "deg s^-1": "deg/s",
    "°/h": "deg/h",
    "deg/hr": "deg/h",
    "dph": "deg/h",
    "°/min": "deg/min",
    "m/s2": "m/s^2",
    "m/s/s": "m/s^2",
    "m s-2": "m/s^2",
    "m s^-2": "m/s^2",
    "m/s**2": "m/s^2",
    "mm/s2": "mm/s^2",
    "µg": "ug",
    "micro-g": "ug",
    "milli-g": "mg",
    "g0": "g",
}


def _unit_factor(unit: Any, sensor: str, key: str) -> float:
    """SI factor of a gyro or accel ``unit`` (SI value = stored value * factor).

    Uses :func:`imupipe.units.to_si` where that module exists, else the local table (same units).
    """
    if _blank(unit):
        raise DataError(
            f"{key}: unit missing (expected e.g. {_SI_UNITS[sensor]!r} or {_example_unit(sensor)!r})"
        )
    text = str(unit).strip()
    try:
        from imupipe import units as _units  # the project's single unit table, when present
    except ImportError:
        _units = None
    if _units is not None:
        try:
            factor = float(_units.to_si(1.0, text, "rate", sensor, key))
        except (ValueError, KeyError, TypeError) as exc:
            raise DataError(f"{key}: unknown unit {text!r} for {sensor} ({exc})") from exc
        return factor
    norm = re.sub(r"\s+", " ", text).replace("⁻¹", "^-1").replace("⁻²", "^-2").replace("²", "^2")
    norm = _UNIT_ALIASES.get(norm, _UNIT_ALIASES.get(norm.lower(), norm))
    table = _LOCAL_UNITS[sensor]
    if norm in table:
        return table[norm]
    if norm.lower() in table:
        return table[norm.lower()]
    raise DataError(f"{key}: unknown unit {text!r} for {sensor}; known: {', '.join(table)}")


def _example_unit(sensor: str) -> str:
    return "deg/s" if sensor == "gyro" else "g"


def parse_axis_map(text: str | Mapping[str, str] | None) -> dict[str, tuple[int, str]]:
    """Parse an axis map ``"x:-y,y:x,z:z"`` into ``{body_axis: (sign, file_axis)}``.

    Each entry ``b:[+-]f`` says that body axis ``b`` is the file's axis ``f`` (from the sheet's
    ``{sensor}_{f}`` column), negated with ``-``. The map must be a permutation of x, y, z; it
    applies to both sensors.

    Parameters
    ----------
    text : str, mapping or None
        ``"x:-y,y:x,z:z"``, ``{"x": "-y", "y": "x", "z": "z"}``, or None / ``""`` for the identity.

    Returns
    -------
    dict
        ``{"x": (-1, "y"), "y": (1, "x"), "z": (1, "z")}``.
    """
    if _blank(text):
        return {a: (1, a) for a in AXES}
    if isinstance(text, Mapping):
        items = [(str(k).strip(), str(v).strip()) for k, v in text.items()]
    else:
        items = []
        for part in str(text).split(","):
            if not part.strip():
                continue
            if ":" not in part:
                raise DataError(f"axis_map {text!r}: entry {part.strip()!r} is not 'axis:[-]axis'")
            k, v = part.split(":", 1)
            items.append((k.strip(), v.strip()))
    result: dict[str, tuple[int, str]] = {}
    for k, v in items:
        sign = -1 if v.startswith("-") else 1
        src = v.lstrip("+-").strip()
        if k not in AXES or src not in AXES:
            raise DataError(f"axis_map {text!r}: {k}:{v} names an axis other than x, y, z")
        if k in result:
            raise DataError(f"axis_map {text!r}: body axis {k!r} given twice")
        result[k] = (sign, src)
    if set(result) != set(AXES) or sorted(s for _, s in result.values()) != list(AXES):
        raise DataError(f"axis_map {text!r}: must map each of x, y, z exactly once (a permutation)")
    return result


def _normalise_channels(channels: Mapping[Any, Any] | None) -> dict[Key, Any] | None:
    if channels is None:
        return None
    out: dict[Key, Any] = {}
    for key, spec in channels.items():
        if isinstance(key, str):
            sensor, _, axis = key.partition("_")
        else:
            sensor, axis = key
        if sensor not in SENSORS or axis not in AXES:
            raise DataError(
                f"channel key {key!r}: expected (sensor, axis) with sensor in {SENSORS}, axis in {AXES}"
            )
        spec = _cell(spec)
        if spec is not None:
            out[(sensor, axis)] = spec
    return out


def _normalise_units(units: Mapping[Any, Any] | None) -> dict[Key, str | None]:
    out: dict[Key, str | None] = {}
    for key, unit in (units or {}).items():
        if isinstance(key, str):
            sensor, _, axis = key.partition("_")
            axis = axis or None
        else:
            sensor, axis = key
        sensor = sensor.removesuffix("_unit")
        if sensor not in SENSORS:
            raise DataError(f"units key {key!r}: expected a sensor in {SENSORS}")
        for a in (axis,) if axis else AXES:
            out[(sensor, a)] = None if _blank(unit) else str(unit).strip()
    return out


def _resolve(spec: Any, names: list[str] | None, ncols: int, what: str, where: str) -> int:
    """Index of column ``spec`` (a name, or a 0-based index) among ``names`` (None: no names)."""
    if names is not None and isinstance(spec, str) and spec in names:
        return names.index(spec)
    is_int = isinstance(spec, (int, np.integer)) and not isinstance(spec, bool)
    is_digits = isinstance(spec, str) and re.fullmatch(r"\d+", spec.strip()) is not None
    index = int(spec) if is_int or is_digits else None
    if index is not None and 0 <= index < ncols:
        return index
    available = ", ".join(repr(n) for n in names) if names is not None else f"indices 0..{ncols - 1}"
    raise DataError(f"{where}: {what} column {spec!r} not found; available: {available}")


def _chname(key: Key) -> str:
    return f"{key[0]}_{key[1]}"


# ----------------------------------------------------------------------------------------------
# raw record from each format
# ----------------------------------------------------------------------------------------------
@dataclass
class _Raw:
    """What a format loader returns: channels in file units, optional time (s), metadata."""

    data: dict[Key, np.ndarray]
    names: dict[Key, str]
    time: np.ndarray | None = None
    time_name: str | None = None
    file_rate: float | None = None
    file_rate_from: str = ""
    file_units: dict[Key, str] = field(default_factory=dict)
    line_of_row: Callable[[int], int] | None = None  # text files: 1-based line of a 0-based row
    detail: str = ""  # for Recording.source: object, variable or topic read
    default_units: dict[str, str] = field(default_factory=dict)


def _time_factor(time_unit: Any, where: str) -> float:
    unit = "s" if _blank(time_unit) else str(time_unit).strip().lower()
    unit = _TIME_ALIASES.get(unit, unit)
    if unit not in _TIME_UNITS:
        raise DataError(f"{where}: unknown time_unit {time_unit!r}; known: s, ms, us, ns")
    return _TIME_UNITS[unit]


def _default_specs(available: list[str], where: str) -> dict[Key, str]:
    specs = {(s, a): f"{s}_{a}" for s in SENSORS for a in AXES if f"{s}_{a}" in available}
    if not specs:
        raise DataError(
            f"{where}: no channels given and no columns named gyro_x ... accel_z; "
            f"available: {', '.join(repr(n) for n in available)}"
        )
    return specs


# --- text ------------------------------------------------------------------------------------
def _is_number(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def _split(line: str, delimiter: str | None) -> list[str]:
    fields = line.split(delimiter) if delimiter is not None else line.split()
    return [f.strip().strip('"').strip("'").strip() for f in fields]


def _content_lines(path: Path, start_line: int) -> Iterator[tuple[int, str]]:
    """(1-based line number, text) of the non-blank, non-comment lines from ``start_line`` on."""
    with open(path, encoding="utf-8-sig", errors="replace", newline="") as fh:
        for number, line in enumerate(fh, start=1):
            if number < start_line:
                continue
            text = line.split("#", 1)[0]
            if text.strip():
                yield number, text.rstrip("\r\n")


def _load_text(path, specs, delimiter, time_column, time_unit, where) -> _Raw:
    if path.stat().st_size == 0:
        raise DataError(f"{where}: file is empty (0 bytes)")
    header_line = None
    header = ""
    for number, text in _content_lines(path, 1):
        header_line, header = number, text
        break
    if header_line is None:
        raise DataError(f"{where}: file holds no data (only blank or comment lines)")
    if delimiter is None:
        delim = "\t" if "\t" in header else "," if "," in header else ";" if ";" in header else None
    else:
        key = delimiter if delimiter in _DELIMITERS else str(delimiter).strip().lower()
        if key not in _DELIMITERS:
            raise DataError(f"{where}: unknown delimiter {delimiter!r}; use ',', tab, semicolon, space")
        delim = _DELIMITERS[key]
    tokens = _split(header, delim)
    has_header = not all(_is_number(t) for t in tokens)
    names = tokens if has_header else None
    ncols = len(tokens)
    first_data_line = header_line + 1 if has_header else header_line

    if specs is None:
        if names is None:
            raise DataError(
                f"{where}: no header line, so the channels must be given as 0-based column indices"
            )
        specs = _default_specs(names, where)
    cols = {k: _resolve(v, names, ncols, _chname(k), where) for k, v in specs.items()}
    tcol = None if _blank(time_column) else _resolve(time_column, names, ncols, "time", where)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # "Empty input file" from loadtxt: checked below
        try:
            table = np.loadtxt(
                path,
                delimiter=delim,
                comments="#",
                skiprows=first_data_line - 1,
                dtype=np.float64,
                ndmin=2,
                encoding="utf-8-sig",
                quotechar='"',
            )
        except ValueError as exc:
            _diagnose_text(path, first_data_line, delim, ncols, names, where)
            raise DataError(f"{where}: cannot parse the data rows ({exc})") from exc
    if table.shape[0] == 0:
        raise DataError(
            f"{where}: no data rows after line {first_data_line - 1} (header only or truncated file)"
        )
    if table.shape[1] != ncols:
        raise DataError(
            f"{where}: line {first_data_line}: data rows have {table.shape[1]} fields but the "
            f"{'header' if has_header else 'first row'} has {ncols}"
        )

    def line_of_row(row: int) -> int:
        for i, (number, _) in enumerate(_content_lines(path, first_data_line)):
            if i == row:
                return number
        return -1

    label = (lambda i: repr(names[i])) if names is not None else (lambda i: f"#{i}")
    time = None
    if tcol is not None:
        time = table[:, tcol] * _time_factor(time_unit, where)
    return _Raw(
        data={k: np.ascontiguousarray(table[:, i]) for k, i in cols.items()},
        names={k: label(i) for k, i in cols.items()},
        time=time,
        time_name=None if tcol is None else label(tcol),
        line_of_row=line_of_row,
    )


def _diagnose_text(path, first_line, delim, ncols, names, where) -> None:
    """Find the first malformed data line and raise a DataError naming it (else return)."""
    for number, text in _content_lines(path, first_line):
        fields = _split(text, delim)
        if len(fields) != ncols:
            kind = "too few" if len(fields) < ncols else "too many"
            raise DataError(
                f"{where}: line {number} has {kind} fields ({len(fields)}, expected {ncols}); truncated or malformed row"
            )
        for i, tok in enumerate(fields):
            if not _is_number(tok):
                col = repr(names[i]) if names is not None else f"#{i}"
                what = "empty field" if tok == "" else f"non-numeric value {tok!r}"
                raise DataError(f"{where}: line {number}, column {col}: {what}")


# --- NumPy -----------------------------------------------------------------------------------
def _load_npy(path, specs, time_column, time_unit, where) -> _Raw:
    try:
        arr = np.load(path, mmap_mode="r", allow_pickle=False)
    except (ValueError, OSError, EOFError) as exc:
        raise DataError(f"{where}: not a readable .npy file (empty or truncated?): {exc}") from exc
    return _from_array(arr, specs, time_column, time_unit, where, what="array")


def _from_array(arr, specs, time_column, time_unit, where, what) -> _Raw:
    if arr.dtype.names:  # structured: channels are field names
        names = list(arr.dtype.names)
        ncols = len(names)
        getcol = lambda i: np.asarray(arr[names[i]], dtype=np.float64)
    else:
        if arr.ndim != 2:
            raise DataError(f"{where}: {what} has shape {arr.shape}; expected 2-D (samples, columns)")
        names = None
        ncols = arr.shape[1]
        getcol = lambda i: np.asarray(arr[:, i], dtype=np.float64)
    if arr.shape[0] == 0:
        raise DataError(f"{where}: {what} holds no samples (shape {arr.shape})")
    if specs is None:
        if names is None:
            raise DataError(f"{where}: channels must be given as 0-based column indices of the {what}")
        specs = _default_specs(names, where)
    cols = {k: _resolve(v, names, ncols, _chname(k), where) for k, v in specs.items()}
    tcol = None if _blank(time_column) else _resolve(time_column, names, ncols, "time", where)
    label = (lambda i: repr(names[i])) if names is not None else (lambda i: f"column {i}")
    return _Raw(
        data={k: np.ascontiguousarray(getcol(i)) for k, i in cols.items()},
        names={k: label(i) for k, i in cols.items()},
        time=None if tcol is None else getcol(tcol) * _time_factor(time_unit, where),
        time_name=None if tcol is None else label(tcol),
    )


def _load_npz(path, specs, variable, time_column, time_unit, where) -> _Raw:
    import zipfile
    import zlib

    broken = (ValueError, OSError, EOFError, zipfile.BadZipFile, zlib.error)

    def member(archive, name):
        try:
            return archive[name]
        except broken as exc:
            raise DataError(
                f"{where}: array {name!r} cannot be read (truncated or corrupt file?): {exc}"
            ) from exc

    with open(path, "rb") as fh:  # np.load(path) leaks the handle when the zip is broken
        try:
            archive = np.load(fh, allow_pickle=False)
        except broken as exc:
            raise DataError(f"{where}: not a readable .npz file (empty or truncated?): {exc}") from exc
        available = list(archive.files)
        listing = ", ".join(map(repr, available))
        if not _blank(variable):
            if variable not in available:
                raise DataError(f"{where}: array {variable!r} not found; available: {listing}")
            matrix = member(archive, variable)
            return _from_array(matrix, specs, time_column, time_unit, where, what=f"array {variable!r}")
        if specs is None:
            specs = _default_specs(available, where)
        data, names = {}, {}
        for key, spec in specs.items():
            name = str(spec)
            if name not in available:
                raise DataError(f"{where}: {_chname(key)} array {name!r} not found; available: {listing}")
            data[key] = _vector(member(archive, name), where, name)
            names[key] = repr(name)
        time = None
        if not _blank(time_column):
            name = str(time_column)
            if name not in available:
                raise DataError(f"{where}: time array {name!r} not found; available: {listing}")
            time = _vector(member(archive, name), where, name) * _time_factor(time_unit, where)
    return _Raw(data=data, names=names, time=time, time_name=None if time is None else repr(str(time_column)))


def _vector(arr, where, name) -> np.ndarray:
    arr = np.asarray(arr)
    if arr.ndim != 1:
        raise DataError(f"{where}: {name!r} has shape {arr.shape}; expected 1-D")
    try:
        return np.asarray(arr, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise DataError(f"{where}: {name!r} is not numeric ({arr.dtype})") from exc


# --- netCDF ----------------------------------------------------------------------------------
def _load_netcdf(path, specs, variable, time_column, time_unit, where) -> _Raw:
    try:
        import netCDF4
    except ImportError as exc:  # pragma: no cover - a dependency of the package
        raise DataError(f"{where}: reading netCDF needs the netCDF4 package") from exc
    try:
        ds = netCDF4.Dataset(path, "r")
    except OSError as exc:
        raise DataError(f"{where}: not a readable netCDF file (empty or truncated?): {exc}") from exc
    with ds:
        ds.set_auto_maskandscale(True)
        available = list(ds.variables)

        def read(name: str) -> np.ndarray:
            return np.ma.filled(np.ma.asarray(ds.variables[name][...], dtype=np.float64), np.nan)

        data, names, file_units = {}, {}, {}
        if not _blank(variable):
            if variable not in available:
                raise DataError(
                    f"{where}: variable {variable!r} not found; available: {', '.join(map(repr, available))}"
                )
            var = ds.variables[variable]
            if var.ndim != 2:
                raise DataError(
                    f"{where}: variable {variable!r} has dimensions {var.dimensions}; expected 2-D"
                )
            labels = None
            coord = var.dimensions[1]
            if coord in ds.variables and ds.variables[coord].dtype == str:
                labels = [str(s) for s in ds.variables[coord][:]]
            if specs is None:
                if labels is None:
                    raise DataError(f"{where}: channels must be 0-based indices into variable {variable!r}")
                specs = _default_specs(labels, where)
            matrix = read(variable)
            for key, spec in specs.items():
                i = _resolve(spec, labels, var.shape[1], _chname(key), f"{where} variable {variable!r}")
                data[key] = np.ascontiguousarray(matrix[:, i])
                names[key] = f"{variable}[:, {i}]"
                if getattr(var, "units", None):
                    file_units[key] = str(var.units)
        else:
            if specs is None:
                specs = _default_specs(available, where)
            for key, spec in specs.items():
                name = str(spec)
                if name not in available:
                    raise DataError(
                        f"{where}: {_chname(key)} variable {name!r} not found; "
                        f"available: {', '.join(map(repr, available))}"
                    )
                if ds.variables[name].ndim != 1:
                    raise DataError(
                        f"{where}: variable {name!r} has dimensions {ds.variables[name].dimensions}; "
                        "expected 1-D (or give `variable` for a 2-D one)"
                    )
                data[key] = read(name)
                names[key] = repr(name)
                if getattr(ds.variables[name], "units", None):
                    file_units[key] = str(ds.variables[name].units)
        time = None
        if not _blank(time_column):
            name = str(time_column)
            if name not in available:
                raise DataError(
                    f"{where}: time variable {name!r} not found; available: {', '.join(map(repr, available))}"
                )
            unit = time_unit
            if _blank(unit):
                unit = str(getattr(ds.variables[name], "units", "s")).split(" since ")[0]
            time = read(name) * _time_factor(unit, f"{where} time variable {name!r}")
    return _Raw(
        data=data,
        names=names,
        time=time,
        time_name=None if time is None else repr(str(time_column)),
        file_units=file_units,
    )


# --- R ---------------------------------------------------------------------------------------
def _r_deref(obj):
    while obj is not None and obj.info.type.name == "REF":
        obj = obj.referenced_object
    return obj


def _r_pairlist(obj) -> Iterator[tuple[str | None, Any]]:
    """(tag, value) of an R pairlist (attributes, .rda contents)."""
    obj = _r_deref(obj)
    while obj is not None and obj.info.type.name == "LIST":
        tag = _r_deref(obj.tag)
        name = None
        if tag is not None and tag.info.type.name == "SYM":
            name = _r_deref(tag.value).value.decode("utf-8", "replace")
        yield name, _r_deref(obj.value[0])
        obj = _r_deref(obj.value[1]) if len(obj.value) > 1 else None


def _r_strings(obj) -> list[str]:
    obj = _r_deref(obj)
    if obj is None or obj.info.type.name != "STR":
        return []
    return [(_r_deref(c).value or b"NA").decode("utf-8", "replace") for c in obj.value]


def _r_numeric(obj, where, name) -> np.ndarray:
    obj = _r_deref(obj)
    kind = obj.info.type.name
    if kind == "REAL":
        return np.asarray(obj.value, dtype=np.float64)
    if kind in ("INT", "LGL"):
        values = np.asarray(obj.value)
        out = values.astype(np.float64)
        out[values == np.iinfo(np.int32).min] = np.nan  # R's NA_integer_
        return out
    raise DataError(f"{where}: R column {name!r} is of type {kind}, not numeric")


def _load_rdata(path, specs, variable, time_column, time_unit, where) -> _Raw:
    try:
        import rdata
    except ImportError as exc:  # pragma: no cover - a dependency of the package
        raise DataError(f"{where}: reading R files needs the rdata package") from exc
    try:
        parsed = rdata.parser.parse_file(path)
    except Exception as exc:  # rdata raises assorted errors on corrupt input
        raise DataError(f"{where}: not a readable R data file (empty or truncated?): {exc}") from exc
    root = _r_deref(parsed.object)
    is_rda = root.info.type.name == "LIST" and root.tag is not None
    if is_rda:
        objects = dict(_r_pairlist(root))
        if _blank(variable):
            if len(objects) != 1:
                raise DataError(
                    f"{where}: {len(objects)} objects in the file; give `variable`, one of "
                    f"{', '.join(map(repr, objects))}"
                )
            variable = next(iter(objects))
        if variable not in objects:
            raise DataError(
                f"{where}: object {variable!r} not found; available: {', '.join(map(repr, objects))}"
            )
        obj = objects[variable]
    else:
        obj = root
    attrs = dict(_r_pairlist(obj.attributes)) if obj.attributes is not None else {}
    kind = obj.info.type.name
    if kind in ("REAL", "INT", "LGL") and "dim" in attrs:
        dim = np.asarray(_r_deref(attrs["dim"]).value)
        if len(dim) != 2:
            raise DataError(f"{where}: R array has {len(dim)} dimensions; expected a matrix")
        nrow, ncol = int(dim[0]), int(dim[1])
        flat = _r_numeric(obj, where, variable)
        matrix = flat.reshape(ncol, nrow)  # R stores column-major: row j of this view is column j
        names = None
        if "dimnames" in attrs:
            dimnames = _r_deref(attrs["dimnames"])
            if dimnames.info.type.name == "VEC" and len(dimnames.value) == 2:
                names = _r_strings(dimnames.value[1]) or None
        columns = {i: matrix[i] for i in range(ncol)}
    elif kind == "VEC" and "names" in attrs:  # data.frame or named list
        names = _r_strings(attrs["names"])
        ncol = len(names)
        columns = {}
        nrow = None
        for i, (nm, col) in enumerate(zip(names, obj.value)):
            if _r_deref(col).info.type.name in ("REAL", "INT", "LGL"):
                columns[i] = _r_numeric(col, where, nm)
    else:
        raise DataError(
            f"{where}: R object {variable or ''!r} of type {kind} is neither a numeric matrix nor a "
            "data.frame / named list of numeric columns"
        )
    if specs is None:
        if names is None:
            raise DataError(
                f"{where}: the R matrix has no column names; give the channels as 0-based indices"
            )
        specs = _default_specs(names, where)
    where_obj = f"{where} object {variable!r}" if variable else where
    data, labels = {}, {}

    def column(spec, what):
        i = _resolve(spec, names, ncol, what, where_obj)
        if i not in columns:
            raise DataError(f"{where_obj}: {what} column {names[i]!r} is not numeric")
        return i

    for key, spec in specs.items():
        i = column(spec, _chname(key))
        data[key] = np.ascontiguousarray(columns[i])
        labels[key] = repr(names[i]) if names else f"column {i}"
    time = None
    if not _blank(time_column):
        i = column(time_column, "time")
        time = columns[i] * _time_factor(time_unit, where)
    file_rate, rate_from = None, ""
    if "freq" in attrs:
        file_rate, rate_from = float(_r_numeric(attrs["freq"], where, "freq")[0]), "R attribute freq"
    elif "tsp" in attrs:  # ts objects: c(start, end, frequency)
        file_rate, rate_from = float(_r_numeric(attrs["tsp"], where, "tsp")[2]), "R attribute tsp"
    return _Raw(
        data=data,
        names=labels,
        time=time,
        time_name=None if time is None else repr(str(time_column)),
        file_rate=file_rate,
        file_rate_from=rate_from,
        detail=f"object {variable!r}" if variable else "",
    )


# --- ROS bags --------------------------------------------------------------------------------
def _load_rosbag(path, specs, topic, time_column, where) -> _Raw:
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore
    except ImportError as exc:
        raise DataError(
            f"{where}: reading ROS bags / MCAP needs the rosbags package (pip install rosbags)"
        ) from exc
    if specs is None:
        specs = dict(_ROS_FIELDS)
    source = "header" if _blank(time_column) else str(time_column).strip().lower()
    if source not in ("header", "bag"):
        raise DataError(
            f"{where}: time_column {time_column!r} for a bag must be 'header' (message stamps) or 'bag'"
        )
    try:
        reader = AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE))
        reader.open()
    except Exception as exc:  # rosbags raises its own error classes on corrupt input
        raise DataError(f"{where}: not a readable ROS bag / MCAP file (empty or truncated?): {exc}") from exc
    try:
        imu = [c for c in reader.connections if c.msgtype.replace("/msg/", "/") == "sensor_msgs/Imu"]
        listing = ", ".join(sorted({f"{c.topic} ({c.msgtype})" for c in reader.connections})) or "none"
        if _blank(topic):
            topics = sorted({c.topic for c in imu})
            if len(topics) != 1:
                raise DataError(
                    f"{where}: {len(topics)} sensor_msgs/Imu topics; give `topic`; topics: {listing}"
                )
            topic = topics[0]
        conns = [c for c in reader.connections if c.topic == topic]
        if not conns:
            raise DataError(f"{where}: topic {topic!r} not found; topics: {listing}")
        if not all(c in imu for c in conns):
            raise DataError(f"{where}: topic {topic!r} carries {conns[0].msgtype}, not sensor_msgs/Imu")
        paths = {k: str(v).split(".") for k, v in specs.items()}
        values: dict[Key, list[float]] = {k: [] for k in specs}
        stamps: list[int] = []
        messages = reader.messages(connections=conns)
        while True:
            try:
                conn, bag_ns, raw = next(messages)
                msg = reader.deserialize(raw, conn.msgtype)
            except StopIteration:
                break
            except Exception as exc:  # rosbags' reader and deserializer errors on a corrupt bag
                raise DataError(
                    f"{where}: message {len(stamps)} (0-based) on {topic!r} cannot be read (truncated or corrupt "
                    f"file?): {exc}"
                ) from exc
            if source == "header":
                stamps.append(int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec))
            else:
                stamps.append(int(bag_ns))
            for key, fields in paths.items():
                value = msg
                try:
                    for f in fields:
                        value = getattr(value, f)
                except AttributeError:
                    raise DataError(
                        f"{where}: {_chname(key)} field {specs[key]!r} not in sensor_msgs/Imu; fields: "
                        "angular_velocity.{x,y,z}, linear_acceleration.{x,y,z}"
                    ) from None
                values[key].append(float(value))
    finally:
        reader.close()
    if not stamps:
        raise DataError(f"{where}: topic {topic!r} holds no messages")
    ns = np.asarray(stamps, dtype=np.int64)
    return _Raw(
        data={k: np.asarray(v, dtype=np.float64) for k, v in values.items()},
        names={k: f"{topic}:{specs[k]}" for k in specs},
        time=(ns - ns[0]).astype(np.float64) * 1e-9,  # s after the first message: no loss of precision
        time_name=f"{topic} {'header.stamp' if source == 'header' else 'bag time'} (t from the first message)",
        default_units=dict(_SI_UNITS),  # sensor_msgs/Imu is SI by definition (REP 103/145)
        detail=f"topic {topic!r}",
    )


# ----------------------------------------------------------------------------------------------
# the reader
# ----------------------------------------------------------------------------------------------
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
