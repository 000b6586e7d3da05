"""Outliers, stuck spans and events of one full-rate axis (rule ``outliers``).

The Hampel/MAD rule with the ``outliers`` policy (:func:`imupipe.outliers.screen_outliers`), the stuck spans
(:func:`imupipe.outliers.stuck_spans`) and the bursts and steps (:func:`imupipe.events.detect_events`) with the
``events`` policy:

- ``warn``: every event is reported (dataset, axis, time from the record's start in s, size in SI and in the
  display unit, kind) and the summary FLAGs it; the data are analysed as recorded, but for the line search, which
  reads each burst's stretch filled (:func:`line_search_series`: a knock's ringing is no line);
- ``exclude``: as ``warn``, and the series the modelling stages read is the longest event-free segment of the
  record (:func:`imupipe.events.event_free_segment`, each event widened by one burst window), written as the
  cleaned series (outliers replaced first when ``outliers.policy`` is ``remove``). A segment shorter than
  ``min_segment_s`` is an error naming the axis;
- ``split``: as ``warn``, and the record is cut at each event (widened by one burst window) into
  event-free segments (:func:`imupipe.segments.split_at_events`) that the modelling stages analyse as records of
  the dataset and axis (decimation, PSD windows, Allan differences, lines, stationarity and the replay never
  straddle a cut: :mod:`imupipe.segments`); segments shorter than ``min_segment_s`` are dropped and reported, and
  none left is an error naming the axis. The report's ``events_segments`` holds the segments (the workflow writes
  them to the axis's segments file). Without events the one segment is the whole record: the analysis is
  ``warn``'s, to the byte.

Plain values in (the series in SI, its rate in Hz, its labels and the settings), the report's dict and the series
the modelling stages read out (:func:`outliers_stage`).
"""

from __future__ import annotations

import math

__all__ = ["EVENT_DEFAULTS", "EFFECT_NOTE", "line_search_series", "outliers_stage"]

EFFECT_NOTE = {
    "remove": "the cleaned series (outliers replaced by their block median) feeds allan, decimate and lines",
    "warn": "data kept as recorded: the effect is what `remove` would change",
    "fail": "no outlier found (any outlier stops the run)",
}

#: Settings of the ``events`` section used when a config has none (config/README.md).
EVENT_DEFAULTS = {"policy": "warn", "alpha": 0.01, "burst_window_s": 1.0, "burst_k": 7.0, "min_scale_s": 1.0,
                  "min_windows": 50, "confidence": 0.95}


