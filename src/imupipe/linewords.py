"""The words of spectral lines in the run summary: the FLAG of each line, once per line over the axes and records
it is seen on, and the band the line search covered.

The lines stage (:func:`imupipe.lines.find_lines`) writes one file per dataset, sensor type and axis; a line of the
sensor (a cooling fan, a dither frequency) is often found on every axis of every record. The summary names it once:
two lines each of whose frequency lies in the other's full-rate interval are one line
(:func:`imupipe.lines.same_line_groups`, the rule by which the bound merges them). Plain dicts in (the lines files'
entries, tagged with dataset, sensor, axis and units by the summary stage), strings out.
"""

from __future__ import annotations

from collections.abc import Mapping

from imupipe.shown import num

__all__ = ["MAX_LINE_FLAGS", "line_chance", "line_reports", "line_text", "search_band_text"]

#: a sensor type with more lines than this (each counted once over its axes and records) has them FLAGged in one
#: line (each stays in its lines file)
MAX_LINE_FLAGS = 2


def line_text(it: Mapping, confidence: float | None = None) -> tuple[str, str]:
    r"""Where one narrowband line is (``dataset/sensor/axis``, else its ``curve``) and what it is: its frequency
    (Hz), its sinusoid amplitude :math:`A = \sqrt{2 P_1}` in the sensor's unit (the lines file's ``units``) with its sd
    :math:`\sqrt{P_1}` beside it (else the sd alone) and, with `confidence` and the line's ``dof``, the sd's upper
    limit at that level (:func:`imupipe.lines.line_power_upper`: what the upper envelope holds; an estimate from a
    few looks can lie well under a wandering line's truth), and its peak PSD over the running-median floor
    (``peak_ratio``, dimensionless)."""
    units = it.get("units") if isinstance(it.get("units"), Mapping) else {}
    where = "/".join(str(it[k]) for k in ("dataset", "sensor", "axis") if it.get(k) is not None)
    f = _frequency(it)
    parts = [f"{num(f, '{:.4g}')} Hz" if f is not None else "frequency -"]
    if it.get("amplitude") is not None:  # the peak; its sd beside it, the quantity the values to paste give
        sd = f" (sd {num(it['sigma'])}{_sd_limit(it, confidence)})" if it.get("sigma") is not None else ""
        parts.append(f"amplitude {num(it['amplitude'])} {units.get('amplitude', '(unit not stated)')}{sd}")
    elif it.get("sigma") is not None:
        parts.append(f"sigma {num(it['sigma'])} {units.get('sigma', '(unit not stated)')}")
    if it.get("peak_ratio") is not None:
        parts.append(f"peak PSD {num(it['peak_ratio'])}x the floor")
    return where or str(it.get("curve", "-")), ", ".join(parts)


def _sd_limit(it: Mapping, confidence: float | None) -> str:
    """``", at most X at c"``: the upper limit of a line's sd at `confidence` (its ``power`` u^2 and ``dof``), or ""."""
    if confidence is None or it.get("dof") is None or it.get("power") is None:
        return ""
    from imupipe.lines import line_power_upper

    return f", at most {num(line_power_upper(float(it['power']), it['dof'], confidence) ** 0.5)} at {float(confidence):g}"


def line_reports(items: list, confidence: float | None = None) -> list[tuple[str, str, list[str]]]:
    """The FLAG texts of the lines `items` of one sensor type: (where, detail, the places of its members).

    One per line (:func:`line_text`); a line seen on several axes or records (each member's frequency in another's
    full-rate interval ``f_lo_hz`` to ``f_hi_hz``; an entry without them occupies its frequency alone) one text
    naming every axis and its strongest member (largest peak over the floor); more than :data:`MAX_LINE_FLAGS` lines
    (an accelerometer's line with its sidebands and harmonics) one text naming every frequency, on how many axes
    each is seen, and the strongest line. `confidence`: each sd's upper limit at that level (:func:`line_text`)."""
    from imupipe.lines import same_line_groups

    texts = [line_text(it, confidence) for it in items]
    placed = [j for j, it in enumerate(items) if _frequency(it) is not None]  # an entry without one: a line apart

    def where(it):
        f, lo, hi = float(_frequency(it)), it.get("f_lo_hz"), it.get("f_hi_hz")
        return (f, float(lo), float(hi)) if lo is not None and hi is not None else (f, f, f)

    groups = [[placed[k] for k in g] for g in same_line_groups([where(items[j]) for j in placed])]
    groups += [[j] for j in sorted(set(range(len(items))) - set(placed))]

    def strongest(g):
        top = max(g, key=lambda j: float(items[j].get("peak_ratio") or 0.0))
        return f"the strongest [{texts[top][0]}]: {texts[top][1]}"

    def seen(g):  # on how many axes the line is seen, and in how many detections (axes x records)
        n = len({str(texts[j][0]).rsplit("/", 1)[-1] for j in g})
        return (f"{n} axes" if n > 1 else "one axis") + (f", {len(g)} detections" if len(g) > n else "")

    def axes(g):
        return f" ({seen(g)})" if len(g) > 1 else ""

    if len(groups) > MAX_LINE_FLAGS:
        every = [j for g in groups for j in g]
        return [(_places(texts, every), f"{len(groups)} lines at "
                 + ", ".join(_frequencies(items, g) + axes(g) for g in groups) + f" Hz; {strongest(every)}",
                 [texts[j][0] for j in every])]
    return [(texts[g[0]][0], texts[g[0]][1], [texts[g[0]][0]]) if len(g) == 1 else
            (_places(texts, g), f"one line ({seen(g)}) at {_frequencies(items, g)} Hz; {strongest(g)}",
             [texts[j][0] for j in g]) for g in groups]


