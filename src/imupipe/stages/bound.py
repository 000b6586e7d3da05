r"""The global bound of one sensor type against one spec sheet (rule ``bound``; :func:`imupipe.api.noise_model`).

Over every included curve's two-sided PSD (decimated, interval ``dt``), the spec sheet and, below the lowest
bin down to :math:`0.01/h` (h = ``span_s``: fix period + outage, verify.fix_s + application.outage_s), the
identified upper envelope (:func:`imupipe.bound.upper_envelope_from_identification` of the identify record), restricted to the
components the identification kept: :func:`imupipe.bound.bound_psd`, the sensor's spectral lines entering
through its line policy (:func:`imupipe.lines.line_policy_from_files`). Then the Allan-domain check of the
bound's kept components against the sample AVs' lower limits over :math:`[1/f_{app}, h]`
(:func:`imupipe.bound.check_allan`); when the identification's pooling test says the axes differ, a bounding
model per axis (:func:`imupipe.bound.bound_by_axis`, each with that axis's envelope, lines and Allan check);
optionally the paper's hand inflation for comparison (:func:`imupipe.bound.paper_inflation`). Not the verdict:
``psd_bounded`` says only that the model's PSD is above its targets; the verdict is the contract's.

:func:`axis_bound_stage` is the per-axis bound (rule ``bound_axis``): the tightest model of one axis of one
dataset by the same rules (kept components, all frequencies, line policy) on a coarser T grid.

Plain values in (arrays keyed by curve label ``dataset/axis``, dicts of the identify and lines files, the
config's numbers), the bound file's dict out (:func:`bound_stage`); :func:`bound_sensor` keeps the
:class:`imupipe.bound.BoundResult` as well. SI units, PSDs two-sided.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["AXIS_T_PER_DECADE", "HEADER", "STRETCH_LABEL", "BoundStage", "axis_bound_stage", "bound_sensor",
           "bound_stage", "phase_ends", "with_stretches"]

#: T grid (points per decade) of the per-axis bound (rule bound_axis): coarser than the global bound's,
#: refined by a bounded search all the same.
AXIS_T_PER_DECADE = 4


#: Header of the bound file (what its fields mean, units).
HEADER = """global bound of one sensor type (docs/outputs.md); the verdict is in contract/{spec}/{sensor}.yaml.
SI: white N in u/sqrt(Hz), gauss_markov sigma in u and T in s, random_walk K in u/sqrt(s); u = rad/s (gyro), m/s^2 (accel).
PSDs two-sided; the model is compared as the PSD of its dt-block-averaged samples (NoiseModel.psd_sampled).
bound_spec_units: the same in the spec sheet's units. inflation: bound/spec per parameter.
margin: min over curves and frequencies of S_model/S_sample (>= 1 when psd_bounded), margin_curve: where.
all_frequency_margin: min of S_model/max(S_spec, S_upper) below the lowest bin (frequency 0: K asymptote, inf: N).
upper_envelope: the identified model at its upper confidence limits (SI), imposed at every frequency.
envelope_target: (auto's envelope candidate, pooled curves) the model it lies above instead: upper_envelope and each
axis's own envelope (identify file: upper_envelope_model_axes); upper_envelope stays the verification's reference.
allan_check.total.tau_band_s: the application band of the total-AV check, [1/application.filter_rate_hz, horizon_s] s.
noisiest_stretch: curves whose noise level changes (the stationarity summary's marks: failing beyond chance, or the
stretch test), each entering the bound a second time with its PSD raised band by band to its noisiest stretch's
(label -> the curve, its largest gain, the shortest stretch length s).
per_axis_models: present when the pooling test rejected one model for all axes: per axis, the bound of that axis's
curves (same fields as the global bound, SI), its envelope and Allan check; null when the axes are pooled."""


@dataclass
class BoundStage:
    """:func:`bound_sensor`'s result: ``record`` (the bound file's dict), the global ``result``
    (:class:`imupipe.bound.BoundResult`), the ``upper`` envelope it imposed and the line ``policy`` (or None)."""

    record: dict
    result: Any
    upper: Any
    policy: Any
    candidates: Any = None  # bound.mode auto: mode -> BoundStage of that candidate


def _auto(frequency, psd, edf, spec_model, identified, settings) -> BoundStage:
    """``bound.mode: auto`` (:mod:`imupipe.bound.auto`): one candidate per mode of
    :func:`imupipe.bound.auto.candidate_modes`, each the bound file entry of :func:`bound_sensor` in that mode; the
    verification verifies each and selects the exported one. The file's top-level fields are the ``raw``
    candidate's (the paper's; what the figures and tables of the bound show), ``mode`` is ``auto`` and
    ``candidates`` holds every candidate's entry."""
    from imupipe.bound.auto import candidate_modes

    modes, why = candidate_modes(identified, settings.get("lines"), stretched=list(settings.get("stretches") or ()))
    cands = {}
    for m in modes:
        kw = dict(settings, mode=m)
        if m != "raw":
            kw["compare_paper"] = False  # the paper's hand inflation once, beside the raw candidate
        cands[m] = bound_sensor(frequency, psd, edf, spec_model, identified, **kw)
    top = cands["raw"]
    record = dict(top.record)
    record["mode"] = "auto"
    record["candidates"] = {m: {k: v for k, v in c.record.items() if k != "candidates"} for m, c in cands.items()}
    record["auto_note"] = ("bound.mode auto: one candidate per mode (candidates); the verification verifies each and "
                           "exports the tightest that passes every check (verify file: auto_selection); the "
                           "top-level fields are the raw candidate's")
    record["auto_envelope_candidate"] = why
    return BoundStage(record=record, result=top.result, upper=top.upper, policy=top.policy, candidates=cands)


