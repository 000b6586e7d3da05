"""Read one recording (any supported format), convert to SI, validate, write one file per channel (rule ingest)."""

import logging

from imupipe.io import run_job, write_series
from imupipe.readers import read_dataset_row

UNITS = {"gyro": "rad/s", "accel": "m/s^2"}


def main(row: dict, base_dir: str, sensors: list, min_duration_s: float, outputs: dict, dataset: str) -> None:
    rec = read_dataset_row(row, base_dir=base_dir, min_duration_s=min_duration_s)
    logging.info("%s: %d samples at %g Hz (%.2f h) from %s", dataset, rec.n_samples, rec.rate_hz,
                 rec.duration_s / 3600, rec.source)
    for sensor in sensors:
        for axis in ("x", "y", "z"):
            write_series(
                outputs[f"{sensor}_{axis}"],
                rec[(sensor, axis)],
                rate_hz=rec.rate_hz,
                units=UNITS[sensor],
                attrs={"long_name": f"{sensor} {axis}", "dataset": dataset, "sensor": sensor, "axis": axis,
                       "source": rec.source, "column": rec.columns[(sensor, axis)],
                       "file_units": rec.file_units[(sensor, axis)]},
            )


if __name__ == "__main__":
    run_job(
        main,
        snakemake.log[0],
        row=dict(snakemake.params.row),
        base_dir=snakemake.params.base_dir,
        sensors=list(snakemake.params.sensors),
        min_duration_s=snakemake.params.min_duration_s,
        outputs=dict(snakemake.output.items()),
        dataset=snakemake.wildcards.dataset,
    )
