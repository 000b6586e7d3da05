"""The integrity contract of one spec sheet and sensor type (rule ``contract``; :func:`imupipe.api.noise_model`)
and the run's verdict over every contract (rule ``integrity``).

contract: ``bounded`` is true only when every check passed AND the verification ran: PSD margin over the sample
bins, the spec sheet over all frequencies, the Allan-domain check of the kept components, the reference-filter
verification of the exported model (:func:`imupipe.verify.integrity_contract`). A failing model is still written,
marked. Per-axis models (bound and verification, when the axes differ): each gets the same contract; the KF file
gives an axis its own model only when that contract is bounded, else the global model (the reason is in both
files). They never change ``bounded``, which is the global model's: the global model covers every axis.
integrity (:func:`verdict_stage`): with ``verify.on_failure = fail`` a contract that is not bounded is an error
naming the failed checks; with ``warn``, a warning.

Plain values in (the bound and verification files' dicts, the spec sheet), the contract file's dict out
(:func:`contract_stage`). SI units, the exported model also in the spec sheet's.
"""

from __future__ import annotations

import logging
import sys
from types import SimpleNamespace

__all__ = ["HEADER", "candidate_contract", "contract_stage", "failed_names", "inband", "per_axis_contracts", "verdict_stage"]

#: Header of the contract file (what its fields mean, units).
HEADER = """integrity contract (docs/method.md, "Integrity: what bounded means").
bounded: true only when every check below passed and the verification ran; verified: the exported model passed the
reference-filter verification; failed_checks: each failed check with its numbers and where (frequencies Hz, tau s,
times s). model: the exported model (SI; u = rad/s gyro, m/s^2 accel: white u/sqrt(Hz), sigma u, T s, random_walk
u/sqrt(s)), model_spec_units: the same in the spec sheet's units; inflation: bound/spec per parameter of the BOUND's
model, before the verified reduction (not of model when the reduction dropped a state); confidence: the one
statistical statement bounded rests on, the identified upper envelope's level (level; per_axis_level: each axis's
own model's; statement); inflation_scope: the
components the exported model dropped and one statement of this (imupipe.kf.inflation_scope). export: the
states the verified reduction dropped (dropped_by_reduction; the model then holds for horizon_s s of outage only), the
reference filter's rate against the KF export's (verified_filter_rate_hz, kf_rate_hz Hz, rate_mismatch), its
narrowband line states (line_states) and one statement of all this.
per_axis_models: null when the axes are pooled; else per axis its own contract (bounded, verified, failed_checks) and
exported_in_kf: whether the KF file gives that axis its own model (only when bounded; else the global one).
inband_inflation: the effective in-band inflation of the exported model against the spec sheet over the application
band [1/horizon_s, filter_rate_hz/2] Hz (imupipe.inband.inband_inflation): sqrt(S_model/S_spec) (vs_spec_psd) and
sqrt(S_model)/N_spec (vs_spec_white), median, max, max_frequency_hz, min (dimensionless amplitude ratios), two-sided
PSDs as sampled at the reference filter's interval, and each component with what it acts as in band (components:
acts_as; corner_hz Hz, as_N u/sqrt(Hz), as_K u/sqrt(s)); per_axis_models carry the same of each axis's model.
auto_selection (bound.mode auto only): the exported candidate (winner), why, the criterion and each candidate's
bounded, failed checks, mean P/MSE against the envelope and worst outage MSE/P; the rest of this file is the
winner's contract (mode: auto (winner))."""


def _bound_view(b: dict):
    """The bound file's margins as the attributes imupipe.verify.integrity_contract reads (None: not finite)."""
    def num(v, default=float("nan")):
        return default if v is None else float(v)

    return SimpleNamespace(margin=num(b.get("margin")), margin_curve=b.get("margin_curve"),
                           margin_frequency=num(b.get("margin_frequency_hz")),
                           spec_margin=num(b.get("spec_margin"), float("inf")),
                           spec_margin_frequency=b.get("spec_margin_frequency_hz"),
                           allf_margin=num(b.get("all_frequency_margin"), float("inf")),
                           allf_margin_frequency=b.get("all_frequency_margin_frequency_hz"),
                           data_check=b.get("data_check"))


