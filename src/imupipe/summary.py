"""The run summary: the answer of a run in plain text / markdown (``results/.../summary.md``), first screen first.

The first screen (:func:`summary_sections`, up to :data:`DETAILS_HEADING`): the verdict per sensor, the values to
paste (the KF file's exported model and Kalibr's densities, one table in the spec sheet's units and one in SI) and
every FAIL / FLAG line. The details, per sensor type: bounded yes/no and the margin (min over curves and
frequencies of S_model/S_sample), the inflation table (spec sheet vs bound, in the spec sheet's units), the
states the filter keeps and why. The checks (stuck channels first, then stationarity, fit adequacy, Allan-domain check,
narrowband lines, outliers, gaps, verification) with where it is (dataset/axis, frequency, tau). Built from the
per-sensor YAML files a run writes (the bound contract, the identification, the stationarity summary); keys that
a run does not write are simply absent from the summary (every lookup is tolerant).

Nothing here prints: :func:`render_summary` returns the text.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from imupipe.flagtext import Flag, clauses, flag_line, short_form
from imupipe.eventwords import event_chance, level_change_note, step_scan_text
from imupipe.linewords import line_chance, line_reports, line_text, search_band_text
from imupipe.markdown import markdown_to_html  # the summary's HTML page; kept importable from here
from imupipe.paste import paste_rows  # the first screen's values to paste; kept importable from here
from imupipe.shown import SI_SPELLING, both_units, in_spec_units, num, p_text, ratio_text, spec_unit
from imupipe.verdict import (BOUNDED_TOLERANCE, chance_failures, confidence_lines, nonstationary_qualifier,
                             stretch_note, taken_in_why, unstated_t_max, within_tolerance)


__all__ = ["DETAILS_HEADING", "Flag", "first_screen", "flags_of", "markdown_to_html", "paste_rows", "psd_usage_flags",
           "render_summary", "summary_sections"]


#: PSD margin (min over every sample bin of S_bound / S_sample) from which the data are flagged as far below the
#: spec sheet. The largest of n periodogram ordinates of a PSD S is about S ln(n) (n = 1e3-1e4 bins: 7-9 S), so a
#: margin of 25 puts the data's mean PSD at least ~200x (14x in amplitude) below the bound at every frequency:
#: no sensor beats its data sheet by that much; a unit error (deg/s declared as mrad/s: 17.5x) does.
FAR_BELOW_SPEC_MARGIN = 25.0

#: White-noise ratios (N amplitudes, u/sqrt(Hz)) above which the summary asks for the unit: each the log-midpoint
#: between the largest ratio a correct unit plausibly gives and the smallest common unit slip that inflates, m/s^2
#: declared g (9.81x; then mrad/s declared deg/s 17.5x, deg/s declared rad/s 57.3x, mrad/s declared rad/s or mg
#: declared g 1000x; the gravity check also catches accel slips when three axes are present). A correct unit may be
#: worse than the sheet's typical value by the data sheets' usual typical-to-maximum spread (<= 2x). Data/spec (the
#: identification's upper envelope over the spec sheet) was at most 1.47 on the ADIS16405 and STIM-300 reference
#: records, so a correct unit gives <= 2 * 1.47 = 2.9 and the limit is sqrt(2.9 * 9.81) = 5.4. Bound/spec, used
#: when the envelope is absent, adds the bound's own inflation (it absorbs components the spec sheet lacks): at
#: most 4.31 on the same records, so <= 8.6 and the limit is sqrt(8.6 * 9.81) = 9.2 (under a slip the bound is
#: at least the data's N, so at least 9.81x the spec's). The same bound/spec limit picks the datasets named.
ABOVE_SPEC_RATIO_DATA = (2.0 * 1.47 * 9.80665) ** 0.5
ABOVE_SPEC_RATIO_BOUND = (2.0 * 4.31 * 9.80665) ** 0.5


def _g(d: Any, *keys, default=None):
    """Nested .get tolerant of None and non-dicts."""
    for k in keys:
        if not isinstance(d, Mapping):
            return default
        d = d.get(k)
    return default if d is None else d


def _where_of(item: Mapping) -> str:
    parts = []
    for k in ("curve", "dataset", "sensor", "axis", "f0_hz", "frequency_hz", "tau_s", "start_s", "stop_s",
              "index", "time_s", "row", "file"):
        if k in item and item[k] is not None:
            v = item[k]
            parts.append(f"{k}={num(v, '{:.6g}') if isinstance(v, float) else v}")
    return ", ".join(parts) or "-"


def _detail_of(item: Mapping, skip=()) -> str:
    shown = ("curve", "dataset", "sensor", "axis", "f0_hz", "frequency_hz", "tau_s", "start_s", "stop_s",
             "index", "time_s", "row", "file")
    def text(k, v):  # a ratio keeps the digits that tell it from 1
        return (ratio_text(v) if "ratio" in k else num(v)) if isinstance(v, float) else v

    parts = [f"{k}={text(k, v)}" for k, v in item.items()
             if k not in shown and k not in skip and not isinstance(v, (Mapping, list))]
    return ", ".join(parts)


def _items(obj) -> list:
    """A list of findings from a list, a dict of lists (keyed by curve) or a dict with a list under 'items'."""
    if obj is None or obj is False:
        return []
    if isinstance(obj, list):
        return obj
    if isinstance(obj, Mapping):
        for key in ("items", "found", "lines", "outliers", "gaps"):
            if isinstance(obj.get(key), list):
                return obj[key]
        out = []
        for k, v in obj.items():
            if k == "units":  # the block that names the units of the other keys, not a finding
                continue
            if isinstance(v, list):
                out += [{"curve": k, **x} if isinstance(x, Mapping) else {"curve": k, "value": x} for x in v]
            elif isinstance(v, Mapping):
                out.append({"curve": k, **{kk: vv for kk, vv in v.items() if not isinstance(vv, (Mapping, list))}})
        return out
    return [{"value": obj}]


def _export_rate_detail(exp: Mapping) -> str:
    """The words of a KF file exported at another rate than the verified reference filter."""
    return (f"verified with a reference filter at {num(exp.get('verified_filter_rate_hz'))} Hz, exported at "
            f"{num(exp.get('kf_rate_hz'))} Hz: the verification and any reduction it accepted do not cover the "
            "exported rate (the workflow runs both at application.filter_rate_hz; a KF file from elsewhere must be re-exported)")


def _tolerance_passes(bound: Mapping) -> list[tuple[str, str, str]]:
    """(model, check, statement) of every verification check of the exported models (the global one and each
    per-axis model of the contract) that passed only by its sampling tolerance: worst MSE/P above 1 within
    ``tolerance`` (:func:`imupipe.verdict.within_tolerance`; the contract's own sentence where it has one)."""
    models = [("global model", bound.get("verification"))]
    models += [(f"axis {ax} model", pa.get("verification")) for ax, pa in (bound.get("per_axis_models") or {}).items()
               if isinstance(pa, Mapping) and pa.get("exported_in_kf")]
    out = []
    for label, checks in models:
        for name, c in (checks or {}).items() if isinstance(checks, Mapping) else ():
            if not isinstance(c, Mapping):
                continue
            text = c.get("within_tolerance") or within_tolerance(
                {**c, "method": c.get("method") or ("replay" if name == "replay" else "exact")})
            if text:
                out.append((label, name, text))
    return out


def replay_allowance_flags(sensor: str, bound: Mapping) -> list[Flag]:
    """FLAG each check of an exported model (global or per axis, the KF file's) that passed only by its sampling
    tolerance: a worst MSE/P above 1 within ``tolerance`` (the replay's 1 + replay_z sqrt(2 / n_eff): with few
    windows of short records the tolerance is wide, and the records themselves then show the filter under-stating
    its error without the check failing). Worded as :func:`imupipe.verdict.within_tolerance`."""
    return [Flag(sensor, f"{name} within its tolerance", label, text, "flag",
                 short=clauses(text, ": ")[0] + ": it neither confirms nor excludes an under-statement; record more or "
                 "longer to settle it") for label, name, text in _tolerance_passes(bound)]


def bias_assumption_flags(sensor: str, bound: Mapping) -> list[Flag]:
    """FLAG a P0 resting on a T_max no record checks and no user stated (:func:`imupipe.verdict.unstated_t_max`)."""
    bi = bound.get("bias_initialisation") if isinstance(bound.get("bias_initialisation"), Mapping) else {}
    text = unstated_t_max(bi, both_units(sensor, bound, "gm_sigma", bi["required_std"]) if "required_std" in bi else None)
    return [Flag(sensor, "initial bias", "KF file P0", text)] if text else []


def _level_flags(sensor: str, c, stationarity: Mapping) -> list:
    """The FLAG of a curve `c` of the stationarity summary whose noise level changes along the record by its stretch
    test while the stationarity test passes (its ``noisiest_stretch`` taken in: :mod:`imupipe.stretches`)."""
    if not isinstance(c, Mapping) or c.get("stationary") is False or not c.get("noisiest_stretch"):
        return []
    return [Flag(sensor, "noise level", f"{c.get('dataset', '-')}/{sensor}/{c.get('axis', '-')}",
                 f"the noise level changes along the record (stretch test p = {num(c.get('stretch_test_p'))}, below "
                 f"alpha / {stationarity.get('n_curves')}) though the stationarity test passes (p = "
                 f"{num(c.get('p_value'))}); kept in the bound" + stretch_note(c["noisiest_stretch"]))]


def _stationarity_flags(sensor: str, stationarity: Mapping, stuck_where, line_where) -> list[Flag]:
    """The FLAGs of the stationarity summary's curves: a noise level that changes (:func:`_level_flags`) and each
    non-stationary axis with what was done with it, its stretch, a stuck span or a line on it (`stuck_where`,
    `line_where`: the places of those FLAGs) and the run's count against chance."""
    out = []
    chance = f"; {stationarity['chance']}" if stationarity.get("chance") else ""  # against chance: verdict.py
    for c in stationarity.get("curves") or []:
        out += _level_flags(sensor, c, stationarity)
        if isinstance(c, Mapping) and c.get("stationary") is False:
            where, inc = f"{c.get('dataset', '-')}/{sensor}/{c.get('axis', '-')}", c.get("included")
            text = (f"non-stationary (p = {num(c.get('p_value'))}, {c.get('test', 'test')})"
                    + ("; excluded from the bound" if inc is False else "; kept in the bound" if inc else "")
                    + stretch_note(c.get("noisiest_stretch")) + taken_in_why(c, stationarity)
                    + (STUCK_NOTE if where in stuck_where else "")
                    + (LINE_NOTE.get(str(c.get("test")), "") if where in line_where else ""))
            out.append(Flag(sensor, "stationarity", where, text + chance,
                            short="" if where in stuck_where else short_form(text, chance, keep=2)))
    return out


def _adequacy_flags(sensor: str, identify: Mapping, bound: Mapping) -> list[Flag]:
    """The FLAG of a pooled Allan fit the adequacy test rejects (its statistic, p and what may help), else []."""
    adequacy = _g(identify, "fit", "adequacy") or identify.get("adequacy")
    if not (isinstance(adequacy, Mapping) and adequacy.get("adequate") is False):
        return []
    cov, dof = adequacy.get("chi2_covariance"), adequacy.get("dof")
    # a p from the generalised statistic (the AV points' correlation) says so beside it: Pearson's 1.19 read
    # against p = 2e-122 (an outside evaluation)
    with_cov = (f" (with the AV points' correlation: {num(float(cov) / float(dof))})"
                if "covariance" in str(adequacy.get("method") or "") and cov is not None and dof else "")
    fit = f"chi2/dof = {num(adequacy.get('chi2_per_dof'))}{with_cov}, {p_text(adequacy)}"
    low = any(isinstance(s, Mapping) and s.get("low_band") for s in bound.get("line_search") or [])
    return [Flag(sensor, "fit adequacy", "pooled Allan-variance fit", f"{fit}: the model does not describe the "
                 "Allan variance within its confidence (identify.n_gm: 2, longer records or, for a line below the "
                 f"line search's band, {'a finer ' if low else ''}lines.low_band_resolution_hz may; a resonance "
                 "wider than about a tenth of the search's floor window lifts its own floor and is found too "
                 "weak or not at all: a bump of the Allan deviation near tau = 1/(2 f) shows it"
                 + ("; auto then builds no envelope candidate on a rejected selected model)"
                    if str(bound.get("mode") or "").startswith("auto") else ")"),
                 short=f"{fit}: the model does not describe the Allan variance within its confidence")]


def flags_of(sensor: str, bound: Mapping | None = None, identify: Mapping | None = None,
             stationarity: Mapping | None = None) -> list[Flag]:
    """Every failed or flagged check of one sensor type, from its run files (plain dicts).

    Parameters
    ----------
    sensor : str
    bound : dict, optional
        The bound contract (``bounded``, ``margin``, ``margin_curve``, ``margin_frequency_hz``,
        ``allan_check``, ``per_axis``; optionally ``verified``, ``failed_checks``, ``narrowband``,
        ``excluded``).
    identify : dict, optional
        The identification file (``fit.adequacy``, per-parameter ``on_boundary``, ``lines`` when present).
    stationarity : dict, optional
        The stationarity summary (``curves`` with ``stationary``, ``p_value``, ``included``;
        optionally ``outliers``, ``gaps``).
    """
    out: list[Flag] = []
    bound, identify, stationarity = bound or {}, identify or {}, stationarity or {}
    # a stuck channel first: it explains the non-stationarity and the lines the same record shows below
    stuck = [_stuck_flag(sensor, it) for src in (bound, identify, stationarity)
             for it in _items(src.get("stuck_spans")) if isinstance(it, Mapping)]
    stuck_where = {f.where for f in stuck}
    out += stuck
    from imupipe.events import event_flags  # bursts and steps of the outliers files: the text built there

    chance = event_chance(bound)
    for items in (src.get("events") for src in (bound, identify, stationarity)):
        for (w, d), (_, s) in zip(event_flags(items), event_flags(items, short=True)):
            note = level_change_note(w, stationarity, items)
            out.append(Flag(sensor, "event", w, d + chance + note,
                            short=short_form(s, chance, keep=None) + note if s != d else ""))
    if bound and bound.get("bounded") is False:
        if bound.get("margin") is None or float(bound["margin"]) < 1.0 - BOUNDED_TOLERANCE:
            out.append(Flag(sensor, "bound", f"{bound.get('margin_curve', '-')} at "
                            f"{num(bound.get('margin_frequency_hz'))} Hz",
                            f"not bounded: margin {num(bound.get('margin'), '{:.4g}')} < 1", "fail"))
        else:  # the verdict's own line: which checks made it, the PSD margin holding
            names = sorted({str(fc.get("check")).replace("_", " ") for fc in bound.get("failed_checks") or []
                            if isinstance(fc, Mapping)})
            out.append(Flag(sensor, "verdict", "contract", f"not bounded: failed {', '.join(names) or 'a check'} "
                            f"(lines below); the PSD margin {num(bound.get('margin'), '{:.4g}')} holds", "fail"))
    failed_names = {fc.get("check") for fc in bound.get("failed_checks") or [] if isinstance(fc, Mapping)}
    if bound.get("verified") is False and ("verification" in failed_names or "export_rate" not in failed_names):
        # (a passed verification of a KF file exported at another rate: the export rate line below says it)
        out.append(Flag(sensor, "verification", "bound", "the bound's verification failed", "fail"))
    exp = bound.get("export") if isinstance(bound.get("export"), Mapping) else {}
    rate_failed = False
    for fc in bound.get("failed_checks") or []:
        if isinstance(fc, Mapping) and fc.get("check") == "export_rate":  # one line, in words, for a rate mismatch
            rate_failed = True
            out.append(Flag(sensor, "export rate", "KF file", _export_rate_detail({**exp, **fc}), "fail"))
        elif isinstance(fc, Mapping) and fc.get("check") == "allan_components" and fc.get("ratio") is not None:
            out.append(Flag(sensor, "allan_components", f"tau {num(fc.get('tau_s'))} s",
                            f"the bound's {fc.get('component', '-')} term, with the terms that may represent it "
                            f"(white noise, random walk, lines), has {ratio_text(fc['ratio'])}x the Allan variance of "
                            "the identified term there (the refit as fitted, identify file model_refit; each "
                            "identified component must be bounded by its representation in the bound)", "fail"))
        elif isinstance(fc, Mapping):
            out.append(Flag(sensor, str(fc.get("check", fc.get("name", "check"))), _where_of(fc),
                            _detail_of(fc, skip=("check", "name")) or "failed", "fail"))
        else:
            out.append(Flag(sensor, "check", "-", str(fc), "fail"))
    for comp, v in (bound.get("allan_check") or {}).items():
        if isinstance(v, Mapping) and v.get("passed") is False:
            tau = v.get("tau_at_min")
            out.append(Flag(sensor, "allan check", f"{comp}" + (f" at tau {num(tau)} s" if tau is not None else ""),
                            "bound component below its identified counterpart in the Allan domain"
                            + (f" (margin {num(v.get('margin'))})" if v.get("margin") is not None else "")
                            + (f": {v['reason']}" if v.get("reason") else ""), "fail"))
    for ax, pa in (bound.get("per_axis_models") or {}).items():
        if isinstance(pa, Mapping) and pa.get("exported_in_kf") is False:
            out.append(Flag(sensor, "per-axis model", str(ax),
                            f"not exported: {pa.get('kf', 'its own contract failed')}"))
    margin = bound.get("margin")
    if margin is not None and float(margin) >= FAR_BELOW_SPEC_MARGIN:
        out.append(_far_below_flag(sensor, bound, float(margin)))
    out += above_spec_flags(sensor, bound)
    out += replay_allowance_flags(sensor, bound)
    out += bias_assumption_flags(sensor, bound)
    if exp.get("rate_mismatch") and not rate_failed:  # a contract written before the export_rate check
        out.append(Flag(sensor, "export rate", "KF file", _export_rate_detail(exp)))
    for ax in bound.get("per_axis") or []:
        if isinstance(ax, Mapping) and ax.get("bounded") is False:
            out.append(Flag(sensor, "per-axis bound", str(ax.get("curve", "-")),
                            f"not bounded alone (margin {num(ax.get('margin'))})"))
    for ex in _items(bound.get("excluded")):
        out.append(Flag(sensor, "excluded bins", _where_of(ex), _detail_of(ex) or "left out of the sample constraints"))
    line_items = [it for key in ("lines", "narrowband") for src in (identify, stationarity, bound)
                  for it in _items(src.get(key)) if isinstance(it, Mapping)]
    out += _stationarity_flags(sensor, stationarity, stuck_where, {line_text(it)[0] for it in line_items})
    out += _adequacy_flags(sensor, identify, bound)
    out += consistency_flags(sensor, identify)
    on_b = _g(identify, "fit", "on_boundary") or identify.get("on_boundary")
    moved = [r for r in _items(identify.get("gm_reassigned")) if isinstance(r, Mapping)]
    for r in moved:
        out.append(Flag(sensor, "GM re-assigned", f"gm_{r.get('term')}", reassigned_text(sensor, r, bound),
                        short=reassigned_text(sensor, r, bound, short=True)))
    for ax, pa in (identify.get("per_axis") or {}).items():
        # an axis's own GM whose T interval is open above: its envelope covers the GM over that whole interval (what
        # the per-axis bound, the KF file and Kalibr then carry); the pooled fit's may not show it
        for r in _items(pa.get("gm_reassigned") if isinstance(pa, Mapping) else None):
            if isinstance(r, Mapping) and r.get("T_open_above"):
                own = (bound.get("per_axis_models") or {}).get(ax)  # the axis's own exported model, where it has one
                src = {**bound, **own} if isinstance(own, Mapping) and own.get("exported_in_kf") else bound
                out.append(Flag(sensor, "GM re-assigned", f"axis {ax} gm_{r.get('term')}",
                                reassigned_text(sensor, r, src) + "; its T interval is open above: the axis's upper "
                                "envelope keeps the GM over that interval (identify file per_axis), and its bound "
                                "covers that envelope"))
    moved_terms = {f"gm_{k}_{r.get('term')}" for r in moved for k in ("T", "sigma")}
    if isinstance(on_b, Mapping):
        model = identify.get("model") if isinstance(identify.get("model"), Mapping) else {}
        for p, v in on_b.items():
            if p in moved_terms:  # the full fit's GM the identification re-assigned: flagged as such above
                continue
            # a component's coefficient at its lower limit 0 is that component absent (the selection lists it as
            # dropped; the data's upper limit for it is in the envelope), not a fit pressed against its range
            if not v:
                continue
            if not _kept_parameter(identify, str(p)):
                continue  # the parameter of a component the selection dropped: not in the model, nothing to flag
            value = _g(identify, "fit", "params", p, default=model.get(p))
            if isinstance(value, (int, float)) and float(value) == 0.0 and not str(p).startswith("gm_T"):
                continue  # a coefficient at 0: the component absent (a GM sigma too), not a fit pressed to its range
            out.append(Flag(sensor, "parameter on boundary", str(p), boundary_text(sensor, bound, identify, str(p),
                                                                                    value)))
    level = (bound.get("identification_intervals") or {}).get("confidence")  # the envelope's: its lines' limits
    out += _line_flags(sensor, line_items, stuck_where, line_chance(bound), level)
    out += psd_usage_flags(sensor, bound.get("psd_usage"))
    for key in ("outliers", "gaps"):
        for src in (stationarity, identify, bound):
            for it in _items(src.get(key)):
                if isinstance(it, Mapping):
                    out.append(Flag(sensor, key, _where_of(it), _detail_of(it) or key[:-1]))
                else:
                    out.append(Flag(sensor, key, "-", str(it)))
    return out


#: The identify file's parameter names -> (the key of :func:`both_units`, the words).
_PARAM_WORDS = {"white": ("white", "white noise N"), "random_walk": ("random_walk", "random walk K"),
                "flicker": ("gm_sigma", "flicker B"), "gm_sigma": ("gm_sigma", "GM sigma"), "gm_T": (None, "GM T"),
                "quantization": (None, "quantization Q"), "ramp": (None, "rate ramp R")}


def boundary_text(sensor: str, bound: Mapping | None, identify: Mapping, p: str, value) -> str:
    """The words of a parameter on a limit of its range (identify file ``fit.on_boundary``): its value with its
    unit (spec sheet's and SI, :func:`both_units`; a GM T in s; quantization u s, ramp u/s in SI), which limit and
    the range searched (a GM T: ``fit.T_search_s``, s; a coefficient: [0, inf)), its interval and its kind
    (``fit.intervals``, ``fit.interval_kind``)."""
    base = p.rsplit("_", 1)[0] if p.startswith("gm_") else p
    key, words = _PARAM_WORDS.get(base, (None, p))
    si = {"quantization": "u s", "ramp": "u/s"}.get(base, "SI")

    def show(x):
        if base == "gm_T":
            return f"{num(x)} s"
        return both_units(sensor, bound, key, x) if key else f"{num(x)} {si}"

    shown = show(value) if isinstance(value, (int, float)) else "-"
    iv = _g(identify, "fit", "intervals", p)
    kind = _g(identify, "fit", "interval_kind", p)
    if base == "gm_T":
        lo, hi = (_g(identify, "fit", "T_search_s") or [None, None])[:2]
        where = ("the shortest" if isinstance(value, (int, float)) and isinstance(lo, (int, float))
                 and isinstance(hi, (int, float)) and abs(float(value) - float(lo)) <= abs(float(value) - float(hi))
                 else "the longest")
        text = (f"{words} {shown} sits on {where} time constant searched (range {num(lo)}-{num(hi)} s, "
                "identify file fit.T_search_s)")
    else:
        text = f"{words} {shown} at a limit of its range [0, inf) (a non-negative coefficient)"
    if isinstance(iv, (list, tuple)) and len(iv) == 2:
        text += f"; interval [{show(iv[0]) if iv[0] is not None else '-'}, {show(iv[1]) if iv[1] is not None else 'inf'}]"
    if kind and kind != "two-sided":
        text += f", {kind}"
    return text


def _kept_parameter(identify: Mapping, p: str) -> bool:
    """Whether the fit parameter `p` (``white``, ``gm_T_1``, ...) belongs to a component the identification kept
    (identify file ``selection.kept``); True when the file names no selection."""
    kept = _g(identify, "selection", "kept")
    if not isinstance(kept, (list, tuple)):
        return True
    component = "gauss_markov" if p.startswith("gm_") else p
    return component in kept


def reassigned_text(sensor: str, r: Mapping, bound: Mapping | None = None, short: bool = False) -> str:
    """The words of one GM the identification re-assigned (identify file ``gm_reassigned``: sigma u, T_s s, why,
    acts_as, value: the white noise N u/sqrt(Hz) or random walk K u/sqrt(s) it acts as), every value in the spec
    sheet's unit and in SI (:func:`both_units`), then what the exported filter model carries instead
    (:func:`exported_instead`): the identification reports the GM as the term it acts as; the bound covers the
    identification's upper envelope, and its own GM terms (the KF file's) are not this GM. `short`: the GM, the term
    reported and what would resolve it (the summary's first screen)."""
    white = r.get("acts_as") == "white"
    as_key = "white" if white else "random_walk"
    acts = f"{'white noise N' if white else 'random walk K'}"
    value = f" {both_units(sensor, bound, as_key, r.get('value'))}" if r.get("value") is not None else ""
    gm = (f"the identified GM (sigma {both_units(sensor, bound, 'gm_sigma', r.get('sigma'))}, T {num(r.get('T_s'))} s) "
          "is not resolved by the records")
    text = (f"{gm} ({r.get('why')}). Reported as the {acts}{value} "
            "it acts as (identify file, gm_reassigned)" + ("." if white else
                                " at taus well below T (beyond T its Allan variance falls below that random "
                                "walk's, so a model under it there can still hold the records)."))
    iv, rng = r.get("T_interval_s"), r.get("T_resolved_s")
    lo = (num(iv[0]) if isinstance(iv, (list, tuple)) and iv and iv[0] is not None and math.isfinite(float(iv[0]))
          else None)
    # a T near the shortest the records resolve (e.g. a sample interval): a higher sample rate resolves it; a T they
    # resolve whose interval reaches down there (a 56 s GM in 20 Hz records): more data narrow the interval
    fast = not (isinstance(rng, (list, tuple)) and rng and r.get("T_s") is not None
                and float(r["T_s"]) >= 2.0 * float(rng[0]))
    if short:
        more = "more or longer records" + (f" (its T interval reaches down to {lo} s)" if lo else "")
        cure = ("a higher sample rate" if fast else more) if white else "longer records"
        return (f"{gm}: the identification reports the {acts}{value} it acts as (the KF file holds the bound's own "
                f"terms); to resolve it: {cure}")
    instead = exported_instead(sensor, bound, as_key)
    now = f" (now down to {lo} s)" if lo else ""
    action = (" To resolve it: a higher sample rate (its T lies near the shortest the records resolve; at a filter "
              "step well above T it acts as white noise)." if white and fast else
              f" To resolve it: more or longer records, which narrow its T interval{now}: the records cannot tell it "
              "from white noise at its short end." if white else
              " To resolve it: longer records (the longest T resolved is about 0.23 of the longest tau; identify "
              "file, fit.T_search_s).")
    return text + (f" In the KF file: {instead}." if instead else "") + action


def exported_instead(sensor: str, bound: Mapping | None, as_key: str) -> str:
    """What the exported filter model (the contract's ``model``, the KF file's) carries where the identification
    re-assigned a GM to the term `as_key` (``white`` / ``random_walk``): that term's exported value, and the
    exported GM states, each named as the bound's own term (its LP chooses sigma and T to cover the
    identification's upper envelope and the spec sheet together, so a GM in the KF file is not the re-assigned
    one); "" when the contract states no exported model."""
    m = (bound or {}).get("model")
    if not isinstance(m, Mapping):
        return ""
    name = "white noise N" if as_key == "white" else "random walk K"
    v = m.get(as_key)
    parts = [f"the exported filter model (KF file) has {name} {both_units(sensor, bound, as_key, v)}" if v else
             f"the exported filter model (KF file) has no {'white noise' if as_key == 'white' else 'random walk'}"]
    gms = [g for g in m.get("gauss_markov") or [] if isinstance(g, Mapping) and g.get("sigma")]
    if gms:
        parts.append("and " + "; ".join(f"a GM of sigma {both_units(sensor, bound, 'gm_sigma', g.get('sigma'))}, "
                                        f"T {num(g.get('T'))} s" for g in gms)
                     + ": the bound's own GM term" + ("s" if len(gms) > 1 else "")
                     + " (chosen to cover the upper envelope and the spec sheet together), not this GM")
    else:
        parts.append("and no GM state")
    return " ".join(parts)


#: How the record-consistency table and FLAG name the parameters (the identify file's keys).
_CONSISTENCY_NAMES = {"white": "N", "flicker": "B", "random_walk": "K"}


def consistency_flags(sensor: str, identify: Mapping | None) -> list[Flag]:
    """The FLAG of each record that disagrees with the other records of its sensor type beyond its intervals
    (the identify file's ``record_consistency``, :func:`imupipe.identify.consistency.record_consistency`), worded
    ``FLAG <sensor> record consistency: <dataset> <param> ...``: one record's event must not drive the global model
    unnoticed."""
    rc = (identify or {}).get("record_consistency")
    if not isinstance(rc, Mapping):
        return []
    out = []
    items = [it for it in rc.get("flagged") or [] if isinstance(it, Mapping)]
    key = {"white": "white", "flicker": "gm_sigma", "random_walk": "random_walk"}  # B is a rate (u), as a GM sigma
    for it in items:
        est, oth, param = it.get("estimate"), it.get("others"), it.get("param")
        ratio = (float(est) / float(oth)) if isinstance(est, (int, float)) and isinstance(oth, (int, float)) and oth else None
        pair = [o.get("dataset") for o in items if o.get("param") == param and o is not it]
        who = (f"{it.get('dataset')} and {pair[0]} disagree (two records: which one is off cannot be told); "
               if len(items) >= 2 and len(pair) == 1 and len(rc.get("datasets") or []) == 2 else "")
        out.append(Flag(sensor, f"{sensor} record consistency", "",
                        f"{who}{it.get('dataset')} {_CONSISTENCY_NAMES.get(param, param)} = "
                        f"{both_units(sensor, None, key.get(param, param), est)} is {num(ratio)}x the other "
                        f"records' {both_units(sensor, None, key.get(param, param), oth)} "
                        f"(test z = {num(it.get('z'))}, beyond the critical {num(rc.get('z_crit'))} at family-wise "
                        f"level {num(rc.get('alpha'))}): this record pulls the pooled model; check it for an event "
                        "(identify file, record_consistency)"))
    return out


def _adequacy_table(identify: Mapping) -> list[str]:
    """The details' table of chi2/dof per axis and pooled, before (no line terms) and after (the lines known to
    the fit), from the identify file's ``adequacy_lines``; and which envelope the bound covers where a fit stays
    inadequate."""
    al = identify.get("adequacy_lines")
    if not isinstance(al, Mapping):
        return []
    rows = [("pooled", al.get("pooled") or {})] + [(f"axis {a}", v) for a, v in (al.get("per_axis") or {}).items()]
    out = ["", "Allan-fit adequacy with the spectral lines as known terms (full fit, chi2/dof and p; p <= "
           f"{num(_g(identify, 'fit', 'adequacy', 'level'))}: inadequate):", "",
           "| fit | chi2/dof before (no lines) | p before | chi2/dof after (lines known) | p after |",
           "|---|---|---|---|---|"]
    inadequate = []
    for name, v in rows:
        b, a = (v.get("before") or {}), (v.get("after") or {})
        out.append(f"| {name} | {num(b.get('chi2_per_dof'))} | {p_text(b, label=False)} | "
                   f"{num(a.get('chi2_per_dof'))} | {p_text(a, label=False)} |")
        if a.get("adequate") is False:
            inadequate.append(name)
    if inadequate:
        out += ["", f"- still inadequate: {', '.join(inadequate)}. There the bound covers the parametric upper "
                "envelope of the selected model at its statistical limits (not widened; a model the data reject), "
                "not a nonparametric envelope of the sample spectra; the replay of the records in the verification "
                "is the model-free check"]
    return out + [""]


def _consistency_table(sensor: str, identify: Mapping, bound: Mapping) -> list[str]:
    """The details' table of each record's own N, B, K with intervals (identify file ``record_consistency``), in
    the spec sheet's units where the contract states them."""
    rc = identify.get("record_consistency")
    if not isinstance(rc, Mapping) or not rc.get("rows"):
        return []
    rows = rc["rows"]
    params = [p for p in _CONSISTENCY_NAMES if any(p in r for r in rows.values())]
    b = {"sensor": sensor, **(bound or {})}
    # B (flicker, u) in the unit the contract states for the GM sigma (u too: deg/h, mg, ...)
    key = {p: ("gm_sigma" if p == "flicker" else p) for p in params}
    units = {p: in_spec_units(b, key[p], 1.0)[1] for p in params}
    out = ["", f"Record consistency ({rc.get('method', 'each record fitted alone')}):", "",
           "| record | " + " | ".join(f"{_CONSISTENCY_NAMES[p]} [{units[p]}] (interval) | z" for p in params) + " |",
           "|---|" + "---|---|" * len(params)]
    for rec, per in rows.items():
        cells = []
        for p in params:
            v = per.get(p) or {}

            def conv(x, p=p):
                return None if x is None else in_spec_units(b, key[p], float(x))[0]

            est = conv(v.get("estimate"))
            iv = f"[{num(conv(v.get('lower')))}, {num(conv(v.get('upper')))}]"
            z = v.get("z")
            cells.append(f"{num(est)} {iv}" + (" **named**" if v.get("flagged") else ""))
            cells.append(num(z) if z is not None else (v.get("note") or "-"))
        out.append(f"| {rec} | " + " | ".join(cells) + " |")
    if rc.get("note"):
        out.append(f"- {rc['note']}")
    bad = [d for d, ok in (rc.get("adequate") or {}).items() if ok is False]
    if bad:
        out.append(f"- the own fit of {', '.join(bad)} is inadequate: its intervals are widened by the "
                   "over-dispersion (indicative), so only a difference beyond those wide intervals is named")
    return out + [""]


def above_spec_flags(sensor: str, bound: Mapping | None) -> list[Flag]:
    """The FLAG of white noise far above the spec sheet's: a unit slip (a record in a larger unit than declared).

    Ratios of white-noise densities N (amplitudes, u/sqrt(Hz), SI): data/spec = ``upper_envelope.white /
    spec.white`` (the identification's upper envelope, the largest N the records allow) and bound/spec =
    ``bound.white / spec.white``. A FLAG when data/spec exceeds :data:`ABOVE_SPEC_RATIO_DATA`, or, without an
    envelope, bound/spec exceeds :data:`ABOVE_SPEC_RATIO_BOUND` (their derivation there). The datasets named are
    those whose per-axis bound alone (``per_axis[].inflation.N``, bound/spec) exceeds the bound limit, else every
    dataset of the bound's ``curves``. The mirror of the far-below-spec FLAG (:data:`FAR_BELOW_SPEC_MARGIN`).
    """
    bound = bound or {}

    def ratio(value):
        try:
            n, s = float(value), float(_g(bound, "spec", "white"))
        except (TypeError, ValueError):
            return None
        return n / s if s > 0 and n > 0 else None

    r_bound, r_data = ratio(_g(bound, "bound", "white")), ratio(_g(bound, "upper_envelope", "white"))
    if r_data is not None:
        limit, over = ABOVE_SPEC_RATIO_DATA, r_data > ABOVE_SPEC_RATIO_DATA
    else:
        limit, over = ABOVE_SPEC_RATIO_BOUND, r_bound is not None and r_bound > ABOVE_SPEC_RATIO_BOUND
    if not over:
        return []

    def dataset(curve):
        return str(curve).split("/")[0]

    high = []
    for ax in bound.get("per_axis") or []:
        try:
            if isinstance(ax, Mapping) and float(_g(ax, "inflation", "N")) > ABOVE_SPEC_RATIO_BOUND:
                high.append(dataset(ax.get("curve", "-")))
        except (TypeError, ValueError):
            continue
    if not high:
        high = [dataset(c) for c in bound.get("curves") or []] or [dataset(bound.get("margin_curve", "-"))]
    datasets = ", ".join(dict.fromkeys(high))
    column = f"{sensor}_unit" if sensor in ("gyro", "accel") else "gyro_unit/accel_unit"
    said = [f"bound/spec {num(r_bound)}x" if r_bound is not None else None,
            f"data/spec {num(r_data)}x (the identification's upper envelope)" if r_data is not None else None]
    examples = ("m/s^2 declared g gives 9.81x, mg declared g 1000x" if sensor == "accel" else
                "deg/s declared rad/s gives 57.3x, mrad/s declared rad/s 1000x")
    return [Flag(sensor, "data far above the spec sheet", datasets,
                 f"white noise N {', '.join(x for x in said if x)}, above the {limit:.2g}x a correct unit "
                 f"plausibly gives ({examples}): check the unit of "
                 f"{sensor} (dataset sheet column {column} of {datasets}) and that the spec sheet is this sensor's; "
                 "a burst (a knock) kept in the data raises N the same way: see the event FLAGs (events.policy "
                 "split or exclude leaves it out)")]


#: Share of a record the Welch segments may leave out before the summary flags it: 10 %. With the rule of
#: imupipe.defaults.psd_window_step (step = window/2, window <= a quarter of the record) at most 1/7 is left, and
#: usually much less; a config whose step exceeds the window or whose window does not divide the record leaves more.
UNUSED_RECORD_LIMIT = 0.10


def psd_usage_flags(sensor: str, usage) -> list[Flag]:
    """FLAGs of the records more than :data:`UNUSED_RECORD_LIMIT` of which no Welch segment uses.

    `usage` is a list of mappings with ``n_samples`` and ``n_samples_used`` (the PSD file's attrs, decimated
    samples), optionally ``dataset``, ``axis``, ``rate_hz`` (Hz), ``window_s``, ``step_s`` (s). One FLAG per
    dataset (its axes share the numbers), naming the samples used, the seconds left out and the settings.
    """
    from imupipe.defaults import PSD_MAX_WINDOW_S, psd_window_step, unused_fraction

    out, groups = [], {}
    for u in usage or []:
        if not isinstance(u, Mapping) or u.get("n_samples") is None or u.get("n_samples_used") is None:
            continue
        n, used = int(u["n_samples"]), int(u["n_samples_used"])
        if unused_fraction(n, used) <= UNUSED_RECORD_LIMIT:
            continue
        # one FLAG per shape of the shortfall (records of one length under one window and step), naming them all
        key = (n, used, float(u.get("rate_hz") or 1.0), u.get("window_s"), u.get("step_s"))
        ds = groups.setdefault(key, [])
        if u.get("dataset", "-") not in ds:
            ds.append(u.get("dataset", "-"))
    for (n, used, rate, window_s, step_s), ds in groups.items():
        frac = unused_fraction(n, used)
        hint = ""
        try:
            w, st = psd_window_step(n / rate, rate)
            hint = f"; e.g. psd.window_s: {w:g}, psd.step_s: {st:g} (or leave both unset: that rule is the default)"
        except ValueError:
            pass
        where = f"{ds[0]}/{sensor}" if len(ds) == 1 else f"{len(ds)} records ({', '.join(map(str, ds))})/{sensor}"
        paper = ""
        if window_s is not None and float(window_s) == PSD_MAX_WINDOW_S and step_s is not None and used == round(
                float(window_s) * rate):  # one 7 h window: the paper's setting, which the default run reproduces
            paper = ("; one 7 h window is the paper's setting (Gallon et al. 2021), kept by the default run to "
                     "reproduce it")
        text = (f"the PSD uses {used} of {n} samples ({100 * frac:.0f} % = {(n - used) / rate:g} s of the record left "
                f"out) with psd.window_s = {num(window_s, '{:g}')} s, psd.step_s = {num(step_s, '{:g}')} s: set a step "
                "that tiles the record")
        out.append(Flag(sensor, "record partly unused", where, text + hint + paper,
                        short=text + paper if hint else ""))
    return out


def filled_lines(usage) -> list[str]:
    """The samples ``gap_policy: fill`` made up, per dataset (the PSD files' ``n_filled`` and ``filled_rows``; one
    line, none where nothing was filled)."""
    filled = {}
    for u in usage or []:
        if isinstance(u, Mapping) and int(u.get("n_filled") or 0) > 0:
            rows = [r for r in str(u.get("filled_rows") or "").split(",") if r]
            more = ", ..." if len(rows) > 5 else ""
            filled[u.get("dataset", "-")] = (f"{u.get('dataset', '-')} {int(u['n_filled'])} samples in {len(rows)} "
                                            f"gap(s) (after file rows {', '.join(rows[:5])}{more})")
    return [f"- samples made up by linear interpolation (gap_policy fill): {'; '.join(filled.values())}"
            ] if filled else []


def _export_lines(bound: Mapping, kept) -> list[str]:
    """Summary bullets on the exported filter model (the contract's ``export``, imupipe.kf.export_scope): the states
    the verified reduction dropped and the horizon (s) the export then holds for, the verification rate against the
    export's; and, when identification kept no random walk while the bound has one, what the bound's random walk
    rests on: the upper limit the data leave for the dropped random walk (the identified envelope's K, SI) where
    there is one, else the spec sheet alone."""
    out = []
    exp = bound.get("export")
    if isinstance(exp, Mapping) and exp.get("statement"):
        out.append(f"- exported filter model (KF file): {exp['statement']}")
    if isinstance(exp, Mapping) and exp.get("verified_filter_rate_hz") is not None:
        fix_rate = exp.get("verified_fix_rate_hz") or exp["verified_filter_rate_hz"]
        sig = (f" (sigma {num(exp['verified_sigma_fix'])} {exp.get('verified_sigma_fix_unit') or ''})".rstrip(" ")
               if exp.get("verified_sigma_fix") is not None else "")
        out.append(f"- verified scenario: reference filter at {num(exp['verified_filter_rate_hz'])} Hz, fixes at "
                   f"{num(fix_rate)} Hz{sig} for {num(exp.get('fix_s'))} s, then an outage of "
                   f"{num(exp.get('horizon_s'))} s (application.filter_rate_hz, verify.fix_rate_hz, "
                   "verify.fix_s, application.outage_s)")
    def k_of(section):
        try:
            return float(_g(bound, section, "random_walk", default=0.0))
        except (TypeError, ValueError):
            return 0.0

    k_env = k_of("upper_envelope")
    if kept is not None and "random_walk" not in kept and k_of("bound") > 0 and (k_of("spec") > 0 or k_env > 0):
        dropped = isinstance(exp, Mapping) and "random_walk" in (exp.get("dropped_by_reduction") or [])
        if k_env > 0:
            value, unit = in_spec_units(bound, "random_walk", k_env)
            head = ("- random walk: the data showed none (identification dropped it) but do not exclude one up to "
                    f"K = {value:.3g} {unit} (the identified envelope); the bound's K covers that limit"
                    + (" and the spec sheet's" if k_of("spec") > 0 else ""))
        else:
            head = "- random walk: the data showed none (identification dropped it); the bound's K rests on the spec sheet alone"
        out.append(head + ("; the exported filter drops it (reduction above)" if dropped else ""))
    return out


def exported_state_lines(sensor: str, bound: Mapping, identify: Mapping | None = None) -> list[str]:
    """The details' lines on the states of the exported filter model (the contract's ``model``, what the KF file
    carries), each with what it stands for, beside the identification's components (which are what the bound must
    cover, not states: a flicker has no Kalman-filter state and a GM the records do not resolve is re-assigned).

    The GM states' sources, as far as the run files state them: a GM the identification kept (``selection.kept``),
    its flicker (covered by GM terms over the band), the spec sheet's GM (the contract's ``spec``), the GM terms of
    the identification's upper envelope (``upper_envelope``); a re-assigned GM is named as not one of them. The
    white noise and random walk: the identification's when it kept them, else the upper envelope's limit or the
    spec sheet's. [] when the contract states no exported model."""
    m = bound.get("model")
    if not isinstance(m, Mapping):
        return []
    identify = identify or {}
    kept = list(_g(identify, "selection", "kept", default=None) or bound.get("states_kept_by_identification") or [])
    spec = bound.get("spec") if isinstance(bound.get("spec"), Mapping) else {}
    env = bound.get("upper_envelope") if isinstance(bound.get("upper_envelope"), Mapping) else {}
    moved = [r for r in _items(identify.get("gm_reassigned")) if isinstance(r, Mapping)]
    n, gm, k, lines = _model_cells(sensor, bound, m)
    out = [f"- states of the exported filter model (KF file): white noise N {n}; GM {gm}; random walk K {k}; "
           f"line states {lines}"]

    def source(comp, spec_has, env_has):
        src = []
        if comp in kept:
            src.append("the identification kept it")
        if spec_has:
            src.append("the spec sheet has one")
        if env_has:
            src.append("the identification's upper envelope has one")
        return src

    if m.get("white"):
        src = source("white", bool(spec.get("white")), bool(env.get("white")))
        out.append(f"  - white noise: {'; '.join(src) or 'the bound (LP)'}")
    gms = [g for g in m.get("gauss_markov") or [] if isinstance(g, Mapping) and g.get("sigma")]
    if gms:
        src = []
        if "gauss_markov" in kept:
            src.append("a GM the identification kept")
        if "flicker" in kept:
            src.append("the identified flicker (no Kalman-filter state: GM terms cover it over the band)")
        if spec.get("gauss_markov"):
            src.append("the spec sheet's GM")
        if env.get("gauss_markov"):
            src.append(f"the {len(env['gauss_markov'])} GM term(s) of the identification's upper envelope")
        text = ("the bound's own term(s), sigma and T chosen by its LP to cover " + ", ".join(src)
                if src else "the bound's own term(s), chosen by its LP")
        if moved:
            text += ("; not the GM the identification re-assigned (" + ", ".join(
                f"T {num(r.get('T_s'))} s, reported as the {'white noise' if r.get('acts_as') == 'white' else 'random walk'}"
                " it acts as" for r in moved) + ")")
        out.append(f"  - GM: {text}")
    elif "flicker" in kept or "gauss_markov" in kept:
        out.append("  - no GM state: the bound covers the identified " + " and ".join(
            c for c in ("gauss_markov", "flicker") if c in kept) + " with its white noise and random walk")
    if m.get("random_walk"):
        src = source("random_walk", bool(spec.get("random_walk")), bool(env.get("random_walk")))
        if moved and any(r.get("acts_as") != "white" for r in moved):
            src.append("a re-assigned GM acts as one")
        out.append(f"  - random walk: {'; '.join(src) or 'the bound (LP)'}")
    return out


def _bias_lines(bound: Mapping) -> list[str]:
    """What the exported filter's initial bias variance is and rests on (the contract's ``bias_initialisation``,
    :mod:`imupipe.biasinit`), with the slow-bias family the records leave open."""
    bi = bound.get("bias_initialisation")
    if not isinstance(bi, Mapping) or not bi.get("statement"):
        return []
    out = [f"- {bi['statement']}; exported P0 of the random-walk state p: {num(bi.get('p0_random_walk'))} "
           f"{(bi.get('units') or {}).get('required_variance', '')}".rstrip()]
    fam = bi.get("slow_bias_family")
    if isinstance(fam, Mapping):
        (lo, hi), (s_lo, s_hi) = fam.get("T_range_s") or (None, None), fam.get("sigma_range") or (None, None)
        u = (fam.get("units") or {}).get("sigma", "")
        drift = f"drift K_eff {num(fam.get('k_eff'))} {(fam.get('units') or {}).get('k_eff', '')}"
        if lo is not None and lo == hi:  # the longest admitted T is not beyond the records: one member
            out.append(f"  - a bias slower than the records: {drift}; the longest bias time admitted "
                       f"({fam.get('T_max_source')}) is not beyond the longest record, so the slowest bias left open "
                       f"is the GM of T = that record, {num(lo)} s, sigma {num(s_lo)} {u} (sigma^2 = K_eff^2 T / 2), "
                       "the verification's slow_bias truth")
        else:
            out.append(f"  - a bias slower than the records: {drift}, any (sigma, T) with sigma^2 = K_eff^2 T / 2 "
                       f"for T {num(lo)}-{num(hi)} s (sigma {num(s_lo)}-{num(s_hi)} {u}); the verification's "
                       f"slow_bias truth is the worst member (T {num(hi)} s)")
    if not bi.get("checked_by_records"):
        out.append("  - the records cannot check this initial variance: set identify.max_bias_time_s (s) or a "
                   "spec sheet's turn_on_bias to state it")
    return out


#: Added to a stationarity or lines FLAG of a record that holds a stuck span.
STUCK_NOTE = "; this record holds a stuck span (stuck channel above): check it before this result"

#: Added to a stationarity FLAG of an axis that holds a spectral line: the test's null is simulated from the axis's
#: broadband Allan fit, without the line, and two outside evaluations saw steady lines flag stationary records (6 of
#: 6 and 4 of 6 axes with a line, none without).
LINE_NOTE = {
    "calibrated": ("; this axis holds a spectral line (lines FLAG), which the test leaves out (notched from the record "
                   "and its null): the verdict is on the broadband noise around it"),
    "paper": ("; this axis holds a spectral line (lines FLAG), which the paper's test's null (independent samples) "
              "does not hold: a steady line can fail it on a stationary record"),
}


def _stuck_flag(sensor: str, it: Mapping) -> Flag:
    """The FLAG of one stuck span (imupipe.outliers.stuck_spans): where (dataset/sensor/axis), the repeated value in
    the sensor's unit (the outliers file's ``units``), its first and last sample's time from the record's start (s)
    and its share of the record's samples (%)."""
    units = it.get("units") if isinstance(it.get("units"), Mapping) else {}
    where = "/".join(str(it[k]) for k in ("dataset", "sensor", "axis") if it.get(k) is not None)
    unit = units.get("value")
    frac = it.get("fraction")
    return Flag(sensor, "stuck channel", where or str(it.get("curve", "-")),
                f"constant at {num(it.get('value'), '{:.6g}')}{f' {unit}' if unit else ''} from "
                f"{num(it.get('start_s'), '{:.6g}')} s to {num(it.get('stop_s'), '{:.6g}')} s"
                + (f" ({num(100.0 * float(frac), '{:.3g}')} % of the record)" if frac is not None else ""))


def _line_flags(sensor: str, items: list, stuck_where=frozenset(), chance: str = "", confidence=None) -> list[Flag]:
    """The FLAGs of narrowband lines (:func:`imupipe.linewords.line_reports`), with :data:`STUCK_NOTE` where a
    line's record holds a stuck span (`stuck_where`: the stuck FLAGs' places) and `chance` (:func:`line_chance`)."""
    out = []
    for where, detail, places in line_reports(items, confidence):
        note = STUCK_NOTE if stuck_where & set(places) else ""
        short = short_form(detail, chance, keep=None)  # the line itself, the chance verdict without its numbers
        out.append(Flag(sensor, "lines", where, detail + chance + note, short=short + note if short else ""))
    return out


#: Spec sheet's white noise over the data's (the identification's upper envelope) from which the summary says that
#: the bound's N rests on the spec sheet rather than on the records.
SPEC_ABOVE_DATA_RATIO = 2.0


def _far_below_flag(sensor: str, bound: Mapping, margin: float) -> Flag:
    """The FLAG of a bound at least FAR_BELOW_SPEC_MARGIN above every sample PSD bin, saying what holds it up: the
    spec sheet (the bound's white noise N within 1.5x the sheet's: the data are not what the sheet describes, a
    unit slip looks like this) or the identification's upper envelope (N far above the sheet's: what the records
    leave open, e.g. a GM time-constant interval reaching far from the fitted T, is covered whole)."""
    where = f"{bound.get('margin_curve', '-')} at {num(bound.get('margin_frequency_hz'))} Hz"
    head = f"every sample PSD bin is at least {num(margin, '{:.3g}')}x below the bound (min S_bound/S_sample); "
    b_n, s_n = _g(bound, "bound", "white"), _g(bound, "spec", "white")
    ratio = float(b_n) / float(s_n) if isinstance(b_n, (int, float)) and isinstance(s_n, (int, float)) and s_n else None
    if ratio is not None and ratio > 1.5:
        return Flag(sensor, "bound far above the data", where, head + (
            f"the bound's white noise is {num(ratio, '{:.3g}')}x the spec sheet's, so it rests on the "
            "identification's upper envelope, not on the sheet: the envelope covers what the records leave open "
            "(each interval of identify/<sensor>.yaml whole, e.g. a GM time constant the data do not pin down); "
            "longer or more records narrow it (imupipe plan)"))
    return Flag(sensor, "data far below the spec sheet", where, head + (
        "the bound is the spec sheet's, the data are not what it describes: check the data's unit in the dataset "
        "sheet (a record in a smaller unit than declared, e.g. deg/s declared as mrad/s, looks like this) and that "
        "the spec sheet is this sensor's"))


def _spec_above_data(bound: Mapping) -> str | None:
    """A sentence when the spec sheet's white noise N is at least SPEC_ABOVE_DATA_RATIO times the data's (the
    identification's upper envelope, the largest N the records allow at the stated level): the bound's N then
    rests on the spec sheet, and the table's bound/spec of 1 does not show how far the data are below it."""
    spec_si = _g(bound, "spec", "white")
    env_si = _g(bound, "upper_envelope", "white")
    shown = _g(bound, "spec_spec_units", "white")
    if not (isinstance(spec_si, (int, float)) and isinstance(env_si, (int, float)) and env_si > 0):
        return None
    ratio = float(spec_si) / float(env_si)
    if ratio < SPEC_ABOVE_DATA_RATIO:
        return None
    value = (f"{num(shown.get('value') / ratio, '{:.3g}')} {shown.get('unit')}"
             if isinstance(shown, Mapping) and isinstance(shown.get("value"), (int, float)) else
             f"{num(env_si, '{:.3g}')} {SI_SPELLING.get((bound.get('sensor'), 'white'), 'u/sqrt(Hz)')} (SI)")
    return (f"- white noise: the records allow at most N = {value} (the identification's upper envelope), "
            f"{num(ratio, '{:.3g}')}x below the spec sheet's: the bound's N rests on the spec sheet, not on these "
            "records")


def _inflation_rows(bound: Mapping) -> list[tuple]:
    """(parameter, unit, spec, bound, ratio) rows from bound_spec_units / spec_spec_units (spec-sheet units),
    falling back to SI. A component the spec sheet (or the bound) does not give, value 0 or absent, is None
    (shown "-", ratio None), as in the tables of :func:`imupipe.specsheet.inflation_rows`."""
    b, s = bound.get("bound_spec_units"), bound.get("spec_spec_units")
    rows = []
    if isinstance(b, Mapping):
        s = s if isinstance(s, Mapping) else {}

        def val(d, *k):
            v = _g(d, *k)
            return (v.get("value"), v.get("unit")) if isinstance(v, Mapping) else (None, None)

        for name, key in (("white noise N", "white"), ("random walk K", "random_walk")):
            bv, unit = val(b, key)
            sv, sunit = val(s, key)
            rows.append((name, unit or sunit or "-", sv, bv))
        bgm, sgm = b.get("gauss_markov") or [], (s.get("gauss_markov") or [])
        for i in range(max(len(bgm), len(sgm))):
            tag = f" {i + 1}" if max(len(bgm), len(sgm)) > 1 else ""
            for name, key in ((f"GM sigma{tag}", "sigma"), (f"GM T{tag}", "T")):
                bv, unit = val(bgm[i] if i < len(bgm) else {}, key)
                sv, sunit = val(sgm[i] if i < len(sgm) else {}, key)
                rows.append((name, unit or sunit or "-", sv, bv))
    else:
        si_b, si_s = bound.get("bound") or {}, bound.get("spec") or {}
        sensor = bound.get("sensor")

        def si(key, generic):
            return SI_SPELLING.get((sensor, key), generic)

        rows.append(("white noise N (SI)", si("white", "u/sqrt(Hz)"), si_s.get("white"), si_b.get("white")))
        rows.append(("random walk K (SI)", si("random_walk", "u/sqrt(s)"), si_s.get("random_walk"),
                     si_b.get("random_walk")))
        for i, g in enumerate(si_b.get("gauss_markov") or []):
            sg = (si_s.get("gauss_markov") or [{}] * (i + 1))
            sg = sg[i] if i < len(sg) else {}
            rows.append((f"GM sigma {i + 1} (SI)", si("gm_sigma", "u"), sg.get("sigma"), g.get("sigma")))
            rows.append((f"GM T {i + 1}", "s", sg.get("T"), g.get("T")))
    def given(v):
        try:
            return v if float(v) != 0.0 else None
        except (TypeError, ValueError):
            return v

    out = []
    for name, unit, sv, bv in rows:
        sv, bv = given(sv), given(bv)
        try:
            ratio = float(bv) / float(sv) if sv else None
        except (TypeError, ValueError):
            ratio = None
        out.append((name, unit, sv, bv, ratio))
    return out


#: The heading that ends a summary's first screen (verdicts, values to paste, checks); the details follow it.
DETAILS_HEADING = "# Details"


def first_screen(text: str) -> str:
    """The part of a summary text before :data:`DETAILS_HEADING` (the whole text when it has none)."""
    head, sep, _ = text.partition("\n" + DETAILS_HEADING + "\n")
    return (head.rstrip() + "\n") if sep else text


def render_summary(runs: Mapping[str, Mapping[str, Any]], *, title: str = "imupipe run summary",
                   kalibr: Mapping | None = None, kalibr_path: str | None = None) -> str:
    """Markdown summary of a run (also readable as plain text): :func:`summary_sections`, the first screen, then
    :data:`DETAILS_HEADING` and the details."""
    head, details = summary_sections(runs, title=title, kalibr=kalibr, kalibr_path=kalibr_path)
    return head.rstrip() + "\n\n" + DETAILS_HEADING + "\n\n" + details.rstrip() + "\n"


def auto_selection_lines(contract: Mapping) -> list[str]:
    """bound.mode auto: the candidates' table (bounded, failed checks, mean P/MSE over the outage against the envelope,
    worst outage MSE/P of the exact checks (bound at <= 1) and of the sampled replay beside its limit 1 + tolerance)
    and why the winner won, from the contract's ``auto_selection`` (:mod:`imupipe.bound.auto`); else empty."""
    sel = contract.get("auto_selection")
    if not isinstance(sel, Mapping) or not sel.get("candidates"):
        return []
    out = ["", f"- bound mode auto: exported **{sel.get('winner')}**: {sel.get('reason', '-')}", "",
           "| candidate | bounded | failed checks | mean P/MSE vs envelope (outage) | worst MSE/P, outage (exact checks: "
           "<= 1) | replay MSE/P, outage (sampled: passes up to its limit) |", "|---|---|---|---|---|---|"]
    for r in sel["candidates"]:
        tol, rep = r.get("sampled_tolerance"), r.get("worst_outage_ratio_sampled")
        out.append(f"| {r.get('mode')}{' (exported)' if r.get('mode') == sel.get('winner') else ''} | "
                   f"{'yes' if r.get('bounded') else 'NO'} | {', '.join(r.get('failed_checks') or []) or '-'} | "
                   f"{num(r.get('criterion_mean_conservatism'))} | {num(r.get('worst_outage_ratio_exact'))} | "
                   f"{num(rep)}{f' (limit {num(1.0 + float(tol))})' if tol is not None and rep is not None else ''} |")
    return out + [""]


def _per_axis_lines(bound: Mapping) -> list[str]:
    """The details' per-axis table (when the pooling test says the axes differ) and each axis's in-band line."""
    from imupipe.inband import inband_line

    lines: list[str] = []
    per = bound.get("per_axis_models") or {}
    if per:
        lines += ["", "Per-axis models (the pooling test says the axes differ; the KF file's per_axis):", "",
                  "| axis | N bound/spec | own model in the KF file | why | exported filter model |",
                  "|---|---|---|---|---|"]
        glob = (bound.get("export") or {}).get("statement") if isinstance(bound.get("export"), Mapping) else None
        for ax, pa in per.items():
            if isinstance(pa, Mapping):
                own = pa.get("exported_in_kf")
                scope = _g(pa, "export", "statement") if own else (f"global: {glob}" if glob else "global")
                lines.append(f"| {ax} | {num(_g(pa, 'inflation', 'N'))} | "
                             f"{'yes' if own else 'no (global model)'} | "
                             f"{pa.get('kf', '-')} | {scope or '-'} |")
        lines.append("")
        for ax, pa in per.items():
            text = inband_line(pa.get("inband_inflation")) if isinstance(pa, Mapping) else None
            if text:
                lines.append(f"- axis {ax}: {text}")
        lines.append("")
    return lines


def _line_terms(model) -> list:
    """The narrowband line states (sigma > 0) of a model dict (SI)."""
    m = model if isinstance(model, Mapping) else {}
    return [t for t in m.get("narrowband") or [] if isinstance(t, Mapping) and float(t.get("sigma") or 0.0) > 0]


def _model_cells(sensor: str, bound: Mapping, model) -> tuple[str, str, str, str]:
    """(white noise N, GM terms, random walk K, lines) of a model dict (SI) as table cells, each value in the spec
    sheet's unit and SI (:func:`both_units`); "-" for a term the model lacks."""
    m = model if isinstance(model, Mapping) else {}
    n = both_units(sensor, bound, "white", m.get("white")) if m.get("white") else "-"
    k = both_units(sensor, bound, "random_walk", m.get("random_walk")) if m.get("random_walk") else "-"
    gms = [f"sigma {both_units(sensor, bound, 'gm_sigma', g.get('sigma'))}, T {num(g.get('T'))} s"
           for g in m.get("gauss_markov") or [] if isinstance(g, Mapping) and g.get("sigma")]
    lines = [f"{num(t.get('f0_hz'), '{:.4g}')} Hz (sigma {both_units(sensor, bound, 'gm_sigma', t.get('sigma'))})"
             for t in _line_terms(m)]
    return n, "; ".join(gms) or "-", k, "; ".join(lines) or "none"


def per_axis_exports(sensor: str, bound: Mapping) -> list[dict]:
    """What the KF file exports per axis when the axes differ (the contract's ``per_axis_models``): per axis
    ``axis``, ``own`` (its own model, bounded, or the global one), ``model`` (SI dict), ``why`` and ``dropped`` (the
    states the exported model's verified reduction dropped); [] when the axes are pooled."""
    per = bound.get("per_axis_models") or {}
    out = []
    for ax, pa in per.items():
        if not isinstance(pa, Mapping):
            continue
        own = bool(pa.get("exported_in_kf"))
        src = pa if own else bound
        dropped = [d for d in (_g(src, "export", "dropped_by_reduction") or []) if isinstance(d, str)]
        out.append({"axis": str(ax), "own": own, "model": src.get("model"), "dropped": dropped,
                    "why": ("its own contract is bounded (the pooling test says the axes differ)" if own else
                            str(pa.get("kf") or "its own contract failed"))})
    return out


def per_axis_export_lines(runs: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """The first screen's per-axis export table: for each sensor whose axes differ, which model the KF file exports
    per axis (its own or the global), why, and that model's values (spec sheet's units and SI) and line states,
    with the lines its verified reduction dropped; empty when every sensor is pooled. The values-to-paste tables
    hold the global model; this table says which axes use it."""
    rows = []
    for sensor, files in runs.items():
        bound = files.get("bound") or {}
        for e in per_axis_exports(sensor, bound):
            n, gm, k, lines = _model_cells(sensor, bound, e["model"])
            gone = [d for d in e["dropped"] if d.startswith("narrowband")]
            if gone:
                lines += f"; dropped by the verified reduction: {', '.join(d.split('=', 1)[-1] for d in gone)}"
            held = ", ".join(d.split(" ", 1)[0] for d in e["dropped"] if d not in gone)  # holds for the outage only
            rows.append(f"| {sensor} | {e['axis']} | {'own model' if e['own'] else 'global model'} | {n} | {gm} | "
                        f"{k} | {lines} | {e['why']}" + (f"; the verified reduction dropped {held}: valid for the "
                                                         "configured outage and fixes only |" if held else " |"))
    if not rows:
        return []
    return ["", "The axes differ: give each axis the model the KF file's `per_axis` exports for it, below (the tables "
            "above are the global model, verified on every axis's envelope too; Kalibr's: the largest over these):", "",
            "| sensor | axis | exported | white noise N | GM | random walk K | line states | why |",
            "|---|---|---|---|---|---|---|---|", *rows]


def kalibr_line_holders(runs: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """Which exported model holds the line states that make Kalibr refuse: per sensor the global model (when some
    axis exports it, or the axes are pooled) and each axis's own model, with the lines' frequencies (Hz)."""
    out = []
    for sensor, files in runs.items():
        bound = files.get("bound") or {}
        exports = per_axis_exports(sensor, bound)
        if not exports:
            terms = _line_terms(bound.get("model"))
            if terms:
                out.append(f"{sensor} model: " + ", ".join(f"{num(t.get('f0_hz'), '{:.4g}')} Hz" for t in terms))
            continue
        users = [e["axis"] for e in exports if not e["own"]]
        terms = _line_terms(bound.get("model"))
        if users and terms:
            out.append(f"{sensor} global model (exported for axis {', '.join(users)}): "
                       + ", ".join(f"{num(t.get('f0_hz'), '{:.4g}')} Hz" for t in terms))
        for e in exports:
            if e["own"] and _line_terms(e["model"]):
                out.append(f"{sensor} axis {e['axis']} model: "
                           + ", ".join(f"{num(t.get('f0_hz'), '{:.4g}')} Hz" for t in _line_terms(e["model"])))
    return out


def _reduced_lines(runs: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """Under the first screen's values: each sensor whose KF model the verified reduction reduced, with the scope of
    that export (its statement, :func:`imupipe.kf.export_scope`): a user who reads only this screen learns it."""
    out = []
    for sensor, files in runs.items():
        exp = (files.get("bound") or {}).get("export")
        if isinstance(exp, Mapping) and exp.get("dropped_by_reduction") and exp.get("statement"):
            out.append(f"- {sensor}: {exp['statement']}")
    return ["", *out] if out else []


def _scenario_lines(runs: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """The first screen's line of the scenario the exported filters were verified in (the contracts' ``export``:
    filter rate, fix period and its sd, outage), one per distinct scenario with its sensors; a blank line after."""
    by: dict = {}
    for sensor, files in runs.items():
        exp = (files.get("bound") or {}).get("export")
        if isinstance(exp, Mapping) and exp.get("horizon_s") is not None:
            g = "{:g}"
            text = (f"the reference filter at {num(exp.get('verified_filter_rate_hz'), g)} Hz, "
                    f"{num(exp.get('fix_s'), g)} s of fixes every "
                    f"{num(1.0 / float(exp.get('verified_fix_rate_hz') or 1.0), g)} s (sd "
                    f"{num(exp.get('verified_sigma_fix'))} {exp.get('verified_sigma_fix_unit', '')}), then an outage "
                    f"of {num(exp.get('horizon_s'), g)} s")
            by.setdefault(text, []).append(str(sensor))
    return [line for text, sensors in by.items() for line in (
        f"Verified in ({', '.join(sensors)}): {text}; a filter used otherwise (a longer outage, another rate, "
        "rarer or more accurate fixes) is outside what was verified (application.* and verify.* in the config).", "")]


def _paste_section(runs: Mapping[str, Mapping[str, Any]], paste: list) -> list[str]:
    """The first screen's values to paste: one table in the spec sheet's units, one in SI (rows of
    :func:`paste_rows` with the sensor in front); empty when there is nothing to paste."""
    head: list[str] = []
    if paste:
        own = [s for s, files in runs.items() if any(e["own"] for e in per_axis_exports(s, files.get("bound") or {}))]
        head += ["## Values to paste, in the spec sheet's units", ""]
        if own:  # an outside evaluation pasted the global model, 30x looser on the axes without another's line
            head += [f"**The axes differ ({', '.join(own)}):** paste each axis's own model, the per-axis table below "
                     "the first one; the tables hold the global model, verified on every axis too but looser on an "
                     "axis without another's line or drift.", ""]
        head += ["The exported filter model's continuous-time values (its Phi, Qd and P0 at the filter rate are in "
                 "the KF file) and Kalibr's densities. Bounding values: use them as they are, do not inflate them "
                 "again, with the KF file's states and their initial variances P0 (the random-walk bias state p's "
                 "initial sd is in the table; a GM state starts at its sigma): a filter that takes the bias as known "
                 "at the start under-states its error. Kalibr has white noise "
                 "and a bias random walk only: its pair is chosen to bound the exported model in the application "
                 "band on its own, so it differs from the KF file's N and K where that model has a GM or lines "
                 "(docs/method.md, \"Kalibr's pair and the in-band inflation\").", "",
                 "| sensor | file | parameter | value | unit |", "|---|---|---|---|---|"]
        head += [f"| {se} | {fi} | {pa} | {num(vs, '{:.4g}')} | {us} |" for se, fi, pa, vs, us, _, _ in paste]
        head += _reduced_lines(runs)
        head += per_axis_export_lines(runs)
        head += ["", "## The same values in SI", "",
                 "(Kalibr's random-walk units as Kalibr writes them, rad/s^2/sqrt(Hz) and m/s^3/sqrt(Hz), are the KF "
                 "file's rad/s/sqrt(s) and m/s^2/sqrt(s).)", "",
                 "| sensor | file | parameter | value | unit |", "|---|---|---|---|---|"]
        head += [f"| {se} | {fi} | {pa} | {num(vi, '{:.4g}')} | {ui} |" for se, fi, pa, _, _, vi, ui in paste]
        head.append("")
    return head


def summary_sections(runs: Mapping[str, Mapping[str, Any]], *, title: str = "imupipe run summary",
                     kalibr: Mapping | None = None, kalibr_path: str | None = None) -> tuple[str, str]:
    """The first screen and the details of a run's summary (markdown), one spec sheet.

    Parameters
    ----------
    runs : mapping
        Sensor -> ``{"bound": dict, "identify": dict, "stationarity": dict}`` (each optional), the
        run's per-sensor YAML files as read (:func:`imupipe.stages.summary.group_run_files`).
    title : str, optional
        First heading.
    kalibr : mapping, optional
        The spec sheet's Kalibr file as read (its fields; ``refused`` and ``reason`` when refused).
    kalibr_path : str, optional
        Where that file is, named in the summary.

    Returns
    -------
    (str, str)
        The first screen: the verdict line, a table of the verdict per sensor (``BOUNDED`` / ``NOT BOUNDED``,
        PSD margin, verification, KF file), the values to paste (:func:`paste_rows`) as two tables, one in the
        spec sheet's units and one in SI, and every ``FAIL`` / ``FLAG`` line per sensor (or "none flagged").
        The details: one section per sensor with the inflation table (spec-sheet units), the in-band line, the
        exported model's scope, the initial bias, the states kept and dropped with the reasons.
    """
    from imupipe.inband import inband_line

    lines = []  # the details
    all_flags: list[Flag] = []
    verdicts, table, paste, checks = [], [], [], []
    for sensor, files in runs.items():
        bound = files.get("bound") or {}
        identify = files.get("identify") or {}
        stat = files.get("stationarity") or {}
        flags = flags_of(sensor, bound, identify, stat)
        all_flags += flags
        bounded = bound.get("bounded")
        fails = [f for f in flags if f.severity == "fail"]
        verdict = ("NOT BOUNDED" if bounded is False else "BOUNDED" if bounded else "no bound")
        if bounded and fails:
            verdict += " (with failed checks)"
        verdict += nonstationary_qualifier(stat) if bounded else ""
        verdicts.append(f"{sensor}: {verdict}")
        ver = bound.get("verified")
        within = sorted({f"{name} ({label})" for label, name, _ in _tolerance_passes(bound)})
        ver_text = ("-" if ver is None else "FAILED" if not ver else
                    f"passed, {', '.join(within)} only within its sampling tolerance (FLAG below)" if within else
                    "passed")
        table.append(f"| {sensor} | {verdict} | {num(bound.get('margin'), '{:.4g}')} | {ver_text} | "
                     f"{'`' + str(bound['kf_file']) + '`' if bound.get('kf_file') else '-'} |")
        paste += [(sensor, *r) for r in paste_rows(sensor, bound, kalibr)] if bound else []
        n_fail = sum(f.severity == "fail" for f in flags)
        checks.append(f"{sensor}: " + (f"{n_fail} failed, {len(flags) - n_fail} flagged" if flags else
                                       "none failed or flagged."))
        checks += [flag_line(f, short=True) for f in flags]
        checks.append("")
        lines.append(f"## {sensor}: {verdict}")
        lines.append("")
        lines.append(f"- margin (min S_model/target, the mode's; raw: S_sample): {num(bound.get('margin'), '{:.4g}')}"
                     + (f" at {bound.get('margin_curve')}, {num(bound.get('margin_frequency_hz'))} Hz"
                        if bound.get("margin_curve") else ""))
        if bound.get("spec_name") or bound.get("mode"):
            lines.append(f"- spec sheet: {bound.get('spec_name', '-')}; bound mode: {bound.get('mode', '-')}; "
                         f"curves: {bound.get('n_curves', len(bound.get('curves') or []))}")
        lines += filled_lines(bound.get("psd_usage"))
        rows = _inflation_rows(bound) if bound else []
        if rows:
            lines += ["", "| parameter | unit | spec | bound | bound/spec |", "|---|---|---|---|---|"]
            lines += [f"| {n} | {u} | {num(s, '{:.4g}')} | {num(b, '{:.4g}')} | {num(r)} |"
                      for n, u, s, b, r in rows]
            lines.append("")
        inband = inband_line(bound.get("inband_inflation")) if bound else None
        if inband:
            # what the whole exported model does over the application band (imupipe.inband): beside the table
            lines += [f"- {inband}", ""]
        if rows:
            gap = _spec_above_data(bound)
            if gap:
                lines += [gap, ""]
            below = [n for n, _, sv, bv, r in rows if n.startswith("GM sigma") and r is not None and r < 1.0]
            spec_margin = bound.get("spec_margin")
            if below and isinstance(spec_margin, (int, float)) and spec_margin >= 1.0:
                # the LP trades the spec's GM against white noise, random walk and a GM of another T: the spec
                # sheet's PSD is bounded as a whole, not term by term
                lines += [f"- {', '.join(below)} below the spec sheet's: the spec sheet's PSD is bounded at every "
                          f"frequency by the bound's terms together (white noise, GM and random walk; spec margin "
                          f"{num(spec_margin, '{:.4g}')}), not term by term", ""]
            scope = bound.get("inflation_scope")
            if isinstance(scope, Mapping) and scope.get("dropped_from_exported_model") and scope.get("statement"):
                # the table is the bound's; the exported model lacks these states (imupipe.kf.inflation_scope)
                lines += [f"- the table above: {scope['statement']}", ""]
        band = bound.get("allan_tau_band_s")
        if band:
            lines.append(f"- Allan total check over the application band: tau from {num(band[0])} to "
                         f"{num(band[1])} s")
        # what the line search and the event scan could see
        lines += [t for t in (search_band_text(bound.get("line_search")),
                              step_scan_text(bound.get("step_floor"), bound.get("events_scanned"))) if t]
        lines += _per_axis_lines(bound)
        lines += auto_selection_lines(bound)
        sel = identify.get("selection") or {}
        kept = sel.get("kept") or bound.get("states_kept_by_identification")
        lines += _export_lines({"sensor": sensor, **bound}, kept)
        lines += _bias_lines(bound)
        if kept is not None:
            lines.append("- components the identification kept (identify file, selection: what the bound covers, not "
                         f"the filter's states): {', '.join(kept) if kept else 'none'}")
            reasons = sel.get("reasons") or {}
            moved = [r for r in _items(identify.get("gm_reassigned")) if isinstance(r, Mapping)]
            for comp in list(kept) + list(sel.get("dropped") or []):
                why = reasons.get(comp) if isinstance(reasons, Mapping) else None
                if comp == "gauss_markov" and moved and why:  # the identification's words carry SI placeholders
                    was = str(why).partition("; was: ")[2]
                    why = ("re-assigned: " + "; ".join(f"GM term {r.get('term')}: {reassigned_text(sensor, r, bound)}"
                                                       for r in moved) + (f"; was: {was}" if was else ""))
                mark = "kept" if comp in kept else "dropped"
                lines.append(f"  - {comp} ({mark}): {why if why else '-'}")
        lines += exported_state_lines(sensor, bound, identify)
        lines += _adequacy_table(identify)
        lines += _consistency_table(sensor, identify, bound)
        lines.append("")
        shortened = [flag_line(f) for f in flags if f.short]
        lines.append("Checks: " + ("on the first screen (above)" if flags else "none failed or flagged.")
                     + ("; in full:" if shortened else "." if flags else ""))
        lines += [*(["", *shortened] if shortened else []), ""]
    contracts = {k: f.get("bound") for k, f in runs.items()}
    rests_on = confidence_lines(contracts)
    lines = [*(["## What BOUNDED rests on", ""] if rests_on else []), *rests_on, *lines]
    n_fail = sum(f.severity == "fail" for f in all_flags)
    n_flag = len(all_flags) - n_fail + bool(isinstance(kalibr, Mapping) and kalibr.get("refused"))
    head = [f"# {title}", "", f"**Verdict:** {'; '.join(verdicts)}. {n_fail} failed, {n_flag} flagged check(s).", ""]
    head += ["| sensor | verdict | PSD margin (min S_model / target: the exported mode's, e.g. the sample PSDs in raw "
             "mode, the upper envelope for the envelope candidate; details: its curve) | verification | KF file |",
             "|---|---|---|---|---|", *table, "", *_scenario_lines(runs), *confidence_lines(contracts, "short")]
    head += _paste_section(runs, paste)
    if isinstance(kalibr, Mapping):
        where = f" [{kalibr_path}]" if kalibr_path else ""
        if kalibr.get("refused"):
            holders = kalibr_line_holders(runs)
            checks.append("export (Kalibr): 0 failed, 1 flagged")  # its own heading, not the last sensor's
            checks.append(f"- FLAG kalibr export{where}: refused: {kalibr.get('reason', '-')}"
                          + (f"; the exported line states: {'; '.join(holders)}" if holders else "")
                          + " (no Kalibr fields written; use the Kalman-filter export)")
            checks.append("")
        else:
            head += [f"Kalibr imu.yaml{where}: update_rate {num(kalibr.get('update_rate'), '{:g}')} Hz, rostopic "
                     f"{kalibr.get('rostopic')}.", ""]
    head += [f"## Checks: {n_fail} failed, {n_flag} flagged", "", *checks]
    return "\n".join(head).rstrip() + "\n", "\n".join(lines).rstrip() + "\n"
