"""Read one recording (any supported format), convert to SI, validate, write one file per channel (rule ingest):
imupipe.stages.ingest.ingest_stage."""

from imupipe.io import run_job

if __name__ == "__main__":
    from imupipe.stages.ingest import ingest_stage

    run_job(ingest_stage, snakemake.log[0], row=dict(snakemake.params.row), keys=list(snakemake.params.channels),
            outputs=dict(snakemake.output.items()), dataset=snakemake.wildcards.dataset)