def candidate_contract(bound: dict, report: dict) -> dict:
    """The contract checks of one candidate of ``bound.mode: auto`` (:mod:`imupipe.bound.auto`):
    :func:`imupipe.verify.integrity_contract` on its bound file entry `bound` and its verification report `report`
    (PSD margin, spec over all frequencies, Allan check, the identification's intervals, every verification check
    of its exported model). The export-rate check is the contract's own, the same for every candidate."""
    from imupipe.verify import integrity_contract

    ver = report["exported"]["verification"]
    return integrity_contract(_bound_view(bound), bound.get("allan_check"),
                              {"reference filter": ver} if ver.get("checks") else None,
                              intervals=bound.get("identification_intervals"))


def _checks(bound: dict, exported: dict | None, reduction: dict | None, spec, sensor: str,
            kf_rate_hz: float | None):
    """The steps of every contract, the global model's and each per-axis model's: (the checks of
    imupipe.verify.integrity_contract on the bound entry `bound` and the verification of `exported`, the exported
    model in the spec sheet's units (imupipe.specsheet.model_in_units), its unit note, the export's scope
    (imupipe.kf.export_scope)). Without an exported model (an axis that was not verified) the last three are None."""
    from imupipe.kf import export_scope
    from imupipe.models import NoiseModel
    from imupipe.specsheet import display_units, model_in_units
    from imupipe.verify import integrity_contract

    verification = ({f"{sensor} reference filter": exported["verification"]}
                    if exported and exported["verification"].get("checks") else None)
    scope = None if (kf_rate_hz is None or not exported) else export_scope(exported, reduction, float(kf_rate_hz))
    c = integrity_contract(_bound_view(bound), bound.get("allan_check"), verification, export=scope,
                           intervals=bound.get("identification_intervals"))
    if not exported:
        return c, None, None, None
    in_units, note = model_in_units(NoiseModel.from_dict(exported["model"]), display_units(spec, sensor), sensor)
    return c, in_units, note, scope


def inband(exported: dict | None, spec, sensor: str, band_hz) -> dict | None:
    """The exported model's effective in-band inflation against the spec sheet (imupipe.inband.inband_inflation), or
    None without an exported model, a band, or a spec model of this sensor with a positive PSD."""
    from imupipe.inband import inband_inflation
    from imupipe.models import NoiseModel

    specm = spec.models.get(sensor)
    if not exported or band_hz is None or specm is None:
        return None
    try:
        return inband_inflation(NoiseModel.from_dict(exported["model"]), specm, band_hz)
    except ValueError as exc:
        logging.warning("%s: no in-band inflation: %s", sensor, exc)
        return None


