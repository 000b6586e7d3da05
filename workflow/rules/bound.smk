# The bound: per axis, then global over every dataset and axis of a sensor type (the contract file).
# These are the first rules that read the spec sheet.


rule axis_bound:
    input:
        psd="results/psd/{dataset}/{sensor}/{axis}.nc",
        identified="results/identify/{sensor}.yaml",
        spec=spec_file,
    output:
        bound="results/bound/{spec}/axes/{dataset}/{sensor}/{axis}.yaml",
    params:
        mode=config["bound"]["mode"],
        n_gm=config["bound"]["n_gm"],
        confidence=config["bound"]["confidence"],
        bands_per_decade=config["bound"]["bands_per_decade"],
    log:
        "logs/axis_bound/{spec}/{dataset}/{sensor}/{axis}.log",
    benchmark:
        "results/benchmarks/axis_bound/{spec}/{dataset}/{sensor}/{axis}.tsv"
    script:
        "../scripts/axis_bound.py"


rule global_bound:
    input:
        spectra="results/spectra/{sensor}.nc",
        allan="results/allan/{sensor}.nc",
        identified="results/identify/{sensor}.yaml",
        axis_bounds=axis_bounds_of,
        spec=spec_file,
    output:
        bound="results/bound/{spec}/{sensor}.yaml",
    params:
        mode=config["bound"]["mode"],
        n_gm=config["bound"]["n_gm"],
        confidence=config["bound"]["confidence"],
        bands_per_decade=config["bound"]["bands_per_decade"],
        compare_paper=config["bound"]["compare_paper"],
    log:
        "logs/global_bound/{spec}/{sensor}.log",
    benchmark:
        "results/benchmarks/global_bound/{spec}/{sensor}.tsv"
    script:
        "../scripts/global_bound.py"
