"""Read a static IMU record from a file into SI arrays, with checks that name the culprit.

One entry point, :func:`read_dataset`, reads the gyro and/or accelerometer channels of one
recording from any of the supported formats, converts them once to SI (gyro rad/s, accel m/s^2),
applies an optional axis/sign map and validates the record: missing or empty file, truncated
rows, unknown columns, NaN/inf samples, timestamps (gaps, duplicates, non-monotonic, rate
disagreeing with the sheet), a record too short for the requested analysis, constant channels
and unknown units. Every failure raises :class:`DataError` with the file, the channel or column,
the row (and for text files the line) and what was expected.

Supported formats (``format`` argument; ``"auto"`` picks by file extension):

========  ==========================  ==============================================================
format    extensions                  channels are ...
========  ==========================  ==============================================================
csv       .csv .txt .tsv .dat         column names of the header line, or 0-based column indices
netcdf    .nc .nc4 .cdf               names of 1-D variables, or indices into the 2-D ``variable``
npy       .npy                        0-based column indices of a 2-D array (field names if structured)
npz       .npz                        names of 1-D arrays, or indices into the 2-D array ``variable``
rdata     .rda .rdata .rds            column names of an R matrix / data.frame / named list
rosbag    .bag .mcap .db3, bag dir    ``sensor_msgs/Imu`` fields (default ``angular_velocity.x`` ...)
========  ==========================  ==============================================================

:func:`read_dataset_row` maps one row of the workflow's dataset sheet (``config/datasets.tsv``)
onto :func:`read_dataset`; :data:`SHEET_COLUMNS` documents the columns it reads.


Modules: :mod:`~imupipe.readers.core` (the reader and its checks), :mod:`~imupipe.readers.checks`
(file, range, name and config checks shared by all formats), :mod:`~imupipe.readers.probe`
(metadata without the samples, for start-up checks), one module per format family
(:mod:`~imupipe.readers.text`, :mod:`~imupipe.readers.arrays`, :mod:`~imupipe.readers.netcdf`,
:mod:`~imupipe.readers.rdata`, :mod:`~imupipe.readers.rosbag`).
"""

from __future__ import annotations

__all__ = [
    "AXES",
    "FORMATS",
    "GAP_POLICIES",
    "SENSORS",
    "SHEET_COLUMNS",
    "ConfigError",
    "DataError",
    "FROM_FILE",
    "FilledGap",
    "Probe",
    "RATE_RTOL",
    "DEFAULT_FILL_MAX_FRACTION",
    "GapWarning",
    "Recording",
    "Segment",
    "GRAVITY_WINDOW",
    "check_against_config",
    "check_file",
    "check_gravity",
    "check_sheet_header",
    "check_unchanged",
    "check_values",
    "missing_channel_columns",
    "parse_axis_map",
    "format_of",
    "gravity_removed",
    "probe",
    "probe_row",
    "read_dataset",
    "read_dataset_row",
    "read_channel",
    "sheet_row_to_kwargs",
    "snap_rate",
    "validate_dataset_name",
]
from imupipe.readers._common import (  # noqa: F401
    AXES, FORMATS, GAP_POLICIES, SENSORS, SHEET_COLUMNS, DataError, GapWarning, Recording, Segment, parse_axis_map,
)
from imupipe.readers.checks import (  # noqa: F401
    GRAVITY_WINDOW, PLAUSIBLE_SI, ConfigError, check_against_config, check_file, check_gravity, check_sheet_header,
    check_unchanged, check_values, gravity_removed, validate_dataset_name,
)
from imupipe.readers.core import (  # noqa: F401
    DEFAULT_FILL_MAX_FRACTION, FROM_FILE, RATE_RTOL, FilledGap, format_of, missing_channel_columns, read_channel, read_dataset, read_dataset_row, sheet_row_to_kwargs, snap_rate,
)
from imupipe.readers.probe import Probe, probe, probe_row  # noqa: F401