def contract_stage(bound: dict, verification: dict, spec, *, sensor: str, kf_file: str | None = None,
                   on_failure: str = "fail", kf_rate_hz: float | None = None, outage_s: float | None = None,
                   filter_rate_hz: float | None = None) -> dict:
    """The contract file's content (YAML-ready) of the bound file's dict `bound` and the verification file's dict
    `verification`, against the spec sheet `spec` (:class:`imupipe.specsheet.SpecSheet`) of `sensor`; `kf_file`
    names the KF file it marks, `on_failure` is ``verify.on_failure`` (stated, not acted on here) and
    `kf_rate_hz` (Hz) the KF export's rate (application.filter_rate_hz), checked against the verification's;
    `outage_s` (s, application.outage_s) and `filter_rate_hz` (Hz, the verification's, application.filter_rate_hz in
    the workflow) set the application
    band [1/outage_s, filter_rate_hz/2] of the in-band inflation (:mod:`imupipe.inband`; None: not computed)."""
    from imupipe.inband import application_band
    from imupipe.kf import inflation_scope
    from imupipe.verdict import confidence_statement

    ver = verification
    sel = ver.get("auto_selection")
    if sel and bound.get("candidates"):  # bound.mode auto: the contract is the selected candidate's
        bound = dict(bound["candidates"][sel["winner"]], mode=f"auto ({sel['winner']})")
    exported = ver["exported"]
    band = application_band(outage_s, filter_rate_hz) if outage_s and filter_rate_hz else None
    c, in_spec_units, note, scope = _checks(bound, exported, ver.get("reduction"), spec, sensor, kf_rate_hz)
    out = {
        "sensor": sensor, "spec_name": bound["spec_name"],
        "bounded": c["bounded"], "verified": c["verified"], "failed_checks": c["failed_checks"],
        "checks_run": c["checks_run"], "note": c["note"],
        "on_failure": on_failure,
        "model": exported["model"], "model_spec_units": in_spec_units,
        "model_reduced": bool(exported["reduced"]), "model_reason": exported["reason"],
        "inflation": bound.get("inflation"),
        # the one statistical statement behind bounded: the identified upper envelope's level (imupipe.verdict)
        "confidence": confidence_statement(bound),
        "inflation_scope": inflation_scope(exported, ver.get("reduction")),
        "kf_file": kf_file,
        # what the exported filter model is: states the verified reduction dropped, the horizon it then holds for,
        # the reference filter's rate against the export's (imupipe.kf.export_scope)
        "export": scope,
        # the least initial bias variance the exported P0 carries and what it rests on (imupipe.biasinit)
        "bias_initialisation": exported.get("bias_initialisation"),
        # the bound's numbers the run summary reads beside the verdict
        "psd_bounded": bound.get("psd_bounded"), "margin": bound.get("margin"),
        "margin_curve": bound.get("margin_curve"), "margin_frequency_hz": bound.get("margin_frequency_hz"),
        "spec_margin": bound.get("spec_margin"), "all_frequency_margin": bound.get("all_frequency_margin"),
        "all_frequency_margin_frequency_hz": bound.get("all_frequency_margin_frequency_hz"),
        "allan_check_passed": bound.get("allan_check_passed"),
        "allan_tau_band_s": ((bound.get("allan_check") or {}).get("total") or {}).get("tau_band_s"),
        "per_axis": bound.get("per_axis"),
        # what the bound covers of records whose noise level changes: each such curve's noisiest stretch (its label,
        # the curve and the largest gain), or null: the records' average PSD (docs/method.md, "Stationarity")
        "noisiest_stretch": bound.get("noisiest_stretch"),
        **{k: bound.get(k) for k in ("mode", "n_curves", "bound", "spec", "bound_spec_units", "spec_spec_units")},
        "verification": verification_checks(exported),
        "reduction": None if ver.get("reduction") is None else
        {k: ver["reduction"][k] for k in ("accepted", "refused", "tried")},
    }
    if note:
        out["unit_note"] = note
    if sel:
        out["auto_selection"] = {"winner": sel["winner"], "reason": sel["reason"], "criterion": sel["criterion"],
                                 "candidates": [{k: r[k] for k in ("mode", "bounded", "failed_checks",
                                                                   "criterion_mean_conservatism",
                                                                   "worst_outage_ratio_exact",
                                                                   "worst_outage_ratio_sampled",
                                                                   "sampled_tolerance")}
                                                for r in sel["candidates"]]}
    # what the whole exported model does in the application band against the spec sheet (imupipe.inband)
    out["inband_inflation"] = inband(exported, spec, sensor, band)
    out["per_axis_models"] = per_axis_contracts(bound, ver, spec, sensor, kf_rate_hz, band)
    if not c["bounded"]:
        logging.warning("%s: NOT BOUNDED; failed checks: %s", sensor, failed_names(out))
    return out


#: The keys of each verification check the contract repeats (imupipe.verify.Verification.to_dict): the numbers and,
#: for a check that passed only by its sampling tolerance, the sentence saying so (imupipe.verdict.within_tolerance).
VERIFICATION_KEYS = ("worst_outage_ratio", "worst_outage_t_s", "worst_t_s", "worst_ratio", "first_exceed_s",
                     "mean_conservatism", "tolerance", "passed", "n_eff", "within_tolerance")


