r"""``bound.mode: auto``: every mode's bound is a candidate, each is verified, the tightest that passes every check
is exported (docs/method.md, "The auto bound").

The bound stage computes one candidate per mode of :data:`AUTO_MODES` (:func:`imupipe.stages.bound.bound_sensor`),
the verification stage verifies each the same way (:func:`imupipe.stages.verify.verify_sensor`: the reference
filter against the identified upper envelope, the spec sheet, the slow bias, the truth where known, and the replay of
the records) and :func:`select` picks the exported one:

* **passes**: the candidate's contract would be ``bounded`` (:func:`imupipe.stages.contract.candidate_contract`:
  :func:`imupipe.verify.integrity_contract` on its bound file entry and its verification: PSD margin, spec over all
  frequencies, Allan check, the identification's intervals, every verification check of its exported model);
* **criterion**: of the passing candidates, the smallest mean conservatism :math:`\overline{P/\mathrm{MSE}}` over
  the outage of the exported model's check against the upper envelope (``upper_envelope``'s
  ``mean_conservatism``: P the filter's variance, MSE the true error variance when the envelope is the truth;
  dimensionless, >= 1 for a model that bounds the envelope everywhere in the outage). Ties (within 1e-9
  relative) go to the earlier mode of :data:`AUTO_MODES`;
* **none passes**: the candidate with the smallest worst outage MSE/P against the envelope is exported, marked not
  bounded by its contract (the contract's ``failed_checks`` say why).

The envelope is the criterion's reference because it is what every run has (the truth only where simulated) and is
what the bound must cover below the lowest PSD bin; the spec sheet is a floor, not an estimate of the sensor. Where
the envelope sets the level (a random walk or a long GM a few records barely resolve), every candidate sits on it
and the conservatism is the envelope's: ``identify.envelope: joint`` (:mod:`imupipe.identify.joint`, what
``imupipe init`` writes with ``auto``) makes it the simultaneous band of the fit's bootstrap instead of every
component at its upper limit at once.
"""

from __future__ import annotations

import math

from imupipe.bound.axes import curves_by_axis
from imupipe.shown import num, p_text

__all__ = ["AUTO_MODES", "CRITERION", "ENVELOPE_MODE", "candidate_modes", "candidate_row", "select"]

#: The candidates of ``bound.mode: auto`` built from the sample PSDs, in tie-break order (the paper's first).
AUTO_MODES = ("raw", "smoothed", "confidence", "pooled")

#: The candidate whose target is the joint upper envelope (:func:`candidate_modes`), after :data:`AUTO_MODES` in
#: the tie-break order.
ENVELOPE_MODE = "envelope"


