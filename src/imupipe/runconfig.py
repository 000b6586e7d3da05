"""The workflow's run configuration as plain Python: what the Snakefile's rule files and ``imupipe check`` both
need, testable without Snakemake.

- :func:`load_config`: a partial config on top of ``config/config.yaml`` (:func:`imupipe.io.merged_with_defaults`),
  renamed keys refused by name (:data:`RENAMED_KEYS`), the schema ``workflow/schemas/config.schema.yaml`` checked
  (jsonschema, which comes with Snakemake), then the checks across keys (:func:`check_cross_keys`);
- :func:`read_sheet`: the dataset sheet (TSV) parsed, its cells cast and checked row by row;
  :func:`simulated_datasets`: the rows of the simulated recordings; :func:`datasets_of`: either;
- :func:`check_records`: the cheap probe of every record against the config at start-up (and the PSD window
  and step when the config leaves them unset); :func:`check_specs`: every spec sheet read once;
- :func:`remove_stale`: the stale-output clean-up (docs/inputs.md, "Stale outputs");
- small derived values the rules pass on (:func:`span_s`, :func:`replay_from_decimated`, :func:`lines_params`,
  :func:`ingest_rule_groups`, :func:`sheet_column`).

Units: rates in Hz, durations in s, as in the config.
"""

from __future__ import annotations


import csv
import math
import os
from fnmatch import fnmatch
from pathlib import Path

__all__ = ["AXES", "RENAMED_KEYS", "axes_of", "check_cross_keys", "check_records", "check_specs", "datasets_of",
           "divides", "ingest_rule_groups", "lines_params", "load_config", "merged_config", "read_sheet",
           "refuse_renamed_keys", "sheet_lines",
           "remove_stale", "replay_from_decimated", "repo_path", "sheet_column", "simulated_datasets",
           "simulation_seeds", "span_s", "spec_path", "validate_schema"]

AXES = ("x", "y", "z")
SCHEMAS = Path("workflow") / "schemas"

#: Config keys that were renamed or removed: old key -> (new key or None when removed, why).
RENAMED_KEYS = {
    "application.rate_hz": ("application.filter_rate_hz", "the filter's update rate"),
    "application.horizon_s": ("application.outage_s", "the outage (no fixes) the filter must coast through"),
    "simulation.rate_hz": ("simulation.record_rate_hz", "the simulated records' sample rate"),
    "verify.filter_rate_hz": (None, "the verification's reference filter runs at application.filter_rate_hz, the "
                                    "exported filter's rate"),
}


def refuse_renamed_keys(given: dict, where: str = "config") -> None:
    """Raise ValueError naming every key of `given` (a config as written) that :data:`RENAMED_KEYS` lists, with the
    key to use instead."""
    problems = []
    for old, (new, what) in RENAMED_KEYS.items():
        section, key = old.split(".")
        if isinstance(given.get(section), dict) and key in given[section]:
            problems.append(f"{old} is now {new} ({what})" if new else f"{old} is no longer a key: {what}; remove it")
    if problems:
        raise ValueError(f"{where}: renamed config key(s): " + "; ".join(problems))


def validate_schema(data: dict, schema_path, where: str = "config") -> bool:
    """Check `data` against the JSON schema (YAML file) `schema_path`; raise ValueError with the first violation and
    where it is (jsonschema's message, e.g. "Additional properties are not allowed ('windw_s' was unexpected)").
    Returns False, checking nothing, when jsonschema (installed with Snakemake) is missing."""
    try:
        import jsonschema
    except ImportError:
        return False
    import yaml

    schema = yaml.safe_load(Path(schema_path).read_text())
    validator = jsonschema.validators.validator_for(schema)(schema)
    errors = sorted(validator.iter_errors(data), key=lambda e: list(e.absolute_path))
    if errors:
        e = errors[0]
        at = ".".join(str(p) for p in e.absolute_path)
        raise ValueError(f"{where}: {e.message}" + (f" (at {at})" if at else ""))
    return True


