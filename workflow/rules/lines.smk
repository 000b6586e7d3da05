# Spectral lines of one full-rate axis (before decimation, on the cleaned series when outliers.policy is
# `remove`): imupipe.lines.find_lines at lines.resolution_hz (and lines.scales, lines.low_band_resolution_hz),
# family-wise level lines.alpha. The bound reads these files with lines.policy (per sensor) and
# lines.application_band_hz. Under events.policy warn the search reads each burst's stretch filled (the outliers
# job's burst scan run again with the same settings: imupipe.stages.outliers.line_search_series): a knock's ringing
# is no line.


# memory: the axis and one batch of its segments' spectra (imupipe.lines.SPECTRUM_BATCH); measured at 125 Hz:
# 130 MB at 10 h, 244 MB at 40 h (100 MB + one axis): axis_mem_mb, 80 MB + 2 x the axis file's size
MEM_MB["lines"] = axis_mem_mb
RUNTIME_MIN["lines"] = full_rate_runtime


rule lines:
    input:
        **FULL_RATE_INPUTS,  # the series and, under events.policy split, its segments
    output:
        lines=f"{RESULTS}/lines/{{dataset}}/{{sensor}}/{{axis}}.yaml",
    params:
        resolution_hz=config["lines"]["resolution_hz"],
        alpha=config["lines"]["alpha"],
        floor_window_bins=config["lines"]["floor_window_bins"],
        scales=config["lines"].get("scales", [1]),
        low_band_resolution_hz=config["lines"].get("low_band_resolution_hz"),
        # the burst scan's settings under events.policy warn (the others cut bursts out): an outliers or step-scan
        # setting re-runs no line search
        events={k: EVENTS[k] for k in ("alpha", "burst_window_s", "burst_k") if k in EVENTS}
        if EVENT_POLICY == "warn" else None,
    group:
        "per_axis"
    threads: 1
    resources:
        mem_mb=MEM_MB["lines"],
        runtime=RUNTIME_MIN["lines"],
    log:
        f"{LOGS}/lines/{{dataset}}/{{sensor}}/{{axis}}.log",
    benchmark:
        f"{BENCHMARKS}/lines/{{dataset}}/{{sensor}}/{{axis}}.tsv"
    conda:
        "../envs/imupipe.yaml"
    script:
        "../scripts/lines.py"


# The bound reads the lines files of its sensor with per_axis("lines", "yaml") (common.smk).
LINE_FILES = [f for s in SENSORS for f in per_axis_files("lines", "yaml", s)]
EXTRA_TARGETS.extend(LINE_FILES)
SUMMARY_INPUTS["lines"] = LINE_FILES
