# Levene + two-sample KS on one decimated axis (paper), or the same statistics calibrated on a null simulated
# from the axis's own Allan-variance fit, the axis's spectral lines notched out of both (a steady line is
# stationary); then, per sensor type, the summary with stationarity.on_fail applied (which curves the stacked
# files mark `included`).


rule stationarity:
    input:
        decimated=f"{RESULTS}/decimated/{{dataset}}/{{sensor}}/{{axis}}.nc",
        allan=f"{RESULTS}/allan/{{dataset}}/{{sensor}}/{{axis}}.nc",
        lines=f"{RESULTS}/lines/{{dataset}}/{{sensor}}/{{axis}}.yaml",
    output:
        verdict=f"{RESULTS}/stationarity/{{dataset}}/{{sensor}}/{{axis}}.yaml",
    params:
        n_segments=config["stationarity"]["n_segments"],
        alpha=config["stationarity"]["alpha"],
        test=config["stationarity"]["test"],
        n_sim=config["stationarity"]["n_sim"],
        n_sim_max=config["stationarity"]["n_sim_max"],
        close_z=config["stationarity"]["close_z"],
    group:
        "per_axis"
    threads: 1
    resources:
        mem_mb=MEM_MB["stationarity"],
        runtime=RUNTIME_MIN["stationarity"],
    log:
        f"{LOGS}/stationarity/{{dataset}}/{{sensor}}/{{axis}}.log",
    benchmark:
        f"{BENCHMARKS}/stationarity/{{dataset}}/{{sensor}}/{{axis}}.tsv"
    conda:
        "../envs/imupipe.yaml"
    script:
        "../scripts/stationarity.py"


rule stationarity_summary:
    input:
        verdicts=per_axis("stationarity", "yaml"),
        decimated=per_axis("decimated", "nc"),  # the paper's test, run here once per sensor type
    output:
        summary=f"{RESULTS}/stationarity/{{sensor}}.yaml",
    params:
        # the dataset list as a parameter: a changed sheet re-runs the merges even where Snakemake's record of
        # the input set is incomplete (final_outputs also asks for every per-axis verdict, see common.smk)
        datasets=sorted(DATASETS),
        on_fail=config["stationarity"]["on_fail"],
    threads: 1
    resources:
        mem_mb=MEM_MB["stationarity_summary"],
        runtime=RUNTIME_MIN["stationarity_summary"],
    log:
        f"{LOGS}/stationarity/{{sensor}}.log",
    benchmark:
        f"{BENCHMARKS}/stationarity_summary/{{sensor}}.tsv"
    conda:
        "../envs/imupipe.yaml"
    script:
        "../scripts/stationarity_summary.py"
