"""netCDF files (.nc .nc4 .cdf)."""

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


def _load_netcdf(path, specs, variable, time_column, time_unit, where) -> _Raw:
    import netCDF4
    try:
        ds = netCDF4.Dataset(path, "r")
    except OSError as exc:
        raise DataError(f"{where}: not a readable netCDF file (empty or truncated?): {exc}") from exc
    with ds:
        ds.set_auto_maskandscale(True)
        available = list(ds.variables)

        def read(name: str, column: int | None = None) -> np.ndarray:
            return _read_float64(ds.variables[name], column)

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
            for key, spec in specs.items():
                i = _resolve(spec, labels, var.shape[1], _chname(key), f"{where} variable {variable!r}")
                data[key] = read(variable, i)
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


#: Samples per read of :func:`_read_float64` (2 MB of float64): the memory a read needs beyond its result.
READ_CHUNK = 1 << 18


def _read_float64(var, column: int | None = None) -> np.ndarray:
    """Samples of a netCDF variable as float64, masked (fill) values as NaN, packed values unpacked.

    A 1-D variable, or column `column` of a 2-D one, is read in slabs of :data:`READ_CHUNK` samples into
    one float64 buffer, so reading a channel of n samples needs 8 n bytes plus one slab (netCDF4 returns
    a masked array per read and unmasking it whole would add a second copy). Other shapes are read whole.
    """
    if var.ndim == 1 and column is None or var.ndim == 2 and column is not None:
        n = var.shape[0]
        out = np.empty(n, dtype=np.float64)
        for i in range(0, n, READ_CHUNK):
            part = var[i : i + READ_CHUNK] if column is None else var[i : i + READ_CHUNK, column]
            out[i : i + READ_CHUNK] = np.ma.filled(np.ma.asarray(part, dtype=np.float64), np.nan)
        return out
    data = np.ma.filled(np.ma.asarray(var[...], dtype=np.float64), np.nan)
    return data if column is None else np.ascontiguousarray(data[:, column])
