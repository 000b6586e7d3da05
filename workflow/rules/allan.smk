# Overlapping Allan variance of one full-rate axis of one dataset (imports numpy, netCDF4 and the C kernel
# only: at most one axis's samples in memory, integrated in place).


rule allan:
    input:
        **FULL_RATE_INPUTS,  # the series and, under events.policy split, its segments
    output:
        allan=f"{RESULTS}/allan/{{dataset}}/{{sensor}}/{{axis}}.nc",
    params:
        taus=config["allan"]["taus"],
        confidence=config["allan"]["confidence"],
    group:
        "per_axis"
    threads: 1
    resources:
        mem_mb=axis_mem_mb,
        runtime=full_rate_runtime,
    log:
        f"{LOGS}/allan/{{dataset}}/{{sensor}}/{{axis}}.log",
    benchmark:
        f"{BENCHMARKS}/allan/{{dataset}}/{{sensor}}/{{axis}}.tsv"
    conda:
        "../envs/imupipe.yaml"
    script:
        "../scripts/allan.py"
