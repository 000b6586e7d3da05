"""Statistics of a record's sampling intervals, computed block-wise over the timestamps.

The intervals of timestamps ``t`` (s) are ``dt[i] = t[i+1] - t[i]`` (s), i = 0 .. n-2, as ``np.diff(t)`` gives
them. The timestamp checks of :mod:`imupipe.readers.core` (strictly increasing time, median and mean interval,
gaps) need a few numbers and index lists of ``dt``, not ``dt`` itself: here each is found over blocks of
:data:`INTERVAL_BLOCK` intervals (``t[a : b + 1]`` gives intervals a .. b-1, so the timestamp at a block's
edge is shared by both blocks), so that the checks cost the timestamps plus a fixed working set instead of
``dt`` (8 bytes per sample) and its boolean masks.

Every result equals, to the last bit, what the whole-array NumPy expression it replaces returns (named in
each docstring): the same subtractions, an exact selection for the median, and the summation order of
``np.sum(dt, where=mask)`` (the masked reduction sums each maximal run of selected elements with NumPy's
pairwise summation, :func:`_pairwise_sum`, and adds the runs in order to 0: NumPy's float64 reduction loop,
checked against NumPy itself by tests/test_readers_memory.py for the installed version).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

__all__ = [
    "INTERVAL_BLOCK",
    "interval",
    "intervals",
    "interval_blocks",
    "first_nonpositive",
    "nonpositive",
    "count_zero",
    "intervals_above",
    "median_interval",
    "sum_between",
]

#: Intervals per block (2**16: 0.5 MB of float64, and a few such temporaries while a block is examined).
INTERVAL_BLOCK = 1 << 16

#: NumPy's pairwise summation sums up to this many elements in one unrolled loop and splits longer runs
#: (numpy/_core/src/umath/loops_utils.h.src, ``PW_BLOCKSIZE``): a block of the emulated recursion must not
#: be shorter, or it would split where NumPy does not.
_PW_BLOCKSIZE = 128


def _block() -> int:
    return max(int(INTERVAL_BLOCK), _PW_BLOCKSIZE)


def interval(t: np.ndarray, i: int) -> float:
    """``dt[i] = t[i+1] - t[i]`` (s), the value ``np.diff(t)[i]`` holds."""
    return float(t[i + 1] - t[i])


def intervals(t: np.ndarray, index: np.ndarray) -> np.ndarray:
    """``np.diff(t)[index]`` (s) for an index array, without the whole ``np.diff``."""
    index = np.asarray(index, dtype=np.int64)
    return t[index + 1] - t[index]


def interval_blocks(t: np.ndarray, start: int = 0, stop: int | None = None) -> Iterator[tuple[int, np.ndarray]]:
    """Yield ``(a, dt[a:b])`` for consecutive blocks of the intervals ``start .. stop-1`` of `t`.

    The yielded array is a buffer reused by the next block (copy what must outlive the step).
    """
    stop = len(t) - 1 if stop is None else stop
    step = _block()
    buf = np.empty(min(step, max(stop - start, 0)), dtype=np.float64)
    for a in range(start, stop, step):
        b = min(stop, a + step)
        out = buf[: b - a]
        np.subtract(t[a + 1 : b + 1], t[a:b], out=out)
        yield a, out


def first_nonpositive(t: np.ndarray) -> int | None:
    """First i with ``dt[i] <= 0`` (``np.flatnonzero(np.diff(t) <= 0)[0]``), None when time increases strictly.
    A NaN interval is not <= 0 (as in the whole-array expression)."""
    for a, d in interval_blocks(t):
        bad = np.flatnonzero(d <= 0)
        if bad.size:
            return a + int(bad[0])
    return None


def nonpositive(t: np.ndarray) -> np.ndarray:
    """Indices i (int64, ascending) with ``dt[i] <= 0``: ``np.flatnonzero(np.diff(t) <= 0)``."""
    found = [a + np.flatnonzero(d <= 0) for a, d in interval_blocks(t)]
    return np.concatenate(found).astype(np.int64, copy=False) if found else np.empty(0, dtype=np.int64)


def count_zero(t: np.ndarray) -> int:
    """Number of zero intervals (duplicate timestamps), ``np.count_nonzero(np.diff(t) == 0)``."""
    return sum(int(np.count_nonzero(d == 0)) for _, d in interval_blocks(t))


def intervals_above(t: np.ndarray, limit: float) -> np.ndarray:
    """Indices i (int64, ascending) with ``dt[i] > limit`` (s): ``np.flatnonzero(np.diff(t) > limit)``."""
    found = [a + np.flatnonzero(d > limit) for a, d in interval_blocks(t)]
    return np.concatenate(found).astype(np.int64, copy=False) if found else np.empty(0, dtype=np.int64)


def _pairwise_sum(t: np.ndarray, a: int, n: int) -> float:
    """``np.add.reduce(np.diff(t)[a : a + n])`` to the last bit, with at most one block of intervals at a time.

    NumPy sums a float64 array pairwise: a run of more than ``PW_BLOCKSIZE`` (128) elements is split at
    ``n2 = n // 2 - (n // 2) % 8`` and the two halves' sums are added; shorter runs are summed in one loop.
    The recursion is followed here down to pieces of at most one block (:data:`INTERVAL_BLOCK`, at least 128),
    which NumPy then sums exactly as it sums them inside the whole array.
    """
    if n <= _block():
        return float(np.add.reduce(np.subtract(t[a + 1 : a + n + 1], t[a : a + n])))
    n2 = n // 2
    n2 -= n2 % 8
    return _pairwise_sum(t, a, n2) + _pairwise_sum(t, a + n2, n - n2)


def sum_between(t: np.ndarray, gaps: np.ndarray) -> tuple[int, float]:
    """(count, sum in s) of the intervals that are not in `gaps`: ``np.count_nonzero(ok)`` and
    ``np.sum(np.diff(t), where=ok)`` with ``ok`` False exactly at the (ascending, unique) indices `gaps`.

    The masked sum is the runs of ``ok`` summed one after the other, each run pairwise
    (:func:`_pairwise_sum`), starting from 0.
    """
    n = len(t) - 1
    total = 0.0
    count = 0
    a = 0
    for g in (*(int(i) for i in gaps), n):
        if g > a:
            total = total + _pairwise_sum(t, a, g - a)
            count += g - a
        a = g + 1
    return count, total


def _kth_positive(t: np.ndarray, k: int) -> float:
    """The k-th smallest (0-based) interval when every interval is > 0, exactly.

    Method: radix selection on the bit patterns. For positive float64 numbers (infinity included) the
    order of the values is the order of their bit patterns read as uint64, so four passes over the
    intervals, each counting the next 16 bits (a histogram of 65536 bins) among those whose higher bits
    equal the ones chosen so far, find the element's 64 bits.
    """
    prefix = 0
    for shift in (48, 32, 16, 0):
        counts = np.zeros(1 << 16, dtype=np.int64)
        for _, d in interval_blocks(t):
            u = d.view(np.uint64)
            if shift < 48:
                u = u[(u >> np.uint64(shift + 16)) == np.uint64(prefix)]
            digit = ((u >> np.uint64(shift)) & np.uint64(0xFFFF)).astype(np.intp)
            counts += np.bincount(digit, minlength=1 << 16)
        cum = np.cumsum(counts)
        digit = int(np.searchsorted(cum, k, side="right"))
        k -= int(cum[digit - 1]) if digit else 0
        prefix = (prefix << 16) | digit
    return float(np.array(prefix, dtype=np.uint64).view(np.float64))


def median_interval(t: np.ndarray) -> float:
    """``np.median(np.diff(t))`` (s), to the last bit, for strictly increasing `t` (every interval > 0).

    With m intervals, the median is the element of rank m // 2 (m odd) or the mean of the elements of ranks
    m/2 - 1 and m/2 (m even), as ``np.median`` computes it from the two (their sum over 2). The first is
    selected exactly (:func:`_kth_positive`); the second is the same value when more than m/2 intervals are
    at most the first, else the smallest interval above the first (one more pass).
    """
    m = len(t) - 1
    if m < 1:
        raise ValueError("the median interval needs at least two timestamps")
    lo = _kth_positive(t, (m - 1) // 2)
    if m % 2:
        return lo
    at_most, above = 0, np.inf
    for _, d in interval_blocks(t):
        at_most += int(np.count_nonzero(d <= lo))
        over = d[d > lo]
        if over.size:
            above = min(above, float(over.min()))
    hi = lo if at_most > m // 2 else above
    return float(np.median(np.array([lo, hi])))
