# Configuration, dataset sheet and the helpers that name files. No numerics here.
#
# Folders: every output of a run lies under results/{name}/ and its log under logs/{name}/ (`name`: top-level
# config key), so runs of different configurations side by side do not overwrite each other. Paths are
# relative to the working directory (the repository root, or --directory); files of the repository that the
# config names (spec sheets, truth model, dataset sheet, recordings) are given relative to the working
# directory too, so a checkout moved or copied elsewhere with its results re-runs nothing.
import csv
import os
import re
from pathlib import Path

import yaml
from snakemake.utils import validate


ROOT = Path(workflow.basedir)  # repository root: config paths are relative to it
AXES = ["x", "y", "z"]
DEFAULT_CONFIG = ROOT / "config" / "config.yaml"


def _apply_defaults():
    """Snakemake reads --configfile instead of the Snakefile's configfile: put the given keys on top of
    config/config.yaml, then validate."""
    from imupipe.io import merged_with_defaults

    with open(DEFAULT_CONFIG) as fh:
        merged = merged_with_defaults(yaml.safe_load(fh), dict(config))
    config.clear()
    config.update(merged)


_apply_defaults()
validate(config, schema="../schemas/config.schema.yaml", set_default=False)

# The KF export runs at application.rate_hz; the verification (and so any reduction it accepted) ran its reference
# filter at verify.filter_rate_hz. A reduction verified at another rate is not verified for the exported filter:
# said at start-up here, and in the KF file, the contract and the run summary (rate_mismatch).
if abs(float(config["verify"]["filter_rate_hz"]) - float(config["application"]["rate_hz"])) > 1e-9 * float(
        config["application"]["rate_hz"]):
    import sys as _sys

    print(f"imupipe warning: verify.filter_rate_hz = {config['verify']['filter_rate_hz']} Hz differs from "
          f"application.rate_hz = {config['application']['rate_hz']} Hz (the KF export's rate): the verification "
          "and any state reduction it accepts hold at the verification rate, not at the exported filter's; set "
          "verify.filter_rate_hz to application.rate_hz (a divisor of the records' rate) to verify the exported "
          "filter itself; until then the contract fails its export_rate check (not verified)", file=_sys.stderr)

# The replay check of the verification runs the reference filter on the records block-averaged to its rate: each
# record's rate must be a whole multiple of verify.filter_rate_hz (checked per record in _check_records below).

# Fixes every m filter steps: m = verify.filter_rate_hz / verify.fix_rate_hz must be a whole number >= 1.
if config["verify"].get("fix_rate_hz") is not None:
    _m = float(config["verify"]["filter_rate_hz"]) / float(config["verify"]["fix_rate_hz"])
    if _m < 1.0 - 1e-9 or abs(_m - round(_m)) > 1e-9 * _m:
        raise ValueError(f"config: verify.fix_rate_hz = {config['verify']['fix_rate_hz']} Hz must divide "
                         f"verify.filter_rate_hz = {config['verify']['filter_rate_hz']} Hz (a fix every whole number "
                         "of filter steps); e.g. fix_rate_hz 1 with filter_rate_hz 100, or null for a fix every step")

NAME = config["name"]
RESULTS = f"results/{NAME}"
LOGS = f"logs/{NAME}"
BENCHMARKS = f"{RESULTS}/benchmarks"
SENSORS = list(config["sensors"])
SPECS = list(config["specs"])


def repo_path(path):
    """A path the config names (relative to the repository root unless absolute), as Snakemake should see it:
    relative to the working directory when it lies below a common folder, else absolute."""
    p = Path(path)
    p = p if p.is_absolute() else ROOT / p
    return os.path.relpath(p) if _shares_root(p) else str(p)


def _shares_root(p):
    cwd = Path.cwd().resolve()
    try:
        target = str(p.resolve())
    except (RuntimeError, OSError):  # a symbolic link loop: its ingest job names it
        target = os.path.abspath(p)
    try:
        return os.path.commonpath([target, str(cwd)]) != os.sep
    except ValueError:
        return False


