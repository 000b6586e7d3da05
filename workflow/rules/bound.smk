# The bound of one sensor type against one spec sheet: the tightest model of each axis alone (bound_axis),
# then the global bound over every included curve and the spec sheet (bound), with the Allan-domain check of
# the kept components and the paper's hand inflation for comparison. Both bound over all frequencies: below
# the lowest PSD bin down to 0.01 / span (span = verify.fix_s + application.outage_s, SPAN_S) the bound's PSD
# stays above the spec sheet's and the identified model's upper confidence envelope (docs/method.md, "Bound
# over all frequencies"). Spectral lines found by the lines stage enter through the sensor's line policy
# (`lines.policy`: model | exclude | keep). A record whose noise level changes (the stationarity summary's marks)
# enters the global bound a second time, its PSD raised to its noisiest stretch's.
# With kf, verify, contract, figures and tables the only stages that read the spec sheet: a new spec sheet
# re-runs these jobs alone.


rule bound_axis:
    input:
        psd=f"{RESULTS}/psd/{{dataset}}/{{sensor}}/{{axis}}.nc",
        identified=f"{RESULTS}/identify/{{sensor}}.yaml",
        spec=spec_file,
        lines=lines_files_of,
    output:
        bound=f"{RESULTS}/bound/{{spec}}/axes/{{dataset}}/{{sensor}}/{{axis}}.yaml",
    params:
        mode=config["bound"]["mode"],
        n_gm=config["bound"]["n_gm"],
        confidence=config["bound"]["confidence"],
        bands_per_decade=config["bound"]["bands_per_decade"],
        span_s=SPAN_S,
        lines=LINES_PARAMS,
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
        lines=lines_files_of,
        stationarity=f"{RESULTS}/stationarity/{{sensor}}.yaml",  # the noisiest stretches the bound covers
    output:
        bound=f"{RESULTS}/bound/{{spec}}/{{sensor}}.yaml",
    params:
        mode=config["bound"]["mode"],
        n_gm=config["bound"]["n_gm"],
        confidence=config["bound"]["confidence"],
        bands_per_decade=config["bound"]["bands_per_decade"],
        compare_paper=config["bound"]["compare_paper"],
        span_s=SPAN_S,
        filter_rate_hz=FILTER_RATE_HZ,
        lines=LINES_PARAMS,
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
