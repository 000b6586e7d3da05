# Configuration, dataset sheet and the helpers that name files. No numerics here.
import csv
import threading
from pathlib import Path

from snakemake.utils import validate


ROOT = Path(workflow.basedir)  # repository root: config paths are relative to it
AXES = ["x", "y", "z"]

validate(config, schema="../schemas/config.schema.yaml", set_default=False)

SENSORS = list(config["sensors"])
SPECS = list(config["specs"])


def repo_path(path):
    """A path from the config, relative to the repository root unless absolute."""
    p = Path(path)
    return p if p.is_absolute() else ROOT / p


def _read_sheet(path):
    """Rows of the dataset sheet (TSV) as dicts of non-empty cells, validated one by one."""
    if not path.is_file():
        raise ValueError(f"config key 'datasets': dataset sheet {str(path)!r} not found")
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh, delimiter="\t"))
    if not rows:
        raise ValueError(f"dataset sheet {str(path)!r} has no rows")
    out = {}
    for i, row in enumerate(rows, start=2):
        cells = {k.strip(): v.strip() for k, v in row.items() if k is not None and v is not None and v.strip()}
        if "rate_hz" in cells:
            try:
                cells["rate_hz"] = float(cells["rate_hz"])
            except ValueError:
                raise ValueError(f"{path}, line {i}: rate_hz = {cells['rate_hz']!r} is not a number (Hz)")
        try:
            validate(cells, schema="../schemas/datasets.schema.yaml", set_default=False)
        except Exception as exc:
            raise ValueError(f"{path}, line {i}: {exc}")
        name = cells["dataset"]
        if name in out:
            raise ValueError(f"{path}, line {i}: dataset {name!r} appears twice")
        missing = [f"{s}_{a}" for s in SENSORS for a in AXES if f"{s}_{a}" not in cells]
        if missing:
            raise ValueError(f"{path}, line {i}: dataset {name!r} has no column for {', '.join(missing)}"
                             f" (config sensors: {SENSORS})")
        out[name] = cells
    return out


SIMULATION = config.get("simulation")
if SIMULATION and config.get("datasets"):
    raise ValueError("config: give either 'datasets' (a sheet of recordings) or 'simulation', not both")
if not SIMULATION and not config.get("datasets"):
    raise ValueError("config: neither 'datasets' nor 'simulation' is set: nothing to process")

if SIMULATION:
    DATASETS = {
        f"sim{i + 1:02d}": {
            "dataset": f"sim{i + 1:02d}",
            "path": f"data/simulated/sim{i + 1:02d}.nc",
            "format": "netcdf",
            "rate_hz": float(SIMULATION["rate_hz"]),
            "gyro_unit": "rad/s",
            "accel_unit": "m/s^2",
            **{f"{s}_{a}": f"{s}_{a}" for s in ("gyro", "accel") for a in AXES},
        }
        for i in range(SIMULATION["n_datasets"])
    }
    SIM_SEEDS = {name: SIMULATION["seed"] + i for i, name in enumerate(DATASETS)}
else:
    DATASETS = _read_sheet(repo_path(config["datasets"]))


wildcard_constraints:
    dataset="|".join(DATASETS),
    sensor="gyro|accel",
    axis="x|y|z",
    spec="|".join(SPECS),


def _check_specs():
    """Read every spec sheet once at start-up: a missing sheet or a value without a valid unit stops the run
    before any job, naming the file and the key (the bound jobs would otherwise fail one by one)."""
    from imupipe.specsheet import load_spec

    for name in SPECS:
        sheet = load_spec(repo_path(config.get("spec_dir", "config/specs")) / f"{name}.yaml")
        missing = [s for s in SENSORS if s not in sheet.models]
        if missing:
            raise ValueError(f"spec sheet {sheet.path}: no section for {', '.join(missing)} (config sensors: {SENSORS})")


_check_specs()


def raw_input(wildcards):
    """The recording of a dataset, declared as input only if it exists (a missing file fails its
    own ingest job with a clear message instead of blocking the whole DAG)."""
    row = DATASETS[wildcards.dataset]
    if SIMULATION:
        return {"raw": row["path"]}
    p = repo_path(row["path"])
    return {"raw": str(p)} if p.exists() else {}


def sheet_row(wildcards):
    return DATASETS[wildcards.dataset]


def spec_file(wildcards):
    return str(repo_path(config.get("spec_dir", "config/specs")) / f"{wildcards.spec}.yaml")


def axis_files(pattern):
    """Input function: pattern for every dataset and axis of the job's sensor."""

    def _files(wildcards):
        return expand(pattern, dataset=list(DATASETS), sensor=wildcards.sensor, axis=AXES)

    return _files


def axis_files_out(pattern):
    """Output list: pattern for every dataset and axis (other wildcards kept as {{...}} in `pattern`)."""
    return expand(pattern, dataset=list(DATASETS), axis=AXES)


def channel_files(pattern):
    """Output list: pattern for every sensor and axis (other wildcards kept as {{...}} in `pattern`)."""
    return expand(pattern, sensor=SENSORS, axis=AXES)


def simulation_seed(wildcards):
    return SIM_SEEDS[wildcards.dataset]


def final_outputs():
    # Per-axis outputs are asked for too: Snakemake re-runs a job for a missing output only when some job asks
    # for that output, so a dataset added to the sheet must show up here to re-run the per-sensor merges.
    per_axis = dict(dataset=list(DATASETS), sensor=SENSORS, axis=AXES)
    out = expand("results/stationarity/{dataset}/{sensor}/{axis}.yaml", **per_axis)
    out += expand("results/bound/{spec}/axes/{dataset}/{sensor}/{axis}.yaml", spec=SPECS, **per_axis)
    out += expand("results/spectra/{sensor}.nc", sensor=SENSORS)
    out += expand("results/allan/{sensor}.nc", sensor=SENSORS)
    out += expand("results/identify/{sensor}.yaml", sensor=SENSORS)
    out += expand("results/bound/{spec}/{sensor}.yaml", spec=SPECS, sensor=SENSORS)
    out += expand("results/kf/{spec}/{sensor}.yaml", spec=SPECS, sensor=SENSORS)
    if set(SENSORS) == {"gyro", "accel"}:
        out += expand("results/kf/{spec}/kalibr_imu.yaml", spec=SPECS)
    out += expand(
        "results/figures/{spec}/{fig}_{sensor}.png",
        spec=SPECS,
        fig=["psd_bound", "allan_components", "inflation_steps"],
        sensor=SENSORS,
    )
    out += ["results/figures/inflation_effect.png"]
    out += expand("results/tables/{spec}/inflation.md", spec=SPECS)
    return out


def cancel_pending_timers():
    """Cancel the threading.Timer threads still waiting in this process (see onsuccess in the Snakefile)."""
    for thread in threading.enumerate():
        if isinstance(thread, threading.Timer):
            thread.cancel()
