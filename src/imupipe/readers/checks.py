"""Checks shared by every reader: the file itself, sample ranges, dataset names, config against metadata.

All raise :class:`~imupipe.readers.DataError` (or :class:`ConfigError`, a subclass) with a message that
names the file, the column and row, or the config key, and what was expected.
"""

from __future__ import annotations

import errno
import math
import os
import re
import stat
from pathlib import Path
from typing import Any

import numpy as np

from imupipe.readers._common import SHEET_COLUMNS, DataError
from imupipe.units import SI_UNITS, STANDARD_GRAVITY, UnitError, rate_factor

__all__ = [
    "PLAUSIBLE_SI",
    "SQUARE_SAFE_MIN",
    "ConfigError",
    "check_file",
    "check_sheet_header",
    "check_unchanged",
    "check_values",
    "validate_dataset_name",
    "check_against_config",
    "GRAVITY_WINDOW",
    "check_gravity",
    "gravity_removed",
]

#: Largest plausible magnitude of a sample in SI (gyro rad/s, accel m/s^2). Generous on purpose: the
#: widest MEMS / tactical full-scale ranges are ~70 rad/s (4000 deg/s) and ~2000 m/s^2 (200 g); a sample
#: beyond these limits is a wrong unit, a wrong column or a corrupt value, not a measurement.
PLAUSIBLE_SI = {"gyro": 1.0e3, "accel": 1.0e4}

#: Smallest non-zero channel scale (max |x|, SI) whose square is a normal float64 with room for sums:
#: sqrt(2.2e-308) ~ 1.5e-154; below it x**2 underflows and the Allan variance and PSD become 0 or
#: subnormal garbage. 1e-150 keeps a margin of 1e-8 (sums of 1e8 samples remain normal).
SQUARE_SAFE_MIN = 1.0e-150

#: Window of |mean specific force| / g0 (g0 = 9.80665 m/s^2, dimensionless) a static accelerometer record
#: with gravity in it must show. Derivation: a static IMU measures f = -g + b whatever its tilt, so
#: |f| = |g| + b.u to first order (u the unit vector along f, b the bias). |g| on Earth is 9.780 m/s^2
#: (equator) .. 9.832 m/s^2 (poles) at sea level, -3.1e-6 m/s^2 per m of height: within 0.5 % of g0 for
#: any site below ~5 km. The bias along gravity plus the scale-factor error of a MEMS accelerometer stay
#: below ~0.09 g0 (consumer parts: zero-g offset <= 80 mg, scale error <= 3 %; the ADIS16405: 50 mg).
#: Hence 0.9 .. 1.1 g0. A wrong but valid unit shifts |f| by the ratio of two accepted accel units, at
#: least 9.81 (m/s^2 for g), else 100 (cm/s^2 for m/s^2) or 1000 (mg for g): far outside the window.
GRAVITY_WINDOW = (0.9, 1.1)

#: Accel units the gravity check proposes when the measured magnitude is outside GRAVITY_WINDOW.
_GRAVITY_UNITS = ("m/s^2", "g", "mg", "ug", "cm/s^2", "mm/s^2")

_TRUE = ("yes", "true", "1")
_FALSE = ("no", "false", "0")

_MAGIC = {  # leading bytes -> what the file really is
    b"\x1f\x8b": "gzip-compressed",
    b"BZh": "bzip2-compressed",
    b"\xfd7zXZ\x00": "xz-compressed",
    b"(\xb5/\xfd": "zstd-compressed",
    b"PK\x03\x04": "a zip archive",
    b"\x89HDF\r\n\x1a\n": "HDF5 / netCDF-4",
    b"CDF\x01": "netCDF-3",
    b"CDF\x02": "netCDF-3 (64-bit offset)",
    b"\x93NUMPY": "a NumPy .npy file",
}
_EXPECTED_MAGIC = {  # format -> kinds that are fine for it
    "csv": (),
    "npy": ("a NumPy .npy file",),
    "npz": ("a zip archive",),
    "netcdf": ("HDF5 / netCDF-4", "netCDF-3", "netCDF-3 (64-bit offset)"),
    "rdata": ("gzip-compressed", "bzip2-compressed", "xz-compressed"),  # R saves compressed by default
    "rosbag": (),
}


class ConfigError(DataError):
    """A config value that a dataset cannot satisfy: the message names the config key and the dataset."""


