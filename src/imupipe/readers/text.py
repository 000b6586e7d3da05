"""Delimited text files (.csv .txt .tsv .dat)."""

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
from imupipe.readers._common import _Raw, _blank, _chname, _default_specs, _resolve, _time_factor, Key, _DELIMITERS


def _is_number(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def _names_columns(spec: Any) -> bool:
    return isinstance(spec, str) and re.fullmatch(r"\s*\d+\s*", spec) is None


def _is_header(tokens: list[str], specs, time_column) -> bool:
    """Whether the first content line is a header.

    A line with a non-number is a header. A line of numbers is a header too when the sheet names the
    columns (a name that is not a 0-based index: the names must come from a header), or when it reads
    ``0,1,2,...,n-1`` (what ``pandas.DataFrame.to_csv(index=False)`` writes for unnamed columns);
    otherwise it is the first data row.
    """
    if not all(_is_number(t) for t in tokens):
        return True
    given = list((specs or {}).values()) + ([] if _blank(time_column) else [time_column])
    if any(_names_columns(v) for v in given):
        return True
    return len(tokens) >= 2 and tokens == [str(i) for i in range(len(tokens))]


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
    has_header = _is_header(tokens, specs, time_column)
    if has_header:
        dup = sorted({t for t in tokens if tokens.count(t) > 1})
        if dup:
            where_dup = ", ".join(f"{t!r} (columns {[i for i, u in enumerate(tokens) if u == t]})" for t in dup)
            raise DataError(
                f"{where}: line {header_line}: duplicated column header {where_dup}; expected unique column names"
            )
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


