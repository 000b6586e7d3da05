# Simulated recordings (default config only) and ingest: one recording -> one SI float64 file per channel.


rule simulate:
    input:
        truth=str(repo_path(config["simulation"]["truth"])) if config.get("simulation") else [],
    output:
        recording="data/simulated/{dataset}.nc",
    params:
        seed=simulation_seed,
        duration_s=float(config["simulation"]["duration_h"]) * 3600.0 if config.get("simulation") else None,
        rate_hz=config["simulation"]["rate_hz"] if config.get("simulation") else None,
        gravity_axis=config["simulation"].get("gravity_axis", "z") if config.get("simulation") else None,
    log:
        "logs/simulate/{dataset}.log",
    benchmark:
        "results/benchmarks/simulate/{dataset}.tsv"
    script:
        "../scripts/simulate.py"


rule ingest:
    input:
        unpack(raw_input),
    output:
        **{
            f"{s}_{a}": f"results/series/{{dataset}}/{s}/{a}.nc"
            for s in SENSORS
            for a in AXES
        },
    params:
        row=sheet_row,
        base_dir=str(ROOT) if not config.get("simulation") else ".",
        sensors=SENSORS,
        min_duration_s=float(config["psd"]["window_s"]),
    log:
        "logs/ingest/{dataset}.log",
    benchmark:
        "results/benchmarks/ingest/{dataset}.tsv"
    script:
        "../scripts/ingest.py"