def _backslash_hint(where: str) -> str:
    """The hint for a missing path written with backslashes: a Windows path, whose separators are ordinary
    characters of a file name on Linux and macOS."""
    if "\\" not in where:
        return ""
    return (f" (the path has backslashes, a Windows path? Here '\\' is part of a file name, not a separator: "
            f"write {where.replace(chr(92), '/')!r})")


def check_file(path: str | Path, fmt: str | None = None) -> os.stat_result:
    """Refuse a path that cannot be read as a data file of format `fmt`, before opening it for data.

    Checks, in order: a symlink loop (named as such), a missing file (a path with backslashes: the hint that
    it is a Windows path), a FIFO / socket / device (refused
    at once: reading a FIFO would block forever), a directory (allowed for ROS 2 bags only), and for
    regular files the leading bytes: a compressed or binary file given as text (e.g. a gzip'd CSV), or
    a file of another format than `fmt`.

    Parameters
    ----------
    path : str or Path
    fmt : str, optional
        Reader format (``csv``, ``npy``, ``npz``, ``netcdf``, ``rdata``, ``rosbag``). Defaults to None:
        no content check.

    Returns
    -------
    os.stat_result
        ``os.stat(path)``, for :func:`check_unchanged` after the read.

    Raises
    ------
    DataError
    """
    path = Path(path)
    where = str(path)
    try:
        st = os.stat(path)
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise DataError(f"{where}: symbolic link loop (the link points, directly or not, to itself)") from None
        if exc.errno == errno.ENOENT:
            if path.is_symlink():
                raise DataError(f"{where}: broken symbolic link (its target {os.readlink(path)!r} is missing)") from None
            raise DataError(f"{where}: file not found{_backslash_hint(where)}") from None
        if exc.errno == errno.EACCES:
            raise DataError(f"{where}: permission denied") from None
        raise DataError(f"{where}: cannot stat ({exc.strerror})") from None
    mode = st.st_mode
    if stat.S_ISDIR(mode):
        if fmt not in (None, "rosbag"):
            raise DataError(f"{where}: is a directory, not a {fmt} file")
        return st
    if not stat.S_ISREG(mode):
        kind = (
            "a FIFO (named pipe)"
            if stat.S_ISFIFO(mode)
            else "a socket"
            if stat.S_ISSOCK(mode)
            else "a character device"
            if stat.S_ISCHR(mode)
            else "a block device"
            if stat.S_ISBLK(mode)
            else "not a regular file"
        )
        raise DataError(f"{where}: is {kind}, not a regular file; refused (reading it could block or never end)")
    if fmt is None or st.st_size == 0:
        return st
    with open(path, "rb") as fh:
        head = fh.read(512)
    kind = next((k for magic, k in _MAGIC.items() if head.startswith(magic)), None)
    if fmt == "csv":
        if kind is not None:
            hint = " (decompress it first, e.g. gunzip)" if "compressed" in kind else ""
            raise DataError(f"{where}: is {kind}, not a text file{hint}")
        if b"\x00" in head:
            raise DataError(f"{where}: holds NUL bytes in its first {len(head)} bytes: a binary file, not text")
    elif fmt in _EXPECTED_MAGIC and fmt != "rosbag" and kind is not None and kind not in _EXPECTED_MAGIC[fmt]:
        hint = " (decompress it first)" if "compressed" in kind else ""
        raise DataError(f"{where}: is {kind}, not a {fmt} file{hint}")
    return st


def check_unchanged(path: str | Path, before: os.stat_result) -> None:
    """Fail when `path` changed while it was read (size or modification time differ from `before`).

    A file rewritten during ingest would otherwise leave a shortened record whose output is newer than
    the input, so that it is never read again.

    Raises
    ------
    DataError
    """
    path = Path(path)
    try:
        after = os.stat(path)
    except OSError as exc:
        raise DataError(f"{path}: vanished while it was read ({exc.strerror})") from None
    if stat.S_ISDIR(before.st_mode):  # a rosbag2 directory: its files are checked by their size sum
        return
    if (after.st_size, after.st_mtime_ns) != (before.st_size, before.st_mtime_ns):
        raise DataError(
            f"{path}: changed while it was read (size {before.st_size} -> {after.st_size} bytes, "
            f"mtime {before.st_mtime_ns} -> {after.st_mtime_ns} ns); read it again once it is complete"
        )


