"""The integrity contract of one spec sheet and sensor type (rule contract) and the run's verdict over every
contract (rule integrity): imupipe.stages.contract on the bound and verification files and the spec sheet; the
verdict job (the last of the run) fails with verify.on_failure = fail when a contract is not bounded."""

from imupipe.io import read_yaml, run_job, write_yaml_atomic


def contract(path_bound: str, path_verify: str, path_spec: str, kf_file: str, on_failure: str, path_out: str,
             sensor: str, kf_rate_hz: float | None = None, outage_s: float | None = None,
             filter_rate_hz: float | None = None) -> None:
    from imupipe.specsheet import load_spec
    from imupipe.stages.contract import HEADER, contract_stage

    out = contract_stage(read_yaml(path_bound), read_yaml(path_verify), load_spec(path_spec), sensor=sensor,
                         kf_file=kf_file, on_failure=on_failure, kf_rate_hz=kf_rate_hz, outage_s=outage_s,
                         filter_rate_hz=filter_rate_hz)
    write_yaml_atomic(out, path_out, header=HEADER)


def verdict(contracts: list, on_failure: str, path_out: str) -> None:
    from imupipe.stages.contract import verdict_stage

    out = verdict_stage([read_yaml(p) for p in contracts], contracts, on_failure)  # raises when it fails the run
    write_yaml_atomic(out, path_out,
                      header="the run's integrity verdict: every contract's bounded flag (contract/{spec}/{sensor}.yaml)")


if __name__ == "__main__":
    p, i, o = snakemake.params, snakemake.input, snakemake.output
    if snakemake.rule == "integrity":
        run_job(verdict, snakemake.log[0], contracts=list(i.contracts), on_failure=p.on_failure, path_out=o.verdict)
    else:
        run_job(contract, snakemake.log[0], path_bound=i.bound, path_verify=i.verify, path_spec=i.spec,
                kf_file=p.kf_file, kf_rate_hz=getattr(p, "kf_rate_hz", None), on_failure=p.on_failure,
                outage_s=getattr(p, "outage_s", None), filter_rate_hz=getattr(p, "filter_rate_hz", None),
                path_out=o.contract, sensor=snakemake.wildcards.sensor)
