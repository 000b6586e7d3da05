r"""The Kalman-filter export of one sensor type (rule ``kf``; :func:`imupipe.api.noise_model`).

Continuous F, G, Qc of paper eq. 17 (or eq. 19 without the random-walk state), narrowband states of the model's
lines, exact discrete Phi, Qd by Van Loan, and P0 (:func:`imupipe.kf.export_kf`) of the model the verification
exported (the bound's, all of it, or its reduction by integrity when the verification accepted one), the bias
state started where the verification started the filter (its ``bias_initialisation``: the P0 of p is
:func:`imupipe.biasinit.filter_p0` of the verified least initial bias variance). :func:`exported_kf` is that
export of one verification's ``exported`` block (the API's); :func:`kf_stage` the KF file with the contract's
verdict and, when the axes differ, each axis's matrices (its own bounding model when that passed its own
contract, else the global model, with the reason). SI units.
"""

from __future__ import annotations

__all__ = ["BIAS_RULE", "bias_block", "exported_kf", "kf_header", "kf_stage", "kinematic_p0"]

BIAS_RULE = ("the bias states start with a total variance (GM states' sigma^2 + P0 of p) at least required_variance: "
             "the largest of the spec sheet's stationary bias (GM sigma^2, a random walk as the GM of T_max with its "
             "drift, the turn-on bias^2) and the records' slow drift extrapolated to T_max (sigma^2 = K_eff^2 T_max / "
             "2), and its part from biases slower than the verified run (required_slow_variance) on states at least as slow "
             "(p, GMs with T >= wander_s); p0 = max(K^2 * wander_s, required_variance - sum GM sigma^2, "
             "required_slow_variance - sum of GM sigma^2 with T >= wander_s). A filter using this model must "
             "initialise its bias at least so (docs/method.md, section 'The bias a filter starts with').")


def bias_block(bias: dict, p0) -> dict:
    """The KF file's statement of the initial bias variance (SI) and the rule it follows."""
    keep = ("required_variance", "required_std", "rests_on", "parts", "T_max_s", "T_max_source", "record_s",
            "checked_by_records", "required_slow_variance", "wander_s", "statement", "units")
    return {"p0_random_walk": p0, "rule": BIAS_RULE, **{k: bias[k] for k in keep if k in bias}}


def _bias_p0(exported: dict):
    """The verified initial variance of p (imupipe.biasinit.filter_p0: the bias floor less the GM states'
    sigma^2, its slow part less the slow GM states', at least K^2 * wander_s), u^2, or None when it is 0 (no p state), and the bias block it comes from:
    the KF file starts the filter where the verification did. p stays a state (a random constant when K = 0)
    whenever that variance is positive."""
    bi = exported.get("bias_initialisation") or {}
    p0 = float(bi.get("p0_random_walk") or 0.0)
    return (p0 if p0 > 0 else None), bi


def kinematic_p0(exported: dict) -> dict:
    """The initial variances of the kinematic states the verification started its reference filter at (the
    ``exported`` block's ``verification.scenario``: ``var_pos``, ``var_vel``; a verify file without them: the defaults
    of its scenario, :func:`imupipe.verify.kinematic_start`), as :func:`imupipe.kf.export_kf`'s ``var_x``, ``var_v``,
    ``var_theta`` (m^2, (m/s)^2, rad^2): the KF file's P0 is then the one verified. Zero without a scenario."""
    from imupipe.verify import kinematic_start, reference_scenario

    scen = (exported.get("verification") or {}).get("scenario") or {}
    if "var_pos" not in scen:
        if scen.get("sigma_fix") is None:
            return {}
        sc = reference_scenario(scen.get("sensor", "accel"), sigma_fix=float(scen["sigma_fix"]))
        scen = {**kinematic_start(sc), **scen}  # the scenario's own defaults (one home: imupipe.verify)
    return {"var_x": float(scen["var_pos"]), "var_theta": float(scen["var_pos"]),
            "var_v": float(scen.get("var_vel", 0.0))}