def check_values(x: np.ndarray, sensor: str, column: str, where: str, row_text=None) -> None:
    """Validate one channel's samples in SI: finite, physically plausible, representable after squaring.

    Limits: ``|x| <= PLAUSIBLE_SI[sensor]`` (gyro 1e3 rad/s, accel 1e4 m/s^2) for every sample, and a
    non-zero channel's ``max |x| >= SQUARE_SAFE_MIN`` (1e-150, so that ``x**2`` and its sums stay normal
    float64 numbers).

    Parameters
    ----------
    x : ndarray
        Samples in SI (rad/s or m/s^2).
    sensor : {'gyro', 'accel'}
    column : str
        Channel and file column, quoted in the message.
    where : str
        File, quoted in the message.
    row_text : callable, optional
        ``row -> "row r (0-based), line l"``. Defaults to ``"row r (0-based)"``.

    Raises
    ------
    DataError
    """
    row_text = row_text or (lambda r: f"row {r} (0-based)")
    # min and max need no temporary array (a NaN propagates into both, an infinity into one of them); the
    # element-wise arrays that name the culprit are built only when a check fails
    lo, hi = (float(x.min()), float(x.max())) if x.size else (0.0, 0.0)
    if math.isfinite(lo) and math.isfinite(hi):
        top = max(-lo, hi)
        if top <= PLAUSIBLE_SI[sensor] and not 0.0 < top < SQUARE_SAFE_MIN:
            return
    a = np.abs(x)
    finite = np.isfinite(a)
    if not finite.all():
        row = int(np.argmin(finite))
        raise DataError(
            f"{where}: {column} has a non-finite sample ({float(x[row])}) at {row_text(row)}; "
            f"{int(np.count_nonzero(~finite))} in all; expected finite numbers"
        )
    limit = PLAUSIBLE_SI[sensor]
    peak = int(np.argmax(a))
    if a[peak] > limit:
        unit = SI_UNITS[sensor]
        raise DataError(
            f"{where}: {column} has a sample of {float(x[peak]):.6g} {unit} at {row_text(peak)} "
            f"({int(np.count_nonzero(a > limit))} beyond the limit in all); every {sensor} sample must satisfy "
            f"|x| <= {limit:g} {unit}: wrong unit, wrong column or a corrupt value?"
        )
    if 0.0 < a[peak] < SQUARE_SAFE_MIN:
        raise DataError(
            f"{where}: {column}: the largest sample is {float(a[peak]):.6g} in SI (at {row_text(peak)}); its square "
            f"underflows float64: expected a channel scale >= {SQUARE_SAFE_MIN:g} (wrong unit or a corrupt file?)"
        )


_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.+-]*")


def validate_dataset_name(name: Any, where: str = "dataset sheet") -> str:
    """Return `name` when it can name files and wildcards; else raise.

    A dataset name becomes a path component of every output. Accepted: a letter or digit, then
    letters, digits, ``_``, ``.``, ``+``, ``-`` (at most 128 characters); not ``.`` or ``..``, no path
    separator, no whitespace, not empty.

    Raises
    ------
    DataError
    """
    text = "" if name is None or (isinstance(name, float) and math.isnan(name)) else str(name)
    reason = None
    if not text.strip():
        reason = "is empty"
    elif text in (".", "..") or text.strip(".") == "":
        reason = "is a relative directory ('.' or '..')"
    elif "/" in text or "\\" in text or os.sep in text:
        reason = "holds a path separator"
    elif len(text) > 128:
        reason = f"is {len(text)} characters long (at most 128)"
    elif not _NAME.fullmatch(text):
        reason = "holds characters other than letters, digits, '_', '.', '+', '-' or does not start with a letter or digit"
    if reason:
        raise DataError(
            f"{where}: dataset name {text!r} {reason}; a name becomes a folder of the outputs "
            "(expected e.g. 'adis_run1')"
        )
    return text


#: Time units a time column may count when the sheet's time_unit is left at seconds, with their factor to s.
_STAMP_UNITS = (("ms", 1e3), ("us", 1e6), ("ns", 1e9))
#: Rates (Hz) an IMU record plausibly has: 1 Hz .. 10 kHz (a rate outside it read from stamps is a unit slip).
_PLAUSIBLE_RATE_HZ = (1.0, 1e4)


