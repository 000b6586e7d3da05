# Per sensor type, one job: Levene + two-sample KS on every decimated axis (paper), calibrated on a null
# simulated from the axis's own Allan-variance fit; stationarity.on_fail applied; then every axis's PSD and
# Allan variance gathered into one file per sensor type with an `included` flag.


rule collect:
    input:
        decimated=axis_files("results/decimated/{dataset}/{sensor}/{axis}.nc"),
        allan=axis_files("results/allan/{dataset}/{sensor}/{axis}.nc"),
        psd=axis_files("results/psd/{dataset}/{sensor}/{axis}.nc"),
    output:
        verdicts=axis_files_out("results/stationarity/{dataset}/{{sensor}}/{axis}.yaml"),
        summary="results/stationarity/{sensor}.yaml",
        spectra="results/spectra/{sensor}.nc",
        allan="results/allan/{sensor}.nc",
    params:
        # the dataset list as a parameter: a changed sheet re-runs the merges even where Snakemake's record of
        # the input set is incomplete (final_outputs also asks for every per-axis verdict, see common.smk)
        datasets=sorted(DATASETS),
        n_segments=config["stationarity"]["n_segments"],
        alpha=config["stationarity"]["alpha"],
        test=config["stationarity"]["test"],
        n_sim=config["stationarity"]["n_sim"],
        on_fail=config["stationarity"]["on_fail"],
    log:
        "logs/collect/{sensor}.log",
    benchmark:
        "results/benchmarks/collect/{sensor}.tsv"
    script:
        "../scripts/collect.py"
