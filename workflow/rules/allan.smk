# Overlapping Allan variance of each full-rate axis, then one file per sensor type: avar(dataset, axis, tau).


rule allan:
    input:
        series="results/series/{dataset}/{sensor}/{axis}.nc",
    output:
        allan="results/allan/{dataset}/{sensor}/{axis}.nc",
    params:
        taus=config["allan"]["taus"],
        confidence=config["allan"]["confidence"],
    log:
        "logs/allan/{dataset}/{sensor}/{axis}.log",
    benchmark:
        "results/benchmarks/allan/{dataset}/{sensor}/{axis}.tsv"
    script:
        "../scripts/allan.py"


rule merge_allan:
    input:
        allan=axis_files("results/allan/{dataset}/{sensor}/{axis}.nc"),
        stationarity="results/stationarity/{sensor}.yaml",
    output:
        allan="results/allan/{sensor}.nc",
    log:
        "logs/merge_allan/{sensor}.log",
    benchmark:
        "results/benchmarks/merge_allan/{sensor}.tsv"
    script:
        "../scripts/merge_allan.py"
