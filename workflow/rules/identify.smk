# Pooled Allan-variance fit per sensor type, model selection for the application band.


rule identify:
    input:
        allan="results/allan/{sensor}.nc",
    output:
        identified="results/identify/{sensor}.yaml",
    params:
        components=config["identify"]["components"],
        n_gm=config["identify"]["n_gm"],
        n_boot=config["identify"]["n_boot"],
        confidence=config["identify"]["confidence"],
        significance=config["identify"]["significance"],
        relevance=config["identify"]["relevance"],
        rate_hz=config["application"]["rate_hz"],
        horizon_s=config["application"]["horizon_s"],
        truth=str(repo_path(config["simulation"]["truth"])) if config.get("simulation") else None,
    log:
        "logs/identify/{sensor}.log",
    benchmark:
        "results/benchmarks/identify/{sensor}.tsv"
    script:
        "../scripts/identify.py"
