# Welch PSD of each decimated axis, then one file per sensor type: psd(dataset, axis, frequency).


rule psd:
    input:
        decimated="results/decimated/{dataset}/{sensor}/{axis}.nc",
    output:
        psd="results/psd/{dataset}/{sensor}/{axis}.nc",
    params:
        window_s=config["psd"]["window_s"],
        step_s=config["psd"]["step_s"],
        taper=config["psd"]["taper"],
        detrend=config["psd"]["detrend"],
        confidence=config["psd"]["confidence"],
    log:
        "logs/psd/{dataset}/{sensor}/{axis}.log",
    benchmark:
        "results/benchmarks/psd/{dataset}/{sensor}/{axis}.tsv"
    script:
        "../scripts/psd.py"


rule merge_spectra:
    input:
        psd=axis_files("results/psd/{dataset}/{sensor}/{axis}.nc"),
        stationarity="results/stationarity/{sensor}.yaml",
    output:
        spectra="results/spectra/{sensor}.nc",
    log:
        "logs/merge_spectra/{sensor}.log",
    benchmark:
        "results/benchmarks/merge_spectra/{sensor}.tsv"
    script:
        "../scripts/merge_spectra.py"
