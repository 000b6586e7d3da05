# The full-rate stage, one job per dataset (its six channels one after the other, at most one axis's samples
# in memory): overlapping Allan variance of the full-rate axis, block average to decimate.rate_hz, Welch PSD
# of the decimated axis. One job instead of one per channel: a job costs ~0.2 s to start plus its imports,
# about half of a channel's numerics (docs/architecture.md). The job imports numpy, netCDF4 and the C kernel
# only (no xarray, no scipy.signal), so its peak memory stays near the data of one axis. Parallelism: the
# dataset jobs run side by side on --cores.


rule reduce:
    input:
        series=channel_files("results/series/{{dataset}}/{sensor}/{axis}.nc"),
    output:
        allan=channel_files("results/allan/{{dataset}}/{sensor}/{axis}.nc"),
        decimated=channel_files("results/decimated/{{dataset}}/{sensor}/{axis}.nc"),
        psd=channel_files("results/psd/{{dataset}}/{sensor}/{axis}.nc"),
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
        "logs/reduce/{dataset}.log",
    benchmark:
        "results/benchmarks/reduce/{dataset}.tsv"
    script:
        "../scripts/reduce.py"
