"""Simulate one static recording from the true noise model (rule simulate; default config only)."""

import numpy as np

from imupipe.io import atomic_path, run_job
from imupipe.simulate import simulate
from imupipe.specsheet import load_spec
from imupipe.units import STANDARD_GRAVITY as GRAVITY  # m/s^2, the one definition

AXES = ("x", "y", "z")


def main(truth: str, seed: int, duration_s: float, rate_hz: float, gravity_axis, path_out: str, name: str) -> None:
    import netCDF4

    sheet = load_spec(truth)
    n = int(round(duration_s * rate_hz))
    streams = np.random.SeedSequence(seed).spawn(6)
    with atomic_path(path_out) as tmp, netCDF4.Dataset(tmp, "w", format="NETCDF4") as nc:
        nc.createDimension("sample", n)
        nc.rate_hz = float(rate_hz)
        nc.title = f"simulated static IMU record {name}"
        nc.truth = truth.rsplit("/", 1)[-1]
        nc.seed = int(seed)
        for i, (sensor, unit) in enumerate((("gyro", "rad/s"), ("accel", "m/s^2"))):
            model = sheet.models[sensor]
            for j, axis in enumerate(AXES):
                x = simulate(model, n, rate_hz, np.random.default_rng(streams[3 * i + j]))
                if sensor == "accel" and axis == gravity_axis:
                    x -= GRAVITY
                v = nc.createVariable(f"{sensor}_{axis}", "f8", ("sample",))
                v.units = unit
                v.long_name = f"{sensor} {axis}"
                v[:] = x


if __name__ == "__main__":
    run_job(
        main,
        snakemake.log[0],
        truth=snakemake.input.truth,
        seed=snakemake.params.seed,
        duration_s=snakemake.params.duration_s,
        rate_hz=snakemake.params.rate_hz,
        gravity_axis=snakemake.params.gravity_axis,
        path_out=snakemake.output.recording,
        name=snakemake.wildcards.dataset,
    )
