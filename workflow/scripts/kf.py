"""Kalman-filter matrices of one global bound, one axis, SI (rule kf): continuous F, G, Qc of paper eq. 17 (or
eq. 19 without the random-walk state), exact discrete Phi, Qd by Van Loan, and P0."""

from imupipe.io import read_yaml, run_job, write_yaml_atomic


def main(path_bound: str, dt_s: float, horizon_s: float, path_out: str, sensor: str) -> None:
    from imupipe.kf import export_kf
    from imupipe.models import NoiseModel

    bound = read_yaml(path_bound)
    b = bound["bound"]
    model = NoiseModel(white=b["white"] or 0.0, random_walk=b["random_walk"] or 0.0,
                       gauss_markov=tuple((g["sigma"], g["T"]) for g in b["gauss_markov"]))
    # The random walk has no steady state: start it with what it accumulates over the application horizon,
    # K^2 * horizon (u^2); replace by the turn-on bias repeatability squared when the spec sheet gives it.
    p0_rw = model.random_walk**2 * horizon_s if model.random_walk > 0 else None
    out = {"sensor": sensor, "spec_name": bound["spec_name"], "dt_s": dt_s,
           "p0_random_walk_rule": "K^2 * application.horizon_s" if p0_rw else None,
           **export_kf(model, dt_s, sensor=sensor, p0_random_walk=p0_rw)}
    write_yaml_atomic(out, path_out, header=f"{sensor}: Kalman-filter model of the bound (SI), one axis")


if __name__ == "__main__":
    p = snakemake.params
    run_job(main, snakemake.log[0], path_bound=snakemake.input.bound, dt_s=p.dt_s, horizon_s=p.horizon_s,
            path_out=snakemake.output.kf, sensor=snakemake.wildcards.sensor)
