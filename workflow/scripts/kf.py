"""Kalman-filter matrices of the exported model, one axis, SI (rule kf): continuous F, G, Qc of paper eq. 17 (or
eq. 19 without the random-walk state), narrowband states of the model's lines, exact discrete Phi, Qd by Van
Loan, and P0. The model is the bound's (all of it: white, GM, random walk, narrowband), or its reduction by
integrity when the verification accepted one; the contract's verdict marks the file. When the axes differ (pooling
test rejected), `per_axis` gives each axis the matrices of its own bounding model when that model passed its own
contract, else those of the global model, with the reason."""

from imupipe.io import read_yaml, run_job, write_yaml_atomic


def main(path_bound: str, path_verify: str, path_contract: str, dt_s: float, horizon_s: float, path_out: str,
         sensor: str) -> None:
    from imupipe.kf import export_kf, export_scope
    from imupipe.models import NoiseModel

    bound, ver, con = read_yaml(path_bound), read_yaml(path_verify), read_yaml(path_contract)
    model = NoiseModel.from_dict(ver["exported"]["model"])

    def p0_random_walk(m):
        # The random walk has no steady state: start it with what it accumulates over the application horizon,
        # K^2 * horizon (u^2); replace by the turn-on bias repeatability squared when the spec sheet gives it.
        return m.random_walk**2 * horizon_s if m.random_walk > 0 else None

    p0_rw = p0_random_walk(model)
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
           "export": export_scope(ver["exported"], red, 1.0 / dt_s, horizon_s),
           "p0_random_walk_rule": "K^2 * application.horizon_s" if p0_rw else None,
           **export_kf(model, dt_s, sensor=sensor, p0_random_walk=p0_rw)}
    out["per_axis"] = None
    if con.get("per_axis_models"):
        out["per_axis"] = {}
        for ax, c in con["per_axis_models"].items():
            own = bool(c["exported_in_kf"])
            m = NoiseModel.from_dict(c["model"]) if own else model
            p0 = p0_random_walk(m)
            rep = (ver.get("per_axis_models") or {}).get(ax) if own else None
            scope = export_scope(rep["exported"], rep.get("reduction"), 1.0 / dt_s, horizon_s) if rep else out["export"]
            out["per_axis"][ax] = {"model": "own" if own else "global", "reason": c["kf"], "curves": c["curves"],
                                   "bounded": bool(c["bounded"]) if own else bool(con["bounded"]), "export": scope,
                                   **export_kf(m, dt_s, sensor=sensor, p0_random_walk=p0)}
    head = f"{sensor}: Kalman-filter model of the bound (SI), one axis"
    if out["per_axis"]:
        head += ("; per_axis: the model of each axis (its own bound where that passed its contract, else the "
                 "global one above)")
    head += f"; {out['export']['statement']}"
    if not con["bounded"]:
        head = f"NOT BOUNDED (see the contract file): {head}"
    write_yaml_atomic(out, path_out, header=head)


if __name__ == "__main__":
    p, i = snakemake.params, snakemake.input
    run_job(main, snakemake.log[0], path_bound=i.bound, path_verify=i.verify, path_contract=i.contract,
            dt_s=p.dt_s, horizon_s=p.horizon_s, path_out=snakemake.output.kf, sensor=snakemake.wildcards.sensor)