def candidate_modes(identified: dict, lines=None, stretched=()) -> tuple[tuple[str, ...], str]:
    r"""The modes ``bound.mode: auto`` builds a candidate of, and why the ``envelope`` candidate is or is not one.

    :data:`AUTO_MODES` always. :data:`ENVELOPE_MODE` (:func:`imupipe.bound.bound_psd` ``mode="envelope"``: the
    tightest model of the same components above the identified upper envelope and the spec sheet at every
    frequency; docs/method.md "The auto bound") when its level is the joint band's, family-wise over the band's
    frequencies and one statement for every curve:

    * the identify record's envelope is the joint one (``upper_envelope_kind: joint`` and its band record without a
      fallback note: at least 20 finite bootstrap replicates);
    * with more than one axis, every axis's own joint band is recorded (where the pooling test rejects one model
      for every curve, ``pooling.consistent`` false: ``per_axis[axis].upper_envelope_joint``; where it accepts:
      ``axis_envelopes[axis].upper_envelope_joint``), each at level c (over k axes they hold together with
      probability at least 1 - k (1 - c), the level the reason states), and every axis's model describes its Allan
      variances; the candidate's target dominates the pooled and every per-axis envelope (where pooled: the identify
      file's ``upper_envelope_model_axes``). Accepting one model does not show the axes equal: a gyro z drifting
      20 % more than x and y (two 1.5 h records) passed the test (p 0.28), the pooled band lay under z's random
      walk and the candidate on it under-stated z's error (MSE/P 1.07). Where the test rejects: five records of one
      held-out truth lost the envelope candidate to a pooling false alarm, the test's 1 % by design, and the
      exported model's conservatism rose to 2.02 (docs/performance.md). Where the test rejects, also: the
      record-consistency test names no record (``record_consistency.flagged``): per-axis envelopes answer axes
      that differ, not records that do, whose differences only the candidates built from every sample PSD cover;
    * no spectral line in the lines files `lines` (curve label -> :meth:`imupipe.lines.LineSearch.to_dict`): the
      envelope is a broadband model and carries no line, which only the sample PSDs' rows would bound;
    * the selected model (per axis where the curves are not pooled) describes the Allan variances (the identify
      record's ``adequacy.pooled.adequate``, each ``per_axis[axis].adequacy.adequate``): the band is the spread of
      refits of that model, which says nothing of what the model cannot represent. Where the data reject it (a
      floor of four GMs fitted as white noise alone: chi2/dof 3.3, p 4e-53), the envelope lay 2.9 % below such a
      truth's PSD between 0.001 and 0.07 Hz, the envelope candidate sat on it, and a filter on it under-stated its
      error (MSE/P 1.003); the candidates of :data:`AUTO_MODES` bound the records' own spectra.

    * no curve whose noisiest stretch the bound covers (`stretched`: the curves' labels,
      :func:`imupipe.stages.bound.with_stretches`): the envelope is fitted to the records' average Allan variance, a
      filter meeting a record's noisier stretch needs more (an outside evaluation: white noise 2.5x over a record's
      last third, MSE/P 1.5 there under a bound of the average).

    Returns (modes, reason)."""
    kind = identified.get("upper_envelope_kind", "marginal")
    rec = identified.get("upper_envelope_joint")
    found = [ln for doc in (lines or {}).values() for ln in (doc or {}).get("lines") or ()]
    n_lines = len(found)
    pooled = (identified.get("pooling") or {}).get("consistent", True) is not False
    axes = (identified.get("axis_envelopes") if pooled else identified.get("per_axis")) or {}
    # what the bound reads: the pooled band and each axis's band and fit (where pooled: ``axis_envelopes``)
    bands = [("pooled", rec)] + [(f"axis {ax}", e.get("upper_envelope_joint")) for ax, e in axes.items()]
    fits = ([("selected model", (identified.get("adequacy") or {}).get("pooled") or {})] if pooled else []) + [
        (f"model of axis {ax}", e.get("adequacy") or {}) for ax, e in axes.items()]
    open_band = next(((who, r) for who, r in bands
                      if not isinstance(r, dict) or r.get("note") or r.get("worst_ratio_to_band") is None), None)
    rejected = next(((who, a) for who, a in fits if a.get("adequate", True) is False), None)
    n_axes = len(curves_by_axis(identified.get("curves") or ()))
    if kind != "joint":
        why = f"not built: the identification's envelope is {kind!r}, not the joint band (identify.envelope: joint)"
    elif stretched:
        why = (f"not built: {len(stretched)} curve(s) change their noise level along the record (noisiest stretch of "
               f"{', '.join(stretched)} among the bound's curves), and the envelope, fitted to the records' average "
               "noise, does not cover a noisier stretch")
    elif pooled and n_axes > 1 and not axes:
        why = (f"not built: the identify file has no envelope of each of its {n_axes} axes (axis_envelopes: written "
               "by this version's identify rule; re-run it), and the pooled band alone need not cover every axis")
    elif not pooled and not axes:
        why = "not built: the pooling test rejects one model for every curve, and the file has no per-axis fits"
    elif not pooled and ((identified.get("record_consistency") or {}).get("flagged")):
        named = sorted({f"{r.get('dataset')} ({r.get('param')})" for r in identified["record_consistency"]["flagged"]
                        if isinstance(r, dict)})
        why = ("not built: the pooling test rejects one model for every curve and the record-consistency test names "
               f"{', '.join(named)}: per-axis envelopes do not answer records that differ")
    elif open_band is not None:
        who, r = open_band
        why = (f"not built: the joint band ({who}) fell back to the marginal envelope ("
               + str((r or {}).get("note")) + ")")
    elif n_lines:
        why = (f"not built: {_lines_counted(found)} found, which the broadband envelope does not carry")
    elif rejected is not None:
        who, a = rejected
        why = (f"not built: the data reject the {who} (adequacy: chi2/dof {num(a.get('chi2_per_dof'))}, "
               f"{p_text(a)}), so the joint band, the spread of that model's refits, does not cover what "
               "the model cannot represent; the candidates built from the sample PSDs bound the records' own spectra")
    elif pooled and not axes:
        return AUTO_MODES + (ENVELOPE_MODE,), (
            f"built: the joint envelope's band (level {rec.get('confidence')}, family-wise over "
            f"{rec.get('band_hz')} Hz) is the target")
    else:
        levels = [float(r.get("confidence")) for _, r in bands[1:]]
        together = max(0.0, 1.0 - sum(1.0 - c for c in levels))
        why_axes = ("the pooling test rejects one model for every curve" if not pooled else
                    "the pooling test accepts one model, which does not show the axes equal")
        return AUTO_MODES + (ENVELOPE_MODE,), (
            f"built: {why_axes}, so the target dominates the pooled joint envelope and each axis's own (bands at "
            f"level {', '.join(sorted({num(c) for c in levels}))} per axis over {len(axes)} axes: together at least "
            f"{num(together)} (Bonferroni), over {rec.get('band_hz')} Hz)")
    return AUTO_MODES, why


