# Outliers (spikes) on one full-rate axis: the Hampel/MAD rule of imupipe.outliers with the policy of
# outliers.policy (fail | warn | remove). The report lists counts, the first indices, the threshold, the policy
# and the effect on the shortest-tau Allan variance. With `remove` the cleaned series (each outlier replaced by
# its block median) is what allan, decimate and lines read; with warn and fail they read the ingested series.
# The same job finds the axis's events (bursts, steps: imupipe.events) and applies events.policy: warn (default:
# reported, FLAGged in the summary), split (the record is cut at each event into segments, written to segments/,
# that every modelling stage analyses as records: imupipe.segments) or exclude (the cleaned series is the longest
# event-free segment).

OUTLIER_POLICY = config["outliers"]["policy"]
EVENTS = dict(config.get("events") or {})
EVENT_POLICY = EVENTS.get("policy", "warn")
CLEANED = OUTLIER_POLICY == "remove" or EVENT_POLICY == "exclude"
SPLIT = EVENT_POLICY == "split"


# The full-rate axis the modelling stages (allan, decimate, lines) read.
FULL_RATE_SERIES = f"{RESULTS}/{'cleaned' if CLEANED else 'series'}/{{dataset}}/{{sensor}}/{{axis}}.nc"
# Under split: the axis's segments (imupipe.segments.Segments as YAML; the whole record when it has no event).
SEGMENTS_FILE = f"{RESULTS}/segments/{{dataset}}/{{sensor}}/{{axis}}.yaml"
# The inputs of a stage that reads the full-rate axis: the series and, under split, its segments.
FULL_RATE_INPUTS = {"series": FULL_RATE_SERIES, **({"segments": SEGMENTS_FILE} if SPLIT else {})}
# The report, with `remove` or events `exclude` the cleaned series, with split the segments.
OUTLIER_OUTPUTS = {"report": f"{RESULTS}/outliers/{{dataset}}/{{sensor}}/{{axis}}.yaml"}
if CLEANED:
    OUTLIER_OUTPUTS["cleaned"] = f"{RESULTS}/cleaned/{{dataset}}/{{sensor}}/{{axis}}.nc"
if SPLIT:
    OUTLIER_OUTPUTS["segments"] = SEGMENTS_FILE


# memory: the axis, one batch of the rule's work arrays (imupipe.outliers.HAMPEL_BATCH), the event scans'
# cumulative sum, block deviations and median copies (imupipe.events) and the cleaned copy; measured at 125 Hz:
# 111 MB at 2.2 h (8 MB file), 226 MB at 10 h (36 MB; outliers.policy remove + events.policy exclude alike):
# 78 MB + 4.1 x the axis file's size, so 100 MB + 4.5 x
MEM_MB["outliers"] = lambda wildcards, input: int(100 + 4.5 * input.size_mb)
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
        events=EVENTS,
        # the PSD stage needs one window of the record: the shortest event-free segment `exclude` and `split` keep (a
        # param only under those, so that psd.window_s re-runs no outliers job under warn)
        min_segment_s=float(config["psd"]["window_s"]) if EVENT_POLICY in ("exclude", "split") else 0.0,
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