def phase_ends(history):
    """The hand procedure's state at the start and at the end of each phase (paper Figure 8)."""
    from imupipe.io import plain

    keys = ("parameter", "N", "sigma", "T", "K", "margin")
    ends = [h for i, h in enumerate(history) if i == 0 or i + 1 == len(history) or history[i + 1][0] != h[0]]
    return [dict(zip(keys, plain(list(h)))) for h in ends]


def bound_sensor(frequency, psd: Mapping, edf: Mapping, spec_model, identified: dict, *, dt: float, sensor: str,
                 mode: str, n_gm: int, confidence: float, bands_per_decade: int, span_s: float,
                 filter_rate_hz: float = 1.0, taper: str = "hann", allan=None, lines: Mapping | None = None,
                 line_policy: str = "model", application_band_hz=None, axis_bounds=(), compare_paper: bool = False,
                 spec_units=None, spec_name: str = "", spec_file: str | None = None,
                 stretches: Mapping | None = None) -> BoundStage:
    """The bound of one sensor type (module docstring).

    Parameters
    ----------
    frequency : array_like
        The decimated PSD grid, Hz (every curve's).
    psd, edf : mapping of str to array_like
        Curve label -> two-sided PSD (u^2/Hz) and its equivalent degrees of freedom (scalar or per bin).
    spec_model : imupipe.models.NoiseModel
        The spec sheet's model of `sensor` (SI).
    identified : dict
        The identification record (:func:`imupipe.stages.identify.identification_stage`, or its file).
    dt : float
        Decimated sample interval, s. `mode`, `n_gm`, `confidence`, `bands_per_decade`: ``bound.*``;
        `span_s`: s, fix period + outage (the all-frequency bound's reach, written as ``horizon_s``);
        `filter_rate_hz`: Hz, the filter's update rate: the Allan check's shortest tau is
        its inverse; `taper`: the PSD's window.
    allan : (tau, mapping of str to (avar, edf)) or None
        The stacked Allan grid (s) and each included curve's AV (u^2, NaN where a curve has no value) and edf;
        None: no Allan check.
    lines : mapping of str to dict, optional
        Curve label -> its lines file (:meth:`imupipe.lines.LineSearch.to_dict`); None or empty: no lines stage.
    line_policy, application_band_hz :
        ``lines.policy`` of `sensor` and ``lines.application_band_hz`` (Hz, None: the whole decimated band).
    axis_bounds : sequence of dict
        The per-axis bound files (rule ``bound_axis``), summarised under ``per_axis``.
    compare_paper : bool
        Also run the paper's hand inflation and its looseness.
    spec_units, spec_name, spec_file :
        The spec sheet's display units (:func:`imupipe.specsheet.display_units`), name and file name.
    stretches : mapping of str to dict, optional
        Curve label -> its noisiest-stretch scan (:meth:`imupipe.stretches.StretchLevels.to_dict`), for the curves
        whose noisiest stretch the bound covers (the stationarity summary's ``noisiest_stretch``): each enters as a
        further curve, its PSD times the scan's gain (:func:`with_stretches`).
    """
    if mode == "auto":
        return _auto(frequency, psd, edf, spec_model, identified, dict(
            dt=dt, sensor=sensor, n_gm=n_gm, confidence=confidence, bands_per_decade=bands_per_decade, span_s=span_s,
            filter_rate_hz=filter_rate_hz, taper=taper, allan=allan, lines=lines, line_policy=line_policy,
            application_band_hz=application_band_hz, axis_bounds=axis_bounds, compare_paper=compare_paper,
            spec_units=spec_units, spec_name=spec_name, spec_file=spec_file, stretches=stretches))
    from imupipe.bound import (bound_by_axis, bound_psd, check_allan, looseness, paper_inflation,
                               upper_envelope_from_identification)
    from imupipe.io import plain
    from imupipe.models import NoiseModel
    from imupipe.lines import line_policy_from_files
    from imupipe.stages.identify import fitted_model

    f = np.asarray(frequency, dtype=np.float64)
    curves = {k: np.asarray(v) for k, v in psd.items()}
    edf_of = {k: np.broadcast_to(np.asarray(edf[k], dtype=np.float64), f.shape) for k in curves}
    stretched = with_stretches(f, curves, edf_of, stretches)
    kept = identified["selection"]["kept"]
    upper = upper_envelope_from_identification(identified)
    # pooled axes with their own joint bands: every mode lies above the pooled envelope and each axis's (identify's
    # upper_envelope_model_axes; why: _axis_envelopes); the file's upper_envelope stays the pooled one
    target = (NoiseModel.from_dict(identified["upper_envelope_model_axes"])
              if identified.get("upper_envelope_model_axes") else upper)
    lines = dict(lines or {})
    pol = line_policy_from_files(lines, dt, f, line_policy, application_band_hz)
    pooled = (identified.get("pooling") or {}).get("consistent", True) is not False
    result = bound_psd(f, curves, spec_model, dt=dt, mode=mode, n_gm=n_gm, confidence=confidence,
                       bands_per_decade=bands_per_decade, edf=np.array(list(edf_of.values())), keep=kept,
                       taper=taper, span_s=span_s, upper_model=target,
                       pool_groups=_pool_groups(curves, stretched, pooled),
                       **(pol.bound_kwargs() if pol is not None else {}))
    logging.info("bound %s: margin %.4g (%s), all-frequency margin %.4g, looseness %.4g, %d LPs in %.3g s",
                 result.model, result.margin, result.margin_curve, result.allf_margin, result.looseness,
                 result.n_lp, result.solve_time_s)
    body = result.to_dict(spec_units=spec_units, sensor=sensor)
    body["psd_bounded"] = body.pop("bounded")
    body.pop("solve_time_s", None)  # wall clock: in the log, not in the file (identical runs, identical files)
    out = {"spec_name": spec_name, "spec_file": spec_file, "sensor": sensor, "dt_s": dt,
           "horizon_s": float(span_s), "n_curves": len(psd), "curves": list(psd),
           "states_kept_by_identification": kept, **body,
           "upper_envelope": upper.to_dict(),
           **({"envelope_target": target.to_dict()} if target is not upper else {}),
           "identification_intervals": identified.get("intervals_bootstrap"),
           "upper_envelope_kind": identified.get("upper_envelope_kind", "marginal"),
           "axis_upper_envelopes": _axis_envelopes(identified) if pooled else None,
           "noisiest_stretch": stretched or None,
           "lines": pol.to_dict() if pol is not None else {"policy": None, "note": "no lines files (lines stage not run)"}}
    tau_min_s = 1.0 / float(filter_rate_hz)
    labels, avars, edfs = [], [], []
    if allan is not None:
        tau, per_curve = allan
        for lab, (a, e) in per_curve.items():
            labels.append(lab)
            avars.append(a)
            edfs.append(e)
        ref, ref_kept = fitted_model(identified, kept)
        checked = check_allan(result.model, ref, tau, kept=ref_kept,
                              sample_avar=np.array(avars), sample_edf=np.array(edfs), labels=labels,
                              span_s=span_s, tau_min_s=tau_min_s)
        out["allan_check"] = plain(checked)
        out["allan_check_passed"] = bool(checked["passed"])
    # per-axis models where the pooling test says the axes differ (docs/method.md, "Per-axis models")
    axes_fit = identified.get("per_axis") or {}
    out["per_axis_models"] = None
    if not pooled and axes_fit:
        uppers = {ax: NoiseModel.from_dict(v["upper_envelope_model"]) for ax, v in axes_fit.items()
                  if v.get("upper_envelope_model")}
        line_kw = _axis_line_policies(axes_fit, lines, dt, f, line_policy, application_band_hz)
        per = bound_by_axis(f, curves, spec_model, upper_models=uppers, edf=edf_of,
                            line_kwargs={ax: kw for ax, (kw, _) in line_kw.items()}, dt=dt, mode=mode, n_gm=n_gm,
                            confidence=confidence, bands_per_decade=bands_per_decade, keep=kept, taper=taper,
                            span_s=span_s)
        out["per_axis_models"] = {}
        for ax, (labs, res) in per.items():
            if ax not in axes_fit:
                continue  # an axis without its own fit keeps the global model
            b_ax = res.to_dict(spec_units=spec_units, sensor=sensor)
            b_ax["psd_bounded"] = b_ax.pop("bounded")
            b_ax.pop("solve_time_s", None)
            b_ax.pop("details", None)
            entry = {"axis": ax, "curves": [lab for lab in labs if lab not in stretched], **b_ax,
                     "noisiest_stretch": [lab for lab in labs if lab in stretched] or None,
                     "upper_envelope": uppers[ax].to_dict() if ax in uppers else None,
                     "identification_level": axes_fit[ax].get("level"),
                     "lines": line_kw[ax][1].to_dict() if line_kw.get(ax, ({}, None))[1] is not None else None}
            if allan is not None:
                sel = [labels.index(lab) for lab in labs if lab in labels]
                ref, ref_kept = fitted_model(axes_fit[ax], kept)
                al_ax = check_allan(res.model, ref, allan[0], kept=ref_kept,
                                    sample_avar=np.array(avars)[sel], sample_edf=np.array(edfs)[sel],
                                    labels=[labels[j] for j in sel], span_s=span_s, tau_min_s=tau_min_s)
                entry |= {"allan_check": plain(al_ax), "allan_check_passed": bool(al_ax["passed"])}
            out["per_axis_models"][ax] = entry
            logging.info("per-axis bound %s: %s, margin %.4g, all-frequency margin %.4g", ax, res.model, res.margin,
                         res.allf_margin)
    out["per_axis"] = [{"curve": ax["curve"], "psd_bounded": ax["psd_bounded"], "margin": ax["margin"],
                        "all_frequency_margin": ax.get("all_frequency_margin"), "inflation": ax["inflation"]}
                       for ax in axis_bounds]
    if compare_paper:
        hand = paper_inflation(f, curves, spec_model, dt=dt)
        out["paper_hand_inflation"] = {
            "model": hand.model.to_dict(), "inflation": hand.inflation, "psd_bounded": bool(hand.bounded),
            "margin": float(hand.margin), "looseness": float(looseness(hand.model, f, curves, spec_model, dt=dt)),
            "lp_looseness_raw": float(looseness(result.model, f, curves, spec_model, dt=dt)),
            "n_steps": int(hand.details.get("n_steps", 0)),
            "phases": phase_ends(hand.details.get("history", [])),
        }
    return BoundStage(record=plain(out), result=result, upper=upper, policy=pol)


