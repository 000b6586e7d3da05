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

from imupipe.units import header_rate_unit
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


def _delimiter_of(header: str, delimiter=None, where: str | None = None):
    """The field separator of a text record: `delimiter` as the dataset sheet spells it (a key of ``_DELIMITERS``:
    ',', tab, semicolon, space, ...), else the one the header line shows (tab, comma, semicolon; None: whitespace).
    With `where` (the file, for the message) an unknown spelling is a :class:`DataError`; without, it reads as
    whitespace (a probe, whose full read names it)."""
    if delimiter is None:
        return "\t" if "\t" in header else "," if "," in header else ";" if ";" in header else None
    key = delimiter if delimiter in _DELIMITERS else str(delimiter).strip().lower()
    if key not in _DELIMITERS and where is not None:
        raise DataError(f"{where}: unknown delimiter {delimiter!r}; use ',', tab, semicolon, space")
    return _DELIMITERS.get(key)


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
    delim = _delimiter_of(header, delimiter, where)
    tokens = _split(header, delim)
    trailing = _trailing_delimiter(path, header_line, tokens, delim)
    if trailing and tokens[-1] == "":
        tokens = tokens[:-1]
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

    wanted = sorted(set(cols.values()) | ({tcol} if tcol is not None else set()))
    values, n_rows, width = _parse_columns(path, first_data_line, delim, ncols, names, wanted, where, trailing)
    if n_rows == 0:
        raise DataError(
            f"{where}: no data rows after line {first_data_line - 1} (header only or truncated file)"
        )
    if width != ncols:
        raise DataError(
            f"{where}: line {first_data_line}: data rows have {width} fields but the "
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
        time = values[tcol]
        if tcol in cols.values():
            time = time * _time_factor(time_unit, where)  # a new array: a channel shares the column
        else:
            time *= _time_factor(time_unit, where)  # in place: no second record-length array while parsed
    # a bracketed unit in a column's header is the file's statement of its unit (checked against the sheet's)
    stated = {k: header_rate_unit(names[i], k[0]) for k, i in cols.items()} if names is not None else {}
    return _Raw(
        data={k: values[i] for k, i in cols.items()},
        names={k: label(i) for k, i in cols.items()},
        file_units={k: u for k, u in stated.items() if u is not None},
        time=time,
        time_name=None if tcol is None else label(tcol),
        line_of_row=line_of_row,
    )


#: Lines per parse of :func:`_parse_columns`: 2**14 lines cost ~4.5 MB while parsed (the lines as Python
#: strings, the parser's buffers and the float64 block; ~270 B per line of a four-column table, measured) and
#: parse as fast as larger blocks.
READ_LINES = 1 << 14


def _count_lines(path) -> int:
    """Number of lines of a file (newlines, plus a last line without one): an upper bound of its data rows."""
    count, last = 0, b"\n"
    with open(path, "rb") as fh:
        while block := fh.read(1 << 22):
            count += block.count(b"\n")
            last = block[-1:]
    return count + (last != b"\n")


def _trailing_delimiter(path, header_line, tokens, delim) -> bool:
    """Whether the rows end with a delimiter (``1.0,2.0,``, a common spreadsheet / logger export): the header line
    ends with one, or the line after it has one field more than it with that field empty. Its empty last field
    is not data: :func:`_parse_columns` drops one trailing delimiter from every line that has one, and a row with
    a value there still differs from the header's field count (and is refused)."""
    if delim is None or len(tokens) < 1:
        return False
    if len(tokens) > 1 and tokens[-1] == "":
        return True
    following = next(_content_lines(path, header_line + 1), None)
    if following is None:
        return False
    fields = _split(following[1], delim)
    return len(fields) == len(tokens) + 1 and fields[-1] == ""


def _drop_trailing(line: str, delim: str) -> str:
    """`line` without one delimiter at its end (spaces and the newline aside)."""
    body = line.rstrip("\r\n").rstrip(" ")
    return (body[: -len(delim)] if body.endswith(delim) else body) + "\n"


def _parse_columns(path, first_line, delim, ncols, names, wanted, where, trailing=False):
    """Columns `wanted` (0-based) of the data rows from line `first_line` on, as float64; (columns, rows, fields).

    The rows are parsed :data:`READ_LINES` lines at a time (``numpy.loadtxt``: ``#`` comments, blank lines
    skipped, ``"`` quotes) and only the wanted columns are kept, in buffers sized by the file's line count, so
    reading k columns of n rows needs 8 k n bytes plus one block of lines, whatever the table's width. Every
    row must have as many fields as the first (the caller compares that with the header); a row that does not
    parse is named by :func:`_diagnose_text`.
    """
    capacity = max(0, _count_lines(path) - (first_line - 1))
    out = {i: np.empty(capacity, dtype=np.float64) for i in wanted}
    n, width = 0, None
    with open(path, encoding="utf-8-sig", errors="replace") as fh:
        for _ in range(first_line - 1):
            next(fh, None)
        while lines := list(itertools.islice(fh, READ_LINES)):
            if trailing:
                lines = [_drop_trailing(ln, delim) for ln in lines]
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # "Empty input file" from loadtxt: a block of comments only
                try:
                    block = np.loadtxt(lines, delimiter=delim, comments="#", dtype=np.float64, ndmin=2, quotechar='"')
                except ValueError as exc:
                    _diagnose_text(path, first_line, delim, ncols, names, where, trailing)
                    raise DataError(f"{where}: cannot parse the data rows ({exc})") from exc
            if block.shape[0] == 0:
                continue
            if width is None:
                width = block.shape[1]
            if block.shape[1] != width:
                _diagnose_text(path, first_line, delim, ncols, names, where, trailing)
                raise DataError(f"{where}: cannot parse the data rows (the number of fields changed from "
                                f"{width} to {block.shape[1]} after row {n})")
            rows = block.shape[0]
            if width == ncols:  # else the caller names the mismatch once every row is known to agree
                for i, buf in out.items():
                    buf[n : n + rows] = block[:, i]
            n += rows
    for buf in out.values():
        buf.resize(n, refcheck=False)  # shrink in place: the comment and blank lines counted above
    return out, n, width if width is not None else ncols


def _diagnose_text(path, first_line, delim, ncols, names, where, trailing=False) -> None:
    """Find the first malformed data line and raise a DataError naming it (else return); `trailing`: one
    empty last field per line is dropped first (:func:`_trailing_delimiter`)."""
    for number, text in _content_lines(path, first_line):
        fields = _split(text, delim)
        if trailing and len(fields) > 1 and fields[-1] == "":
            fields = fields[:-1]
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


