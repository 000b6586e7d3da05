# Block average of one full-rate axis to decimate.rate_hz (the PSD and stationarity stages' input); under
# events.policy split each segment on its own, the decimated file carrying the segments (imupipe.segments).


rule decimate:
    input:
        **FULL_RATE_INPUTS,
    output:
        decimated=f"{RESULTS}/decimated/{{dataset}}/{{sensor}}/{{axis}}.nc",
    params:
        rate_hz=config["decimate"]["rate_hz"],
    group:
        "per_axis"
    threads: 1
    resources:
        mem_mb=axis_mem_mb,
        runtime=full_rate_runtime,
    log:
        f"{LOGS}/decimate/{{dataset}}/{{sensor}}/{{axis}}.log",
    benchmark:
        f"{BENCHMARKS}/decimate/{{dataset}}/{{sensor}}/{{axis}}.tsv"
    conda:
        "../envs/imupipe.yaml"
    script:
        "../scripts/decimate.py"
