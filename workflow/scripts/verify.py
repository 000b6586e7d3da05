"""Verification of one spec sheet's bound of one sensor type (rule verify): imupipe.stages.verify.verify_job on the
bound file and the included curves' records (stacked spectra file), block-averaged to the reference filter's rate.
Writes the report (SI) and the figure sqrt(P) against the true / empirical RMS error of the exported model."""

from imupipe.io import run_job
from imupipe.stages.verify import verify_job

if __name__ == "__main__":
    p, i, o = snakemake.params, snakemake.input, snakemake.output
    run_job(verify_job, snakemake.log[0], path_bound=i.bound, path_spectra=i.spectra, path_spec=i.spec,
            path_truth=i.get("truth") or None, records=list(i.records), path_out=o.verify, path_figure=o.figure,
            spec_name=snakemake.wildcards.spec, sensor=snakemake.wildcards.sensor, fix_s=p.fix_s,
            outage_s=p.outage_s, sigma_fix_m=p.sigma_fix_m, sigma_fix_rad=p.sigma_fix_rad,
            filter_rate_hz=p.filter_rate_hz, reduce=p.reduce, replay_z=p.replay_z,
            max_bias_time_s=p.max_bias_time_s, fix_rate_hz=p.fix_rate_hz, segments=list(i.get("segments") or []))