def _lines_counted(found: list) -> str:
    """How many spectral lines the lines files' entries `found` are, and in how many detections (over axes and
    records), by the rule that makes one line of several (:func:`imupipe.lines.same_line_groups`): "2 spectral
    line(s) (6 detections over axes and records)"; an entry without its frequency and interval is a line apart."""
    from imupipe.lines import same_line_groups

    placed = [(float(d["frequency_hz"]), float(d["f_lo_hz"]), float(d["f_hi_hz"])) for d in found
              if isinstance(d, dict) and all(d.get(k) is not None for k in ("frequency_hz", "f_lo_hz", "f_hi_hz"))]
    n = len(same_line_groups(placed)) + len(found) - len(placed)
    return f"{n} spectral line(s)" + (f" ({len(found)} detections over axes and records)" if len(found) > n else "")


#: The stated criterion (written into the verification file).
CRITERION = ("the passing candidate (its contract bounded: PSD margin, spec over all frequencies, Allan check and "
             "every verification check of its exported model) with the smallest mean P/MSE over the outage of its "
             "exported model against the identified upper envelope; none passing: the smallest worst outage MSE/P "
             "against the envelope, marked not bounded")

_ENVELOPE = "upper_envelope"


def candidate_row(mode: str, bound: dict, report: dict, contract_of) -> dict:
    """What the verification file and the summary show of one candidate: bounded, failed checks, per check the
    worst outage MSE/P and mean P/MSE of its exported model, the criterion's value, the bound's inflation.
    `contract_of(bound, report)` is the candidate's contract (``bounded``, ``failed_checks``:
    :func:`imupipe.stages.contract.candidate_contract`)."""
    c = contract_of(bound, report)
    checks = report["exported"]["verification"].get("checks", {})
    env = checks.get(_ENVELOPE, {})
    per = {name: {"worst_outage_ratio": ch.get("worst_outage_ratio"), "mean_conservatism": ch.get("mean_conservatism"),
                  "passed": ch.get("passed"), "sampled": _sampled(ch), "tolerance": ch.get("tolerance")}
           for name, ch in checks.items()}
    exact = [v["worst_outage_ratio"] for v in per.values() if not v["sampled"] and v["worst_outage_ratio"] is not None]
    sampled = [v for v in per.values() if v["sampled"] and v["worst_outage_ratio"] is not None]
    # the sampled check nearest its own limit (ratio over 1 + tolerance)
    near = max(sampled, key=lambda v: float(v["worst_outage_ratio"]) / (1.0 + float(v["tolerance"] or 0.0)),
               default=None)
    failed = [" ".join(str(x) for x in (f["check"], f.get("against") or f.get("component") or "") if x)
              for f in c["failed_checks"]]
    return {"mode": mode, "bounded": bool(c["bounded"]), "failed_checks": failed,
            "criterion_mean_conservatism": env.get("mean_conservatism"),
            "envelope_worst_outage_ratio": env.get("worst_outage_ratio"),
            "worst_outage_ratio_exact": max(exact, default=None),
            "worst_outage_ratio_sampled": None if near is None else near["worst_outage_ratio"],
            "sampled_tolerance": None if near is None else near["tolerance"],
            "model_reduced": bool(report["exported"].get("reduced")), "inflation": bound.get("inflation"),
            "data_lift": ((bound.get("details") or {}).get("data_lift") or {}).get("variance_factor"),
            "checks": per}