def _axis_envelopes(identified: dict) -> dict | None:
    """Where the pooling test accepts one model for axes that each have their own joint band (the identify file's
    ``axis_envelopes``): axis -> that axis's own upper envelope (SI dict), which the verification checks the global
    model against as where the axes differ (an outside evaluation: axis y's random walk 4x x and z's passed the
    pooling test, p 1.0, and the smoothed candidate under-stated y's error, MSE/P 1.42). None elsewhere."""
    axes = identified.get("axis_envelopes") or {}
    out = {str(ax): e["upper_envelope_model"] for ax, e in axes.items() if e.get("upper_envelope_model")}
    return out or None


def _axis_line_policies(axes, lines: Mapping, dt: float, f, line_policy: str, application_band_hz) -> dict:
    """Axis -> (the bound's line keyword arguments, the line policy or None) of that axis's curves' lines files
    (:func:`imupipe.lines.line_policy_from_files`): each per-axis model carries its own axis's lines."""
    from imupipe.bound import axis_of
    from imupipe.lines import line_policy_from_files

    out = {}
    for ax in axes:
        p_ax = line_policy_from_files({lab: doc for lab, doc in lines.items() if axis_of(lab) == ax}, dt, f,
                                      line_policy, application_band_hz)
        out[ax] = (p_ax.bound_kwargs() if p_ax is not None else {}, p_ax)
    return out