def divides(fast_hz: float, slow_hz: float) -> bool:
    """True when fast_hz / slow_hz is a whole number >= 1 (relative tolerance 1e-9: rates written in decimal)."""
    m = float(fast_hz) / float(slow_hz)
    return m >= 1.0 - 1e-9 and abs(m - round(m)) <= 1e-9 * m


def check_cross_keys(cfg: dict) -> None:
    """The checks the schema cannot state: exactly one of ``datasets`` and ``simulation``; ``verify.fix_rate_hz``
    dividing ``application.filter_rate_hz`` (a fix every whole number of filter steps); ``lines.low_band_resolution_hz``
    finer than ``lines.resolution_hz`` (the low band is searched below the first search's band, at a finer spacing)."""
    if cfg.get("simulation") and cfg.get("datasets"):
        raise ValueError("config: give either 'datasets' (a sheet of recordings) or 'simulation', not both")
    if not cfg.get("simulation") and not cfg.get("datasets"):
        raise ValueError("config: neither 'datasets' nor 'simulation' is set: nothing to process")
    fix, rate = cfg["verify"].get("fix_rate_hz"), cfg["application"]["filter_rate_hz"]
    if fix is not None and not divides(rate, fix):
        raise ValueError(f"config: verify.fix_rate_hz = {fix} Hz must divide application.filter_rate_hz = {rate} Hz "
                         "(a fix every whole number of filter steps); e.g. fix_rate_hz 1 with filter_rate_hz 100, or "
                         "null for a fix every step")
    lines = cfg.get("lines") or {}
    low, res = lines.get("low_band_resolution_hz"), lines.get("resolution_hz")
    if low is not None and res is not None and not float(low) < float(res):
        raise ValueError(f"config: lines.low_band_resolution_hz = {low} Hz must be finer (smaller) than "
                         f"lines.resolution_hz = {res} Hz: the band below the line search's is searched at a finer "
                         "bin spacing (e.g. 1 / psd.window_s), or null for none")


def merged_config(given: dict, root, where: str = "config") -> dict:
    """`given` (a config file's keys, renamed keys refused) merged over ``{root}/config/config.yaml``
    (:func:`imupipe.io.merged_with_defaults`; `given` alone when there is no such file)."""
    from imupipe.io import merged_with_defaults, read_yaml

    if not isinstance(given, dict):
        raise ValueError(f"{where}: expected a YAML mapping of config keys")
    refuse_renamed_keys(given, where)
    defaults_path = Path(root) / "config" / "config.yaml"
    if not defaults_path.is_file():
        return dict(given)
    return merged_with_defaults(read_yaml(defaults_path), given)


def load_config(given: dict, root, where: str = "config") -> dict:
    """:func:`merged_config`, then the schema (``{root}/workflow/schemas/config.schema.yaml``) and the cross-key checks
    passed: the configuration a run uses."""
    cfg = merged_config(given, root, where)
    validate_schema(cfg, Path(root) / SCHEMAS / "config.schema.yaml", where)
    check_cross_keys(cfg)
    return cfg


def repo_path(path, root) -> str:
    """A path the config names (relative to `root`, the repository, unless absolute) as a job should see it:
    relative to the working directory when both lie below a common folder, else absolute."""
    p = Path(path)
    p = p if p.is_absolute() else Path(root) / p
    cwd = str(Path.cwd().resolve())
    try:
        target = str(p.resolve())
    except (RuntimeError, OSError):  # a symbolic link loop: its ingest job names it
        target = os.path.abspath(p)
    try:
        shared = os.path.commonpath([target, cwd]) != os.sep
    except ValueError:
        shared = False
    return os.path.relpath(p) if shared else str(p)


_CASTS = (("rate_hz", float, "a number (Hz)"), ("fill_max_samples", int, "an integer (samples)"),
          ("fill_max_s", float, "a number (s)"), ("fill_max_fraction", float, "a number (fraction of the record)"))