def _read_sheet(path):
    """Rows of the dataset sheet (TSV) as dicts of non-empty cells, validated one by one: the header (no
    duplicated column), each dataset name (it names folders), each row against the sheet schema, and the
    channel columns of the configured sensors (a sensor names one, two or three axes, or none: then the
    file's own gyro_x ... columns, or a bag's sensor_msgs/Imu fields, give all three)."""
    from imupipe.readers import DataError, check_sheet_header, validate_dataset_name

    path = Path(path)
    if not path.is_file():
        raise ValueError(f"config key 'datasets': dataset sheet {str(path)!r} not found")
    try:
        check_sheet_header(path)
    except DataError as exc:
        raise ValueError(str(exc)) from None
    with open(path, newline="", encoding="utf-8-sig") as fh:
        lines = [line for line in fh if not line.lstrip().startswith("#")]
    rows = list(csv.DictReader(lines, delimiter="\t"))
    if not rows:
        raise ValueError(f"dataset sheet {str(path)!r} has no rows")
    out = {}
    for i, row in enumerate(rows, start=2):
        if None in row:
            raise ValueError(f"{path}, line {i}: {len(row[None])} more cell(s) than the header has columns"
                             f" ({len(row) - 1}); expected one cell per header column")
        cells = {k.strip(): v.strip() for k, v in row.items() if k is not None and v is not None and v.strip()}
        try:
            validate_dataset_name(cells.get("dataset"), where=f"{path}, line {i}")
        except DataError as exc:
            raise ValueError(str(exc)) from None
        for key, kind, what in (("rate_hz", float, "a number (Hz)"), ("fill_max_samples", int, "an integer (samples)"),
                                ("fill_max_s", float, "a number (s)"),
                                ("fill_max_fraction", float, "a number (fraction of the record)")):
            if key in cells:
                try:
                    cells[key] = kind(cells[key])
                except ValueError:
                    raise ValueError(f"{path}, line {i}: {key} = {cells[key]!r} is not {what}") from None
        try:
            validate(cells, schema="../schemas/datasets.schema.yaml", set_default=False)
        except Exception as exc:
            first = str(exc).splitlines()[0]
            raise ValueError(f"{path}, line {i} (dataset {cells.get('dataset')!r}): {first}") from None
        name = cells["dataset"]
        if name in out:
            raise ValueError(f"{path}, line {i}: dataset {name!r} appears twice")
        out[name] = cells
    return out


def _axes_of_row(cells):
    """{sensor: axes} of one dataset: the axes whose column the sheet names; a sensor naming none takes all
    three (the file's default column names or a bag's sensor_msgs/Imu fields)."""
    axes = {}
    for s in SENSORS:
        given = [a for a in AXES if f"{s}_{a}" in cells]
        axes[s] = given or list(AXES)
    return axes


SIMULATION = config.get("simulation")
if SIMULATION and config.get("datasets"):
    raise ValueError("config: give either 'datasets' (a sheet of recordings) or 'simulation', not both")
if not SIMULATION and not config.get("datasets"):
    raise ValueError("config: neither 'datasets' nor 'simulation' is set: nothing to process")

if SIMULATION:
    DATASETS = {
        f"sim{i + 1:02d}": {
            "dataset": f"sim{i + 1:02d}",
            "path": f"{RESULTS}/simulated/sim{i + 1:02d}.nc",
            "format": "netcdf",
            "rate_hz": float(SIMULATION["rate_hz"]),
            "gyro_unit": "rad/s",
            "accel_unit": "m/s^2",
            # a simulation without gravity (gravity_axis: null) has none to check
            **({"gravity_removed": "yes"} if SIMULATION.get("gravity_axis", "z") is None else {}),
            **{f"{s}_{a}": f"{s}_{a}" for s in ("gyro", "accel") for a in AXES},
        }
        for i in range(SIMULATION["n_datasets"])
    }
    SIM_SEEDS = {name: SIMULATION["seed"] + i for i, name in enumerate(DATASETS)}
else:
    # recording paths of the sheet are relative to the repository root: rewritten relative to the working
    # directory here, so the ingest job reads them as they are
    DATASETS = {
        name: {**row, "path": repo_path(row["path"])} for name, row in _read_sheet(repo_path(config["datasets"])).items()
    }


