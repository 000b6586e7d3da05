"""Shared parts of the readers: constants, errors, the Recording, channel specs and checks."""

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

from imupipe.units import SI_UNITS, UnitError, rate_factor, split_unit_suffix

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
]

SENSORS = ("gyro", "accel")
AXES = ("x", "y", "z")
GAP_POLICIES = ("fail", "split", "fill")

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
    "gap_policy": "fail (default), split (keep the longest contiguous segment, warn) or fill (interpolate short gaps)",
    "fill_max_samples": "gap_policy fill: longest gap filled, in missing samples (default 10)",
    "fill_max_s": "gap_policy fill: longest gap filled, in s (instead of fill_max_samples)",
    "fill_max_fraction": "gap_policy fill: most samples inserted in all, as a fraction of the file's samples (default 0.01)",
    "gravity_removed": "yes when gravity was removed from the accel record (no gravity check); default no",
    "long_gap_policy": "gap_policy fill: fail (default) or split for longer gaps",
}

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
    """What the reader did with or could not tell from the timestamps: gaps found (``gap_policy="split"`` kept the
    longest contiguous segment), gaps the stamps' jitter hides, stamps that step back within their jitter."""


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
    filled : tuple of FilledGap
        Gaps filled by ``gap_policy="fill"`` (row before the gap, samples inserted); rows of
        ``channels`` then count the inserted samples. Empty otherwise.
    """

    channels: dict[Key, np.ndarray]
    rate_hz: float
    source: str
    units: dict[Key, str]
    file_units: dict[Key, str]
    columns: dict[Key, str]
    segments: tuple[Segment, ...]
    selected: int = 0
    filled: tuple = ()
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
    def n_filled(self) -> int:
        """Samples inserted by ``gap_policy="fill"`` (0 when nothing was filled)."""
        return int(sum(g.n_missing for g in self.filled))

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


# ----------------------------------------------------------------------------------------------
# units, axis map, channel specifications
# ----------------------------------------------------------------------------------------------
def _unit_factor(unit: Any, sensor: str, key: str) -> float:
    """SI factor of a gyro or accel ``unit`` (SI value = stored value * factor), by :func:`imupipe.units.rate_factor`."""
    if _blank(unit):
        raise DataError(
            f"{key}: unit missing (expected e.g. {SI_UNITS[sensor]!r} or {_example_unit(sensor)!r})"
        )
    text = str(unit).strip()
    try:
        return rate_factor(text, sensor)
    except UnitError as exc:
        raise DataError(
            f"{key}: unknown unit {text!r} for {sensor} ({exc}); expected e.g. {SI_UNITS[sensor]!r}, "
            f"{_example_unit(sensor)!r} (accepted spellings: docs/inputs.md)"
        ) from None


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
    """Index of column ``spec`` among ``names`` (None: no names): a name, a 0-based index, or a name without its
    bracketed unit (``gx`` for the header ``gx [deg/s]``, :func:`imupipe.units.split_unit_suffix`) where exactly one
    column has that name."""
    if names is not None and isinstance(spec, str) and spec in names:
        return names.index(spec)
    is_int = isinstance(spec, (int, np.integer)) and not isinstance(spec, bool)
    is_digits = isinstance(spec, str) and re.fullmatch(r"\d+", spec.strip()) is not None
    index = int(spec) if is_int or is_digits else None
    if index is not None and 0 <= index < ncols:
        return index
    if names is not None and isinstance(spec, str):
        bare = [i for i, n in enumerate(names) if split_unit_suffix(str(n))[0] == spec.strip()]
        if len(bare) == 1:
            return bare[0]
        if bare:
            raise DataError(f"{where}: {what} column {spec!r} names {len(bare)} columns once their units are left "
                            f"out ({', '.join(repr(names[i]) for i in bare)}): give the full name")
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


