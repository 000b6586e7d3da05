"""What events.policy split does to one full-rate axis: the events found (imupipe.events), the segments kept for a
minimum segment length (imupipe.segments), and the overlapping Allan deviation and the fitted random walk K of the
whole record against the estimate pooled over the segments. Prints one table (SI: ADEV in the series' unit, K in
unit/sqrt(s)).

``python benchmarks/split_effect.py --min-segment-s 1800 results/<name>/series/<dataset>/accel/x.nc ...``
(full-rate series written by the ingest rule; the fit: white, GM, flicker, random walk, no bootstrap).
"""

from __future__ import annotations

import argparse

import numpy as np

from imupipe.allan import allan_variance_labelled
from imupipe.events import detect_events
from imupipe.identify import fit_allan
from imupipe.io import read_series
from imupipe.segments import pooled_allan, split_at_events

TAUS_S = (100.0, 1000.0)


def _k(av) -> float:
    fit = fit_allan(av.coords["tau"][0], av.data_vars["avar"][0], av.data_vars["edf"][0],
                    components=("white", "gauss_markov", "flicker", "random_walk"), n_boot=0)
    return float(fit.model.random_walk)


def _adev(av, tau: float) -> float:
    t = av.coords["tau"][0]
    return float(np.sqrt(np.interp(np.log(tau), np.log(t), av.data_vars["avar"][0])))


def row(path: str, min_segment_s: float, burst_window_s: float) -> list:
    x, rate, attrs = read_series(path)
    label = "/".join(str(attrs.get(k)) for k in ("dataset", "sensor", "axis"))
    events = detect_events(x, rate, sensor=attrs.get("sensor"))["events"]
    try:
        seg = split_at_events(x.size, rate, events, guard=int(round(burst_window_s * rate)),
                              min_samples=int(np.ceil(min_segment_s * rate)), where=label)
    except ValueError:
        seg = None
    whole = allan_variance_labelled(x, rate)
    out = [label, str(len(events))]
    if seg is None:
        return out + ["none >= min", "-"] + [f"{_adev(whole, t):.3g} / -" for t in TAUS_S] + [f"{_k(whole):.3g} / -"]
    pooled = whole if seg.is_whole else pooled_allan(x, rate, seg)
    kept = f"{len(seg.bounds)} ({100 * seg.lengths.sum() / x.size:.0f} %)"
    return out + [kept, str(len(seg.dropped))] + [f"{_adev(whole, t):.3g} / {_adev(pooled, t):.3g}" for t in TAUS_S] + [
        f"{_k(whole):.3g} / {_k(pooled):.3g}"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("series", nargs="+")
    ap.add_argument("--min-segment-s", type=float, default=3600.0, help="shortest segment kept (psd.window_s), s")
    ap.add_argument("--burst-window-s", type=float, default=1.0, help="guard on each side of an event, s")
    args = ap.parse_args()
    head = ["axis", "events", "segments kept", "dropped"] + [f"ADEV({t:g} s) whole / split" for t in TAUS_S] + [
        "K whole / split"]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for path in args.series:
        print("| " + " | ".join(row(path, args.min_segment_s, args.burst_window_s)) + " |", flush=True)


if __name__ == "__main__":
    main()
