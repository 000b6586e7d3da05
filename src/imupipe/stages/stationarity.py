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

Noisiest stretch: each verdict also carries the record's scan (:func:`imupipe.stretches.stretch_levels`, field
``stretches``); the summary marks the curves whose scan the bound takes in (:data:`STRETCH_RULE`, field
``noisiest_stretch``).

Plain values in (the decimated record, its rate and labels, its Allan curve), the verdict file's dict out
(:func:`stationarity_stage`). p-values are probabilities, the rate in Hz.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from imupipe.verdict import chance_failures

__all__ = ["NULL_COMPONENTS", "STRETCH_RULE", "marked_stretches", "paper_test", "paper_tests", "stationarity_stage",
           "summary_stage"]

#: Components of the calibrated null's model (the axis's Allan fit), beside the axis's spectral lines.
NULL_COMPONENTS = ("white", "gauss_markov", "flicker", "random_walk")


#: Allan taus of the notched record's own curve, on which the null of an axis with lines is fitted
#: (``allan_variance``'s `taus`: points per decade).
NULL_FIT_TAUS = 8

#: Coherence times of an unresolved spectral line that the calibrated null tries, in record lengths
#: (:func:`null_line_sets`).
NULL_COHERENCE_RECORDS = (0.125, 0.5, 2.0, 8.0)


def null_line_sets(lines, rate: float, duration_s: float) -> list[tuple]:
    r"""The narrowband terms (sigma u, f0 Hz, zeta) that the axis's full-rate spectral lines `lines`
    (:class:`imupipe.lines.Line`) make in its record of `duration_s` (s) block-averaged to `rate` (Hz), as the
    sets of terms the calibrated null tries (the first: each line as measured).

    Each line lies at its alias :math:`f_a` (:func:`imupipe.lines.alias_frequency`) with its model term's power
    (:attr:`imupipe.lines.Line.narrowband`) times :math:`\mathrm{sinc}^2(f_0/\mathrm{rate})` (the block average's
    gain) and its half-power width
    :math:`\Gamma` kept: :math:`\zeta = \min(\Gamma / (2 f_a), 1/2)`. A line folded onto 0 Hz (a multiple of the
    rate) is left out: the block average removes it. A line no wider than its search's resolution is unresolved:
    its width is an upper limit, and its amplitude may wander over any coherence time
    :math:`\tau_c = 1/(2\pi\zeta f_a)` longer than the measured width allows, which the segments' variances
    see. The further sets give such lines :math:`\tau_c` = :data:`NULL_COHERENCE_RECORDS` x `duration_s`
    (where that is narrower than measured); the verdict takes the largest p-value over the sets (a test of
    level alpha whenever one of them holds the line's true width, up to the grid's spacing)."""
    base, unresolved = [], []
    for line in lines:
        folded = _in_record(line, rate)
        if folded is not None:
            fa, gain = folded
            if not _resolved(line):
                unresolved.append(len(base))
            base.append((line.narrowband[0] * gain, fa, min(line.width_hz / (2.0 * fa), 0.5)))
    sets = [tuple(base)] if base else []
    for c in NULL_COHERENCE_RECORDS if unresolved else ():
        terms = list(base)
        for i in unresolved:
            sigma, fa, zeta = terms[i]
            terms[i] = (sigma, fa, min(zeta, 1.0 / (2.0 * math.pi * fa * c * duration_s)))
        if tuple(terms) not in sets:
            sets.append(tuple(terms))
    return sets


#: Half-width of a line's notch beyond its interval (:func:`notch_bands`): bins of the record's spectrum, and
#: multiples of the line's half-power width.
NOTCH_BINS, NOTCH_WIDTHS = 25, 10.0
#: Largest share of the record's band one line's notch may take (:func:`notch_bands`).
NOTCH_MAX_SHARE = 0.5