def _sampled(check: dict) -> bool:
    """Whether a verification check's ratio is a sampled statistic (the replay of the records, a Monte Carlo),
    which passes within its own tolerance, rather than an exact covariance analysis, which must stay <= 1."""
    method = str(check.get("method") or "")
    return bool(method) and "exact" not in method


def _finite(x, default):
    return float(x) if x is not None and math.isfinite(float(x)) else default


def select(candidates: dict, reports: dict, contract_of, envelope_candidate: str | None = None) -> dict:
    """The selection of ``bound.mode: auto`` (module docstring): `candidates` mode -> bound file entry, `reports`
    mode -> its verification report, `contract_of` as :func:`candidate_row`'s. `envelope_candidate`: why the
    envelope candidate was or was not built (:func:`candidate_modes`, the bound file's ``auto_envelope_candidate``);
    where it is absent, the reason ends with why. Returns ``{criterion, winner, bounded, reason, candidates: [row,
    ...]}`` (:func:`candidate_row` per mode, in :data:`AUTO_MODES` order)."""
    order = [m for m in AUTO_MODES if m in candidates] + [m for m in candidates if m not in AUTO_MODES]
    if not order:
        raise ValueError("auto bound: no candidate (the bound file has an empty 'candidates')")
    rows = [candidate_row(m, candidates[m], reports[m], contract_of) for m in order]
    ok = [r for r in rows if r["bounded"]]
    if ok:
        best = min(ok, key=lambda r: _finite(r["criterion_mean_conservatism"], math.inf))
        val = _finite(best["criterion_mean_conservatism"], math.inf)
        best = next(r for r in ok if _finite(r["criterion_mean_conservatism"], math.inf) <= val * (1 + 1e-9))
        others = ", ".join(f"{r['mode']} {r['criterion_mean_conservatism']:.3g}" for r in ok if r is not best)
        failed = ", ".join(f"{r['mode']} ({'; '.join(r['failed_checks']) or 'no verification'})"
                           for r in rows if not r["bounded"])
        lift = (f" (its PSD scaled by {best['data_lift']:.4g} where the records' lower confidence limit lay above it "
                "by chance: the bound's details.data_lift)") if best.get("data_lift") else ""
        reason = (f"bounded and the tightest passing candidate{lift}, mean P/MSE {val:.3g} over the outage "
                  f"against the upper envelope" + (f" (other passing: {others})" if others else "")
                  + (f"; not passing: {failed}" if failed else ""))
        bounded = True
    else:
        best = min(rows, key=lambda r: _finite(r["envelope_worst_outage_ratio"], math.inf))
        reason = (f"no candidate passes every check; {best['mode']} exported (the smallest worst outage MSE/P "
                  f"against the envelope, {_finite(best['envelope_worst_outage_ratio'], math.inf):.3g}), NOT BOUNDED: "
                  + "; ".join(f"{r['mode']}: {', '.join(r['failed_checks'])}" for r in rows))
        bounded = False
    if envelope_candidate and ENVELOPE_MODE not in candidates:  # why the tightest-by-design candidate is absent
        reason += f"; the envelope candidate was {envelope_candidate}"
    return {"criterion": CRITERION, "winner": best["mode"], "bounded": bounded, "reason": reason, "candidates": rows}