def _rate_hint(rate: float, rate_from, decimate_rate_hz: float) -> str:
    """The fix for a record rate that decimate.rate_hz does not divide, when the rate came from the timestamps
    (the sheet's rate_hz empty): the stamps' unit when reading them as ms, us or ns gives a plausible rate that the
    decimation divides (set time_unit), else the round rate within the reader's 1 % rate tolerance that it divides
    (set rate_hz: the sheet's rate is then checked against the stamps within 1 %); "" when neither fits or the
    rate is the sheet's or the file's (Hz)."""
    if str(rate_from or "") != "timestamps" or not rate or rate <= 0:
        return ""

    def divides(r):
        q = r / decimate_rate_hz
        return round(q) >= 1 and abs(q - round(q)) <= 1e-9 * q

    for unit, factor in _STAMP_UNITS:
        r = rate * factor
        if _PLAUSIBLE_RATE_HZ[0] <= r <= _PLAUSIBLE_RATE_HZ[1] and divides(round(r, 6)):
            return (f"; read as {unit} the timestamps give {r:.6g} Hz: if the time column counts {unit}, set "
                    f"time_unit: {unit} in the dataset sheet")
    for digits in (-3, -2, -1, 0, 1, 2, 3):  # the coarsest round rate first
        nominal = round(rate, digits)
        if nominal > 0 and abs(rate - nominal) <= 0.01 * nominal and divides(nominal):
            off = 100 * (rate - nominal) / nominal
            return (f"; the timestamps' mean rate is {abs(off):.2f} % {'above' if off > 0 else 'below'} {nominal:g} Hz: "
                    f"if {nominal:g} Hz is the record's nominal rate, set rate_hz: {nominal:g} in the dataset sheet "
                    "(accepted within 1 % of the timestamps' rate)")
    return ""


def check_against_config(
    meta: Any,
    *,
    window_s: float | None = None,
    decimate_rate_hz: float | None = None,
    n_segments: int | None = None,
    dataset: str | None = None,
    min_segment_samples: int = 3,
) -> None:
    """Check a record's metadata against the config before any job runs; errors name the config key.

    Checks (each when its argument is given):

    - ``decimate.rate_hz``: ``rate_hz / decimate_rate_hz`` is an integer m >= 1 (block-average
      decimation), to 1e-9 relative.
    - ``psd.window_s``: the record lasts at least one Welch window, ``duration_s >= window_s``, and the
      window holds at least 2 decimated samples.
    - ``stationarity.n_segments``: the decimated record, ``floor(n_samples / m)`` samples, holds at
      least ``min_segment_samples`` (3) per segment.

    Parameters
    ----------
    meta : Probe, Recording or mapping
        Anything with ``rate_hz`` (Hz), ``n_samples`` and ``duration_s`` (s) (attributes or keys).
    window_s, decimate_rate_hz, n_segments : optional
        The config values ``psd.window_s`` (s), ``decimate.rate_hz`` (Hz), ``stationarity.n_segments``.
    dataset : str, optional
        Dataset name quoted in the messages. Defaults to ``meta.dataset`` or ``meta.path``.
    min_segment_samples : int, optional
        Decimated samples needed per stationarity segment. Defaults to 3.

    Raises
    ------
    ConfigError
    """

    def get(name):
        return meta.get(name) if isinstance(meta, dict) else getattr(meta, name, None)

    rate = get("rate_hz")
    n = get("n_samples")
    duration = get("duration_s")
    if duration is None and rate and n is not None:
        duration = n / rate
    name = dataset or get("dataset") or get("path") or "<dataset>"
    label = f"dataset {name!r}"
    m = None
    if decimate_rate_hz is not None:
        if not (isinstance(decimate_rate_hz, (int, float)) and math.isfinite(decimate_rate_hz) and decimate_rate_hz > 0):
            raise ConfigError(f"config key decimate.rate_hz = {decimate_rate_hz!r}: expected a positive number of Hz")
        if rate is None:
            raise ConfigError(f"{label}: sample rate unknown; cannot check config key decimate.rate_hz")
        ratio = rate / decimate_rate_hz
        m = round(ratio)
        if m < 1 or abs(ratio - m) > 1e-9 * ratio:
            raise ConfigError(
                f"config key decimate.rate_hz = {decimate_rate_hz:g} Hz does not divide the rate of {label} "
                f"({rate:.12g} Hz; ratio {ratio:.9g}): block-average decimation needs an integer ratio"
                + _rate_hint(rate, get("rate_from"), decimate_rate_hz)
            )
    if window_s is not None:
        if not (isinstance(window_s, (int, float)) and math.isfinite(window_s) and window_s > 0):
            raise ConfigError(f"config key psd.window_s = {window_s!r}: expected a positive number of s")
        if duration is not None and duration < window_s:
            source = {"sheet": ", the sheet's rate_hz", "timestamps": ", from the timestamps",
                      "file": ", the file's rate attribute"}.get(str(get("rate_from") or ""), "")
            raise ConfigError(
                f"{label} lasts {duration:.6g} s ({n} samples at {rate:g} Hz{source}), shorter than config key "
                f"psd.window_s = {window_s:g} s (one Welch window); shorten psd.window_s (verify.fix_s + "
                f"application.outage_s must fit in the longest record too) or give a longer record"
                + (" (or correct rate_hz if it is not the record's rate)" if source.endswith("rate_hz") else "")
            )
        if decimate_rate_hz is not None and window_s * decimate_rate_hz < 2:
            raise ConfigError(
                f"config key psd.window_s = {window_s:g} s holds {window_s * decimate_rate_hz:g} samples at "
                f"decimate.rate_hz = {decimate_rate_hz:g} Hz; expected at least 2"
            )
    if n_segments is not None:
        if not (isinstance(n_segments, (int, np.integer)) and not isinstance(n_segments, bool) and n_segments >= 2):
            raise ConfigError(f"config key stationarity.n_segments = {n_segments!r}: expected an integer >= 2")
        if n is not None and m is not None:
            n_dec = n // m
            if n_dec < n_segments * min_segment_samples:
                raise ConfigError(
                    f"{label}: {n_dec} decimated samples (at decimate.rate_hz = {decimate_rate_hz:g} Hz) are too few "
                    f"for config key stationarity.n_segments = {n_segments} (need >= {min_segment_samples} per "
                    f"segment, {n_segments * min_segment_samples} in all)"
                )