def sheet_lines(path) -> list[int]:
    """The line numbers (1-based, as an editor shows them) of the data rows of the dataset sheet at `path`: every
    line after the header that is neither a ``#`` comment nor blank (what :func:`read_sheet` reads as rows)."""
    with open(path, newline="", encoding="utf-8-sig") as fh:
        body = [i for i, ln in enumerate(fh, start=1) if ln.strip() and not ln.lstrip().startswith("#")]
    return body[1:]


def read_sheet(path, schema_path) -> dict:
    """{dataset: its non-empty cells} of the dataset sheet (TSV, ``#`` lines comments), checked one by one: the
    header (:func:`imupipe.readers.check_sheet_header`), each dataset name (it names folders), the numeric cells
    cast (:data:`_CASTS`), each row against the sheet schema, no dataset twice. Raises ValueError naming the
    sheet, the line and the column."""
    from imupipe.readers import DataError, check_sheet_header, validate_dataset_name

    path = Path(path)
    if not path.is_file():
        raise ValueError(f"config key 'datasets': dataset sheet {str(path)!r} not found")
    try:
        check_sheet_header(path)
    except DataError as exc:
        raise ValueError(str(exc)) from None
    with open(path, newline="", encoding="utf-8-sig") as fh:
        rows = list(csv.DictReader([ln for ln in fh if not ln.lstrip().startswith("#")], delimiter="\t"))
    if not rows:
        raise ValueError(f"dataset sheet {str(path)!r} has no rows")
    out = {}
    for i, row in zip(sheet_lines(path), rows):
        if None in row:
            raise ValueError(f"{path}, line {i}: {len(row[None])} more cell(s) than the header has columns"
                             f" ({len(row) - 1}); expected one cell per header column")
        cells = {k.strip(): v.strip() for k, v in row.items() if k is not None and v is not None and v.strip()}
        try:
            validate_dataset_name(cells.get("dataset"), where=f"{path}, line {i}")
        except DataError as exc:
            raise ValueError(str(exc)) from None
        for key, kind, what in _CASTS:
            if key in cells:
                try:
                    cells[key] = kind(cells[key])
                except ValueError:
                    raise ValueError(f"{path}, line {i}: {key} = {cells[key]!r} is not {what}") from None
        try:
            validate_schema(cells, schema_path, where=f"{path}, line {i} (dataset {cells.get('dataset')!r})")
        except ValueError as exc:
            raise ValueError(str(exc).splitlines()[0]) from None
        if cells["dataset"] in out:
            raise ValueError(f"{path}, line {i}: dataset {cells['dataset']!r} appears twice")
        out[cells["dataset"]] = cells
    return out


def simulated_datasets(simulation: dict, results: str) -> dict:
    """{sim01: row, ...}: the sheet rows of the simulated recordings (netCDF under ``{results}/simulated/``, SI, every
    channel; ``gravity_removed: yes`` when the simulation has no gravity axis). Record i's seed is
    simulation.seed + i (:func:`simulation_seeds`)."""
    names = [f"sim{i + 1:02d}" for i in range(int(simulation["n_datasets"]))]
    return {name: {"dataset": name, "path": f"{results}/simulated/{name}.nc", "format": "netcdf",
                   "rate_hz": float(simulation["record_rate_hz"]), "gyro_unit": "rad/s", "accel_unit": "m/s^2",
                   **({"gravity_removed": "yes"} if simulation.get("gravity_axis", "z") is None else {}),
                   **{f"{s}_{a}": f"{s}_{a}" for s in ("gyro", "accel") for a in AXES}}
            for name in names}


def simulation_seeds(simulation: dict | None) -> dict:
    """{sim01: seed, ...}: simulation.seed + the record's index; {} without a simulation."""
    if not simulation:
        return {}
    return {f"sim{i + 1:02d}": int(simulation["seed"]) + i for i in range(int(simulation["n_datasets"]))}


