"""NumPy files (.npy, memory-mapped; .npz)."""

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
from imupipe.readers._common import _Raw, _blank, _chname, _default_specs, _resolve, _time_factor, Key


#: Rows per read of :func:`_stream_columns`: the memory a read needs beyond its result (2**16 rows of six
#: float64 columns: 3 MB).
READ_ROWS = 1 << 16


def _load_npy(path, specs, time_column, time_unit, where) -> _Raw:
    try:  # checks the header and the file's length; the samples are read by _stream_columns, not the map
        arr = np.load(path, mmap_mode="r", allow_pickle=False)
    except (ValueError, OSError, EOFError) as exc:
        raise DataError(f"{where}: not a readable .npy file (empty or truncated?): {exc}") from exc

    def columns(idx):
        with open(path, "rb") as fh:
            fh.seek(arr.offset)
            return _stream_columns(fh, arr.shape, arr.dtype, _is_fortran(arr), idx, where, "array")

    return _from_array(arr, specs, time_column, time_unit, where, what="array", columns=columns)


def _is_fortran(arr) -> bool:
    return arr.ndim == 2 and arr.flags.f_contiguous and not arr.flags.c_contiguous


def _stream_columns(fh, shape, dtype, fortran: bool, idx, where, what) -> dict:
    """Columns `idx` of an array stored in .npy layout, read from `fh` (at the first sample) as float64.

    The samples are read :data:`READ_ROWS` rows at a time into one float64 buffer per column, so reading k
    columns of n rows needs 8 k n bytes plus one block, whatever the array's width (a memory-mapped column
    of a C-ordered array would bring every page of the file into the process's resident memory). A 2-D
    array's columns are indices, a structured array's are field positions; a Fortran-ordered array holds
    each column contiguously, one after the other.
    """
    n = shape[0]
    out = {i: np.empty(n, dtype=np.float64) for i in idx}
    names = dtype.names
    ncols = 1 if names else shape[1]
    width = dtype.itemsize

    def read(count: int):
        nbytes = count * width
        data = fh.read(nbytes)
        if len(data) != nbytes:
            raise DataError(f"{where}: {what} ends early (truncated file?): expected {n} rows of {shape}")
        return np.frombuffer(data, dtype=dtype, count=count)

    if fortran:
        for col in range(max(idx) + 1):
            for i in range(0, n, READ_ROWS * 8):
                part = read(min(READ_ROWS * 8, n - i))
                if col in out:
                    out[col][i : i + part.size] = part
        return out
    for i in range(0, n, READ_ROWS):
        rows = min(READ_ROWS, n - i)
        block = read(rows * ncols) if not names else read(rows)
        for col, buf in out.items():
            buf[i : i + rows] = block[names[col]] if names else block.reshape(rows, ncols)[:, col]
    return out


def _from_array(arr, specs, time_column, time_unit, where, what, columns=None) -> _Raw:
    """Channels of a 2-D (or structured 1-D) array; `columns(indices) -> {index: float64 array}` reads them
    (default: from `arr` in memory)."""
    if arr.dtype.names:  # structured: channels are field names
        names = list(arr.dtype.names)
        ncols = len(names)
        getcol = lambda i: np.asarray(arr[names[i]], dtype=np.float64)
    else:
        if arr.ndim != 2:
            raise DataError(f"{where}: {what} has shape {arr.shape}; expected 2-D (samples, columns)")
        names = None
        ncols = arr.shape[1]
        getcol = lambda i: np.ascontiguousarray(arr[:, i], dtype=np.float64)
    if arr.shape[0] == 0:
        raise DataError(f"{where}: {what} holds no samples (shape {arr.shape})")
    if specs is None:
        if names is None:
            raise DataError(f"{where}: channels must be given as 0-based column indices of the {what}")
        specs = _default_specs(names, where)
    cols = {k: _resolve(v, names, ncols, _chname(k), where) for k, v in specs.items()}
    tcol = None if _blank(time_column) else _resolve(time_column, names, ncols, "time", where)
    label = (lambda i: repr(names[i])) if names is not None else (lambda i: f"column {i}")
    wanted = sorted(set(cols.values()) | ({tcol} if tcol is not None else set()))
    values = columns(wanted) if columns is not None else {i: getcol(i) for i in wanted}
    time = None if tcol is None else values[tcol] * _time_factor(time_unit, where)
    return _Raw(
        data={k: values[i] for k, i in cols.items()},  # the time is a product, a new array
        names={k: label(i) for k, i in cols.items()},
        time=time,
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
            what = f"array {variable!r}"
            head = _member_header(archive, variable, broken, where)
            if head is None:  # a .npy layout this reader does not stream: decompressed whole
                matrix = member(archive, variable)
                return _from_array(matrix, specs, time_column, time_unit, where, what=what)
            shape, fortran, dtype, name = head

            def columns(idx):  # decompressed again, one block of rows at a time
                try:
                    with archive.zip.open(name) as fm:
                        _read_npy_header(fm)
                        return _stream_columns(fm, shape, dtype, fortran, idx, where, what)
                except broken as exc:
                    raise DataError(f"{where}: {what} cannot be read (truncated or corrupt file?): {exc}") from exc

            return _from_array(_Shape(shape, dtype, len(shape)), specs, time_column, time_unit, where, what=what, columns=columns)
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


@dataclass(frozen=True)
class _Shape:
    """What :func:`_from_array` needs of an array it does not hold: shape, dtype, ndim."""

    shape: tuple
    dtype: np.dtype
    ndim: int


def _read_npy_header(fh):
    """(shape, fortran_order, dtype) of the .npy stream `fh`, which is left at the first sample; None for a
    format version other than 1.0 and 2.0."""
    version = np.lib.format.read_magic(fh)
    readers = {(1, 0): np.lib.format.read_array_header_1_0, (2, 0): np.lib.format.read_array_header_2_0}
    if version not in readers:
        return None
    return readers[version](fh)


def _member_header(archive, variable, broken, where):
    """(shape, fortran_order, dtype, member name) of array `variable` of an open .npz, else None."""
    names = archive.zip.namelist()
    name = f"{variable}.npy" if f"{variable}.npy" in names else variable
    try:
        with archive.zip.open(name) as fm:
            head = _read_npy_header(fm)
    except broken as exc:
        raise DataError(f"{where}: array {variable!r} cannot be read (truncated or corrupt file?): {exc}") from exc
    if head is None or head[2].hasobject:
        return None
    return (*head, name)