def check_sheet_header(path: str | Path, delimiter: str = "\t") -> list[str]:
    """Read the header line of the dataset sheet and refuse a sheet separated by commas or semicolons instead of
    tabs (a spreadsheet's CSV export), duplicated or empty column names, and columns the sheet does not know
    (:data:`~imupipe.readers.SHEET_COLUMNS`, named with the allowed ones).

    A TSV reader such as pandas renames a second ``gyro_x`` column to ``gyro_x.1`` silently, so that a
    channel would be read from whichever column the sheet names first; the workflow calls this before
    reading the sheet. Lines starting with ``#`` are comments.

    Parameters
    ----------
    path : str or Path
        Dataset sheet.
    delimiter : str, optional
        Defaults to a tab.

    Returns
    -------
    list of str
        Column names, in order.

    Raises
    ------
    DataError
        Naming the sheet, the duplicated name and its column numbers (1-based, as a spreadsheet shows them).
    """
    path = Path(path)
    check_file(path, "csv")
    with open(path, encoding="utf-8-sig") as fh:
        for number, line in enumerate(fh, start=1):
            if line.strip() and not line.lstrip().startswith("#"):
                break
        else:
            raise DataError(f"dataset sheet {str(path)!r}: no header line")
    if delimiter == "\t" and "\t" not in line:
        found = [name for sep, name in ((",", "commas"), (";", "semicolons")) if sep in line]
        if found:
            raise DataError(
                f"dataset sheet {str(path)!r}, line {number}: not tab-separated (found {found[0]} in the header line "
                f"{line.strip()[:80]!r}); the sheet is a TSV: save it as tab-separated text (a spreadsheet's "
                "'Text (tab delimited)' / 'TSV' export), not as CSV"
            )
    names = [c.strip() for c in line.rstrip("\r\n").split(delimiter)]
    dup = sorted({c for c in names if c and names.count(c) > 1})
    if dup:
        listed = "; ".join(
            f"{c!r} in columns {', '.join(str(i + 1) for i, d in enumerate(names) if d == c)}" for c in dup
        )
        raise DataError(
            f"dataset sheet {str(path)!r}, line {number}: duplicated column header {listed}; expected each column once"
        )
    empty = [i + 1 for i, c in enumerate(names) if not c and any(names[i + 1 :])]  # trailing tabs are fine
    if empty:
        raise DataError(f"dataset sheet {str(path)!r}, line {number}: column(s) {empty} have an empty header")
    unknown = [(i + 1, c) for i, c in enumerate(names) if c and c not in SHEET_COLUMNS]
    if unknown:
        listed = ", ".join(f"{c!r} (column {i})" for i, c in unknown)
        raise DataError(
            f"dataset sheet {str(path)!r}, line {number}: unknown column {listed}; allowed columns: "
            f"{', '.join(SHEET_COLUMNS)} (config/README.md; a note belongs in a '#' comment line)"
        )
    return names


