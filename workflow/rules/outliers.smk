# Outliers (spikes) on one full-rate axis: the Hampel/MAD rule of imupipe.outliers with the policy of
# outliers.policy (fail | warn | remove). The report lists counts, the first indices, the threshold, the policy
# and the effect on the shortest-tau Allan variance. With `remove` the cleaned series (each outlier replaced by
# its block median) is what allan, decimate and lines read; with warn and fail they read the ingested series.

OUTLIER_POLICY = config["outliers"]["policy"]


# The full-rate axis the modelling stages (allan, decimate, lines) read.
FULL_RATE_SERIES = f"{RESULTS}/{'cleaned' if OUTLIER_POLICY == 'remove' else 'series'}/{{dataset}}/{{sensor}}/{{axis}}.nc"
# The report, and with `remove` the cleaned series.
OUTLIER_OUTPUTS = {"report": f"{RESULTS}/outliers/{{dataset}}/{{sensor}}/{{axis}}.yaml"}
if OUTLIER_POLICY == "remove":
    OUTLIER_OUTPUTS["cleaned"] = f"{RESULTS}/cleaned/{{dataset}}/{{sensor}}/{{axis}}.nc"

# memory: the axis, one batch of the rule's work arrays (imupipe.outliers.HAMPEL_BATCH) and, when there are
# outliers, the cleaned copy; measured at 125 Hz (no outlier): 130 MB at 10 h, 240 MB at 40 h (96 MB + one
# axis); with the copy 96 MB + 2 axes: 100 MB + 2.5 x the axis file's size
MEM_MB["outliers"] = lambda wildcards, input: int(100 + 2.5 * input.size_mb)
RUNTIME_MIN["outliers"] = full_rate_runtime


rule outliers:
    input:
        series=f"{RESULTS}/series/{{dataset}}/{{sensor}}/{{axis}}.nc",
    output:
        **OUTLIER_OUTPUTS,
    params:
        policy=OUTLIER_POLICY,
        k=config["outliers"]["k"],
        window_samples=config["outliers"]["window_samples"],
        max_indices=config["outliers"]["max_indices"],
    group:
        "per_axis"
    threads: 1
    resources:
        mem_mb=MEM_MB["outliers"],
        runtime=RUNTIME_MIN["outliers"],
    log:
        f"{LOGS}/outliers/{{dataset}}/{{sensor}}/{{axis}}.log",
    benchmark:
        f"{BENCHMARKS}/outliers/{{dataset}}/{{sensor}}/{{axis}}.tsv"
    conda:
        "../envs/imupipe.yaml"
    script:
        "../scripts/outliers.py"


OUTLIER_REPORTS = [f for s in SENSORS for f in per_axis_files("outliers", "yaml", s)]
EXTRA_TARGETS.extend(OUTLIER_REPORTS)
SUMMARY_INPUTS["outliers"] = OUTLIER_REPORTS