def notch_bands(lines, rate: float, n: int) -> list[tuple[float, float]]:
    r"""The bands (Hz) of a record of `n` samples block-averaged to `rate` (Hz) that the stationarity test leaves
    out for the axis's full-rate spectral lines `lines` (:class:`imupipe.lines.Line`; those of
    :func:`null_line_sets`): each line's interval folded into the record's band
    (:func:`imupipe.lines.decimated_line`), widened on each side by the larger of :data:`NOTCH_BINS` bins
    (rate / n Hz each) and, for a resolved line (wider than its search's resolution), :data:`NOTCH_WIDTHS`
    half-power widths :math:`\Gamma`. What a notch leaves of a line
    leaks from beyond it: about :math:`2/(\pi^2 w)` of a sinusoid's power beyond w bins (0.8 % at 25) and
    :math:`\Gamma/(\pi \Delta)` of a Lorentzian's beyond :math:`\Delta` Hz (3 % at 10 widths). A line whose notch
    would take more than :data:`NOTCH_MAX_SHARE` of the band [0, rate/2] is broadband in the record (a resonance
    wider than the band it folds into: 40 Hz in 100 Hz records at damping 0.003, 0.24 Hz wide, block-averaged to 1
    Hz, had its notch take the whole band): it is not notched, the null carries it (:func:`null_line_sets`)."""
    from imupipe.lines import decimated_line

    out = []
    for line in lines:
        if _in_record(line, rate) is not None:
            d = decimated_line(line, 1.0 / float(rate))
            margin = max(NOTCH_BINS * float(rate) / n, NOTCH_WIDTHS * line.width_hz if _resolved(line) else 0.0)
            lo, hi = max(0.0, d["f_lo_hz"] - margin), d["f_hi_hz"] + margin
            if min(hi, 0.5 * float(rate)) - lo <= NOTCH_MAX_SHARE * 0.5 * float(rate):
                out.append((lo, hi))
    return out


def _in_record(line, rate: float):
    r"""(alias Hz, amplitude gain) of a full-rate line in the record block-averaged to `rate` (Hz): its frequency
    folded into the record's band (:func:`imupipe.lines.alias_frequency`) and :math:`|\mathrm{sinc}(f_0/rate)|`;
    None where it folds onto 0 Hz or the block average removes it."""
    from imupipe.lines import alias_frequency

    dt = 1.0 / float(rate)
    fa, gain = alias_frequency(line.frequency_hz, dt), abs(float(np.sinc(line.frequency_hz * dt)))
    return (fa, gain) if fa > 0 and gain > 0 else None


def _resolved(line) -> bool:
    """A line wider than its search's resolution (else its width is the search's floor, an upper limit)."""
    return line.width_hz > line.resolution_hz * (1.0 + 1e-9)


def stationarity_stage(x, rate: float, *, dataset=None, sensor=None, axis=None, allan=None, n_segments: int = 2,
                       alpha: float = 0.05, test: str = "calibrated", n_sim: int = 199, n_sim_max: int | None = None,
                       close_z: float = 2.0, segments=None, lines=()) -> dict:
    """The verdict of the decimated record `x` (u) at `rate` (Hz) of `dataset`/`sensor`/`axis`: the
    ``stationarity`` settings (`n_segments`, `alpha`, `test` ``calibrated`` or ``paper``, `n_sim`, `n_sim_max`,
    `close_z`), `allan` the axis's (tau s, avar u^2, edf) on its grid (NaN where missing: the fit drops them;
    needed by ``calibrated``); `segments` (:class:`imupipe.segments.Segments` of `x`, None: the whole record) each
    tested as a record (module docstring); `lines` the axis's spectral lines found at full rate
    (:class:`imupipe.lines.Line`), which the calibrated test notches out of the record and its null
    (:func:`notch_bands`) and its null carries (:func:`null_line_sets`): a steady line is part of a stationary
    record, and a null without it flagged such axes. With lines the null's broadband model is fitted to the Allan
    variance of the notched record (:data:`NULL_FIT_TAUS`), not to `allan`. ``stretches``: the record's
    noisiest-stretch scan (:func:`imupipe.stretches.stretch_levels`, over the segments' views under split; None for
    a record too short for it) and, for a whole record under the calibrated test, ``stretch_test``
    (:func:`imupipe.stretches.stretch_test` on the null the test fitted); the bound takes the scan in by
    :func:`summary_stage`'s rule (:data:`STRETCH_RULE`)."""
    from imupipe.stretches import stretch_levels

    whole = segments is None or segments.is_whole
    levels = stretch_levels(x, rate, views=None if whole else list(segments.views(x)))
    stretches = levels.to_dict() if levels is not None else None
    if not whole:
        k = len(segments.bounds)
        parts = [_tested(v, rate, dataset=dataset, sensor=sensor, axis=axis, allan=allan, n_segments=n_segments,
                         alpha=alpha / k, test=test, n_sim=n_sim, n_sim_max=n_sim_max, close_z=close_z, lines=lines)
                 for v in segments.views(x)]
        return {**_segment_verdict(parts, segments, "p_value"), "n_samples": int(x.size), "stretches": stretches}
    out = _tested(x, rate, dataset=dataset, sensor=sensor, axis=axis, allan=allan, n_segments=n_segments, alpha=alpha,
                  test=test, n_sim=n_sim, n_sim_max=n_sim_max, close_z=close_z, lines=lines)
    if test == "calibrated" and levels is not None:  # does the noise level change beyond a stationary record's?
        from imupipe.models import NoiseModel
        from imupipe.stretches import stretch_test

        out["stretch_test"] = stretch_test(x, rate, NoiseModel.from_dict(out["calibrated"]["null_model"]),
                                           levels=levels)
    return {**out, "stretches": stretches}


