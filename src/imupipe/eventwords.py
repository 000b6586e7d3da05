"""The words of events (bursts, mean steps) in the run summary beyond each event's own FLAG text
(:func:`imupipe.events.event_flags`): the run's count of axes with an event against what the scan's false-alarm rate
gives, the strongest event that chance does not explain whatever the count, and the note where an axis with events
also fails the stationarity test. Plain dicts in (the outliers files' entries and the stationarity summary), strings
out.
"""

from __future__ import annotations

from collections.abc import Mapping

from imupipe.shown import num
from imupipe.verdict import chance_failures

__all__ = ["event_chance", "level_change_note", "step_scan_text", "strongest_event_beyond"]


def event_chance(bound: Mapping) -> str:
    """``"; k of n axes show an event ..."``: the run's event count against what the scan's false-alarm rate gives
    (:func:`imupipe.verdict.chance_failures`; the outliers files' ``events_scan``, merged as ``events_scanned``, one
    rate per axis scanned); empty without them."""
    rates, events = bound.get("events_scanned") or [], bound.get("events") or []
    axes = {(it.get("dataset"), it.get("axis")) for it in events if isinstance(it, Mapping)}
    text = chance_failures(len(axes), len(rates), max(rates), "show an event", "show one",
                           "no event in any record", beyond=strongest_event_beyond(events, max(rates), len(rates))
                           ) if rates and axes else None
    return f"; {text}" if text else ""


def strongest_event_beyond(events, alpha: float, n: int) -> str | None:
    """The clause of the strongest event whose ``p_value`` (the scan's false-alarm rate per record with its
    threshold at the event's z: :func:`imupipe.events.detect_events`) is below alpha / n over the n axes scanned:
    chance gives such an event on any of them with probability below alpha, whatever the count of axes with an event
    says (a 1 mg step at z 45.9, threshold 6.06, read "1 of 3 axes show an event, consistent with chance": an outside
    evaluation). None where no event is that strong or the outliers files lack p_value."""
    strong = [it for it in events if isinstance(it, Mapping) and it.get("p_value") is not None
              and float(it["p_value"]) < alpha / max(n, 1)]
    if not strong:
        return None
    it = min(strong, key=lambda e: float(e["p_value"]))
    where = "/".join(str(it[k]) for k in ("dataset", "sensor", "axis") if it.get(k) is not None)
    return (f"the strongest, a {it.get('kind', 'event')} on {where} at z {num(it.get('z'), '{:.3g}')} (threshold "
            f"{num(it.get('threshold_z'), '{:.3g}')}), has p = {float(it['p_value']):.2g} per record, below alpha / {n}"
            f" = {alpha / max(n, 1):.2g}")


def level_change_note(where: str, stationarity: Mapping, items=()) -> str:
    """An event FLAG's note where the record's axis (``dataset/sensor/axis``) or, for a record's group of events
    (``dataset/sensor``), any of its axes fails the stationarity test or is bounded at its noisiest stretch: a level
    change also reads as mean steps (white noise 3x over half a record gave 7 "mean steps"). Empty otherwise, and
    for the one event of its axis (`items`: the run's events): one mean step fails the stationarity test by itself (an
    outside evaluation's 1 mg step read as a possible level change)."""
    parts = where.split("/")
    if len(parts) >= 3 and sum(1 for it in items or () if isinstance(it, Mapping) and
                               [str(it.get(k)) for k in ("dataset", "sensor", "axis")] == parts[:3]) == 1:
        return ""
    curves = stationarity.get("curves")
    failed = [c for c in (curves if isinstance(curves, list) else []) if isinstance(c, Mapping)
              and (c.get("stationary") is False or c.get("noisiest_stretch"))
              and str(c.get("dataset")) == parts[0] and (len(parts) < 3 or str(c.get("axis")) == parts[2])]
    if not failed:
        return ""
    axes = sorted({str(c.get("axis")) for c in failed})
    which = f"axis {axes[0]} also fails" if len(axes) == 1 else f"axes {', '.join(axes)} also fail"
    return (f"; the record's {which} the stationarity test or its stretch test: a change of the noise level, not of "
            "the mean, reads as mean steps too (look at the record's spread over time)")


def step_scan_text(floors: list, rates: list) -> str | None:
    """The details' line on what the event scan can see: its false-alarm rate per record and axis (`rates`, the
    outliers files' ``events_scan``) and the least mean step its step scan reports on each axis (`floors`: the
    outliers files' ``step_scan.smallest_step`` with its window and display, tagged with dataset and axis), their
    range over the axes and the axis where it is largest. A smaller step stays in the records as low-frequency
    noise, which the bound covers, without a FLAG that names it (an outside evaluation's 10 deg/h step in a 3 h
    record whose scan reported steps above 12.6 deg/h). None without floors."""
    floors = [f for f in floors or [] if isinstance(f, Mapping) and f.get("smallest_step") is not None]
    if not floors:
        return None
    disp = [f.get("smallest_step_display") if isinstance(f.get("smallest_step_display"), Mapping) else None
            for f in floors]
    unit = disp[0]["unit"] if all(disp) and len({d["unit"] for d in disp}) == 1 else None
    size = [(d["size"] if unit else f["smallest_step"]) for f, d in zip(floors, disp)]
    worst = max(range(len(floors)), key=lambda i: size[i])
    w = floors[worst]
    rate = f" at a false-alarm rate of {num(max(rates))} per record and axis" if rates else ""
    span = num(min(size), "{:.3g}") + ("" if num(min(size), "{:.3g}") == num(size[worst], "{:.3g}") else
                                        f" to {num(size[worst], '{:.3g}')}")
    return (f"- event scan (outliers stage, each full-rate record){rate}: the least mean step it reports is {span} "
            f"{unit or '(SI units)'} over the axes (threshold x sigma_D at the best window; largest on "
            f"{w.get('dataset')}/{w.get('axis')}, window {num(w.get('smallest_step_tau_s'))} s): a smaller step stays "
            "in the record as low-frequency noise, which the bound covers, without a FLAG that names it")