# Axes of each dataset and sensor: {dataset: {sensor: [axis, ...]}} (the sheet's channel columns; a simulation
# has all three). Every helper naming per-axis files uses these.
AXES_OF = {name: _axes_of_row(row) for name, row in DATASETS.items()}


def channels_of(dataset):
    """The (sensor, axis) channels of a dataset, sensor-major."""
    return [(s, a) for s in SENSORS for a in AXES_OF[dataset][s]]


def _check_records():
    """Start-up check of every record against the config (issue 19: once, before any job, naming the key):
    the record is long enough for `psd.window_s`, its rate divides into `decimate.rate_hz`, the decimated
    record fills `stationarity.n_segments`. The metadata come from a cheap probe of each file (header, row
    count, rate; no samples for netCDF/npy). A file that cannot be probed is left to its own ingest job,
    which fails that dataset alone with the reader's message; a config mismatch stops the run here, with
    every dataset's message at once."""
    from imupipe.readers import ConfigError, check_against_config, probe_row

    problems, durations = [], []
    psd_rule = config["psd"]["window_s"] is None or config["psd"]["step_s"] is None
    for name, row in DATASETS.items():
        if SIMULATION:
            rate = float(SIMULATION["rate_hz"])
            n = int(round(float(SIMULATION["duration_h"]) * 3600.0 * rate))
            meta = {"rate_hz": rate, "n_samples": n, "duration_s": n / rate}
        else:
            try:
                meta = probe_row(row)
            except Exception:  # noqa: BLE001 (any failure of the cheap probe: the ingest job reads the file
                continue  # and reports it with the reader's message, for this dataset only)
        rate_known = (meta["rate_hz"] if isinstance(meta, dict) else meta.rate_hz) is not None
        duration = meta["duration_s"] if isinstance(meta, dict) else meta.duration_s
        if duration is not None:
            durations.append(float(duration))
        try:  # a rate only the timestamps give (no rate_hz cell) is checked by the decimate job
            check_against_config(meta, window_s=config["psd"]["window_s"],
                                 decimate_rate_hz=config["decimate"]["rate_hz"] if rate_known else None,
                                 n_segments=config["stationarity"]["n_segments"], dataset=name)
        except ConfigError as exc:
            problems.append(str(exc))
        rate = meta["rate_hz"] if isinstance(meta, dict) else meta.rate_hz
        if rate is not None:
            m = float(rate) / float(config["verify"]["filter_rate_hz"])
            if m < 1.0 - 1e-9 or abs(m - round(m)) > 1e-9 * m:
                problems.append(f"{name}: record rate {float(rate):g} Hz is not a whole multiple of "
                                f"verify.filter_rate_hz = {config['verify']['filter_rate_hz']} Hz (the verification "
                                "replays each record block-averaged to the reference filter's rate); set "
                                "verify.filter_rate_hz to the record rate or a divisor of it")
    if problems:
        raise ValueError("records do not fit the config:\n  " + "\n  ".join(problems))
    if psd_rule:  # unset psd.window_s / psd.step_s: the rule of imupipe.defaults.psd_window_step on the
        # shortest record, one window for every record (the bound needs one frequency grid)
        from imupipe.defaults import psd_window_step

        if not durations:
            raise ValueError("psd.window_s / psd.step_s unset and no record's duration could be probed: "
                             "set both in the config (e.g. window_s = a quarter of the shortest record, step_s = half that)")
        w, st = psd_window_step(min(durations), float(config["decimate"]["rate_hz"]))
        if config["psd"]["window_s"] is None:
            config["psd"]["window_s"] = w
        if config["psd"]["step_s"] is None:
            config["psd"]["step_s"] = st if config["psd"]["window_s"] == w else config["psd"]["window_s"] / 2.0


_check_records()


wildcard_constraints:
    dataset="|".join(re.escape(n) for n in DATASETS),
    sensor="gyro|accel",
    axis="x|y|z",
    spec="|".join(SPECS),
    kind="spectra|allan",


