# Pooled Allan-variance fit per sensor type, model selection for the application band.


rule identify:
    input:
        allan=f"{RESULTS}/allan/{{sensor}}.nc",
        truth=truth_file(),
    output:
        identified=f"{RESULTS}/identify/{{sensor}}.yaml",
    params:
        components=config["identify"]["components"],
        n_gm=config["identify"]["n_gm"],
        n_boot=config["identify"]["n_boot"],
        confidence=config["identify"]["confidence"],
        significance=config["identify"]["significance"],
        relevance=config["identify"]["relevance"],
        rate_hz=config["application"]["rate_hz"],
        horizon_s=config["application"]["horizon_s"],
    threads: 1
    resources:
        mem_mb=MEM_MB["identify"],
        runtime=RUNTIME_MIN["identify"],
    log:
        f"{LOGS}/identify/{{sensor}}.log",
    benchmark:
        f"{BENCHMARKS}/identify/{{sensor}}.tsv"
    conda:
        "../envs/imupipe.yaml"
    script:
        "../scripts/identify.py"