def line_chance(merged: Mapping) -> str:
    """``"; k of n axes show a line ..."``: how many of the searched series (records x axes) show a line against what
    the search's family-wise false-alarm level gives with no line in any record
    (:func:`imupipe.verdict.chance_failures`; `merged`: a sensor's run files merged, ``line_search`` one entry per
    lines file with its ``alpha``, ``lines`` the found lines tagged with their dataset and axis); empty without them.
    A line on a record whose truth has none reads as a FLAG like any other: this says how many the level explains."""
    from imupipe.verdict import chance_failures

    alphas = [float(s["alpha"]) for s in merged.get("line_search") or [] if isinstance(s, Mapping) and s.get("alpha")]
    found = {(it.get("dataset"), it.get("axis")) for it in merged.get("lines") or []
             if isinstance(it, Mapping) and it.get("dataset") is not None}
    text = chance_failures(len(found), len(alphas), max(alphas), "show a line", "show one", "no line in any record",
                           beyond=_strongest_beyond(merged)) if alphas and found else None
    return f"; {text}" if text else ""


def _strongest_beyond(merged: Mapping) -> str | None:
    r"""The clause of the most significant line (the largest r / t) whose peak-to-floor ratio r exceeds the detection
    threshold t of its own search at the level alpha / n over all n series searched
    (:func:`imupipe.lines.detection_threshold` with that search's tested bins M, segments K and floor window W, the
    narrowest of a low band's; the search at the line's resolution: the first, a scale or a low band): a line chance
    gives with probability below alpha / n on its series, so below alpha over all of them, whatever the count of
    series with a line says (a 30 deg/h line 805x its floor read "1 of 3 axes show a line, consistent with chance":
    an outside evaluation). None where no line is that strong or the lines files lack the search's statement."""
    from imupipe.lines import detection_threshold

    searches = [s for s in merged.get("line_search") or [] if isinstance(s, Mapping) and s.get("alpha")]
    best = None
    for it in merged.get("lines") or []:
        if not isinstance(it, Mapping) or it.get("peak_ratio") is None or it.get("resolution_hz") is None:
            continue
        own = next((s for s in searches if (s.get("dataset"), s.get("axis")) == (it.get("dataset"), it.get("axis"))),
                   None)
        subs = ([own] + list(own.get("scales") or []) + [own[k] for k in ("low_band", "low_band_finer") if own.get(k)]
                if own else [])
        sub = next((s for s in subs if s.get("n_tested") and s.get("resolution_hz") and
                    abs(float(s["resolution_hz"]) - float(it["resolution_hz"])) <= 1e-9 * float(s["resolution_hz"])),
                   None)
        if sub is None:
            continue
        K = float(sub.get("effective_segments") or sub.get("n_segments") or 1)
        W = sub.get("floor_window_min_bins") or own.get("floor_window_bins")  # the low band's narrowest: the highest
        t = detection_threshold(float(own["alpha"]) / len(searches), int(sub["n_tested"]), K, int(W) if W else None)
        r = float(it["peak_ratio"])
        if r > t and (best is None or r / t > best[0] / best[1]):
            best = (r, t)
    if best is None:
        return None
    return (f"the most significant, {num(best[0], '{:.3g}')}x its floor, above its search's threshold at alpha / "
            f"{len(searches)} ({num(best[1], '{:.3g}')}x)")