def verification_checks(exported: dict | None) -> dict:
    """Check name -> the :data:`VERIFICATION_KEYS` of the exported model's verification ({} without one)."""
    checks = ((exported or {}).get("verification") or {}).get("checks") or {}
    return {name: {k: ch.get(k) for k in VERIFICATION_KEYS if k in ch or k not in ("n_eff", "within_tolerance")}
            for name, ch in checks.items()}


def per_axis_contracts(bound: dict, ver: dict, spec, sensor: str, kf_rate_hz: float | None = None, band_hz=None):
    """The contract of each per-axis model (None when the bound file has none): its checks as the global model's,
    and whether the KF file exports it (bounded) or gives that axis the global model."""
    from imupipe.kf import inflation_scope

    axes = bound.get("per_axis_models")
    if not axes:
        return None
    vers = ver.get("per_axis_models") or {}
    out = {}
    for ax, pa in axes.items():
        v = vers.get(ax)
        exported = v["exported"] if v else None
        c, in_spec_units, _, scope = _checks(pa, exported, v.get("reduction") if v else None, spec, sensor,
                                             kf_rate_hz)
        entry = {"curves": pa.get("curves"), "bounded": c["bounded"], "verified": c["verified"],
                 "failed_checks": c["failed_checks"], "exported_in_kf": bool(c["bounded"]),
                 "model": exported["model"] if exported else None,
                 "model_spec_units": in_spec_units,
                 "model_reduced": bool(exported["reduced"]) if exported else None,
                 "inflation": pa.get("inflation"),
                 "inflation_scope": inflation_scope(exported, v.get("reduction")) if exported else None,
                 "margin": pa.get("margin"),
                 "all_frequency_margin": pa.get("all_frequency_margin"),
                 "allan_check_passed": pa.get("allan_check_passed"),
                 "inband_inflation": inband(exported, spec, sensor, band_hz),
                 "verification": verification_checks(exported),
                 "export": scope}
        entry["kf"] = (f"axis {ax}: its own model" if c["bounded"] else
                       f"axis {ax}: the global model (its own failed: {failed_names(entry)})")
        out[ax] = entry
    return out


def failed_names(doc: dict) -> str:
    """One line naming each failed check and its number."""
    parts = []
    for f in doc.get("failed_checks") or ():
        num = next((f[k] for k in ("worst_ratio", "margin", "ratio") if k in f), None)
        where = f.get("against") or f.get("component") or f.get("curve") or ""
        parts.append(f"{f['check']}{' ' + str(where) if where else ''}"
                     f"{'' if num is None else f' ({num:.4g})'}")
    if not doc.get("verified") and not any(f["check"] in ("verification", "export_rate")
                                           for f in doc.get("failed_checks") or ()):
        parts.append("verification did not run")
    return "; ".join(parts) or "none"


def verdict_stage(docs: list, contracts: list, on_failure: str) -> dict:
    """The run's verdict over the contract files' dicts `docs` (their paths `contracts`): the verdict file's dict;
    with `on_failure` ``fail`` a contract that is not bounded raises ValueError naming its failed checks, with
    ``warn`` it is logged and printed on stderr."""
    failing = [d for d in docs if not d["bounded"]]
    rows = [{"spec_name": d["spec_name"], "sensor": d["sensor"], "bounded": d["bounded"], "verified": d["verified"],
             "failed_checks": failed_names(d) if not d["bounded"] else "none", "contract": p}
            for d, p in zip(docs, contracts)]
    msg = "; ".join(f"{d['sensor']} against {d['spec_name']}: {failed_names(d)}" for d in failing)
    if failing and on_failure == "fail":
        text = (f"imupipe integrity: NOT BOUNDED ({msg}). The models are written, marked bounded: false, in the "
                f"contract files; verify.on_failure: warn downgrades this to a warning.")
        raise ValueError(text)  # run_job prints it on the terminal and exits non-zero
    if failing:
        logging.warning("NOT BOUNDED (verify.on_failure: warn): %s", msg)
        print(f"imupipe integrity warning: NOT BOUNDED ({msg})", file=sys.__stderr__)
    return {"all_bounded": not failing, "on_failure": on_failure, "contracts": rows}
