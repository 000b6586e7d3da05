"""Read one recording (any supported format), convert to SI, validate, write one file per channel (rule ingest).

The channels are written one after the other (write_channel). The readers' whole-record call still holds the
six channels at once; a per-channel read goes in `channels` below, leaving the writing unchanged."""

import logging

from imupipe.io import run_job, write_series
from imupipe.readers import read_dataset_row

UNITS = {"gyro": "rad/s", "accel": "m/s^2"}
AXES = ("x", "y", "z")


def channels(row: dict, sensors: list, dataset: str):
    """(sensor, axis, samples in SI, attributes) of each channel of the recording, one at a time."""
    rec = read_dataset_row(row, base_dir=".")  # recording paths are relative to the working directory
    logging.info("%s: %d samples at %g Hz (%.2f h) from %s", dataset, rec.n_samples, rec.rate_hz,
                 rec.duration_s / 3600, rec.source)
    for sensor in sensors:
        for axis in AXES:
            yield sensor, axis, rec[(sensor, axis)], {
                "rate_hz": rec.rate_hz, "source": rec.source, "column": rec.columns[(sensor, axis)],
                "file_units": rec.file_units[(sensor, axis)]}


def write_channel(path: str, x, sensor: str, axis: str, dataset: str, meta: dict) -> None:
    write_series(path, x, rate_hz=meta["rate_hz"], units=UNITS[sensor],
                 attrs={"long_name": f"{sensor} {axis}", "dataset": dataset, "sensor": sensor, "axis": axis,
                        "source": meta["source"], "column": meta["column"], "file_units": meta["file_units"]})


def main(row: dict, sensors: list, outputs: dict, dataset: str) -> None:
    for sensor, axis, x, meta in channels(row, sensors, dataset):
        write_channel(outputs[f"{sensor}_{axis}"], x, sensor, axis, dataset, meta)


if __name__ == "__main__":
    run_job(main, snakemake.log[0], row=dict(snakemake.params.row), sensors=list(snakemake.params.sensors),
            outputs=dict(snakemake.output.items()), dataset=snakemake.wildcards.dataset)
