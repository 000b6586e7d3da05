# Levene + two-sample KS on the decimated record (paper), calibrated on a simulated null from the axis's
# own Allan-variance fit; then a per-sensor summary that applies stationarity.on_fail.


rule stationarity:
    input:
        decimated="results/decimated/{dataset}/{sensor}/{axis}.nc",
        allan="results/allan/{dataset}/{sensor}/{axis}.nc",
    output:
        verdict="results/stationarity/{dataset}/{sensor}/{axis}.yaml",
    params:
        n_segments=config["stationarity"]["n_segments"],
        alpha=config["stationarity"]["alpha"],
        test=config["stationarity"]["test"],
        n_sim=config["stationarity"]["n_sim"],
    log:
        "logs/stationarity/{dataset}/{sensor}/{axis}.log",
    benchmark:
        "results/benchmarks/stationarity/{dataset}/{sensor}/{axis}.tsv"
    script:
        "../scripts/stationarity.py"


rule merge_stationarity:
    input:
        verdicts=axis_files("results/stationarity/{dataset}/{sensor}/{axis}.yaml"),
    output:
        summary="results/stationarity/{sensor}.yaml",
    params:
        on_fail=config["stationarity"]["on_fail"],
    log:
        "logs/merge_stationarity/{sensor}.log",
    script:
        "../scripts/merge_stationarity.py"
