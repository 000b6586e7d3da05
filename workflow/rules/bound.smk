# The bound of one sensor type against one spec sheet, in one job: the tightest model per axis (every
# dataset and axis), the global bound over every included curve (the contract file), the Allan-domain
# check per component, the paper's hand inflation for comparison, and the Kalman-filter matrices of the
# global bound. The only stage that reads the spec sheet with kalibr, figures and table: a new spec sheet
# re-runs these jobs alone.


rule bound:
    input:
        spectra="results/spectra/{sensor}.nc",
        allan="results/allan/{sensor}.nc",
        identified="results/identify/{sensor}.yaml",
        spec=spec_file,
    output:
        axis_bounds=axis_files_out("results/bound/{{spec}}/axes/{dataset}/{{sensor}}/{axis}.yaml"),
        bound="results/bound/{spec}/{sensor}.yaml",
        kf="results/kf/{spec}/{sensor}.yaml",
    params:
        mode=config["bound"]["mode"],
        n_gm=config["bound"]["n_gm"],
        confidence=config["bound"]["confidence"],
        bands_per_decade=config["bound"]["bands_per_decade"],
        compare_paper=config["bound"]["compare_paper"],
        kf_dt_s=1.0 / float(config["application"]["rate_hz"]),
        horizon_s=config["application"]["horizon_s"],
    log:
        "logs/bound/{spec}/{sensor}.log",
    benchmark:
        "results/benchmarks/bound/{spec}/{sensor}.tsv"
    script:
        "../scripts/bound.py"