def _pool_groups(curves, stretched, pooled: bool):
    """The ``pooled`` mode's group of each curve: one group where the identification's pooling test accepts one
    true PSD for every curve (None), else one per axis. The noisiest-stretch copies (`stretched`) are pooled apart
    from the records (each repeats its record's periodogram, raised): one group per dataset where the axes are
    pooled (its axes' copies, raised by their own gains), else each copy alone."""
    from imupipe.bound import axis_of

    if pooled and not stretched:
        return None
    return [(k.rsplit("/", 1)[0] if pooled else k) if k in stretched else "all" if pooled else axis_of(k)
            for k in curves]


#: Label of a curve's noisiest-stretch copy (:func:`with_stretches`): the axis stays after the last "/".
STRETCH_LABEL = "{dataset} noisiest stretch/{axis}"


def with_stretches(frequency, curves: dict, edf_of: dict, stretches: Mapping | None) -> dict:
    """Add (in place) to `curves` and `edf_of` a copy of each curve of `stretches` (label -> scan dict,
    :meth:`imupipe.stretches.StretchLevels.to_dict`) raised to its noisiest stretch, :math:`g(f) \\hat S(f)` with
    g the scan's gain on `frequency` (Hz; :meth:`imupipe.stretches.StretchLevels.gain`) and the curve's own edf,
    labelled :data:`STRETCH_LABEL`. Returns the bound file's ``noisiest_stretch`` record: new label -> the curve it
    copies, the scan's largest gain and stretch length (s). A label not among `curves` is an error."""
    from imupipe.bound import axis_of
    from imupipe.stretches import StretchLevels

    out = {}
    for label, scan in (stretches or {}).items():
        if label not in curves:
            raise ValueError(f"noisiest stretch of {label!r}: no such curve among the bound's ({', '.join(curves)})")
        levels = StretchLevels.from_dict(scan)
        axis = axis_of(label)
        new = STRETCH_LABEL.format(dataset=label[: -len(axis) - 1], axis=axis)
        curves[new] = np.asarray(curves[label]) * levels.gain(frequency)
        edf_of[new] = edf_of[label]
        out[new] = {"curve": label, "max_gain": levels.max_gain, "stretch_s": float(levels.stretch_s)}
    return out


