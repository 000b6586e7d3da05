"""The unit of a record's timestamps, inferred from their spacing when the user does not state it.

A time column holds numbers; only their unit makes them seconds. Read as seconds, integer-millisecond stamps of a
100 Hz record give 0.1 Hz (every Allan tau 1000x too long), nanosecond stamps 1e-7 Hz. :func:`infer_time_unit`
picks the unit from the stamps' sample interval: against a stated rate when there is one, else against the range
of rates an IMU plausibly records at.
"""

from __future__ import annotations

from ._common import _TIME_UNITS, DataError

__all__ = ["PLAUSIBLE_RATE_HZ", "TIME_UNIT_RTOL", "infer_time_unit"]

#: Rates (Hz) an IMU record plausibly has: from 1 Hz (a slow logger) to 10 kHz (a fast MEMS or FOG output). The
#: candidate units are 1000x apart and the range spans 1e4, so two units fit when the slower reading lies in
#: 1 .. 10 Hz (a 5 Hz record stamped in s reads 5 kHz in ms): the inference then refuses rather than guess.
PLAUSIBLE_RATE_HZ = (1.0, 1.0e4)

#: Relative tolerance between the stamps' rate in a candidate unit and a stated rate: 1 %, the reader's
#: ``rate_rtol`` default; the candidates are 1000x apart, so the match is never ambiguous.
TIME_UNIT_RTOL = 0.01


def infer_time_unit(spacing: float, rate_hz: float | None = None, *, rtol: float = TIME_UNIT_RTOL,
                    rate_range: tuple[float, float] = PLAUSIBLE_RATE_HZ, where: str = "record") -> tuple[str, str]:
    """The unit (``s``, ``ms``, ``us``, ``ns``) of timestamps whose sample interval is `spacing`.

    With a candidate unit of ``f`` seconds per stamp unit, the sample rate is ``r_u = 1 / (spacing * f)`` (Hz).

    - `rate_hz` given: the unit whose ``r_u`` is within `rtol` (relative) of it; none: DataError.
    - else: the unit whose ``r_u`` lies in `rate_range` (Hz, inclusive); none or more than one: DataError.

    Parameters
    ----------
    spacing : float
        The stamps' sample interval in their own (unknown) unit, e.g. the mean gap-free interval the reader
        measures when reading them as seconds (a median would report a quantised clock's quantum).
    rate_hz : float, optional
        The stated sample rate (Hz).
    where : str
        Named in messages (the file).

    Returns
    -------
    unit : str
    reason : str
        One line saying what the unit was inferred from.

    Raises
    ------
    DataError
        No unit (or, without a rate, more than one) fits; the message suggests ``--time-unit`` / ``time_unit``.
    """
    if not spacing > 0:
        raise DataError(f"{where}: timestamp spacing {spacing!r} is not positive; cannot infer the time unit "
                        "(give --time-unit: s, ms, us or ns)")
    rates = {u: 1.0 / (spacing * f) for u, f in _TIME_UNITS.items()}
    listed = ", ".join(f"{u}: {r:.4g} Hz" for u, r in rates.items())
    if rate_hz is not None:
        fits = [u for u, r in rates.items() if abs(r - rate_hz) <= rtol * rate_hz]
        if not fits:
            raise DataError(f"{where}: no time unit makes the timestamps' spacing {spacing:.6g} match --rate-hz "
                            f"{rate_hz:g} within {100 * rtol:g} % ({listed}): check --rate-hz, or give --time-unit")
        return fits[0], (f"the stamps' spacing {spacing:.6g} {fits[0]} matches --rate-hz {rate_hz:g} "
                         f"({rates[fits[0]]:.6g} Hz)")
    lo, hi = rate_range
    fits = [u for u, r in rates.items() if lo <= r <= hi]
    if len(fits) != 1:
        what = "no unit puts" if not fits else f"{' and '.join(fits)} both put"
        raise DataError(f"{where}: cannot infer the time unit: {what} the sample rate in {lo:g} .. {hi:g} Hz "
                        f"({listed}); give --time-unit (s, ms, us, ns) or --rate-hz")
    return fits[0], (f"the stamps' spacing {spacing:.6g} gives {rates[fits[0]]:.6g} Hz in {fits[0]}, the only unit "
                     f"in {lo:g} .. {hi:g} Hz")