def _tested(x, rate, *, dataset, sensor, axis, allan, n_segments, alpha, test, n_sim, n_sim_max, close_z,
            lines) -> dict:
    """The verdict of one record or segment `x` (:func:`stationarity_stage`'s arguments), without the scan."""
    out = {"dataset": dataset, "sensor": sensor, "axis": axis, "rate_hz": rate, "n_samples": int(x.size),
           "test": test}
    if test == "calibrated":
        from imupipe.identify import fit_allan

        sets = null_line_sets(lines, rate, x.size / rate)
        bands = notch_bands(lines, rate, x.size)
        if bands:  # the broadband fit on what the test reads: the notched record's own Allan variance
            from imupipe.allan import allan_variance_labelled
            from imupipe.stationarity import notch

            av = allan_variance_labelled(notch(x, rate, bands), rate, taus=NULL_FIT_TAUS)  # no xarray import
            tau, avar, edf = av.coords["tau"][0], av.data_vars["avar"][0], av.data_vars["edf"][0]
        else:
            tau, avar, edf = allan
        fit = fit_allan(tau, avar, edf, components=NULL_COMPONENTS, n_boot=0)
        cal = _calibrated_over(x, rate, fit.model, sets, bands, n_segments=n_segments,
                               alpha=alpha, n_sim=n_sim, n_sim_max=n_sim_max, close_z=close_z)
        out["paper"] = "the paper's test on this record: in the sensor's stationarity summary"
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


def _calibrated_over(x, rate, model, sets, bands, **settings) -> dict:
    """The calibrated test (:func:`imupipe.stationarity.calibrated_stationarity`) of `x` on the null `model` with
    each set of line terms of :func:`null_line_sets` added (`model` alone without lines), the record and every null
    record notched in `bands` (Hz, :func:`notch_bands`; none without lines): the verdict of the first set that does
    not reject, else of the set with the largest p-value, its ``null_model`` and, with lines, ``null_lines`` (the
    bands, each tried set's zetas and p-value).

    The verdict is that of the largest p-value over all sets (stationary when any set does not reject), so the sets
    after the first that does not reject are not run: they cannot change it. The p-value reported for a stationary
    record is then that set's, a lower bound of the largest (above the level either way); a rejected record runs
    every set and reports the largest."""
    from dataclasses import replace

    from imupipe.stationarity import calibrated_stationarity, notch

    transform = (lambda r: notch(r, rate, bands)) if bands else None
    results = []
    for terms in sets or [()]:
        null = replace(model, narrowband=tuple(model.narrowband) + tuple(terms)) if terms else model
        # the null draws are seeded from the record itself (common random numbers): identical records give
        # identical verdicts whatever their axis or dataset; close verdicts draw more (up to n_sim_max)
        cal = calibrated_stationarity(x, rate, null, rng="data", paper=False, transform=transform, **settings)
        cal["null_model"] = null.to_dict()
        results.append((terms, cal))
        if cal["stationary"]:
            break
    terms, best = max(results, key=lambda r: r[1]["p_value"])
    if sets:
        best["null_lines"] = {
            "statement": (f"{len(terms)} spectral line(s) of the axis notched out of the record and of the null "
                          "records, which carry them as narrowband terms at their alias in the decimated record; an "
                          "unresolved line's width tried over coherence times until one does not reject (else the "
                          "largest p-value taken)"),
            "notch_hz": [[float(lo), float(hi)] for lo, hi in bands],
            "tried": [{"zeta": [float(z) for _, _, z in t], "p_value": float(c["p_value"])} for t, c in results],
        }
    return best


def paper_tests(verdicts: list, decimated: list) -> list:
    """The paper's test of each axis (:func:`paper_test`) of the per-axis verdicts `verdicts` and their decimated
    record files `decimated` (read only where the verdict does not carry the test)."""
    out = []
    for v, path in zip(verdicts, decimated, strict=True):
        if isinstance(v.get("paper"), dict):
            out.append(v["paper"])
            continue
        from imupipe.io import read_series
        from imupipe.segments import Segments

        x, rate, attrs = read_series(path)
        if (str(attrs.get("dataset")), str(attrs.get("axis"))) != (str(v["dataset"]), str(v["axis"])):
            raise ValueError(f"{path}: holds {attrs.get('dataset')}/{attrs.get('axis')}, expected the verdict's "
                             f"{v['dataset']}/{v['axis']}")
        out.append(paper_test(v, x, Segments.from_attrs(attrs, x.size, rate, path)))
    return out


