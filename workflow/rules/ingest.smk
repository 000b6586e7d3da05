# Simulated recordings (default config only) and ingest: one recording -> one SI float64 file per channel.


rule simulate:
    input:
        truth=truth_file(),
    output:
        recording=f"{RESULTS}/simulated/{{dataset}}.nc",
    params:
        seed=simulation_seed,
        duration_s=simulation_param("duration_h", 3600.0),
        rate_hz=simulation_param("rate_hz"),
        gravity_axis=simulation_param("gravity_axis"),
    threads: 1
    resources:
        mem_mb=simulate_mem_mb,
        runtime=RUNTIME_MIN["simulate"],
    log:
        f"{LOGS}/simulate/{{dataset}}.log",
    benchmark:
        f"{BENCHMARKS}/simulate/{{dataset}}.tsv"
    conda:
        "../envs/imupipe.yaml"
    script:
        "../scripts/simulate.py"


# One ingest rule per set of channels: a dataset's sheet row may name one, two or three axes of a sensor
# (AXES_OF, common.smk), and a rule's outputs cannot depend on the dataset. The rule of the datasets with
# every axis of every configured sensor is `ingest`; the others are `ingest_<channels>` (e.g.
# `ingest_gyro_x`), each constrained to its datasets. netCDF and npy/npz records are read one channel at a
# time (readers.read_channel: peak memory about one channel); text, R and bag records are parsed whole once
# (their layout has no per-channel access), then written one channel after the other.
def _channel_groups():
    groups = {}
    for name in DATASETS:
        groups.setdefault(tuple(channels_of(name)), []).append(name)
    full = tuple((s, a) for s in SENSORS for a in AXES)
    return {
        ("ingest" if chans == full else "ingest_" + "_".join(f"{s}_{a}" for s, a in chans)): (chans, names)
        for chans, names in groups.items()
    }


def ingest_params(wildcards):
    """Reader settings of the job: the psd.window_s minimum record length is checked at start-up
    (common.smk, _check_records); ingest names that key too if a record read shorter than probed."""
    return {"min_duration_s": float(config["psd"]["window_s"]), "min_duration_key": "psd.window_s"}


INGEST_RULES = _channel_groups()

for _rule_name, (_chans, _names) in INGEST_RULES.items():

    rule:
        name:
            _rule_name
        wildcard_constraints:
            dataset="|".join(re.escape(n) for n in _names),
        input:
            unpack(raw_input),
        output:
            **{f"{s}_{a}": f"{RESULTS}/series/{{dataset}}/{s}/{a}.nc" for s, a in _chans},
        params:
            row=sheet_row,
            channels=[f"{s}_{a}" for s, a in _chans],
            reader=ingest_params,
        threads: 1
        resources:
            mem_mb=ingest_mem_mb,
            runtime=full_rate_runtime,
        log:
            f"{LOGS}/ingest/{{dataset}}.log",
        benchmark:
            f"{BENCHMARKS}/ingest/{{dataset}}.tsv"
        conda:
            "../envs/imupipe.yaml"
        script:
            "../scripts/ingest.py"
