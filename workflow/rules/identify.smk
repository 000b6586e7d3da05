# Allan-variance identification per sensor type: the pooled fit and its adequacy, model selection for the
# application band, the selected model refitted, the pooling test (per-axis fits where the curves differ) and
# the identified upper envelope the bound reads (upper_envelope_model). The lines found by the lines stage (policy
# model or exclude) enter every Allan fit as known terms; each record's own fit is compared with the others'
# (record_consistency).


rule identify:
    input:
        allan=f"{RESULTS}/allan/{{sensor}}.nc",
        truth=truth_file(),
        # the lines stage's lines of every axis: their Allan variance is a known term of every fit
        lines=lines_files_of,
    output:
        identified=f"{RESULTS}/identify/{{sensor}}.yaml",
    params:
        components=config["identify"]["components"],
        n_gm=config["identify"]["n_gm"],
        n_boot=config["identify"]["n_boot"],
        confidence=config["identify"]["confidence"],
        significance=config["identify"]["significance"],
        relevance=config["identify"]["relevance"],
        adequacy_level=config["identify"]["adequacy_level"],
        # optional: the GM T search starts at this many sample intervals of the decimated series (unset: tau_min)
        fit_tau_min_samples=config["identify"].get("fit_tau_min_samples"),
        pooling_level=config["identify"]["pooling_level"],
        pooling_n_boot=config["identify"]["pooling_n_boot"],
        envelope_kind=config["identify"].get("envelope", "marginal"),
        filter_rate_hz=FILTER_RATE_HZ,
        outage_s=OUTAGE_S,
        # the upper envelope covers a GM time constant the data leave open for f >= 1/(fix_s + outage_s)
        span_s=SPAN_S,
        lines=LINES_PARAMS,
        # lines below the decimated Nyquist frequency join the upper envelope as lines (identify_sensor)
        envelope_lines_below_hz=0.5 * config["decimate"]["rate_hz"],
    threads: 1
    resources:
        mem_mb=MEM_MB["identify"],
        runtime=RUNTIME_MIN["identify"],
    log:
        f"{LOGS}/identify/{{sensor}}.log",
    benchmark:
        f"{BENCHMARKS}/identify/{{sensor}}.tsv"
    conda:
        "../envs/imupipe.yaml"
    script:
        "../scripts/identify.py"
