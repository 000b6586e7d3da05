# Simulated recordings (default config only) and ingest: one recording -> one SI float64 file per channel.


rule simulate:
    input:
        truth=truth_file(),
    output:
        recording=f"{RESULTS}/simulated/{{dataset}}.nc",
    params:
        seed=simulation_seed,
        duration_s=simulation_param("duration_h", 3600.0),
        rate_hz=simulation_param("record_rate_hz"),
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
# `ingest_gyro_x`), each constrained to its datasets. netCDF, npy/npz and text records are read one channel
# at a time (readers.read_channel: peak memory one channel plus a fixed overhead; a text file is parsed once
# per channel); R and bag records are parsed whole once (their layout has no per-channel access), then
# written one channel after the other.
INGEST_RULES = rc.ingest_rule_groups(AXES_OF, SENSORS)

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