def datasets_of(cfg: dict, root, results: str, schemas=None) -> dict:
    """The datasets of a run: the simulated ones, or the sheet's with recording paths relative to the working
    directory (:func:`repo_path`). `schemas`: the folder of the sheet's schema (default ``{root}/workflow/schemas``)."""
    if cfg.get("simulation"):
        return simulated_datasets(cfg["simulation"], results)
    schema = Path(schemas or Path(root) / SCHEMAS) / "datasets.schema.yaml"
    sheet = read_sheet(repo_path(cfg["datasets"], root), schema)
    return {name: {**row, "path": repo_path(row["path"], root)} for name, row in sheet.items()}


def axes_of(datasets: dict, sensors) -> dict:
    """{dataset: {sensor: [axis, ...]}}: the axes whose column a row names; a sensor naming none takes all three
    (the file's default column names or a bag's sensor_msgs/Imu fields)."""
    return {name: {s: [a for a in AXES if f"{s}_{a}" in row] or list(AXES) for s in sensors}
            for name, row in datasets.items()}


def _probe(row: dict, simulation: dict | None):
    """(rate Hz or None, duration s or None, the metadata check_against_config reads) of one row; None when the
    cheap probe fails (the ingest job then reads the file and reports it, for this dataset alone)."""
    if simulation:
        rate = float(simulation["record_rate_hz"])
        n = int(round(float(simulation["duration_h"]) * 3600.0 * rate))
        return rate, n / rate, {"rate_hz": rate, "n_samples": n, "duration_s": n / rate}
    from imupipe.readers import probe_row

    try:
        meta = probe_row(row)
    except Exception:  # noqa: BLE001 (any failure of the cheap probe is left to the ingest job)
        return None
    return meta.rate_hz, meta.duration_s, meta


def _stamps_contradict(meta, row: dict) -> float | None:
    """The rate (N - 1) / T (Hz) of a record's N rows over the span T between its first and last stamp where it
    contradicts the sheet's ``rate_hz``, else None (a gap can only lower it). Above rate_hz by more than
    :data:`imupipe.readers.RATE_RTOL`, or below it by more than that plus what the row's gap policy lets the ingest
    fill (``fill``: fill_max_fraction of the record; ``fail``: nothing; a split keeps any gap), rows / rate_hz is not
    the record's duration: the start-up check then leaves the record's length checks out (they would name
    application.outage_s or psd.window_s for a wrong rate: an outside evaluation's 100 Hz sheet for a 50 Hz record),
    and its ingest job stops naming the rate or the gap, the other datasets going on."""
    from imupipe.readers import DEFAULT_FILL_MAX_FRACTION, RATE_RTOL

    span, n = getattr(meta, "span_s", None), getattr(meta, "n_samples", 0)
    if getattr(meta, "rate_from", "") != "sheet" or not span or span <= 0 or n < 2:
        return None
    rate, stamps_rate = float(meta.rate_hz), (n - 1) / span
    policies = {str(row.get("gap_policy") or "fail"), str(row.get("long_gap_policy") or "fail")}
    filled = float(row.get("fill_max_fraction") or DEFAULT_FILL_MAX_FRACTION) if "fill" in policies else 0.0
    low = math.inf if "split" in policies else (RATE_RTOL + filled) * rate
    return None if -low <= stamps_rate - rate <= RATE_RTOL * rate else stamps_rate


