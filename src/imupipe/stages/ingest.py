"""Ingest one recording (rule ``ingest``): any supported format read, converted to SI, validated, one file per
channel.

Memory: netCDF, npy/npz and text records are read one channel at a time (readers.read_channel: one variable,
one column streamed in blocks of rows, one named array; a text file is parsed once per channel, keeping only
that column), so the peak is one channel plus a fixed overhead; R and bag records have no per-channel access
and are parsed whole once (readers.read_dataset_row), then written one channel after the other. Only the
channels the dataset sheet names (or all three axes of a sensor naming none) are read and written.

Each output carries the gap fill of its record (attrs ``n_filled``: gaps filled, ``filled_rows``: the 0-based
file rows before each filled gap, comma separated; docs/inputs.md, "Timestamps and gaps"). The record length
against psd.window_s is checked once, at start-up (imupipe.runconfig.check_records): ingest takes no analysis
setting, so a change of another section does not re-run it.

A dataset with all three accel axes is checked for gravity after its channels are written
(readers.check_gravity: |mean specific force| within 0.9 .. 1.1 g0, else the job fails and Snakemake removes
its outputs; a wrong but valid accel_unit is caught here); the sheet column ``gravity_removed: yes`` skips it.

Plain values in (the dataset sheet's row, the channels, the output paths), the channel files out
(:func:`ingest_stage`).
"""

from __future__ import annotations

import logging
import warnings
from pathlib import Path

import numpy as np

from imupipe.io import write_series
from imupipe.readers import (
    GapWarning, check_gravity, format_of, gravity_removed, read_channel, read_dataset_row, sheet_row_to_kwargs,
)
from imupipe.units import SI_UNITS, STANDARD_GRAVITY

__all__ = ["PER_CHANNEL_FORMATS", "channels", "ingest_stage", "write_channel"]

PER_CHANNEL_FORMATS = ("netcdf", "npy", "npz", "csv")


def _log_record(rec, dataset: str) -> None:
    logging.info("%s: %d samples at %g Hz (%.2f h) from %s", dataset, rec.n_samples, rec.rate_hz,
                 rec.duration_s / 3600, rec.source)
    if rec.n_filled:
        logging.info("%s: %d gap(s) filled by linear interpolation, after file rows %s", dataset, rec.n_filled,
                     ", ".join(str(g.row) for g in rec.filled))


def _meta(rec, key) -> dict:
    return {"rate_hz": rec.rate_hz, "source": rec.source, "column": rec.columns[key],
            "file_units": rec.file_units[key], "n_filled": int(rec.n_filled),
            "filled_rows": ",".join(str(g.row) for g in rec.filled)}


def channels(row: dict, keys: list, dataset: str):
    """(sensor, axis, samples in SI, attributes) of each channel `keys` ("gyro_x", ...), one at a time."""
    kwargs = sheet_row_to_kwargs(row, base_dir=None)  # recording paths are relative to the working directory
    pairs = [tuple(k.split("_", 1)) for k in keys]
    fmt = format_of(Path(kwargs["path"]), kwargs["format"])
    if fmt in PER_CHANNEL_FORMATS:
        path, kwargs["format"] = kwargs.pop("path"), fmt
        for i, key in enumerate(pairs):
            with warnings.catch_warnings():
                if i:  # the same stamps read again with each channel: their warnings once, with the first
                    warnings.simplefilter("ignore", GapWarning)
                rec = read_channel(key, path, **kwargs)
            if i == 0:
                _log_record(rec, dataset)
            yield (*key, rec[key], _meta(rec, key))
            del rec
        return
    if kwargs.get("channels"):  # read only the configured channels
        row = {k: v for k, v in row.items() if not (k[:-2] in SI_UNITS and k[-2:] in ("_x", "_y", "_z")) or k in keys}
    rec = read_dataset_row(row, base_dir=None)
    _log_record(rec, dataset)
    for key in pairs:
        yield (*key, rec[key], _meta(rec, key))


def write_channel(path: str, x, sensor: str, axis: str, dataset: str, meta: dict) -> None:
    write_series(path, x, rate_hz=meta["rate_hz"], units=SI_UNITS[sensor],
                 attrs={"long_name": f"{sensor} {axis}", "dataset": dataset, "sensor": sensor, "axis": axis,
                        "source": meta["source"], "column": meta["column"], "file_units": meta["file_units"],
                        "n_filled": meta["n_filled"], "filled_rows": meta["filled_rows"]})


def ingest_stage(row: dict, keys: list, outputs: dict, dataset: str) -> None:
    """Read the channels `keys` ("gyro_x", ...) of the dataset sheet's `row` (recording path relative to the working
    directory), write each to `outputs[key]` (SI float64 netCDF), then the gravity check of a dataset with all three
    accel axes (unless the row says ``gravity_removed: yes``)."""
    skip = gravity_removed(row.get("gravity_removed"), where=f"dataset {dataset!r}")
    accel_means, accel_units = {}, set()
    for sensor, axis, x, meta in channels(row, keys, dataset):
        write_channel(outputs[f"{sensor}_{axis}"], x, sensor, axis, dataset, meta)
        if sensor == "accel":
            accel_means[axis] = float(np.mean(x))  # m/s^2
            accel_units.add(meta["file_units"])
        del x  # else this channel stays alive while the next one is read: two channels in memory
    if skip or len(accel_means) < 3:
        return
    unit = accel_units.pop() if len(accel_units) == 1 else str(row.get("accel_unit"))
    magnitude = check_gravity([accel_means[a] for a in ("x", "y", "z")], unit,
                              where=f"{row['path']} (dataset {dataset!r})")
    logging.info("%s: gravity check: |mean specific force| = %.6g m/s^2 (%.4f g0)", dataset, magnitude,
                 magnitude / STANDARD_GRAVITY)
