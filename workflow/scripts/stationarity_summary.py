"""Per sensor type (rule stationarity_summary): every axis's verdict with stationarity.on_fail applied and the
paper's test beside it (imupipe.stages.stationarity.paper_tests, summary_stage)."""

from imupipe.io import read_yaml, run_job, write_yaml_atomic


def main(verdicts: list, decimated: list, on_fail: str, path_out: str, sensor: str) -> None:
    from imupipe.stages.stationarity import paper_tests, summary_stage

    loaded = [read_yaml(p) for p in verdicts]
    write_yaml_atomic(summary_stage(loaded, on_fail, sensor, paper_tests(loaded, decimated)), path_out,
                      header="stationarity of every axis of one sensor type; p-values are probabilities")


if __name__ == "__main__":
    run_job(main, snakemake.log[0], verdicts=list(snakemake.input.verdicts),
            decimated=list(snakemake.input.decimated), on_fail=snakemake.params.on_fail,
            path_out=snakemake.output.summary, sensor=snakemake.wildcards.sensor)