def _check_specs():
    """Read every spec sheet once at start-up: a missing sheet or a value without a valid unit stops the run
    before any job, naming the file and the key (the bound jobs would otherwise fail one by one)."""
    from imupipe.specsheet import load_spec

    for name in SPECS:
        sheet = load_spec(Path(config["spec_dir"]) / f"{name}.yaml" if Path(config["spec_dir"]).is_absolute()
                          else ROOT / config["spec_dir"] / f"{name}.yaml")
        missing = [s for s in SENSORS if s not in sheet.models]
        if missing:
            raise ValueError(f"spec sheet {sheet.path}: no section for {', '.join(missing)} (config sensors: {SENSORS})")


_check_specs()


# ---------------------------------------------------------------------------------------------------------
# input functions and parameters (named, no lambdas in the rules)


def raw_input(wildcards):
    """The recording of a dataset, declared as input only if it exists (a missing file fails its own ingest
    job with a clear message instead of blocking the whole DAG)."""
    path = DATASETS[wildcards.dataset]["path"]
    return {"raw": path} if SIMULATION or Path(path).exists() else {}


def sheet_row(wildcards):
    """The dataset sheet's row of the job's dataset (recording path relative to the working directory)."""
    return DATASETS[wildcards.dataset]


def truth_file():
    """The simulation's true noise model (spec-sheet format), or nothing for real data."""
    return repo_path(SIMULATION["truth"]) if SIMULATION else []


def simulation_param(key, scale=1.0):
    """A key of the simulation section (times `scale`), None for real data."""
    if not SIMULATION:
        return None
    value = SIMULATION.get(key, "z" if key == "gravity_axis" else None)
    return float(value) * scale if isinstance(value, (int, float)) and not isinstance(value, bool) else value


def simulation_seed(wildcards):
    return SIM_SEEDS[wildcards.dataset]


def spec_file(wildcards):
    return repo_path(Path(config["spec_dir"]) / f"{wildcards.spec}.yaml")


def per_axis_files(folder, ext, sensor, prefix=""):
    """results/{name}/{folder}/{prefix}{dataset}/{sensor}/{axis}.{ext} of every dataset and each of its axes of
    `sensor` (the sheet's), dataset-major (the order of the stacked files' curves)."""
    return [f"{RESULTS}/{folder}/{prefix}{d}/{sensor}/{a}.{ext}" for d in DATASETS for a in AXES_OF[d][sensor]]


def per_axis(folder, ext):
    """Input function: per_axis_files of the job's sensor."""

    def files(wildcards):
        return per_axis_files(folder, ext, wildcards.sensor)

    return files


def stack_inputs(wildcards):
    """The per-axis files a stacked file gathers (psd/ for spectra, allan/ for allan) and the verdict summary."""
    folder = "psd" if wildcards.kind == "spectra" else "allan"
    return {"curves": per_axis(folder, "nc")(wildcards), "summary": f"{RESULTS}/stationarity/{wildcards.sensor}.yaml"}


def stack_join(wildcards):
    """PSDs of one configuration share their frequencies (exact); AV grids of records of different lengths
    do not (outer join, missing entries NaN)."""
    return "exact" if wildcards.kind == "spectra" else "outer"


def axis_bounds_of(wildcards):
    """The per-axis bounds of the job's spec sheet and sensor, every dataset and each of its axes."""
    return per_axis_files(f"bound/{wildcards.spec}", "yaml", wildcards.sensor, prefix="axes/")


def bounds_of_sensors(wildcards):
    return {s: f"{RESULTS}/bound/{wildcards.spec}/{s}.yaml" for s in SENSORS}


# Targets that the stage files included after this one add to `rule all` (each stage file extends it
# with its own outputs, so a new stage needs no edit here).
EXTRA_TARGETS = []
# Files the run summary reads, by kind (stage files add theirs: SUMMARY_INPUTS["contract"] = [...]).
SUMMARY_INPUTS = {}


