"""The stationarity verdict of one decimated axis (rule ``stationarity``).

The paper's Levene + KS test of consecutive segments (:func:`imupipe.stationarity.stationarity_tests`), or the
same statistics calibrated on a null simulated from the axis's own Allan-variance fit
(:func:`imupipe.stationarity.calibrated_stationarity` with ``paper=False``, the null model
:func:`imupipe.identify.fit_allan` of white, GM, flicker and random walk, the draws seeded from the record
itself so that identical records give identical verdicts whatever their axis or dataset). The calibrated verdict
gives its p-value's Monte Carlo standard error, the draws used and how close p was to the level; the paper's
test on the same record is reported beside it by the sensor's summary (rule ``stationarity_summary``), so that
this job does not import scipy.stats for its asymptotic p-values (about 1.2 s per axis).

Per sensor type (rule ``stationarity_summary``): every axis's verdict with ``stationarity.on_fail`` applied, i.e.
which curves the stacked files mark ``included`` (:func:`summary_stage`), and the paper's test of each axis beside
the calibrated verdict (:func:`paper_tests`), run once per sensor type so that only that job imports scipy.stats.

Segments (``events.policy: split``, :mod:`imupipe.segments`): each segment of the record is tested on its own at
level alpha/K (Bonferroni over its K segments: no segment boundary inside a test), and the axis is stationary when
every segment is; its p-value is min(1, K min_k p_k), the Bonferroni-adjusted smallest one, and the verdict's other
fields are those of that segment, with ``segments`` listing each one's span (s from the record's start), verdict
and p-value.

Plain values in (the decimated record, its rate and labels, its Allan curve), the verdict file's dict out
(:func:`stationarity_stage`). p-values are probabilities, the rate in Hz.
"""

from __future__ import annotations

import logging

from imupipe.verdict import chance_failures

__all__ = ["NULL_COMPONENTS", "paper_tests", "stationarity_stage", "summary_stage"]

#: Components of the calibrated null's model (the axis's Allan fit).
NULL_COMPONENTS = ("white", "gauss_markov", "flicker", "random_walk")


def stationarity_stage(x, rate: float, *, dataset=None, sensor=None, axis=None, allan=None, n_segments: int = 2,
                       alpha: float = 0.05, test: str = "calibrated", n_sim: int = 199, n_sim_max: int | None = None,
                       close_z: float = 2.0, segments=None) -> dict:
    """The verdict of the decimated record `x` (u) at `rate` (Hz) of `dataset`/`sensor`/`axis`: the
    ``stationarity`` settings (`n_segments`, `alpha`, `test` ``calibrated`` or ``paper``, `n_sim`, `n_sim_max`,
    `close_z`), `allan` the axis's (tau s, avar u^2, edf) on its grid (NaN where missing: the fit drops them;
    needed by ``calibrated``); `segments` (:class:`imupipe.segments.Segments` of `x`, None: the whole record) each
    tested as a record (module docstring)."""
    if segments is not None and not segments.is_whole:
        k = len(segments.bounds)
        parts = [stationarity_stage(v, rate, dataset=dataset, sensor=sensor, axis=axis, allan=allan,
                                    n_segments=n_segments, alpha=alpha / k, test=test, n_sim=n_sim,
                                    n_sim_max=n_sim_max, close_z=close_z) for v in segments.views(x)]
        return {**_segment_verdict(parts, segments, "p_value"), "n_samples": int(x.size)}
    out = {"dataset": dataset, "sensor": sensor, "axis": axis, "rate_hz": rate, "n_samples": int(x.size),
           "test": test}
    if test == "calibrated":
        from imupipe.identify import fit_allan
        from imupipe.stationarity import calibrated_stationarity

        tau, avar, edf = allan
        fit = fit_allan(tau, avar, edf, components=NULL_COMPONENTS, n_boot=0)
        # the null draws are seeded from the record itself (common random numbers): identical records give
        # identical verdicts whatever their axis or dataset; close verdicts draw more (up to n_sim_max)
        cal = calibrated_stationarity(x, rate, fit.model, n_segments=n_segments, alpha=alpha, n_sim=n_sim,
                                      rng="data", n_sim_max=n_sim_max, close_z=close_z, paper=False)
        out["paper"] = "the paper's test on this record: in the sensor's stationarity summary"
        cal["null_model"] = fit.model.to_dict()
        out["calibrated"] = cal
        out["stationary"] = bool(cal["stationary"])
        out["p_value"] = float(cal["p_value"])
        out["p_value_mc_se"] = float(cal["p_value_mc_se"])  # Monte Carlo standard error of p
        out["n_sim_run"] = int(cal["n_sim_run"])
        out["closeness"] = float(cal["closeness"])  # (p - alpha) / p_value_mc_se
        out["close_to_level"] = bool(abs(cal["closeness"]) <= close_z)
    else:
        from imupipe.stationarity import stationarity_tests

        out["paper"] = paper = stationarity_tests(x, n_segments=n_segments, alpha=alpha)
        out["stationary"] = bool(paper["stationary"])
        out["p_value"] = float(min(paper["levene_p"], min(paper["ks_p"])))
    return out


