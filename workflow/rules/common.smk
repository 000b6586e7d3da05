# Configuration, datasets and the names of files: the values come from imupipe.runconfig (config merge and
# validation, dataset sheet, start-up probe of the records, spec sheets, stale-output clean-up); this file keeps
# the names, input functions and resources the rules use. No numerics here.
#
# Folders: every output of a run lies under results/{name}/ and its log under logs/{name}/ (`name`: top-level
# config key), so runs of different configurations side by side do not overwrite each other. Paths are relative
# to the working directory (the repository root, or --directory); files of the repository that the config names
# (spec sheets, truth model, dataset sheet, recordings) are given relative to the working directory too, so a
# checkout moved or copied elsewhere with its results re-runs nothing.
import os
import re
from pathlib import Path

from imupipe import runconfig as rc
from imupipe.stages.summary import end_of_run_text

ROOT = Path(workflow.basedir)  # repository root: config paths are relative to it
AXES = list(rc.AXES)
# Snakemake reads --configfile instead of the Snakefile's configfile: the given keys on top of config/config.yaml
_merged = rc.load_config(dict(config), ROOT)
config.clear()
config.update(_merged)

NAME = config["name"]
RESULTS, LOGS = f"results/{NAME}", f"logs/{NAME}"
BENCHMARKS = f"{RESULTS}/benchmarks"
SENSORS, SPECS = list(config["sensors"]), list(config["specs"])
SIMULATION = config.get("simulation")
DATASETS = rc.datasets_of(config, ROOT, RESULTS)
SIM_SEEDS = rc.simulation_seeds(SIMULATION)
AXES_OF = rc.axes_of(DATASETS, SENSORS)  # {dataset: {sensor: [axis, ...]}}: every per-axis file name uses these
for _warning in rc.check_records(config, DATASETS):  # once, before any job; sets psd.window_s / step_s when unset
    from snakemake.logging import logger as _logger

    _logger.warning(f"imupipe warning: {_warning}")
rc.check_specs(config, ROOT)

SPAN_S = rc.span_s(config)  # verify.fix_s + application.outage_s: the bound holds down to 0.01 / SPAN_S
FILTER_RATE_HZ = config["application"]["filter_rate_hz"]  # as written (the params echo it)
OUTAGE_S = config["application"]["outage_s"]
LINES_PARAMS = rc.lines_params(config)
REPLAY_FROM_DECIMATED = rc.replay_from_decimated(config)
KALIBR_RATES = rc.sheet_column(DATASETS, "rate_hz", float)
KALIBR_TOPICS = rc.sheet_column(DATASETS, "topic")
FIGURES = config["figures"]
FIG_FORMAT = FIGURES["format"]
FIG_NAMES = ["psd_bound", "allan_components", "inflation_steps", "allan_readoffs"]
SUMMARY_MD = f"{RESULTS}/summary.md"
# the report's first page: workflow/report/workflow.rst followed by the summary, written by rule summary
REPORT_FRONT = f"{RESULTS}/report/workflow.rst"
VERDICT = f"{RESULTS}/contract/verdict.yaml"


wildcard_constraints:
    dataset="|".join(re.escape(n) for n in DATASETS),
    sensor="gyro|accel",
    axis="x|y|z",
    spec="|".join(SPECS),
    kind="spectra|allan",


# ---------------------------------------------------------------------------------------------------------
# input functions and parameters (named, no lambdas in the rules)


def repo_path(path):
    return rc.repo_path(path, ROOT)


def raw_input(wildcards):
    """The recording, declared as input only if it exists (a missing file fails its own ingest job)."""
    path = DATASETS[wildcards.dataset]["path"]
    return {"raw": path} if SIMULATION or Path(path).exists() else {}


def sheet_row(wildcards):
    return DATASETS[wildcards.dataset]


def truth_file(wildcards=None):
    """The simulation's true noise model (spec-sheet format), or nothing for real data."""
    return repo_path(SIMULATION["truth"]) if SIMULATION else []


def simulation_param(key, scale=1.0):
    """A key of the simulation section (times `scale`), None for real data."""
    value = SIMULATION.get(key, "z" if key == "gravity_axis" else None) if SIMULATION else None
    return float(value) * scale if isinstance(value, (int, float)) and not isinstance(value, bool) else value


def simulation_seed(wildcards):
    return SIM_SEEDS[wildcards.dataset]


def spec_file(wildcards):
    return repo_path(Path(config["spec_dir"]) / f"{wildcards.spec}.yaml")


def channels_of(dataset):
    return [(s, a) for s in SENSORS for a in AXES_OF[dataset][s]]


def per_axis_files(folder, ext, sensor, prefix=""):
    """{RESULTS}/{folder}/{prefix}{dataset}/{sensor}/{axis}.{ext} of every dataset and axis, dataset-major."""
    return [f"{RESULTS}/{folder}/{prefix}{d}/{sensor}/{a}.{ext}" for d in DATASETS for a in AXES_OF[d][sensor]]


