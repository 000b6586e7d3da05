# Two-sided Welch PSD of one decimated axis with its chi-squared limits.


rule psd:
    input:
        decimated=f"{RESULTS}/decimated/{{dataset}}/{{sensor}}/{{axis}}.nc",
    output:
        psd=f"{RESULTS}/psd/{{dataset}}/{{sensor}}/{{axis}}.nc",
    params:
        window_s=config["psd"]["window_s"],
        step_s=config["psd"]["step_s"],
        taper=config["psd"]["taper"],
        detrend=config["psd"]["detrend"],
        confidence=config["psd"]["confidence"],
    group:
        "per_axis"
    threads: 1
    resources:
        mem_mb=MEM_MB["psd"],
        runtime=RUNTIME_MIN["psd"],
    log:
        f"{LOGS}/psd/{{dataset}}/{{sensor}}/{{axis}}.log",
    benchmark:
        f"{BENCHMARKS}/psd/{{dataset}}/{{sensor}}/{{axis}}.tsv"
    conda:
        "../envs/imupipe.yaml"
    script:
        "../scripts/psd.py"