def check_records(cfg: dict, datasets: dict) -> list[str]:
    """Start-up check of every record against the config, once, naming the key: long enough for ``psd.window_s``
    (and the longest for ``verify.fix_s + application.outage_s``, the replay's run),
    its rate a whole multiple of ``decimate.rate_hz`` and of ``application.filter_rate_hz`` (the verification
    replays each record block-averaged to the filter's rate), enough decimated samples for
    ``stationarity.n_segments`` (:func:`imupipe.readers.check_against_config`). Every dataset's problem in one
    ValueError. An unset ``psd.window_s`` / ``psd.step_s`` is set here (in `cfg`) by
    :func:`imupipe.defaults.psd_window_step` on the shortest record: one frequency grid for every record. Returns
    the warnings: a record whose timestamps contradict its ``rate_hz`` (:func:`_stamps_contradict`) is not
    length-checked, and its ingest job stops on it."""
    from imupipe.readers import ConfigError, check_against_config

    problems, lasts, warnings = [], {}, []  # dataset -> duration, s
    filter_rate = float(cfg["application"]["filter_rate_hz"])
    for name, row in datasets.items():
        probed = _probe(row, cfg.get("simulation"))
        if probed is None:
            continue
        rate, duration, meta = probed
        span_rate = _stamps_contradict(meta, row)
        if span_rate is not None:  # rows / rate_hz is not its duration: its ingest job names the rate or gap
            warnings.append(f"{name}: rate_hz = {float(meta.rate_hz):g} Hz, but its {meta.n_samples} rows span "
                            f"{meta.span_s:.6g} s of timestamps ((rows - 1) / span = {span_rate:.6g} Hz; a gap lowers "
                            "it): its length is not checked here; its ingest (imupipe check --read, or the run) "
                            "compares rate_hz with the timestamps and stops if they disagree")
            continue
        if duration is not None:
            lasts[name] = float(duration)
        try:  # a rate only the timestamps give (no rate_hz cell) is checked by the decimate job
            check_against_config(meta, window_s=cfg["psd"]["window_s"],
                                 decimate_rate_hz=cfg["decimate"]["rate_hz"] if rate is not None else None,
                                 n_segments=cfg["stationarity"]["n_segments"], dataset=name)
        except ConfigError as exc:
            problems.append(str(exc))
        if rate is not None and not divides(rate, filter_rate):
            problems.append(f"{name}: record rate {float(rate):g} Hz is not a whole multiple of "
                            f"application.filter_rate_hz = {cfg['application']['filter_rate_hz']} Hz (the verification "
                            "replays each record block-averaged to the filter's rate); set application.filter_rate_hz "
                            "to the record rate or a divisor of it")
    run_s = span_s(cfg)
    longest = max(lasts, key=lasts.get) if lasts else None
    if longest is not None and lasts[longest] < run_s:  # the replay needs one fix period and one outage in a record
        problems.append(
            f"the longest record ({longest!r}, {lasts[longest]:.6g} s) is shorter than config keys verify.fix_s + "
            f"application.outage_s = {cfg['verify']['fix_s']:g} + {cfg['application']['outage_s']:g} = {run_s:g} s: "
            "the verification replays the records through the filter over one fix period and one outage; shorten "
            "application.outage_s (or verify.fix_s) or give a longer record")
    if problems:
        raise ValueError("records do not fit the config:\n  " + "\n  ".join(problems))
    psd = cfg["psd"]
    if psd["window_s"] is None or psd["step_s"] is None:
        from imupipe.defaults import psd_window_step

        if not lasts:
            raise ValueError("psd.window_s / psd.step_s unset and no record's duration could be probed: set both in "
                             "the config (e.g. window_s = a quarter of the shortest record, step_s = half that)")
        w, st = psd_window_step(min(lasts.values()), float(cfg["decimate"]["rate_hz"]))
        if psd["window_s"] is None:
            psd["window_s"] = w
        if psd["step_s"] is None:
            psd["step_s"] = st if psd["window_s"] == w else psd["window_s"] / 2.0
    return warnings


def spec_path(cfg: dict, root, name: str) -> Path:
    """``{spec_dir}/{name}.yaml``, spec_dir relative to `root` unless absolute."""
    folder = Path(cfg["spec_dir"])
    return (folder if folder.is_absolute() else Path(root) / folder) / f"{name}.yaml"