def per_axis(folder, ext):
    def files(wildcards):
        return per_axis_files(folder, ext, wildcards.sensor)

    return files


def stack_inputs(wildcards):
    folder = "psd" if wildcards.kind == "spectra" else "allan"
    return {"curves": per_axis(folder, "nc")(wildcards), "summary": f"{RESULTS}/stationarity/{wildcards.sensor}.yaml"}


def stack_join(wildcards):
    """PSDs of one configuration share their frequencies (exact); AV grids of different lengths do not (outer)."""
    return "exact" if wildcards.kind == "spectra" else "outer"


def axis_bounds_of(wildcards):
    return per_axis_files(f"bound/{wildcards.spec}", "yaml", wildcards.sensor, prefix="axes/")


def bounds_of_sensors(wildcards):
    """Each sensor's bound file; with bound.mode auto also its contract (which candidate is exported)."""
    out = {s: f"{RESULTS}/bound/{wildcards.spec}/{s}.yaml" for s in SENSORS}
    if config["bound"]["mode"] == "auto":
        out.update({f"contract_{s}": f"{RESULTS}/contract/{wildcards.spec}/{s}.yaml" for s in SENSORS})
    return out


def contract_if_auto(wildcards):
    """With bound.mode auto, the sensor's contract (which candidate the run exports, for the figures)."""
    if config["bound"]["mode"] != "auto":
        return {}
    return {"contract": f"{RESULTS}/contract/{wildcards.spec}/{wildcards.sensor}.yaml"}


def lines_of_sensor(wildcards):
    return {"lines": per_axis_files("lines", "yaml", wildcards.sensor)}


def lines_files_of(wildcards):
    return per_axis_files("lines", "yaml", wildcards.sensor)


def verify_records(wildcards):
    """The series the replay reads: decimated when decimate.rate_hz is a multiple of the filter rate, else full-rate
    (FULL_RATE_SERIES, outliers.smk)."""
    if REPLAY_FROM_DECIMATED:
        return per_axis("decimated", "nc")(wildcards)
    return [FULL_RATE_SERIES.format(dataset=d, sensor=wildcards.sensor, axis=a)
            for d in DATASETS for a in AXES_OF[d][wildcards.sensor]]


def copies(pattern):
    """`pattern` (with {fig}, {ext}) in figures.format for every figure, or [] for png (the PNG is always written)."""
    return [] if FIG_FORMAT == "png" else [pattern.format(fig=fig, ext=FIG_FORMAT) for fig in FIG_NAMES]


def summary_inputs(wildcards):
    return {kind: list(dict.fromkeys(paths)) for kind, paths in SUMMARY_INPUTS.items() if paths}


def verdict_inputs(wildcards):
    """Every contract, and every other target (the verdict is the last job: figures, tables, summary come first)."""
    contracts = expand(f"{RESULTS}/contract/{{spec}}/{{sensor}}.yaml", spec=SPECS, sensor=SENSORS)
    return {"contracts": contracts, "others": [t for t in final_outputs() if t != VERDICT and t not in contracts]}


def report_text():
    front = Path(REPORT_FRONT).resolve()
    return str(front) if front.is_file() else str(ROOT / "workflow" / "report" / "workflow.rst")


# Targets the stage files add to `rule all`, and the files the run summary reads by kind.
EXTRA_TARGETS = []
SUMMARY_INPUTS = {}


def final_outputs():
    # per-axis outputs too: a dataset added to the sheet must show up here to re-run the per-sensor merges
    out = [f for s in SENSORS for f in per_axis_files("stationarity", "yaml", s)]
    out += [f for p in SPECS for s in SENSORS for f in per_axis_files(f"bound/{p}", "yaml", s, prefix="axes/")]
    out += expand(f"{RESULTS}/{{kind}}/{{sensor}}.nc", kind=["spectra", "allan"], sensor=SENSORS)
    out += expand(f"{RESULTS}/identify/{{sensor}}.yaml", sensor=SENSORS)
    for folder in ("bound", "kf"):
        out += expand(f"{RESULTS}/{folder}/{{spec}}/{{sensor}}.yaml", spec=SPECS, sensor=SENSORS)
    if set(SENSORS) == {"gyro", "accel"}:
        out += expand(f"{RESULTS}/kf/{{spec}}/kalibr_imu.yaml", spec=SPECS)
    out += expand(f"{RESULTS}/figures/{{spec}}/{{fig}}_{{sensor}}.png", spec=SPECS,
                  fig=["psd_bound", "allan_components", "inflation_steps"], sensor=SENSORS)
    out += [f"{RESULTS}/figures/inflation_effect.png"]
    out += expand(f"{RESULTS}/tables/{{spec}}/inflation.md", spec=SPECS)
    return out + EXTRA_TARGETS