def gravity_removed(value: Any, where: str = "dataset sheet") -> bool:
    """The sheet cell ``gravity_removed``: yes/true/1 (gravity was removed from the accel record: no
    gravity check), no/false/0 or empty (default: the record holds gravity and is checked)."""
    if value is None or (isinstance(value, float) and math.isnan(value)) or str(value).strip() == "":
        return False
    text = str(value).strip().lower()
    if text in _TRUE or value is True:
        return True
    if text in _FALSE or value is False:
        return False
    raise DataError(f"{where}: gravity_removed = {value!r}; expected yes or no (empty: no)")


def check_gravity(mean_si: Any, unit: str, where: str, window: tuple[float, float] = GRAVITY_WINDOW) -> float:
    """Check that the mean specific force of a static accelerometer record is gravity; return |mean| (m/s^2).

    Formula: ``|f| = sqrt(fx^2 + fy^2 + fz^2)`` of the three axes' means (m/s^2, after the unit
    conversion of the sheet's ``accel_unit``) must satisfy ``window[0] <= |f| / g0 <= window[1]``,
    g0 = 9.80665 m/s^2 (:data:`GRAVITY_WINDOW`: 0.9 .. 1.1, derived there). Outside it, the stored unit
    is wrong (a record in g declared m/s^2 shows 0.102 g) or gravity was removed from the record.

    Parameters
    ----------
    mean_si : sequence of 3 floats
        Means of accel x, y, z (m/s^2).
    unit : str
        The unit the record is stored in (the sheet's ``accel_unit`` or the file's), as spelled there.
    where : str
        The file (and dataset), first in the message.
    window : (float, float), optional
        Accepted |f| / g0. Defaults to :data:`GRAVITY_WINDOW`.

    Returns
    -------
    float
        |f| in m/s^2.

    Raises
    ------
    DataError
        Naming `where`, ``accel_unit``, |f| in m/s^2 and in g, the unit that would make it about 1 g
        and the opt-out (``gravity_removed``).
    """
    f = np.asarray(mean_si, dtype=np.float64)
    if f.shape != (3,) or not np.isfinite(f).all():
        raise DataError(f"{where}: the gravity check needs three finite accel means (m/s^2), got {f.tolist()}")
    magnitude = float(math.sqrt(float(f @ f)))
    ratio = magnitude / STANDARD_GRAVITY
    lo, hi = window
    if lo <= ratio <= hi:
        return magnitude
    hint = ""
    try:
        stored = magnitude / rate_factor(str(unit), "accel")  # |f| in the unit the file is stored in
    except UnitError:
        stored = None
    if stored is not None and stored > 0:
        fits = [u for u in _GRAVITY_UNITS if lo <= stored * rate_factor(u, "accel") / STANDARD_GRAVITY <= hi]
        if fits:
            hint = f" The stored values have magnitude {stored:.4g} {unit}: accel_unit = {fits[0]!r} would make it {stored * rate_factor(fits[0], 'accel') / STANDARD_GRAVITY:.3g} g."
    raise DataError(
        f"{where}: accel_unit = {unit!r} gives the mean specific force of the three accel axes a magnitude of "
        f"{magnitude:.4g} m/s^2 = {ratio:.4g} g; a static record on Earth shows {lo:g} .. {hi:g} g "
        f"(gravity, 9.78 .. 9.83 m/s^2, plus the accelerometer's bias).{hint} Correct accel_unit; if gravity "
        "was removed from this record, set gravity_removed: yes in its sheet row"
    )
