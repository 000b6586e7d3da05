# The full-rate stage, one job per dataset and sensor type (its three axes one after the other, at most one
# axis's samples in memory): overlapping Allan variance of the full-rate axis, block average to
# decimate.rate_hz, Welch PSD of the decimated axis. One job instead of nine per sensor type: a job costs
# ~0.1 s to start plus its imports, more than an axis's numerics (docs/architecture.md). The job imports
# numpy, netCDF4 and the C kernel only (no xarray, no scipy.signal), so its peak memory stays near the
# data of one axis. Parallelism: the (dataset, sensor) jobs run side by side on --cores.


rule reduce:
    input:
        series=expand("results/series/{{dataset}}/{{sensor}}/{axis}.nc", axis=AXES),
    output:
        allan=expand("results/allan/{{dataset}}/{{sensor}}/{axis}.nc", axis=AXES),
        decimated=expand("results/decimated/{{dataset}}/{{sensor}}/{axis}.nc", axis=AXES),
        psd=expand("results/psd/{{dataset}}/{{sensor}}/{axis}.nc", axis=AXES),
    params:
        taus=config["allan"]["taus"],
        allan_confidence=config["allan"]["confidence"],
        rate_hz=config["decimate"]["rate_hz"],
        window_s=config["psd"]["window_s"],
        step_s=config["psd"]["step_s"],
        taper=config["psd"]["taper"],
        detrend=config["psd"]["detrend"],
        psd_confidence=config["psd"]["confidence"],
    log:
        "logs/reduce/{dataset}/{sensor}.log",
    benchmark:
        "results/benchmarks/reduce/{dataset}/{sensor}.tsv"
    script:
        "../scripts/reduce.py"