def check_specs(cfg: dict, root) -> list:
    """Read every spec sheet of ``specs`` once (:func:`imupipe.specsheet.load_spec`): a missing sheet, a value
    without a valid unit or a missing sensor section raises, naming the file and the key. Returns the sheets."""
    from imupipe.specsheet import load_spec

    sheets = []
    for name in cfg["specs"]:
        path = spec_path(cfg, root, name)
        if not path.is_file():
            raise ValueError(f"config: specs lists {name!r} but {path} does not exist")
        sheet = load_spec(path)
        missing = [s for s in cfg["sensors"] if s not in sheet.models]
        if missing:
            raise ValueError(f"spec sheet {sheet.path}: no section for {', '.join(missing)} (config sensors: "
                             f"{list(cfg['sensors'])})")
        sheets.append(sheet)
    return sheets


def span_s(cfg: dict) -> float:
    """The window a filter must be right over, s: the reference filter's fix period plus the outage
    (verify.fix_s + application.outage_s); the bound holds from f = 0.01 / span_s up."""
    return float(cfg["verify"]["fix_s"]) + float(cfg["application"]["outage_s"])


def replay_from_decimated(cfg: dict) -> bool:
    """True when decimate.rate_hz is a whole multiple of application.filter_rate_hz: the verification's replay then
    reads the decimated series (the same block averages), else the full-rate ones."""
    return divides(cfg["decimate"]["rate_hz"], cfg["application"]["filter_rate_hz"])


def lines_params(cfg: dict) -> dict:
    """The line policy per sensor (default ``model``) and the application band (Hz; None: all of it)."""
    section = cfg.get("lines") or {}
    policy = section.get("policy") or {}
    return {"policy": {s: policy.get(s, "model") for s in ("gyro", "accel")},
            "application_band_hz": section.get("application_band_hz")}


def sheet_column(datasets: dict, key: str, cast=None) -> dict:
    """{dataset: the row's `key` cell (cast when given), None where empty}."""
    return {name: (cast(row[key]) if cast and row.get(key) is not None else row.get(key))
            for name, row in datasets.items()}


def ingest_rule_groups(axes: dict, sensors) -> dict:
    """Rule name -> (channels, datasets): the datasets sharing one set of (sensor, axis) channels share one ingest
    rule: ``ingest`` for every axis of every sensor, ``ingest_<channels>`` otherwise. `axes`: :func:`axes_of`."""
    groups = {}
    for name, per_sensor in axes.items():
        groups.setdefault(tuple((s, a) for s in sensors for a in per_sensor[s]), []).append(name)
    full = tuple((s, a) for s in sensors for a in AXES)
    return {("ingest" if chans == full else "ingest_" + "_".join(f"{s}_{a}" for s, a in chans)): (chans, names)
            for chans, names in groups.items()}


def remove_stale(roots, produced=None, rerun=(), keep=()) -> list:
    """Remove stale files and return them (sorted): the temporary files (``.tmp-*``) under `roots`; the existing
    files of `rerun` (the outputs, logs and benchmarks of the jobs about to run); and, when `produced` (every
    file the run's jobs write) is given, every file under `roots` it does not hold and no glob of `keep`
    (relative to its root) matches, then the folders left empty. `produced` None (a run of named targets): no
    walk."""
    from imupipe.io import remove_stale_temp

    removed = [str(p) for root in roots for p in remove_stale_temp(root)]
    for f in rerun:
        if os.path.lexists(f) and not os.path.isdir(f):
            os.remove(f)
            removed.append(str(f))
    if produced is not None:
        known = {os.path.normpath(f) for f in produced}
        for root in roots:
            for folder, _, names in os.walk(root):
                for n in names:
                    f = os.path.normpath(os.path.join(folder, n))
                    if f not in known and not any(fnmatch(os.path.relpath(f, root), k) for k in keep):
                        os.remove(f)
                        removed.append(f)
        for root in roots:  # folders left empty, deepest first
            for folder, _, _ in sorted(os.walk(root), key=lambda t: -len(t[0])):
                if folder != root and not os.listdir(folder) and not os.path.ismount(folder):
                    os.rmdir(folder)
    return sorted(removed)