# ---------------------------------------------------------------------------------------------------------
# resources per job: peak memory (MB) and wall time (min). Measured (benchmark files' max_rss, default run:
# 5 x 10 h at 125 Hz, one axis = 36 MB of float64 samples; python benchmarks/dag.py and
# benchmarks/axis_memory.py; docs/performance.md): the jobs that hold full-rate samples get a fixed overhead
# plus a multiple of their input's size, the others about twice the measured peak (verify ~100 MB, contract
# and integrity ~60 MB). Wall time: 10 min, plus 1 min per 20 MB of full-rate input, far above the measured.
MEM_MB = dict(psd=200, stationarity=800, stationarity_summary=100, stack=200, identify=300, bound_axis=300, bound=300,
              kf=200, kalibr=100, figures=300, inflation_effect=200, tables=100, contract=150, integrity=150,
              summary=100, report_file=100)
RUNTIME_MIN = {name: 10 for name in [*MEM_MB, "simulate", "verify"]}


def simulate_mem_mb(wildcards):
    """The simulation's work arrays (measured 12.8 x one axis's samples at 40 h): 200 MB + 14 x one axis."""
    if not SIMULATION:
        return 200
    return int(200 + 14 * 8e-6 * SIMULATION["duration_h"] * 3600.0 * SIMULATION["record_rate_hz"])


def ingest_mem_mb(wildcards, input):
    """netCDF and npy/npz records are read one channel at a time: 100 MB + 3.5 x the file size per channel
    written (measured 109 MB at 10 h, 217 MB at 40 h, 125 Hz); text, R and bag records: 100 MB + 2 x the file."""
    fmt = str(DATASETS[wildcards.dataset].get("format", "auto")).lower()
    suffix = Path(DATASETS[wildcards.dataset]["path"]).suffix.lower()
    by_channel = fmt in ("netcdf", "nc", "npy", "npz") or (fmt == "auto" and suffix in (".nc", ".nc4", ".cdf", ".npy", ".npz"))
    if SIMULATION or by_channel:
        return int(100 + 3.5 * input.size_mb / max(1, len(channels_of(wildcards.dataset))))
    return int(100 + 2 * input.size_mb)


def axis_mem_mb(wildcards, input):
    """One full-rate axis and its integral (measured 124 MB at 10 h, 231 at 40 h): 80 MB + 2 x the axis file."""
    return int(80 + 2 * input.size_mb)


def full_rate_runtime(wildcards, input):
    return int(10 + input.size_mb / 20)


def verify_mem_mb(wildcards, input):
    """300 MB, plus (replay from full-rate series) 2 x the largest file + the records' total at the filter rate."""
    if REPLAY_FROM_DECIMATED:
        return 300
    sizes = [os.path.getsize(f) / 1e6 for f in input.records if os.path.exists(f)]
    return int(300 + 2 * max(sizes, default=0.0) + sum(sizes))


MEM_MB["verify"] = verify_mem_mb


# ---------------------------------------------------------------------------------------------------------
# Nothing stale (docs/inputs.md, "Stale outputs"; imupipe.runconfig.remove_stale): at start, temporary files
# (.tmp-*) and the outputs of every job that will run are removed and, when the run builds rule all, every file
# under results/{name}/ and logs/{name}/ that no job of this DAG writes. Globs (relative to results/{name}/ or
# logs/{name}/) in KEEP_UNDER_RESULTS are kept. At the end temporary files of killed jobs are removed.
KEEP_UNDER_RESULTS = []


def _job_files(job):
    return [str(f) for f in job.output] + [str(f) for f in job.log] + ([str(job.benchmark)] if job.benchmark else [])


def on_start():
    from snakemake.logging import logger

    jobs = list(workflow.dag.jobs)
    whole = any(job.rule.name == "all" for job in jobs)
    removed = rc.remove_stale((RESULTS, LOGS), produced=[f for j in jobs for f in _job_files(j)] if whole else None,
                              rerun=[f for j in workflow.dag.needrun_jobs() for f in _job_files(j)],
                              keep=KEEP_UNDER_RESULTS)
    for f in removed:
        logger.info(f"imupipe: removed {f} (stale: not produced by this run's config, or re-made by this run)")
    if removed:
        logger.info(f"imupipe: removed {len(removed)} stale file(s) under {RESULTS} and {LOGS}")


def on_finish():
    rc.remove_stale((RESULTS, LOGS))


def print_summary(failed=False):
    """The run summary on the terminal; never raises (a handler must not hide the run's own error)."""
    try:
        text = end_of_run_text(RESULTS, LOGS, SUMMARY_MD, failed)
        if text:
            print(text, flush=True)
    except Exception as exc:  # pragma: no cover - a broken summary must not mask the run's status
        print(f"(run summary unavailable: {exc})", flush=True)


# events.policy split (SPLIT and SEGMENTS_FILE: outliers.smk, read when the DAG is built)
def verify_segments(wildcards):
    """The segments files of the full-rate records the replay reads (split, replay not from the decimated series,
    whose files carry their segments); [] otherwise."""
    if not SPLIT or REPLAY_FROM_DECIMATED:
        return []
    return [SEGMENTS_FILE.format(dataset=d, sensor=wildcards.sensor, axis=a)
            for d in DATASETS for a in AXES_OF[d][wildcards.sensor]]