def exported_kf(exported: dict, dt_s: float, sensor: str) -> dict:
    """:func:`imupipe.kf.export_kf` at step `dt_s` (s) of a verification's ``exported`` block (its ``model``,
    SI, ``bias_initialisation`` and scenario), with the ``bias_initialisation`` statement of the KF file; the
    kinematic states start where the verification started them (:func:`kinematic_p0`)."""
    from imupipe.kf import export_kf
    from imupipe.models import NoiseModel

    p0, bias = _bias_p0(exported)
    return {"bias_initialisation": bias_block(bias, p0),
            **export_kf(NoiseModel.from_dict(exported["model"]), dt_s, sensor=sensor, p0_random_walk=p0,
                        reduced=p0 is None, **kinematic_p0(exported))}


def kf_stage(bound: dict, verification: dict, contract: dict, *, dt_s: float, outage_s: float,
             sensor: str) -> dict:
    """The KF file's content (YAML-ready, SI) from the bound, verification and contract files' dicts, at the
    filter step `dt_s` (s, 1/application.filter_rate_hz) for the outage `outage_s` (s, application.outage_s)."""
    from imupipe.kf import export_kf, export_scope
    from imupipe.models import NoiseModel

    ver, con = verification, contract
    model = NoiseModel.from_dict(ver["exported"]["model"])
    p0_rw, bias = _bias_p0(ver["exported"])
    red = ver.get("reduction")
    out = {"sensor": sensor, "spec_name": bound["spec_name"], "dt_s": dt_s,
           "bounded": bool(con["bounded"]), "verified": bool(con["verified"]),
           "failed_checks": [f["check"] for f in con["failed_checks"]],
           "warning": None if con["bounded"] else
           "NOT BOUNDED: this model failed the integrity checks of the contract file; for diagnosis only",
           "reduction": {"exported_reduced": bool(ver["exported"]["reduced"]), "reason": ver["exported"]["reason"],
                         "tried": red["tried"] if red else [], "accepted": red["accepted"] if red else [],
                         "refused": red["refused"] if red else []},
           # which states the verified reduction dropped, the horizon the export then holds for, and the
           # verification's filter rate against this file's (imupipe.kf.export_scope)
           "export": export_scope(ver["exported"], red, 1.0 / dt_s, outage_s),
           **exported_kf(ver["exported"], dt_s, sensor)}
    out["per_axis"] = None
    if con.get("per_axis_models"):
        out["per_axis"] = {}
        for ax, c in con["per_axis_models"].items():
            own = bool(c["exported_in_kf"])
            m = NoiseModel.from_dict(c["model"]) if own else model
            rep = (ver.get("per_axis_models") or {}).get(ax) if own else None
            p0, bias_ax = _bias_p0(rep["exported"]) if rep else (p0_rw, bias)
            scope = export_scope(rep["exported"], rep.get("reduction"), 1.0 / dt_s, outage_s) if rep else out["export"]
            out["per_axis"][ax] = {"model": "own" if own else "global", "reason": c["kf"], "curves": c["curves"],
                                   "bounded": bool(c["bounded"]) if own else bool(con["bounded"]), "export": scope,
                                   "bias_initialisation": bias_block(bias_ax, p0),
                                   **export_kf(m, dt_s, sensor=sensor, p0_random_walk=p0, reduced=p0 is None,
                                               **kinematic_p0(rep["exported"] if rep else ver["exported"]))}
    return out


def kf_header(out: dict) -> str:
    """The KF file's header line of :func:`kf_stage`'s dict: what it holds, its scope, and NOT BOUNDED first
    when the contract failed."""
    head = f"{out['sensor']}: Kalman-filter model of the bound (SI), one axis"
    if out["per_axis"]:
        head += ("; per_axis: the model of each axis (its own bound where that passed its contract, else the "
                 "global one above)")
    head += f"; {out['export']['statement']}"
    if not out["bounded"]:
        head = f"NOT BOUNDED (see the contract file): {head}"
    return head