def paper_tests(verdicts: list, decimated: list) -> list:
    """The paper's test of each axis: the per-axis verdict's own (test = paper), else run here on the axis's
    decimated record (test = calibrated), with the verdict's segments and level."""
    out = []
    for v, path in zip(verdicts, decimated, strict=True):
        if isinstance(v.get("paper"), dict):
            out.append(v["paper"])
            continue
        from imupipe.io import read_series
        from imupipe.stationarity import stationarity_tests

        x, rate, attrs = read_series(path)
        if (str(attrs.get("dataset")), str(attrs.get("axis"))) != (str(v["dataset"]), str(v["axis"])):
            raise ValueError(f"{path}: holds {attrs.get('dataset')}/{attrs.get('axis')}, expected the verdict's "
                             f"{v['dataset']}/{v['axis']}")
        from imupipe.segments import Segments

        seg = Segments.from_attrs(attrs, x.size, rate, path)
        cal = v["calibrated"]  # its alpha: the level of each segment's test (alpha/K under split)
        tests = [stationarity_tests(y, n_segments=int(cal["n_segments"]), alpha=float(cal["alpha"]))
                 for y in seg.views(x)]
        out.append(tests[0] if seg.is_whole else _segment_verdict(
            [{**t, "p_value": min(t["levene_p"], min(t["ks_p"]))} for t in tests], seg, "p_value"))
    return out


def _segment_verdict(parts: list, segments, key: str) -> dict:
    """The axis's verdict from its segments' verdicts `parts` (each with ``stationary`` and the p-value `key`):
    that of the segment with the smallest p, with ``stationary`` = every segment's, `key` = min(1, K min p) and
    ``segments`` (module docstring)."""
    k = len(parts)
    worst = min(range(k), key=lambda i: float(parts[i][key]))
    out = dict(parts[worst])
    out["stationary"] = all(bool(p["stationary"]) for p in parts)
    out[key] = min(1.0, k * float(parts[worst][key]))
    out["segments"] = [{"start_s": float(s), "stop_s": float(s + n / segments.rate_hz),
                        "stationary": bool(p["stationary"]), "p_value": float(p[key])}
                       for s, n, p in zip(segments.start_s, segments.lengths, parts)]
    out["segments_rule"] = (f"each of the {k} segments tested at alpha/{k}; p_value = min(1, {k} x the smallest "
                            "segment p-value) (Bonferroni)")
    return out


def summary_stage(verdicts: list, on_fail: str, sensor: str, papers: list | None = None) -> dict:
    """Per-sensor summary; raises for on_fail = fail, or when on_fail = exclude leaves no curve. `papers`: the
    paper's test of each curve (default: each verdict's own ``paper``)."""
    papers = [v["paper"] for v in verdicts] if papers is None else papers
    curves = [{"dataset": v["dataset"], "axis": v["axis"], "stationary": bool(v["stationary"]),
               "p_value": v["p_value"], "test": v["test"], "paper_stationary": bool(paper["stationary"]),
               "paper": paper}
              for v, paper in zip(verdicts, papers, strict=True)]
    failing = [f"{c['dataset']}/{sensor}/{c['axis']} (p = {c['p_value']:.3g})" for c in curves if not c["stationary"]]
    if failing and on_fail == "fail":
        raise ValueError(f"non-stationary {sensor} records (stationarity.on_fail = fail): {', '.join(failing)}")
    for c in curves:
        c["included"] = c["stationary"] or on_fail == "warn"
    if failing:
        logging.warning("non-stationary: %s (%s)", ", ".join(failing),
                        "excluded from the bound" if on_fail == "exclude" else "kept, on_fail = warn")
    if not any(c["included"] for c in curves):
        raise ValueError(f"every {sensor} record failed the stationarity test and on_fail = exclude: nothing to bound")
    alpha = _axis_level(verdicts[0]) if verdicts else None
    return {"sensor": sensor, "on_fail": on_fail, "n_curves": len(curves), "n_non_stationary": len(failing),
            "alpha": alpha, "chance": chance_failures(len(failing), len(curves), alpha or 0.0), "curves": curves}


def _axis_level(verdict: dict) -> float | None:
    """The level of one axis's verdict: its test's alpha, times the number of segments when the record was split
    (each segment is tested at alpha/K and the axis's p-value is K x the smallest, :func:`_segment_verdict`)."""
    test = verdict.get("calibrated") if isinstance(verdict.get("calibrated"), dict) else verdict.get("paper")
    if not isinstance(test, dict) or test.get("alpha") is None:
        return None
    return float(test["alpha"]) * len(verdict.get("segments") or [None])