def bound_stage(frequency, psd: Mapping, edf: Mapping, spec_model, identified: dict, **settings) -> dict:
    """The bound file's content (a YAML-ready dict, SI) of :func:`bound_sensor` with the same arguments."""
    return bound_sensor(frequency, psd, edf, spec_model, identified, **settings).record


def axis_bound_stage(frequency, psd, edf, label: str, spec_model, identified: dict, *, dt: float, sensor: str,
                     mode: str, n_gm: int, confidence: float, bands_per_decade: int, span_s: float,
                     taper: str = "hann", lines: Mapping | None = None, line_policy: str = "model",
                     application_band_hz=None, spec_units=None, spec_name: str = "") -> dict:
    """The per-axis bound file's content (YAML-ready, SI) of the curve `label` (its two-sided `psd`, u^2/Hz, and
    `edf` on `frequency`, Hz): :func:`imupipe.bound.bound_psd` of the components the pooled identification kept,
    on :data:`AXIS_T_PER_DECADE`, over all frequencies (spec sheet and the identified upper envelope below the
    lowest bin, down to 0.01/`span_s`), with the line policy of `lines` (label -> lines file). The other
    arguments as :func:`bound_sensor`'s."""
    from imupipe.bound import bound_psd, upper_envelope_from_identification
    from imupipe.io import plain
    from imupipe.lines import line_policy_from_files

    f = np.asarray(frequency, dtype=np.float64)
    if mode == "auto":
        mode = "raw"  # an axis's own bound is reported, never exported: the paper's mode (auto selects globally)
    pol = line_policy_from_files(dict(lines or {}), dt, f, line_policy, application_band_hz)
    result = bound_psd(f, {label: np.asarray(psd)}, spec_model, dt=dt, mode=mode, n_gm=n_gm, confidence=confidence,
                       bands_per_decade=bands_per_decade, edf=edf, taper=taper, keep=identified["selection"]["kept"],
                       T_grid=AXIS_T_PER_DECADE, span_s=span_s,
                       upper_model=upper_envelope_from_identification(identified),
                       **(pol.bound_kwargs() if pol is not None else {}))
    logging.info("bound of %s: margin %.4g, %d LPs in %.3g s", label, result.margin, result.n_lp, result.solve_time_s)
    body = result.to_dict(spec_units=spec_units, sensor=sensor)
    body["psd_bounded"] = body.pop("bounded")
    body.pop("solve_time_s", None)  # wall clock: in the log only
    return plain({"spec_name": spec_name, "curve": label, "sensor": sensor, "dt_s": dt, "horizon_s": float(span_s),
                  **body, "lines": pol.to_dict() if pol is not None
                  else {"policy": None, "note": "no lines files (lines stage not run)"}})
