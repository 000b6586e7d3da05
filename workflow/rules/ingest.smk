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


# Reads the recording with the readers' whole-record call, then writes the channels one after the other.
rule ingest:
    input:
        unpack(raw_input),
    output:
        **{
            f"{s}_{a}": f"{RESULTS}/series/{{dataset}}/{s}/{a}.nc"
            for s in SENSORS
            for a in AXES
        },
    params:
        row=sheet_row,
        sensors=SENSORS,
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
