"""R data files (.rda .rdata .rds)."""

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


def _r_table(path, variable, where):
    """(object, its attributes, column names or None, column count, numeric columns by index, object name) of the
    R matrix / data.frame / named list in `path` (object `variable` of an .rda)."""
    import rdata
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
    return obj, attrs, names, ncol, columns, variable


def rdata_columns(path, variable=None) -> tuple[str, ...]:
    """Column names of the R matrix / data.frame of `path` (``()`` for a matrix without names); parses the file."""
    names = _r_table(path, variable, str(path))[2]
    return tuple(names or ())


def _load_rdata(path, specs, variable, time_column, time_unit, where) -> _Raw:
    obj, attrs, names, ncol, columns, variable = _r_table(path, variable, where)
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