def outliers_stage(x, rate: float, *, units: str, dataset=None, sensor=None, axis=None, policy: str = "warn",
                   k: float = 7.0, window_samples: int = 100, max_indices: int = 100, events: dict | None = None,
                   min_segment_s: float = 0.0, series: str | None = None):
    """The outliers report of the full-rate series `x` (`units`, SI) at `rate` (Hz) and the series the modelling
    stages read: (report dict, x_out), x_out None when they read the series as recorded (module docstring).

    `events` holds the ``events`` settings (:data:`EVENT_DEFAULTS` fill what it lacks); `min_segment_s` (s) is the
    shortest event-free segment ``exclude`` and ``split`` keep; `series` names the file in messages."""
    from imupipe.events import POLICIES, detect_events, event_free_segment
    from imupipe.outliers import removal_effect, screen_outliers, stuck_spans

    import numpy as np

    x = np.asarray(x, dtype=np.float64).ravel()  # what every call below reads (copied only if x is not)
    ev_cfg = {**EVENT_DEFAULTS, **(events or {})}
    ev_policy = ev_cfg["policy"]
    label = "/".join(str(v) for v in (dataset, sensor, axis) if v is not None) or (series or "series")
    if ev_policy not in POLICIES:
        raise ValueError(f"events.policy must be one of {POLICIES}, got {ev_policy!r}")
    try:
        x_out, report = screen_outliers(x, policy=policy, k=k, window=window_samples, label=label, units=units)
    except ValueError as exc:
        raise ValueError(f"{series or label}: {exc} (config key outliers.policy = 'fail')") from None
    removed = x_out
    if report.n_outliers and policy != "remove":
        removed, _ = screen_outliers(x, policy="remove", k=k, window=window_samples, label=label, units=units)
    effect = removal_effect(x, removed, rate)
    # no copy of the record is held through the event scan: under remove the cleaned copy is rebuilt at the
    # end from its replaced samples (the same values)
    replaced = (report.indices, x_out[report.indices]) if x_out is not x else None
    del removed, x_out
    effect["note"] = EFFECT_NOTE[policy]
    effect["units"] = {"tau0_s": "s", "avar_tau0_before": f"({units})^2", "avar_tau0_after": f"({units})^2",
                       "avar_ratio": "1", "white_noise_ratio": "1"}
    out = {"dataset": dataset, "sensor": sensor, "axis": axis, "series": series, "rate_hz": float(rate),
           **report.to_dict(max_indices=max_indices), "threshold": float(k), "effect": effect}
    stuck = stuck_spans(x, rate)  # on the record as read: a stuck stretch is no outlier, the rule leaves it
    out["stuck_spans"] = stuck["spans"]
    out["n_stuck_spans"] = stuck["n_stuck_spans"]
    out["stuck_rule"] = (f"runs of >= {stuck['min_run_samples']} identical samples ({stuck['min_run_s']:g} s): "
                         f"expected chance runs (n - 1) p0 q^(r - 2) < {stuck['alpha']:g} with p0 = {stuck['p0']:.4g}, "
                         f"q = {stuck['q']:.4g}, and at least 1 s")
    # events on the record as read (a knock is what the Hampel rule would partly remove)
    det = detect_events(x, rate, alpha=ev_cfg["alpha"], burst_window_s=ev_cfg["burst_window_s"],
                        burst_k=ev_cfg["burst_k"], min_scale_s=ev_cfg["min_scale_s"],
                        min_windows=ev_cfg["min_windows"], confidence=ev_cfg["confidence"], sensor=sensor)
    n = int(x.size)
    seg = (0, n)
    guard = int(round(ev_cfg["burst_window_s"] * rate))
    segments = None
    if ev_policy == "split":
        from imupipe.segments import Segments, split_at_events

        segments = (split_at_events(n, rate, det["events"], guard=guard,
                                    min_samples=int(math.ceil(min_segment_s * rate - 1e-9)), where=series or label)
                    if det["events"] else Segments.whole(n, rate))
    if ev_policy == "exclude" and det["events"]:
        seg = event_free_segment(n, det["events"], guard=guard)
        if (seg[1] - seg[0]) / rate < min_segment_s:
            raise ValueError(
                f"{series or label}: events.policy = 'exclude' leaves {(seg[1] - seg[0]) / rate:.0f} s "
                f"(samples {seg[0]}-{seg[1]}) between {len(det['events'])} event(s), shorter than the "
                f"{min_segment_s:g} s the analysis needs (psd.window_s); use events.policy = 'warn'")
    keep = {"kind", "time_s", "start_s", "stop_s", "size", "size_low", "size_high", "confidence", "z",
            "threshold_z", "scale_s", "size_scale_s", "display", "p_value", "within_burst_s"}
    if ev_policy == "split":
        kept = int(segments.lengths.sum())
        action = (f"cut: the record is analysed as {len(segments.bounds)} segment(s) ({segments.describe()}, "
                  f"{100.0 * kept / n:.3g} % of the record)" + (
                      f"; {len(segments.dropped)} event-free stretch(es) shorter than {min_segment_s:g} s dropped"
                      if segments.dropped else ""))
    else:
        action = ("kept in the analysis (events.policy warn)" if ev_policy == "warn" else
                  f"excluded: the analysis uses {seg[0] / rate:.1f}-{seg[1] / rate:.1f} s, the longest event-free "
                  f"segment ({100.0 * (seg[1] - seg[0]) / n:.3g} % of the record)")
    from imupipe.events import event_effects

    # what an event left in the analysed data does to the model (warn: N at tau0 with/without a burst's samples,
    # the random walk a step acts as)
    effects = (event_effects(x, rate, det["events"], guard=guard, sensor=sensor) if ev_policy == "warn"
               else [None] * len(det["events"]))
    out["events"] = [{"dataset": dataset, "sensor": sensor, "axis": axis,
                      **{k2: v for k2, v in e.items() if k2 in keep}, "units": units, "policy": ev_policy,
                      "action": action, **({"effect": eff} if eff is not None else {})}
                     for e, eff in zip(det["events"], effects)]
    out["n_events"] = len(det["events"])
    out["events_policy"] = ev_policy
    out["events_scan"] = {"false_alarm_rate_per_record": det["false_alarm_rate"], "burst_scan": det["burst_scan"],
                          "step_scan": det["step_scan"]}
    out["events_segment"] = {"start_s": seg[0] / rate, "stop_s": seg[1] / rate, "fraction": (seg[1] - seg[0]) / n}
    if segments is not None:
        out["events_segments"] = {"dataset": dataset, "sensor": sensor, "axis": axis, "series": series,
                                  **segments.to_dict()}
    out["units"] = {**out["units"], "rate_hz": "Hz", "threshold": "robust standard deviations (1.4826 MAD)",
                    "stuck_spans": {"start_s": "s from the record's start", "stop_s": "s from the record's start",
                                    "value": units, "n_samples": "samples", "fraction": "of the record's samples"},
                    "events": {"time_s": "s from the record's start", "size": units, "z": "robust sds of the scan",
                               "display": "spec-like unit (deg/h, mg for steps; deg/s, g for bursts)",
                               "p_value": "probability per record: the scan's false-alarm rate with its threshold "
                                          "at this z (imupipe.events.detect_events)",
                               "within_burst_s": "s from the record's start: where the step lies, a burst stretch "
                                                 "the step scan read filled with the samples its levels came from"},
                    "events_scan": {"step_scan": {"tau_s": "s", "sigma_d": units, "threshold_z": "robust sds",
                                                  "smallest_step": units, "smallest_step_tau_s": "s"},
                                    "burst_scan": {"window_s": "s", "threshold_z": "robust sds"}},
                    "events_segment": "s from the record's start"}
    x_seg = None
    if ev_policy == "exclude" or policy == "remove":
        if replaced is None:
            x_seg = x[seg[0]:seg[1]]
        else:
            x_seg = x[seg[0]:seg[1]].copy()
            inside = (replaced[0] >= seg[0]) & (replaced[0] < seg[1])
            x_seg[replaced[0][inside] - seg[0]] = replaced[1][inside]
    return out, x_seg