def paper_test(verdict: dict, x, segments=None) -> dict:
    """The paper's test of one axis: the verdict's own (test = paper), else run on its decimated record `x` (u; test
    = calibrated) with the verdict's level and number of segments, on each of `segments`
    (:class:`imupipe.segments.Segments` of `x`; None: the whole record). The one rule of the workflow's summary
    (:func:`paper_tests`) and of :func:`imupipe.api.noise_model`."""
    if isinstance(verdict.get("paper"), dict):
        return verdict["paper"]
    from imupipe.stationarity import stationarity_tests

    cal = verdict["calibrated"]  # its alpha: the level of each segment's test (alpha/K under split)
    views = [x] if segments is None else segments.views(x)
    tests = [stationarity_tests(y, n_segments=int(cal["n_segments"]), alpha=float(cal["alpha"])) for y in views]
    if segments is None or segments.is_whole:
        return tests[0]
    return _segment_verdict([{**t, "p_value": min(t["levene_p"], min(t["ks_p"]))} for t in tests], segments,
                            "p_value")


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
    _stretch_bound(curves, verdicts, len(failing), alpha)
    return {"sensor": sensor, "on_fail": on_fail, "n_curves": len(curves), "n_non_stationary": len(failing),
            "alpha": alpha, "chance": chance_failures(len(failing), len(curves), alpha or 0.0),
            "stretch_rule": STRETCH_RULE, "curves": curves}


#: When the bound covers a curve's noisiest stretch (:func:`summary_stage`, the stationarity summary's field).
STRETCH_RULE = ("a curve kept by the bound that fails the stationarity test, where the sensor's failures are more "
                "than chance gives or its own p-value is below alpha / number of curves, or whose stretch test "
                "(the noise level along the record) has a p-value below alpha / number of curves, enters the bound "
                "with its PSD raised to its noisiest stretch's (noisiest_stretch; docs/method.md, 'Stationarity')")


def marked_stretches(summary: dict | None) -> dict:
    """Curve label (``dataset/axis``) -> noisiest-stretch scan of each curve the stationarity summary `summary`
    (:func:`summary_stage`; None: none) marks: what the bound takes in (:func:`imupipe.stages.bound.with_stretches`)."""
    return {f"{c['dataset']}/{c['axis']}": c["noisiest_stretch"] for c in (summary or {}).get("curves") or ()
            if c.get("noisiest_stretch")}


def _stretch_bound(curves: list, verdicts: list, n_failed: int, alpha) -> None:
    """Mark (in place) each curve of `curves` whose noisiest stretch the bound covers (:data:`STRETCH_RULE`): its
    ``noisiest_stretch`` is its verdict's scan (:func:`imupipe.stretches.stretch_levels`); beyond chance where the
    sensor's `n_failed` failures are (:func:`imupipe.verdict.beyond_chance`) or, for one curve, where its p-value is
    below alpha over the number of curves (Bonferroni: family-wise level alpha); and where its stretch test
    (:func:`imupipe.stretches.stretch_test`, the verdict's ``stretch_test``) has a p-value below that, whatever the
    stationarity test said (its p-value is the curve's ``stretch_test_p``). ``taken_in_by`` says which rule took it
    in: ``failures beyond chance``, ``own p-value`` or ``stretch test``."""
    from imupipe.verdict import beyond_chance

    n = len(curves)
    many = bool(alpha) and beyond_chance(n_failed, n, alpha)
    for c, v in zip(curves, verdicts, strict=True):
        alone = bool(alpha) and float(c["p_value"]) < float(alpha) / max(n, 1)
        level = (v.get("stretch_test") or {}).get("p_value")
        if level is not None:
            c["stretch_test_p"] = float(level)
        changes = bool(alpha) and level is not None and float(level) < float(alpha) / max(n, 1)
        failing = not c["stationary"] and (many or alone)
        if c["included"] and (changes or failing) and v.get("stretches"):
            c["noisiest_stretch"] = v["stretches"]
            c["taken_in_by"] = ("failures beyond chance" if failing and many else "own p-value" if failing
                                else "stretch test")


def _axis_level(verdict: dict) -> float | None:
    """The level of one axis's verdict: its test's alpha, times the number of segments when the record was split
    (each segment is tested at alpha/K and the axis's p-value is K x the smallest, :func:`_segment_verdict`)."""
    test = verdict.get("calibrated") if isinstance(verdict.get("calibrated"), dict) else verdict.get("paper")
    if not isinstance(test, dict) or test.get("alpha") is None:
        return None
    return float(test["alpha"]) * len(verdict.get("segments") or [None])
