"""Simulate one static recording from the true noise model (rule simulate; default config only):
imupipe.stages.simulate.simulate_stage."""

from imupipe.io import run_job

if __name__ == "__main__":
    from imupipe.stages.simulate import simulate_stage

    p = snakemake.params
    run_job(simulate_stage, snakemake.log[0], truth=snakemake.input.truth, seed=p.seed, duration_s=p.duration_s,
            rate_hz=p.rate_hz, gravity_axis=p.gravity_axis, path_out=snakemake.output.recording,
            name=snakemake.wildcards.dataset)