def final_outputs():
    # Per-axis outputs are asked for too: Snakemake re-runs a job for a missing output only when some job asks
    # for that output, so a dataset added to the sheet must show up here to re-run the per-sensor merges.
    out = [f for s in SENSORS for f in per_axis_files("stationarity", "yaml", s)]
    out += [f for p in SPECS for s in SENSORS for f in per_axis_files(f"bound/{p}", "yaml", s, prefix="axes/")]
    out += expand(f"{RESULTS}/{{kind}}/{{sensor}}.nc", kind=["spectra", "allan"], sensor=SENSORS)
    out += expand(f"{RESULTS}/identify/{{sensor}}.yaml", sensor=SENSORS)
    out += expand(f"{RESULTS}/bound/{{spec}}/{{sensor}}.yaml", spec=SPECS, sensor=SENSORS)
    out += expand(f"{RESULTS}/kf/{{spec}}/{{sensor}}.yaml", spec=SPECS, sensor=SENSORS)
    if set(SENSORS) == {"gyro", "accel"}:
        out += expand(f"{RESULTS}/kf/{{spec}}/kalibr_imu.yaml", spec=SPECS)
    out += expand(
        f"{RESULTS}/figures/{{spec}}/{{fig}}_{{sensor}}.png",
        spec=SPECS,
        fig=["psd_bound", "allan_components", "inflation_steps"],
        sensor=SENSORS,
    )
    out += [f"{RESULTS}/figures/inflation_effect.png"]
    out += expand(f"{RESULTS}/tables/{{spec}}/inflation.md", spec=SPECS)
    return out + EXTRA_TARGETS


# ---------------------------------------------------------------------------------------------------------
# resources per job: peak memory (MB) and wall time (min). Measured (benchmark files' max_rss, default run:
# 5 x 10 h at 125 Hz, one axis = 36 MB of float64 samples, 2 loaded cores; python benchmarks/dag.py):
# ingest 275 MB (a 216 MB recording), allan 115, decimate 95, psd 82, stationarity 187, stationarity_summary 26,
# stack 73, identify 114, bound_axis 119, bound 128, kf 69, kalibr 44, figures 141, inflation_effect 91,
# tables 44; longest job 14 s. Per-axis and per-dataset jobs at 10 h / 40 h (one dataset, one axis = 36 / 144
# MB; python benchmarks/axis_memory.py, the larger of max_rss and the sampled VmHWM): ingest 109 / 217 MB,
# allan 124 / 231, decimate 101 / 210, psd 89 / 90, stationarity 177 / 299 (its calibrated null grows with the
# record), lines 130 / 244, outliers 130 / 240, simulate 573 / 2085. The jobs that hold full-rate samples get a
# fixed overhead plus a multiple of their input's size (ingest: per channel written; allan, decimate, lines,
# outliers: one axis); the others about twice the measured peak. Wall time: 10 min, plus 1 min per 20 MB of
# full-rate input, far above the measured times.
MEM_MB = {
    "psd": 200,
    "stationarity": 800,
    "stationarity_summary": 100,
    "stack": 200,
    "identify": 300,
    "bound_axis": 300,
    "bound": 300,
    "kf": 200,
    "kalibr": 100,
    "figures": 300,
    "inflation_effect": 200,
    "tables": 100,
}
RUNTIME_MIN = {name: 10 for name in [*MEM_MB, "simulate"]}


def ingest_rule_groups():
    """Rule name -> (channels, datasets): the datasets sharing one set of channels share one ingest rule
    (ingest.smk): `ingest` for every axis of every configured sensor, `ingest_<channels>` otherwise."""
    groups = {}
    for name in DATASETS:
        groups.setdefault(tuple(channels_of(name)), []).append(name)
    full = tuple((s, a) for s in SENSORS for a in AXES)
    return {
        ("ingest" if chans == full else "ingest_" + "_".join(f"{s}_{a}" for s, a in chans)): (chans, names)
        for chans, names in groups.items()
    }


def ingest_params(wildcards):
    """Reader settings of the job: the psd.window_s minimum record length is checked at start-up
    (common.smk, _check_records); ingest names that key too if a record read shorter than probed."""
    return {"min_duration_s": float(config["psd"]["window_s"]), "min_duration_key": "psd.window_s"}


def simulate_mem_mb(wildcards):
    """The simulation's work arrays (measured 12.8 x one axis's samples at 40 h): 200 MB + 14 x one axis."""
    return int(200 + 14 * 8e-6 * SIMULATION["duration_h"] * 3600.0 * SIMULATION["rate_hz"]) if SIMULATION else 200


