# The bound of one sensor type against one spec sheet: the tightest model of each axis alone (bound_axis),
# then the global bound over every included curve and the spec sheet (the contract file), with the
# Allan-domain check per component and the paper's hand inflation for comparison (bound). With kf,
# figures and tables the only stages that read the spec sheet: a new spec sheet re-runs these jobs alone.


rule bound_axis:
    input:
        psd=f"{RESULTS}/psd/{{dataset}}/{{sensor}}/{{axis}}.nc",
        identified=f"{RESULTS}/identify/{{sensor}}.yaml",
        spec=spec_file,
    output:
        bound=f"{RESULTS}/bound/{{spec}}/axes/{{dataset}}/{{sensor}}/{{axis}}.yaml",
    params:
        mode=config["bound"]["mode"],
        n_gm=config["bound"]["n_gm"],
        confidence=config["bound"]["confidence"],
        bands_per_decade=config["bound"]["bands_per_decade"],
    threads: 1
    resources:
        mem_mb=MEM_MB["bound_axis"],
        runtime=RUNTIME_MIN["bound_axis"],
    log:
        f"{LOGS}/bound/{{spec}}/axes/{{dataset}}/{{sensor}}/{{axis}}.log",
    benchmark:
        f"{BENCHMARKS}/bound_axis/{{spec}}/{{dataset}}/{{sensor}}/{{axis}}.tsv"
    conda:
        "../envs/imupipe.yaml"
    script:
        "../scripts/bound_axis.py"


rule bound:
    input:
        spectra=f"{RESULTS}/spectra/{{sensor}}.nc",
        allan=f"{RESULTS}/allan/{{sensor}}.nc",
        identified=f"{RESULTS}/identify/{{sensor}}.yaml",
        spec=spec_file,
        axis_bounds=axis_bounds_of,
    output:
        bound=f"{RESULTS}/bound/{{spec}}/{{sensor}}.yaml",
    params:
        mode=config["bound"]["mode"],
        n_gm=config["bound"]["n_gm"],
        confidence=config["bound"]["confidence"],
        bands_per_decade=config["bound"]["bands_per_decade"],
        compare_paper=config["bound"]["compare_paper"],
    threads: 1
    resources:
        mem_mb=MEM_MB["bound"],
        runtime=RUNTIME_MIN["bound"],
    log:
        f"{LOGS}/bound/{{spec}}/{{sensor}}.log",
    benchmark:
        f"{BENCHMARKS}/bound/{{spec}}/{{sensor}}.tsv"
    conda:
        "../envs/imupipe.yaml"
    script:
        "../scripts/bound.py"
