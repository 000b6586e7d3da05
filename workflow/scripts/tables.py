"""Spec vs bound parameters in the spec sheet's units (paper Table 2), markdown, CSV and HTML (rule tables):
imupipe.stages.tables.tables_stage."""

from imupipe.io import read_yaml, run_job, write_text_atomic


def main(paths: list, sensors: list, path_spec: str, path_md: str, path_csv: str, path_html: str,
         contracts: list) -> None:
    from imupipe.specsheet import load_spec
    from imupipe.stages.tables import tables_stage

    out = tables_stage(load_spec(path_spec), {s: read_yaml(p) for s, p in zip(sensors, paths, strict=True)},
                       {s: read_yaml(p) for s, p in zip(sensors, contracts)})
    for key, path in (("markdown", path_md), ("html", path_html), ("csv", path_csv)):
        write_text_atomic(out[key], path)


if __name__ == "__main__":
    run_job(main, snakemake.log[0], paths=[snakemake.input[s] for s in snakemake.params.sensors],
            sensors=list(snakemake.params.sensors),
            path_spec=snakemake.input.spec, path_md=snakemake.output.markdown, path_csv=snakemake.output.csv,
            path_html=snakemake.output.html,
            contracts=[snakemake.input[f"contract_{s}"] for s in snakemake.params.sensors
                       if f"contract_{s}" in snakemake.input.keys()])