def ingest_mem_mb(wildcards, input):
    """netCDF and npy/npz records are read one channel at a time (ingest.py, readers.read_channel): 100 MB + 3.5
    x the file size per channel written (measured peak at 125 Hz without a time column: 109 MB at 10 h, 217 MB
    at 40 h = 73 MB + one axis; a time column adds its samples, 2 x one axis in all; an
    over-estimate when the file holds more variables than the dataset writes). Text records are parsed once
    per channel, R and bag records whole: 100 MB + 2 x the file size."""
    size = input.size_mb
    fmt = str(DATASETS[wildcards.dataset].get("format", "auto")).lower()
    suffix = Path(DATASETS[wildcards.dataset]["path"]).suffix.lower()
    if SIMULATION or fmt in ("netcdf", "nc", "npy", "npz") or (fmt == "auto" and suffix in (".nc", ".nc4", ".cdf", ".npy", ".npz")):
        return int(100 + 3.5 * size / max(1, len(channels_of(wildcards.dataset))))
    return int(100 + 2 * size)


def axis_mem_mb(wildcards, input):
    """One full-rate axis (and its integral, in the same buffer): 80 MB + 2 x the axis file's size."""
    return int(80 + 2 * input.size_mb)


def full_rate_runtime(wildcards, input):
    """10 min plus 1 min per 20 MB of full-rate input."""
    return int(10 + input.size_mb / 20)


# ---------------------------------------------------------------------------------------------------------
# Nothing stale (docs/inputs.md, "Stale outputs"): the Snakefile's onstart handler calls on_start(), its
# onsuccess and onerror handlers on_finish(). When the run builds the default target (rule all), every file
# under results/{name}/ and logs/{name}/ that no job of this run's DAG writes (a spec, dataset, sensor or
# axis no longer configured) is removed, and so are the existing outputs of every job that will run: a job
# downstream of one that fails then leaves no file that looks complete. A run of named targets only removes
# the outputs of the jobs it runs. Temporary files (.tmp-*) of killed jobs are removed at start and at end.
# Files a stage writes outside the DAG's jobs are kept by adding glob patterns (relative to results/{name}/
# or logs/{name}/) to KEEP_UNDER_RESULTS.
KEEP_UNDER_RESULTS = []


def _job_files(job):
    files = [str(f) for f in job.output]
    files += [str(f) for f in job.log]
    if job.benchmark:
        files.append(str(job.benchmark))
    return files


def _is_kept(path, root):
    from fnmatch import fnmatch

    rel = os.path.relpath(path, root)
    return any(fnmatch(rel, pattern) for pattern in KEEP_UNDER_RESULTS)


def on_start():
    """Remove temporary files, the outputs this run does not produce and the outputs of the jobs that will
    run; log each removed file (Snakemake's log)."""
    from snakemake.logging import logger

    from imupipe.io import remove_stale_temp

    removed = [str(p) for root in (RESULTS, LOGS) for p in remove_stale_temp(root)]
    dag = workflow.dag
    jobs = list(dag.jobs)
    rerun = set(dag.needrun_jobs())
    for job in rerun:
        for f in _job_files(job):
            if os.path.lexists(f) and not os.path.isdir(f):
                os.remove(f)
                removed.append(f)
    if any(job.rule.name == "all" for job in jobs):
        produced = {os.path.normpath(f) for job in jobs for f in _job_files(job)}
        for root in (RESULTS, LOGS):
            for folder, _, names in os.walk(root):
                for n in names:
                    f = os.path.normpath(os.path.join(folder, n))
                    if f not in produced and not _is_kept(f, root):
                        os.remove(f)
                        removed.append(f)
        for root in (RESULTS, LOGS):  # folders left empty
            for folder, subdirs, names in sorted(os.walk(root), key=lambda t: -len(t[0])):
                if folder != root and not os.listdir(folder) and not os.path.ismount(folder):
                    os.rmdir(folder)
    for f in sorted(removed):
        logger.info(f"imupipe: removed {f} (stale: not produced by this run's config, or re-made by this run)")
    if removed:
        logger.info(f"imupipe: removed {len(removed)} stale file(s) under {RESULTS} and {LOGS}")


def on_finish():
    """Remove temporary files left by killed jobs (success or error)."""
    from imupipe.io import remove_stale_temp

    for root in (RESULTS, LOGS):
        remove_stale_temp(root)
