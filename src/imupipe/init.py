r"""A first dataset sheet and config for a user's own records (``imupipe init``).

Each record is probed with :func:`imupipe.readers.probe` (header, row count, rate; no second reader), its
format named by :func:`imupipe.readers.format_of`. From the probes the settings that must fit the records are
derived, each by a stated rule (:func:`derive_settings`):

- ``decimate.rate_hz`` :math:`f_d`: block-average decimation needs an integer ratio ``rate / f_d`` for every
  record (:func:`imupipe.readers.check_against_config`), so :math:`f_d = \gcd(f_1, \dots, f_n, f_0)`, the
  greatest common divisor (of the rates as fractions) of the record rates and :math:`f_0` = 1 Hz the default
  (paper: 1 Hz): 1 Hz for integer rates, 0.5 Hz for 12.5 Hz records.
- ``psd.window_s`` :math:`W` and ``psd.step_s`` :math:`S`: :func:`imupipe.defaults.psd_window_step` on the
  shortest record :math:`T_{min}` (``W = min(floor(T f_d / 4) / f_d, 7 h)``, ``S = W / 2``), the rule the workflow
  applies to unset keys, written out. With :math:`N` decimated samples, :math:`n_w = W f_d`, :math:`n_s = S f_d`,
  Welch uses :math:`K = \lfloor (N - n_w)/n_s \rfloor + 1` segments and leaves :math:`u = N - (K-1) n_s - n_w`
  samples unused. When :math:`u / N > 0.10` (only records longer than 4 x 7 h, where W is capped), the step is
  shortened so that the segments tile the record: :math:`K' = \lceil (N - n_w) / (n_w/2) \rceil + 1`,
  :math:`n_s' = \lfloor (N - n_w)/(K' - 1) \rfloor`, leaving fewer than :math:`K' - 1` samples.
- ``application.filter_rate_hz`` = :math:`f_d` (the exported filter's and the verification's rate): the application
  band ``[1/outage_s, filter_rate_hz / 2]`` then lies inside the band of the decimated spectra the bound is fitted on
  (``[1/W, f_d/2]``), and the verification replay reads the decimated series (a divisor of every record rate).
- ``application.outage_s`` :math:`H = \min(H_0, W, T_{min} - F)` (``H_0`` = 3600 s the default, ``F`` =
  ``verify.fix_s``), down to a whole decimated sample: the band bottom ``1/H`` is not below the lowest PSD
  frequency ``1/W`` the records measure, and one fix period plus one outage fits in the shortest record (the
  replay of :func:`imupipe.verify` needs records of at least ``fix_s + outage_s``). ``imupipe init --outage-s H``
  takes the user's H instead where :math:`H \le T_{min} - F` (the band below ``1/W`` is then covered by the
  identified envelope, as for every run), and refuses it naming :math:`T_{min} - F` otherwise.
- ``lines.scales`` = [1, 8, 64]: the line search also at 8 and 64 times its resolution, so that a resonance wider
  than the running-median floor resolves is found (the default run keeps [1], the paper's).
- ``lines.low_band_resolution_hz`` = :math:`1/W`: the band below the search's lowest tested bin (0.052 Hz at the
  default 0.002 Hz) is searched too, at the PSD window's bin spacing (the default run searches none, the paper's).
  It is searched at half that spacing too, where a record holds two such segments (the first bins' narrowed floor
  windows hold a line's own main lobe: :func:`imupipe.lines.find_lines`). Each of the five searches runs at
  alpha / 5. Where :math:`1/W` is not finer than ``lines.resolution_hz`` (a window
  under 500 s: records under about 33 min), null: no band below the search's is resolved finer than it.

A record with timestamps (a time column, or a ROS bag's message headers) gets ``gap_policy: fill``: a few dropped
samples, common in logged records, are filled and counted instead of stopping the ingest; a longer gap still stops
it, naming the gap (:data:`FILL_NOTE`, the sheet's comment).

Column names gyro_x .. accel_z are guessed from the header (:func:`guess_channels`); units from a bracketed
suffix (``gx [deg/s]``), the file's attribute (netCDF: ``from_file``) or the format (ROS ``sensor_msgs/Imu``:
SI). What cannot be guessed is written as the placeholder :data:`PLACEHOLDER`, which the reader refuses, and
listed for the user.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path

from imupipe.defaults import DEFAULTS, PSD_MAX_WINDOW_S, psd_window_step

__all__ = ["PLACEHOLDER", "MAX_UNUSED_FRACTION", "RecordInfo", "Settings", "inspect_record", "guess_channels",
           "derive_settings", "welch_unused", "sheet_text", "config_text"]

#: Value of a sheet cell the user must fill (the reader refuses it as an unknown unit / column).
PLACEHOLDER = "FILL_ME"
#: Largest share of the shortest record the PSD segments may leave unused.
MAX_UNUSED_FRACTION = 0.10
#: Default verify.fix_s (s) the outage rule subtracts.
_FIX_S = float(DEFAULTS["verify.fix_s"])

_SENSORS, _AXES = ("gyro", "accel"), ("x", "y", "z")
_GYRO = r"(?:gyro(?:scope)?|gyr|g|w|omega|angular_velocity|ang_vel|angvel|rate)"
_ACCEL = r"(?:accel(?:erometer|eration)?|acc|a|f|linear_acceleration|lin_acc)"
_TIME = {"t", "time", "timestamp", "stamp"}
_TIME_SUFFIX = {"s": "s", "sec": "s", "ms": "ms", "us": "us", "ns": "ns"}


def _norm(name: str) -> str:
    return re.sub(r"_+", "_", re.sub(r"[^0-9a-z]+", "_", name.lower())).strip("_")


def guess_channels(names) -> tuple[dict[str, str], dict[str, str], str | None, str | None]:
    """Guess the columns of gyro_x .. accel_z, the units and the time column from header names.

    A name (lower-cased, punctuation to ``_``, a bracketed unit suffix removed) matches gyro axis ``a`` when it
    is ``<gyro word>[_]a`` (gyro, gyr, g, w, omega, angular_velocity, rate) and accel axis ``a`` for
    ``<accel word>[_]a`` (accel, acc, a, f, linear_acceleration); a time column is t, time, timestamp, stamp.
    A sensor's unit is guessed only when its three columns carry the same bracketed unit and
    :func:`imupipe.units.rate_factor` accepts it for that sensor.

    Returns
    -------
    channels : dict
        ``{"gyro_x": column, ...}`` for the channels found (each column at most once).
    units : dict
        ``{sensor: unit}`` for the sensors whose unit was guessed.
    time_column : str or None
    time_unit : str or None
        Of the time column, when its name states it (``t [s]``, ``time_ms``).
    """
    from imupipe.units import rate_factor, split_unit_suffix

    channels, suffix, time_column, time_unit = {}, {}, None, None
    pats = {s: re.compile(rf"^{p}_?([xyz])$") for s, p in (("gyro", _GYRO), ("accel", _ACCEL))}
    for name in names:
        base, unit = split_unit_suffix(str(name))
        key = _norm(base)
        stem, _, tail = key.rpartition("_")
        if time_column is None and (key in _TIME or (stem in _TIME and tail in _TIME_SUFFIX)):
            time_column = str(name)
            time_unit = _TIME_SUFFIX.get(tail if stem in _TIME else str(unit).strip().lower())
            continue
        for s, pat in pats.items():
            m = pat.match(key)
            if m and f"{s}_{m.group(1)}" not in channels:
                channels[f"{s}_{m.group(1)}"] = str(name)
                suffix[f"{s}_{m.group(1)}"] = unit
                break
    units = {}
    for s in _SENSORS:
        found = {suffix.get(f"{s}_{a}") for a in _AXES if f"{s}_{a}" in channels}
        if len(found) == 1 and None not in found:
            unit = found.pop()
            try:
                rate_factor(unit, s)
            except Exception:  # noqa: BLE001 (not a unit of this sensor: left for the user)
                continue
            units[s] = unit
    return channels, units, time_column, time_unit


def _unread_units(channels, sensor: str) -> str:
    """``"; the header's units ... not read as ..."``: the bracketed units of `sensor`'s guessed columns (the
    ``channels`` map of :func:`guess_channels`) that gave no unit for it, or "" when its columns carry none."""
    from imupipe.units import split_unit_suffix

    cols = [channels[f"{sensor}_{a}"] for a in _AXES if f"{sensor}_{a}" in channels]
    found = sorted({str(u) for u in (split_unit_suffix(str(c))[1] for c in cols) if u})
    if not found:
        return ""
    what = "a rate unit" if sensor == "gyro" else "an acceleration unit"
    return (f"; the header's {', '.join(repr(u) for u in found)} was not read as {what}"
            + (" (the three axes differ)" if len(found) > 1 else ""))


@dataclass
class RecordInfo:
    """What :func:`inspect_record` found out about one record (rate Hz, duration s)."""

    dataset: str
    path: Path
    format: str
    rate_hz: float
    rate_from: str
    n_samples: int
    duration_s: float
    row: dict
    todo: list[str] = field(default_factory=list)  #: cells written as PLACEHOLDER, with what they need
    notes: list[str] = field(default_factory=list)  #: what was left out (a sensor without columns)


def inspect_record(path, dataset: str, rate_hz: float | None = None, time_unit: str | None = None) -> RecordInfo:
    """Probe one record and fill its dataset-sheet row (placeholders where nothing could be guessed).

    `rate_hz` (Hz) and `time_unit` (s, ms, us, ns) are the user's, for records that do not state them; a time
    column's unit is otherwise taken from its name (``t [ms]``, ``time_s``), a netCDF ``units`` attribute or the
    stamps' spacing (:func:`imupipe.readers.timeunit.infer_time_unit`, as ``imupipe allan`` does).

    Raises :class:`imupipe.readers.DataError` for a missing file or unknown format, ValueError for a record
    whose rate is known neither from the file, its timestamps nor `rate_hz`.
    """
    time_unit_given = time_unit
    from imupipe.readers import FROM_FILE, format_of, probe
    from imupipe.readers.timeunit import infer_time_unit

    path = Path(path)
    fmt = format_of(path, "auto")
    if fmt == "rdata":  # no index: the column names first, then a probe of the channels guessed from them
        from imupipe.readers.rdata import rdata_columns

        names = rdata_columns(path)
        guessed = guess_channels(names)[0]
        if not guessed:
            raise ValueError(f"{path}: no gyro / accel column recognised among {', '.join(map(repr, names))}: "
                             "write its dataset-sheet row by hand (config/README.md)")
        # (R files are read in full, converted with a unit: SI stands in, the rate and length do not depend on it)
        meta = probe(path, fmt, rate_hz, channels=guessed, units={"gyro": "rad/s", "accel": "m/s^2"})
        meta = type(meta)(**{**meta.__dict__, "channels": tuple(names)})
    else:
        meta = probe(path, fmt, rate_hz)
    row = {"dataset": dataset, "path": str(path), "format": fmt, "rate_hz": ""}
    todo: list[str] = []
    if fmt == "rosbag":  # sensor_msgs/Imu: the reader's default fields, SI by the message definition
        channels, units, time_column, time_unit = {}, {"gyro": "rad/s", "accel": "m/s^2"}, None, None
    else:
        channels, units, time_column, time_unit = guess_channels(meta.channels)
        if fmt == "netcdf":
            units = {s: units.get(s, FROM_FILE) for s in _SENSORS}
    time_unit = time_unit_given or time_unit
    if time_column is not None and fmt == "netcdf" and time_unit is None:  # the variable's units attribute
        meta = probe(path, fmt, rate_hz, time_column=time_column)
        row["time_column"] = time_column
    elif time_column is not None and fmt != "rosbag":
        if time_unit is None:  # not in its name: from the stamps' spacing (as 'imupipe allan' does)
            as_s = probe(path, fmt, rate_hz, time_column=time_column, time_unit="s")
            if as_s.rate_hz:
                time_unit, _ = infer_time_unit(1.0 / as_s.rate_hz, rate_hz, where=str(path))
        if time_unit is not None:
            meta = probe(path, fmt, rate_hz, time_column=time_column, time_unit=time_unit)
            row["time_column"], row["time_unit"] = time_column, time_unit
    if not meta.rate_hz:
        raise ValueError(f"{path}: sample rate unknown (no timestamps or rate in the file): give --rate-hz")
    rate, notes = _gap_proof_rate(path, fmt, meta, row.get("time_column"), time_unit, dataset)
    row["rate_hz"] = f"{rate:.12g}"
    if row.get("time_column") or fmt == "rosbag":  # stamps that can show dropped samples (a bag: its headers')
        row["gap_policy"] = "fill"
    have = set(_SENSORS) if fmt == "rosbag" else {s for s in _SENSORS if any(f"{s}_{a}" in channels for a in _AXES)}
    for s in _SENSORS:
        if have and s not in have:  # the other sensor's columns were found: this one is absent from the record
            row.update({f"{s}_unit": "", **{f"{s}_{a}": "" for a in _AXES}})
            notes.append(f"{dataset}: no {s} column recognised among {', '.join(meta.channels)}: {s} left out "
                         f"(fill {s}_unit and {s}_x .. {s}_z to add it)")
            continue
        row[f"{s}_unit"] = units.get(s, PLACEHOLDER)
        if s not in units:
            todo.append(f"{dataset}: {s}_unit (the unit of the {s} samples as stored, e.g. "
                        + ("deg/s or rad/s" if s == "gyro" else "g or m/s^2") + _unread_units(channels, s) + ")")
        for a in _AXES:
            if fmt == "rosbag":
                row[f"{s}_{a}"] = ""
            elif f"{s}_{a}" in channels:
                row[f"{s}_{a}"] = channels[f"{s}_{a}"]
            else:
                row[f"{s}_{a}"] = PLACEHOLDER
                todo.append(f"{dataset}: {s}_{a} (column not guessed from the header"
                            + (f" {', '.join(meta.channels)})" if meta.channels else "; the file has no header)"))
    return RecordInfo(dataset, path, fmt, rate, meta.rate_from, int(meta.n_samples), meta.n_samples / rate, row, todo,
                      notes)


def _gap_proof_rate(path, fmt: str, meta, time_column, time_unit, dataset: str) -> tuple[float, list[str]]:
    """The record's rate (Hz) and a note when its timestamps' span and their spacing disagree. A text record's
    probed rate is its span's mean, (n - 1) / (t_last - t_first), which a gap lowers (a 10 Hz record with a 60 s
    gap in 1.5 h read 9.89 Hz, which the ingest then refused as contradicting the stamps, without naming the gap).
    Where the spacing of its first 20000 stamps (:func:`imupipe.readers.probe.head_rate`) gives a rate more than
    0.5 % above the span's (time missing: jitter does not lower the span's rate), that rate is taken (rounded as
    :func:`imupipe.readers.snap_rate` does, within 0.5 %) and the note says so; the ingest then names each gap (the
    dataset sheet's ``gap_policy`` says what is done with it)."""
    from imupipe.readers import snap_rate
    from imupipe.readers.probe import head_rate

    rate = float(meta.rate_hz)
    if meta.rate_from != "timestamps" or fmt != "csv" or time_column is None:
        return rate, []
    head = head_rate(path, time_column, time_unit or "s")
    if head is None or rate >= head * (1.0 - 0.005):
        return rate, []
    clock = snap_rate(head, rtol=0.005)
    missing = meta.n_samples / rate - meta.n_samples / clock
    return clock, [f"{dataset}: the timestamps' span gives {rate:.6g} Hz but their spacing {clock:g} Hz: about "
                   f"{missing:.2g} s of the record are missing (gaps); rate_hz set to {clock:g}; the ingest names each "
                   "gap, and the dataset sheet's gap_policy column says what is done with it (docs/inputs.md)"]


def welch_unused(n: int, nperseg: int, step: int) -> int:
    """Samples of an `n`-sample record left after the last Welch segment: ``n - (K - 1) step - nperseg``."""
    k = (n - nperseg) // step + 1
    return n - (k - 1) * step - nperseg


@dataclass
class Settings:
    """The derived config values (module docstring: the rules) and the numbers they came from."""

    decimate_rate_hz: float
    window_s: float
    step_s: float
    outage_s: float
    shortest_s: float
    unused: dict[str, float]
    outage_asked: bool = False  #: outage_s as the user asked for it (imupipe init --outage-s), not the rule's
    #: the longest outage --outage-s takes: one fix period plus it fit in the shortest record
    longest_outage_s: float | None = None


def _rate_gcd(rates) -> Fraction:
    fr = [Fraction(r).limit_denominator(1000) for r in rates]
    num = math.gcd(*(f.numerator for f in fr))
    den = math.lcm(*(f.denominator for f in fr))
    return Fraction(num, den)


def derive_settings(records: list[RecordInfo], outage_s: float | None = None) -> Settings:
    """decimate.rate_hz, psd.window_s / step_s and application.outage_s that fit `records` (module docstring).
    `outage_s` (s): the outage the user's filter must bridge (``imupipe init --outage-s``), taken as it is (down to a
    whole decimated sample) where one fix period plus it fits in the shortest record, instead of the rule's.

    Raises ValueError when the shortest record cannot hold one fix period (verify.fix_s) plus an outage, or plus the
    asked `outage_s` (naming the longest outage the records support).
    """
    from imupipe.readers import check_against_config

    f0 = float(DEFAULTS["decimate.rate_hz"])
    g = _rate_gcd([r.rate_hz for r in records])
    fd = float(_rate_gcd([g, f0]))
    shortest = min(records, key=lambda r: r.duration_s)
    n_min = math.floor(shortest.n_samples / round(shortest.rate_hz / fd))  # decimated samples (block averages)
    window, step = psd_window_step(n_min / fd, fd)
    nw, ns = round(window * fd), round(step * fd)
    if welch_unused(n_min, nw, ns) > MAX_UNUSED_FRACTION * n_min:
        k = math.ceil((n_min - nw) / (nw / 2)) + 1
        ns = (n_min - nw) // (k - 1)
        step = ns / fd
    h0 = float(DEFAULTS["application.outage_s"])
    outage = math.floor(min(h0, window, n_min / fd - _FIX_S) * fd) / fd
    most = math.floor((n_min / fd - _FIX_S) * fd) / fd  # one fix period plus the outage in the shortest record
    if outage_s is not None:
        if not (math.isfinite(float(outage_s)) and float(outage_s) > 0):
            raise ValueError(f"--outage-s must be a positive number of seconds, got {outage_s!r}")
        if float(outage_s) > most:
            raise ValueError(
                f"--outage-s {float(outage_s):g}: the shortest record ({shortest.path}, {shortest.duration_s:.6g} s) "
                f"holds one fix period (verify.fix_s = {_FIX_S:g} s) and an outage of at most {max(most, 0.0):g} s; "
                "the verification replays the records over one fix period and one outage: record longer, or ask "
                "for a shorter outage")
        outage = math.floor(float(outage_s) * fd) / fd
    if outage * fd < 2:
        raise ValueError(f"{shortest.path}: {shortest.duration_s:g} s is too short for the verification: one fix "
                         f"period (verify.fix_s = {_FIX_S:g} s) and an outage of at least 2 samples must fit")
    unused = {}
    for r in records:
        n = math.floor(r.n_samples / round(r.rate_hz / fd))
        check_against_config({"rate_hz": r.rate_hz, "n_samples": r.n_samples, "duration_s": r.duration_s},
                             window_s=window, decimate_rate_hz=fd, n_segments=2, dataset=r.dataset)
        unused[r.dataset] = welch_unused(n, nw, ns) / n
    return Settings(fd, float(window), float(step), float(outage), shortest.duration_s, unused, outage_s is not None,
                    max(most, 0.0))


_SHEET_COLUMNS = ["dataset", "path", "format", "rate_hz", "gyro_unit", "accel_unit", "gyro_x", "gyro_y", "gyro_z",
                  "accel_x", "accel_y", "accel_z", "time_column", "time_unit", "gap_policy"]

#: The sheet's comment where a row says ``gap_policy: fill`` (:func:`sheet_text`).
FILL_NOTE = ("gap_policy fill: a gap of up to 10 missing samples (fill_max_samples) is filled by linear "
             "interpolation, counted in the outputs (n_filled) and the run summary; a longer gap stops the ingest "
             "naming it (long_gap_policy: split keeps the longest segment; docs/inputs.md)")


def sheet_text(records: list[RecordInfo]) -> str:
    """The dataset sheet (TSV; ``#`` lines are comments) of `records`, placeholders listed on top."""
    todo = [t for r in records for t in r.todo]
    lines = ["# dataset sheet written by 'imupipe init' (columns: config/README.md, docs/inputs.md)"]
    if todo:
        lines.append(f"# replace every {PLACEHOLDER} below before running:")
        lines += [f"#   {t}" for t in todo]
    lines += [f"# {t}" for r in records for t in r.notes]
    if any(r.row.get("gap_policy") == "fill" for r in records):
        lines.append(f"# {FILL_NOTE}")
    lines.append("\t".join(_SHEET_COLUMNS))
    lines += ["\t".join(str(r.row.get(c, "")) for c in _SHEET_COLUMNS) for r in records]
    return "\n".join(lines) + "\n"


def _low_band(window_s: float) -> str:
    """``lines.low_band_resolution_hz`` for a PSD window of `window_s` s, as the config's YAML value: 1 / window_s
    (Hz) where that is finer than the default ``lines.resolution_hz``, else null (module docstring)."""
    low = 1.0 / float(window_s)
    return repr(low) if low < float(DEFAULTS["lines.resolution_hz"]) else "null"


def config_text(name: str, sheet: str, spec_dir: str, spec: str, sensors: list[str], s: Settings) -> str:
    """The partial config (merged over config/config.yaml by the workflow), every derived value with its rule."""
    worst = max(s.unused.values())
    outage_rule = ("  # as asked (imupipe init --outage-s): one fix period plus one outage fits in the shortest record "
                   "(the\n  # verification's replay)" if s.outage_asked else
                   "  # min(3600 s default, psd.window_s, shortest record - verify.fix_s): 1/outage not below the "
                   "lowest PSD\n  # frequency, and one fix period plus one outage fits in the shortest record (the "
                   "verification's replay)")
    band_rule = ("  # = decimate.rate_hz: the band [1/outage_s, filter_rate_hz/2] inside the decimated spectra's [1/W, f/2]; "
                 "the\n  # verification's reference filter runs at it too (the exported model is the verified one)"
                 if s.outage_s <= s.window_s else
                 "  # = decimate.rate_hz (the verification's reference filter runs at it too); 1/outage_s lies below the "
                 "lowest PSD\n  # frequency 1/W: there the bound covers the identified envelope (it holds over all "
                 "frequencies)")
    return f"""\
# Written by 'imupipe init': a partial config, merged over config/config.yaml (every other key keeps its
# default there). Each value below is derived from the records by the rule in its comment (imupipe.init).
name: {name}
datasets: {sheet}
simulation: null
sensors: [{', '.join(sensors)}]
spec_dir: {spec_dir}
specs: [{spec}]
decimate:
  # greatest common divisor of the record rates and the default 1 Hz (integer block-average ratio)
  rate_hz: {s.decimate_rate_hz!r}
psd:
  # W = min(floor(T f / 4) / f, 7 h), T = {s.shortest_s:.6g} s the shortest record, f = decimate.rate_hz
  window_s: {s.window_s!r}
  # S = W / 2 (shortened to tile the record when that left more than 10 % unused); unused: {worst:.2%} at most
  step_s: {s.step_s!r}
application:
{band_rule}
  filter_rate_hz: {s.decimate_rate_hz!r}
{outage_rule}
  outage_s: {s.outage_s!r}
lines:
  # the line search at resolution_hz and 8 and 64 times coarser: a resonance wider than about a tenth of the floor
  # window is found at a coarser one (imupipe.lines.find_lines, scales)
  scales: [1, 8, 64]
  # 1 / psd.window_s: the band below the first search's (0.052 Hz) searched at the PSD window's bin spacing and at
  # half of it; each of the five searches at alpha / 5 (null where that spacing is not finer than resolution_hz)
  low_band_resolution_hz: {_low_band(s.window_s)}
bound:
  # auto: every mode's bound (raw, smoothed, confidence, pooled, and with the joint envelope the envelope
  # candidate) verified, the tightest that passes every check exported (imupipe.bound.auto; the paper's default
  # run keeps raw)
  mode: auto
identify:
  # joint: the upper envelope above the simultaneous band of the fit's bootstrap replicates (imupipe.identify.joint),
  # not every component at its upper limit at once: the auto bound's reference, tighter as the records grow
  envelope: joint
"""