def _frequencies(items: list, g: list) -> str:
    """The frequency of the lines `g` of `items` (a number, Hz), or their range where they differ in 4 digits."""
    fr = sorted(float(f) for f in (_frequency(items[j]) for j in g) if f is not None)
    if not fr:
        return "-"
    lo, hi = num(fr[0], "{:.4g}"), num(fr[-1], "{:.4g}")
    return lo if lo == hi else f"{lo}-{hi}"


def _frequency(it: Mapping):
    """A line entry's frequency (Hz): ``frequency_hz`` of a lines file, ``f0_hz`` of a narrowband term; None."""
    return it.get("frequency_hz", it.get("f0_hz"))


def _places(texts: list, g: list) -> str:
    """The places of the lines `g`, each record's axes together (``imu1/accel/x,y,z; imu2/accel/x``)."""
    by: dict = {}
    for j in g:
        head, _, axis = texts[j][0].rpartition("/")
        by.setdefault(head, [])
        if axis not in by[head]:
            by[head].append(axis)
    return "; ".join((f"{head}/" if head else "") + ",".join(sorted(axes)) for head, axes in by.items())


def search_band_text(searches: list) -> str | None:
    """The band the line search covered on the sensor's full-rate records, from the lines files' ``f_min_hz``,
    ``f_max_hz`` (Hz), ``resolution_hz`` (Hz), ``alpha`` and, where it ran, ``low_band`` (the search below the
    first one's band: its ``f_max_hz`` and ``resolution_hz``) and ``bursts_filled`` (the stretches, s, the search
    read filled: :func:`imupipe.stages.outliers.line_search_series`) (each a list over the files; None: no lines
    file).

    The lowest searched frequency is half a running-median window above 0 (:func:`imupipe.lines.find_lines`:
    ``(floor_window_bins // 2 + 1) * resolution_hz``, of the low band's resolution where it ran), where the floor
    is two-sided. A line below it is not searched: it stays in the sample spectra as broadband power, which every
    bound covers as the records hold it (the data check holds each candidate above the spectra's lower limits), not
    as a narrowband term; a line coherent beyond the record is one draw of its amplitude there, and its process may be
    larger (an outside evaluation: a 20 deg/h line at 0.0022 Hz, unsearched, in 2 h records holding 0.34-0.37 of its
    power, MSE/P 1.14 and 1.36)."""
    if not searches:
        return None
    lows = [s["low_band"] for s in searches if isinstance(s.get("low_band"), Mapping)]
    finer = [s["low_band_finer"] for s in searches if isinstance(s.get("low_band_finer"), Mapping)]

    def span(key, fmt="{:.4g}", rows=searches):
        vals = sorted({float(s[key]) for s in rows if s.get(key) is not None})
        if not vals:
            return "-"
        lo, hi = num(vals[0], fmt), num(vals[-1], fmt)
        return lo if lo == hi else f"{lo}-{hi}"

    part = f"in {len(lows)} of {len(searches)} records, " if len(lows) < len(searches) else ""
    low = (f" ({part}below {span('f_max_hz', rows=lows)} Hz at {span('resolution_hz', rows=lows + finer)} Hz: "
           "lines.low_band_resolution_hz" + (" and half of it" if finer else "") + ")") if lows else ""
    filled = [st for s in searches for st in (s.get("bursts_filled") or []) if isinstance(st, Mapping)]
    seconds = sum(float(st["stop_s"]) - float(st["start_s"]) for st in filled)
    burst = (f"; {len(filled)} burst stretch(es), {num(seconds, '{:.3g}')} s in all, read filled so that a "
             "knock's ringing is not taken for a line" if filled else "")
    return (f"- line search (lines stage, each full-rate record{burst}): bins tested {span('f_min_hz')} to "
            f"{span('f_max_hz')} Hz at {span('resolution_hz')} Hz resolution{low} (a found line's centre may lie up "
            f"to 2 bins outside: its main lobe), family-wise level {span('alpha')} per record and axis; a line below "
            f"{span('f_min_hz')} Hz is not searched for: it stays in the spectra as broadband power, which the bound "
            "covers as the records hold it, not as a line term (a line coherent beyond a record is one draw of its "
            "amplitude there: more or longer records cover it; "
            + ("a finer lines.low_band_resolution_hz lowers the limit)" if lows else
               "lines.low_band_resolution_hz, e.g. 1 / psd.window_s, lowers the limit)"))
