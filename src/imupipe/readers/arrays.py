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