def line_search_series(x, rate: float, events: dict | None) -> tuple:
    """The series the line search reads (rule lines) and the stretches filled in it, ((start_s, stop_s), ...) s:
    under events.policy warn `x` (u at `rate` Hz) with its bursts filled (:func:`imupipe.events.fill_bursts` with
    the burst settings of `events`, :data:`EVENT_DEFAULTS` filling what it lacks: the bursts the outliers report
    lists for the same series); under the other policies `x` and () (split and exclude cut the bursts out), and
    with `events` None (no burst search) `x` and ().

    Under warn a burst stays in the data every other stage reads (the bound covers its power as broadband power),
    but its ringing is no stationary line: left in the line search, a knock ringing at 4.7, 12.3 and 31 Hz for 2 s
    of a 2 h record was found as three lines and exported as filter states. The scan runs again here rather than
    the lines job reading the outliers report, so that an outliers setting (outliers.k) re-runs no line search."""
    from imupipe.events import fill_bursts

    cfg = {**EVENT_DEFAULTS, **(events or {})}
    if events is None or cfg["policy"] != "warn":
        return x, ()
    return fill_bursts(x, rate, alpha=float(cfg["alpha"]), burst_window_s=float(cfg["burst_window_s"]),
                       burst_k=float(cfg["burst_k"]))
