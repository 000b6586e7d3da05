"""Simulate one static recording from the true noise model (rule ``simulate``; the default config only).

Each of the six channels is drawn by :func:`imupipe.simulate.simulate_chunks` (written piece by piece) from the
truth's model of its sensor, with its own stream of ``numpy.random.SeedSequence(seed).spawn(6)`` (gyro x, y, z, then accel x, y, z), so records of
different seeds are independent and a record is the same whatever else runs; the accel axis `gravity_axis`
carries -9.80665 m/s^2 (imupipe.units.STANDARD_GRAVITY). The file is netCDF with SI units (rad/s, m/s^2).
"""

from __future__ import annotations

import numpy as np

__all__ = ["simulate_stage"]

AXES = ("x", "y", "z")


def simulate_stage(truth: str, seed: int, duration_s: float, rate_hz: float, gravity_axis, path_out: str,
                   name: str) -> None:
    """Write the record `name` of `duration_s` (s) at `rate_hz` (Hz) drawn from the spec-sheet-format file `truth`
    to `path_out` (netCDF, atomically)."""
    import netCDF4

    from imupipe.io import atomic_path
    from imupipe.simulate import simulate_chunks
    from imupipe.specsheet import load_spec
    from imupipe.units import STANDARD_GRAVITY  # m/s^2, the one definition

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
                v = nc.createVariable(f"{sensor}_{axis}", "f8", ("sample",))
                v.units = unit
                v.long_name = f"{sensor} {axis}"
                # written piece by piece: a few pieces in memory, not the channel (docs/architecture.md)
                for start, x in simulate_chunks(model, n, rate_hz, np.random.default_rng(streams[3 * i + j])):
                    if sensor == "accel" and axis == gravity_axis:
                        x -= STANDARD_GRAVITY
                    v[start:start + x.size] = x
