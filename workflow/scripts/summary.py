"""The run summary (rule summary): results/{name}/summary.md, summary.html and the report's first page
(imupipe.stages.summary.summary_stage on the files the stage files list in SUMMARY_INPUTS, kind -> paths)."""

from imupipe.io import run_job


def main(**kwargs) -> None:
    from imupipe.stages.summary import summary_stage

    summary_stage(**kwargs)


if __name__ == "__main__":
    i = snakemake.input
    files = {kind: [i[kind]] if isinstance(i[kind], str) else list(i[kind])
             for kind in snakemake.params.kinds if kind in i.keys()}
    run_job(main, snakemake.log[0], files=files, sensors=list(snakemake.params.sensors),
            specs=list(snakemake.params.specs), name=snakemake.params.name, path_md=snakemake.output.markdown,
            path_html=snakemake.output.html, template=i.template, path_front=snakemake.output.front)
