r"""The verification stage of one spec sheet's bound of one sensor type (rule ``verify``;
:func:`imupipe.api.noise_model`).

The reference filter built on the bound's model (accel: paper eq. 17 position filter; gyro: angle filter;
``fix_s`` s of fixes, then an outage of ``outage_s`` s, config ``application.outage_s``), checked by exact
covariance analysis against the
identified upper envelope, the spec sheet and, for simulated data, the truth; the replay of the decimated
records of that sensor; the model reduction by integrity (all of it :func:`imupipe.verify.verification_stage`).
When the bound carries per-axis models (the axes differ), each is verified the same way against its own
envelope and the records of its axis.

Plain values in (the bound file's dict, the decimated records keyed by curve label ``dataset/axis``, the
config's numbers), the verification file's dict out (:func:`verify_stage`); :func:`verify_sensor` also gives
the time series of the exported model's checks (for :func:`imupipe.plot.plot_verification`). SI units.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping

__all__ = ["HEADER", "model_of", "records_at_one_rate", "read_records", "verify_sensor", "verify_stage", "verify_job"]

#: Header of the verification file (what its fields mean, units).
HEADER = """verification of the bound in the reference filter (docs/method.md, "Integrity: what bounded means").
SI: times s; sigma_fix m (accel) or rad (gyro); ratio = true (or replayed) MSE / filter variance P, dimensionless.
worst_outage_ratio: the largest MSE/P after the fixes end (the informative number), at worst_outage_t_s s;
worst_ratio at worst_t_s: the same over the whole run (fixes included); mean_conservatism: mean P/MSE
over the outage. exported: the model the KF file carries (the bound's, or its reduction when every check passes).
per_axis_models: the same per axis (each against that axis's envelope, the spec sheet and that axis's records), when
the bound file has per-axis models; null otherwise. The global model is then also checked against each axis's own
envelope and slowest admitted bias (checks upper_envelope_<axis>, slow_bias_<axis>), and so where the axes are pooled
while each has its own joint band (the bound file's axis_upper_envelopes).
auto_selection (bound.mode auto only): every candidate mode verified the same way; criterion, winner, reason and per
candidate bounded, failed_checks, criterion_mean_conservatism (mean P/MSE over the outage against the upper
envelope), worst outage MSE/P of every check; the rest of this file is the winner's verification."""


def model_of(b: dict):
    """A :class:`~imupipe.models.NoiseModel` from a bound file's ``bound`` block (SI; None stands for an absent
    component)."""
    from imupipe.models import NoiseModel

    return NoiseModel.from_dict({"white": b.get("white") or 0.0, "random_walk": b.get("random_walk") or 0.0,
                                 "gauss_markov": b.get("gauss_markov") or [], "narrowband": b.get("narrowband") or []})


def records_at_one_rate(series: Mapping):
    """(label -> record, rate in Hz) of `series` (label -> (record, rate_hz)), the decimated records the
    verification replays; (empty, None) for none. Raises ValueError naming a record whose rate differs from the
    others' (relative 1e-9)."""
    records, rate = {}, None
    for label, (y, r) in series.items():
        if rate is not None and abs(r - rate) > 1e-9 * rate:
            raise ValueError(f"{label}: decimated rate {r} Hz differs from {rate} Hz of the other records")
        records[label], rate = y, r
    return records, rate


def verify_sensor(bound: dict, sensor: str, *, spec, records: Mapping | None = None,
                  record_rate_hz: float | None = None, truth=None, turn_on_bias: float = 0.0, fix_s: float = 600.0,
                  outage_s: float = 3600.0, sigma_fix: float | None = None, filter_rate_hz: float = 1.0,
                  reduce: bool = True, replay_z: float = 2.0, max_bias_time_s: float | None = None,
                  fix_rate_hz: float | None = None, **earlier):
    """The verification of the bound file's dict `bound` (its ``bound``, ``upper_envelope``, ``spec_name``,
    ``psd_bounded`` and ``per_axis_models``): `spec` the spec sheet's model of `sensor` and its `turn_on_bias`
    (u, 1 sigma), `truth` the simulation's model or None, `records` curve label -> record (u) at
    `record_rate_hz` (Hz; the included curves; block-averaged to the filter rate by the replay), the ``verify``
    settings (`fix_s` s, `outage_s` s = ``application.outage_s``, `sigma_fix` m for accel or rad for gyro,
    `filter_rate_hz` Hz, `reduce`, `replay_z`, `fix_rate_hz` Hz: the fixes' rate, None: the filter's) and
    ``identify.max_bias_time_s`` (s).

    Returns (report, checks): the verification file's dict and the exported model's series by check."""
    import numpy as np

    from imupipe.models import NoiseModel
    from imupipe.verify import verification_stage

    from imupipe.verify import refuse_keywords

    refuse_keywords(earlier, "verify_sensor", rate_hz="record_rate_hz", horizon_s="outage_s")
    records = {k: np.asarray(v, dtype=np.float64) for k, v in (records or {}).items()}
    if bound.get("candidates"):  # bound.mode auto: verify every candidate, export the selected one
        return _verify_auto(bound, sensor, dict(
            spec=spec, records=records, record_rate_hz=record_rate_hz, truth=truth, turn_on_bias=turn_on_bias,
            fix_s=fix_s, outage_s=outage_s, sigma_fix=sigma_fix, filter_rate_hz=filter_rate_hz, reduce=reduce,
            replay_z=replay_z, max_bias_time_s=max_bias_time_s, fix_rate_hz=fix_rate_hz))
    kw = dict(spec=spec, truth=truth, record_rate_hz=record_rate_hz, fix_s=fix_s, outage_s=outage_s,
              sigma_fix=sigma_fix,
              filter_rate_hz=filter_rate_hz, reduce=reduce, replay_z=replay_z, max_bias_time_s=max_bias_time_s,
              turn_on_bias=turn_on_bias, fix_rate_hz=fix_rate_hz)
    upper = NoiseModel.from_dict(bound["upper_envelope"]) if bound.get("upper_envelope") else None
    # the axes differ, or are pooled while each has its own band: the global model must also bound each axis's own
    # envelope (a user may give it to any axis)
    axis_uppers = {ax: NoiseModel.from_dict(pa["upper_envelope"])
                   for ax, pa in (bound.get("per_axis_models") or {}).items() if pa.get("upper_envelope")}
    axis_uppers = axis_uppers or {ax: NoiseModel.from_dict(m)
                                  for ax, m in (bound.get("axis_upper_envelopes") or {}).items()}
    report, checks = verification_stage(model_of(bound["bound"]), sensor, upper=upper,
                                        records=list(records.values()) or None, axis_uppers=axis_uppers or None,
                                        **kw)
    report["spec_name"] = bound["spec_name"]
    report["replayed_curves"] = list(records)
    report["bound_file_psd_bounded"] = bound.get("psd_bounded")
    report["per_axis_models"] = None
    if bound.get("per_axis_models"):
        report["per_axis_models"] = {}
        for ax, pa in bound["per_axis_models"].items():
            mine = [lab for lab in records if lab.rsplit("/", 1)[-1] == ax]
            up_ax = NoiseModel.from_dict(pa["upper_envelope"]) if pa.get("upper_envelope") else None
            rep_ax, _ = verification_stage(model_of(pa["bound"]), sensor, upper=up_ax,
                                           records=[records[lab] for lab in mine] or None, **kw)
            rep_ax["replayed_curves"] = mine
            report["per_axis_models"][ax] = rep_ax
            logging.info("per-axis model %s: verification %s", ax, "pass" if rep_ax["passed"] else "FAIL")
    for name, c in report["exported"]["verification"]["checks"].items():
        logging.info("%s: worst MSE/P %.4g at %.0f s, outage worst %.4g at %s s, mean P/MSE %.3g, %s", name,
                     c["worst_ratio"], c["worst_t_s"], c["worst_outage_ratio"], c.get("worst_outage_t_s"),
                     c["mean_conservatism"], "pass" if c["passed"] else "FAIL")
    return report, checks


def _verify_auto(bound: dict, sensor: str, settings: dict):
    """``bound.mode: auto`` (:mod:`imupipe.bound.auto`): :func:`verify_sensor` of every candidate of the bound
    file, each with the same settings (the configured filter rate), and :func:`imupipe.bound.auto.select`. The
    report is the winner's, with ``auto_selection`` (criterion, winner, reason, each candidate's bounded, failed
    checks, worst outage MSE/P and mean P/MSE per check); the series are the winner's."""
    from imupipe.bound.auto import select
    from imupipe.stages.contract import candidate_contract

    reports, series = {}, {}
    for m, cand in bound["candidates"].items():
        reports[m], series[m] = verify_sensor(cand, sensor, **settings)
    sel = select(bound["candidates"], reports, candidate_contract, bound.get("auto_envelope_candidate"))
    logging.info("auto bound: %s exported: %s", sel["winner"], sel["reason"])
    report = dict(reports[sel["winner"]])
    report["auto_selection"] = sel
    return report, series[sel["winner"]]


def verify_stage(bound: dict, sensor: str, **settings) -> dict:
    """The verification file's content (a YAML-ready dict, SI) of :func:`verify_sensor` with the same arguments."""
    return verify_sensor(bound, sensor, **settings)[0]


def read_records(paths, path_spectra: str, filter_rate_hz: float, segments=None):
    """(label -> record, rate in Hz) of the record files `paths` (:func:`imupipe.io.read_series`) whose
    ``dataset/axis`` is an included curve of the stacked spectra file `path_spectra`, each block-averaged to
    `filter_rate_hz` on reading when faster (one full-rate record in memory at a time); one rate, or a ValueError
    naming the record whose rate differs (:func:`records_at_one_rate`). A record cut into segments
    (events.policy split: the decimated file's attributes, or the segments file of `segments`, aligned with
    `paths`) is replayed as one record per segment (``dataset#k/axis``: :func:`imupipe.segments.segment_records`),
    never across a cut."""
    from imupipe.io import read_series
    from imupipe.merge import Stacked
    from imupipe.segments import Segments, decimate_segments, read_segments, segment_records

    included = {f"{d}/{a}" for d, a in Stacked(path_spectra).curves(included_only=True)}
    series = {}
    for path, seg_path in zip(paths, segments or [None] * len(paths), strict=True):
        y, r, at = read_series(path)
        seg = read_segments(seg_path, y.size, r, path) if seg_path else Segments.from_attrs(at, y.size, r, path)
        if (label := f"{at.get('dataset')}/{at.get('axis')}") in included:
            if r > filter_rate_hz * (1 + 1e-9):
                y, r, seg = decimate_segments(y, r, filter_rate_hz, seg)
            series.update({lab: (v, r) for lab, v in segment_records(y, seg, label).items()})
        del y
    return records_at_one_rate(series)


def verify_job(path_bound: str, path_spectra: str, path_spec: str, path_truth, records: list, path_out: str,
               path_figure: str, spec_name: str, sensor: str, *, fix_s: float, outage_s: float, sigma_fix_m: float,
               sigma_fix_rad: float, filter_rate_hz: float, reduce: bool, replay_z: float,
               max_bias_time_s: float | None = None, fix_rate_hz: float | None = None, segments=None) -> dict:
    """Rule ``verify`` for one spec sheet and sensor: :func:`verify_sensor` on the bound file `path_bound`, the
    spec sheet `path_spec` (its model and turn-on bias of `sensor`), the simulation's truth sheet `path_truth` (or
    None) and the included curves' records (:func:`read_records`); writes the report (YAML with :data:`HEADER`,
    SI) to `path_out` and the figure sqrt(P) against the true / empirical RMS error of the exported model to
    `path_figure` (position error in m for accel, angle error in deg for gyro). Returns the report."""
    import math

    from imupipe.io import read_yaml, write_yaml_atomic
    from imupipe.plot import plot_verification, save_figure
    from imupipe.specsheet import load_spec

    sheet = load_spec(path_spec)
    series, rate = read_records(records, path_spectra, filter_rate_hz, segments=segments or None)
    report, checks = verify_sensor(
        read_yaml(path_bound), sensor, spec=sheet.models[sensor], records=series, record_rate_hz=rate,
        truth=load_spec(path_truth).models[sensor] if path_truth else None,
        turn_on_bias=sheet.turn_on_bias.get(sensor, 0.0), fix_s=fix_s, outage_s=outage_s,
        sigma_fix=sigma_fix_m if sensor == "accel" else sigma_fix_rad, filter_rate_hz=filter_rate_hz,
        reduce=reduce, replay_z=replay_z, max_bias_time_s=max_bias_time_s, fix_rate_hz=fix_rate_hz)
    write_yaml_atomic(report, path_out, header=HEADER)
    unit, scale = ("m", 1.0) if sensor == "accel" else ("deg", math.degrees(1.0))
    what = "reduced model" if report["exported"]["reduced"] else "bound"
    save_figure(plot_verification(checks, unit=unit, scale=scale, fix_s=fix_s,
                                  title=f"{sensor}, {spec_name}: reference filter on the exported {what}",
                                  quantity="position error" if sensor == "accel" else "angle error"), path_figure)
    return report
