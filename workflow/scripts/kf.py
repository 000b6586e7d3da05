"""Kalman-filter matrices of the exported model, one axis, SI (rule kf): imupipe.stages.kf on the bound,
verification and contract files (the verification's exported model, the contract's verdict marking the file;
per axis when the axes differ)."""

from imupipe.io import read_yaml, run_job, write_yaml_atomic


def main(path_bound: str, path_verify: str, path_contract: str, dt_s: float, outage_s: float, path_out: str,
         sensor: str) -> None:
    from imupipe.stages.kf import kf_header, kf_stage

    out = kf_stage(read_yaml(path_bound), read_yaml(path_verify), read_yaml(path_contract), dt_s=dt_s,
                   outage_s=outage_s, sensor=sensor)
    write_yaml_atomic(out, path_out, header=kf_header(out))


if __name__ == "__main__":
    p, i = snakemake.params, snakemake.input
    run_job(main, snakemake.log[0], path_bound=i.bound, path_verify=i.verify, path_contract=i.contract,
            dt_s=p.dt_s, outage_s=p.outage_s, path_out=snakemake.output.kf, sensor=snakemake.wildcards.sensor)
