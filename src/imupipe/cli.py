"""The ``imupipe`` command (also ``python -m imupipe``).

::

    imupipe run CONFIG [--cores N] [--directory D] [--dry-run] [-- SNAKEMAKE_ARGS...]
    imupipe allan FILE [--format F] [--rate-hz R] [--sensor S] [--units U] [--channel K=COL ...]
                       [--time-column C] [--time-unit U] [--variable V] [--topic T] [--plot OUT] [--si]
    imupipe check CONFIG [--directory D] [--no-dry-run] [--read]
    imupipe summary [RESULTS] [--markdown OUT] [--html OUT] [--quiet]
    imupipe init DATA... --spec SPEC [--out DIR] [--rate-hz R] [--time-unit U] [--force]

``run`` runs the Snakemake workflow of this checkout through the snakemake command line; ``allan`` prints
the Allan deviation of every channel of one file, read with :func:`imupipe.readers.read_dataset` (and
writes a figure with ``--plot``, format from the file name: .png, .svg, .pdf); ``check`` validates a
config, its dataset sheet and its spec sheets without running anything (and, unless ``--no-dry-run``,
asks Snakemake for a dry run of the DAG; with ``--read`` it also reads every record as a run would,
:func:`read_records`); ``summary`` prints (and writes) the run summary of a finished run
(:mod:`imupipe.summary`); ``init`` writes a dataset sheet and a partial config fitted to a user's records
(:func:`init_files`, rules in :mod:`imupipe.init`).

Exit status: 0 on success, 1 on an input error (one line ``imupipe: error: ...`` on stderr), the
snakemake status for ``run``.
"""

from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path

__all__ = ["main", "checkout_root", "check_config", "read_records", "allan_table", "init_files"]


def checkout_root() -> Path:
    """The project checkout holding the Snakefile (the package is installed from it in editable mode).

    Raises
    ------
    FileNotFoundError
        When the installed package is not inside a checkout with a Snakefile.
    """
    root = Path(__file__).resolve().parents[2]
    if not (root / "Snakefile").is_file():
        raise FileNotFoundError(f"no Snakefile at {root}: 'imupipe run' and 'check' need a clone of the project "
                                "installed with 'pip install -e .'")
    return root


def _snakemake_exe() -> list[str]:
    exe = Path(sys.executable).with_name("snakemake")
    if exe.is_file():
        return [str(exe)]
    found = shutil.which("snakemake")
    if found:
        return [found]
    raise FileNotFoundError("snakemake not found: install the workflow extra ('pip install -e .[workflow]')")


def _snakemake_cmd(config: Path, cores: int | None, directory: Path | None, extra: Sequence[str]) -> list[str]:
    root = checkout_root()
    cmd = _snakemake_exe() + ["--snakefile", str(root / "Snakefile"), "--configfile", str(config)]
    if cores is not None:
        cmd += ["--cores", str(cores)]
    if directory is not None:
        cmd += ["--directory", str(directory)]
    return cmd + list(extra)


def check_config(config: str | Path) -> list[str]:
    """Validate a config, its dataset sheet and spec sheets without running the workflow, with the workflow's own
    start-up code (:mod:`imupipe.runconfig`).

    Checks: the config is a YAML mapping without a renamed key (:func:`imupipe.runconfig.merged_config`, merged
    over config/config.yaml); every spec sheet ``{spec_dir}/{name}.yaml`` of ``specs`` parses and has a section
    for every sensor of ``sensors`` (:func:`imupipe.runconfig.check_specs`); the dataset sheet (when ``datasets``
    is not null) parses as the workflow parses it (:func:`imupipe.runconfig.read_sheet`) and each row names an
    existing file; then the config schema and the checks across keys. Paths are relative to the checkout (as in
    the workflow).

    Returns
    -------
    list of str
        One line per check passed.

    Raises
    ------
    ValueError
        The first problem, naming the file and key / row.
    """
    from imupipe import runconfig as rc
    from imupipe.io import read_yaml
    from imupipe.readers import check_file, sheet_row_to_kwargs

    import yaml

    from imupipe.init import PLACEHOLDER
    from imupipe.readers import FROM_FILE
    from imupipe.units import UnitError, rate_factor

    config = Path(config)
    if not config.is_file():
        raise ValueError(f"{config}: config file not found")
    try:
        given = read_yaml(config)  # a key given twice is refused there, naming both lines
    except yaml.YAMLError as exc:
        raise ValueError(f"{config}: not valid YAML ({' '.join(str(exc).split())})") from None
    root = _root()
    cfg = rc.merged_config(given, root, where=str(config))
    done = [f"config {config}: YAML mapping with {len(given)} keys"
            + (" (the others from config/config.yaml)" if (root / "config" / "config.yaml").is_file() else "")]
    if not cfg.get("specs"):
        raise ValueError(f"{config}: key 'specs' is empty (expected names of {cfg.get('spec_dir')}/<name>.yaml)")
    cfg.setdefault("sensors", ["gyro", "accel"])
    for sheet in rc.check_specs(cfg, root):
        done.append(f"spec sheet {Path(sheet.path).name}: {sheet.name}, sensors {', '.join(cfg['sensors'])}")
    if cfg.get("datasets"):
        sheet_path = root / str(cfg["datasets"])
        if not sheet_path.is_file():
            raise ValueError(f"{config}: datasets = {cfg['datasets']!r} but {sheet_path} does not exist")
        rows = rc.read_sheet(sheet_path, root / rc.SCHEMAS / "datasets.schema.yaml")
        for i, row in zip(rc.sheet_lines(sheet_path), rows.values()):
            todo = [k for k, v in row.items() if str(v).strip() == PLACEHOLDER]
            if todo:  # cells 'imupipe init' could not guess (its comment lines list them) or a user left
                raise ValueError(f"{sheet_path}, line {i} (dataset {row.get('dataset')!r}): column(s) "
                                 f"{', '.join(todo)} still hold the placeholder {PLACEHOLDER}: fill them in (the "
                                 "file's column name, or its unit; 'imupipe init' lists what each needs when it "
                                 "writes one)")
            try:
                check_file(sheet_row_to_kwargs(row, base_dir=root)["path"])  # a symlink loop, a Windows path
            except ValueError as exc:
                raise ValueError(f"{sheet_path}, line {i} (dataset {row.get('dataset')!r}): {exc}") from None
            for sensor in ("gyro", "accel"):  # the stored unit, as the ingest job reads it (imupipe.units)
                unit = row.get(f"{sensor}_unit")
                if unit and unit != FROM_FILE:  # from_file: the file's own unit, read by ingest
                    try:
                        rate_factor(unit, sensor)
                    except UnitError as exc:
                        raise ValueError(f"{sheet_path}, line {i} (dataset {row.get('dataset')!r}), column "
                                         f"{sensor}_unit: {exc}") from None
        done.append(f"dataset sheet {sheet_path.name}: {len(rows)} rows, every file present")
    elif not cfg.get("simulation"):
        raise ValueError(f"{config}: 'datasets' is null and 'simulation' is empty: nothing to analyse")
    else:
        done.append("datasets: simulated")
    schema = rc.validate_schema(cfg, root / rc.SCHEMAS / "config.schema.yaml", where=str(config))
    rc.check_cross_keys(cfg)
    done.append("config keys: " + ("the schema and the checks across keys" if schema else
                                   "the checks across keys (the schema needs jsonschema, installed with Snakemake)"))
    # the workflow's start-up probe of every record against the config (length, rates), as common.smk runs it
    datasets = rc.datasets_of(cfg, root, f"results/{cfg.get('name', 'run')}")
    warned = rc.check_records(cfg, datasets)
    done.append(f"records against the config: {len(datasets)} probed (length for psd.window_s, rates)")
    done += [f"warning: {w}" for w in warned]
    return done


def allan_table(rec, taus="octave") -> tuple[list[str], list[list[float]], dict]:
    """Allan deviation of every channel of a :class:`imupipe.readers.Recording`.

    Returns
    -------
    header : list of str
        ``tau_s`` then one column per channel ``<sensor>_<axis> [unit]``.
    rows : list of list of float
        tau (s) and ADEV (rad/s or m/s^2) per tau; NaN where a channel has no such tau.
    avs : dict
        (sensor, axis) -> the ``xarray.Dataset`` of :func:`imupipe.allan_variance`.
    """
    import numpy as np

    from imupipe.allan import allan_variance

    avs = {k: allan_variance(x, rec.rate_hz, taus=taus, units=rec.units[k]) for k, x in rec.items()}
    tau = np.unique(np.concatenate([av["tau"].values for av in avs.values()]))
    header = ["tau_s"] + [f"{s}_{a} [{rec.units[(s, a)]}]" for (s, a) in avs]
    rows = []
    for t in tau:
        row = [float(t)]
        for av in avs.values():
            hit = np.flatnonzero(av["tau"].values == t)
            row.append(float(np.sqrt(av["avar"].values[hit[0]])) if hit.size else float("nan"))
        rows.append(row)
    return header, rows, avs


def _read_with_time_unit(path, fmt, rate_hz, channels, units, kwargs):
    """read_dataset for ``imupipe allan``: a ``t`` column is the time column when none is given, and a time column
    without a unit gets the one :func:`imupipe.readers.timeunit.infer_time_unit` infers (stated on stderr) from the
    stamps' mean gap-free interval read as seconds; formats whose stamps carry their unit (netCDF, bags) as given."""
    from imupipe.readers import format_of, probe, read_dataset
    from imupipe.readers.timeunit import infer_time_unit

    kind = format_of(path, fmt)
    if kind in ("netcdf", "rosbag"):
        return read_dataset(path, format=fmt, rate_hz=rate_hz, channels=channels, units=units, **kwargs)
    if "time_column" not in kwargs:
        names = probe(path, fmt, **{k: v for k, v in kwargs.items() if k in ("delimiter", "variable")}).channels
        if "t" in names:
            kwargs = {**kwargs, "time_column": "t"}
            print(f"imupipe allan: {path}: column 't' read as the time column (--time-column to choose another)",
                  file=sys.stderr)
    if "time_column" not in kwargs or "time_unit" in kwargs:
        return read_dataset(path, format=fmt, rate_hz=rate_hz, channels=channels, units=units, **kwargs)
    as_s = read_dataset(path, format=fmt, channels=channels, units=units, **{**kwargs, "time_unit": "s"})
    unit, reason = infer_time_unit(1.0 / as_s.rate_hz, rate_hz, where=str(path))
    print(f"imupipe allan: {path}: time unit {unit} ({reason}; --time-unit to state it)", file=sys.stderr)
    if unit == "s" and rate_hz is None:
        return as_s
    return read_dataset(path, format=fmt, rate_hz=rate_hz, channels=channels, units=units,
                        **{**kwargs, "time_unit": unit})


def _cmd_allan(args) -> int:
    from imupipe.readers import read_dataset

    channels = None
    if args.channel:
        channels = {}
        for item in args.channel:
            if "=" not in item:
                raise ValueError(f"--channel {item!r}: expected SENSOR_AXIS=COLUMN, e.g. gyro_x=wx")
            k, v = item.split("=", 1)
            channels[k.strip()] = int(v) if v.strip().isdigit() else v.strip()
    units = None
    if args.units:
        units = {}
        for item in args.units:
            if "=" not in item:
                raise ValueError(f"--units {item!r}: expected SENSOR=UNIT, e.g. gyro=deg/s")
            k, v = item.split("=", 1)
            units[k.strip()] = v.strip()
    kwargs = dict(time_column=args.time_column, time_unit=args.time_unit, variable=args.variable, topic=args.topic,
                  delimiter=args.delimiter)
    kwargs = {k: v for k, v in kwargs.items() if v is not None}
    rec = _read_with_time_unit(args.file, args.format, args.rate_hz, channels, units, kwargs)
    if args.sensor:
        keep = {k: v for k, v in rec.items() if k[0] == args.sensor}
        if not keep:
            raise ValueError(f"{args.file}: no {args.sensor} channel (channels: {sorted(rec.keys())})")
    header, rows, avs = allan_table(rec)
    if args.sensor:
        cols = [0] + [i + 1 for i, k in enumerate(avs) if k[0] == args.sensor]
        header = [header[i] for i in cols]
        rows = [[r[i] for i in cols] for r in rows]
    print(f"# {rec.source}: {rec.n_samples} samples at {rec.rate_hz:g} Hz; overlapping Allan deviation")
    print("\t".join(header))
    for r in rows:
        print("\t".join(f"{v:.6g}" for v in r))
    if args.plot:
        from imupipe.plot import plot_allan_deviation, save_figure

        by_sensor = {}
        for (s, a), av in avs.items():
            if args.sensor and s != args.sensor:
                continue
            by_sensor.setdefault(s, []).append((a, av))
        out = Path(args.plot)
        for s, items in by_sensor.items():
            import numpy as np

            tau = np.unique(np.concatenate([av["tau"].values for _, av in items]))
            arr = np.full((len(items), tau.size), np.nan)
            for i, (_, av) in enumerate(items):
                arr[i, np.searchsorted(tau, av["tau"].values)] = av["avar"].values
            fig = plot_allan_deviation(tau, arr, sensor=s, labels=[f"{s} {a}" for a, _ in items],
                                       display_unit="SI" if args.si else "spec",
                                       title=f"{Path(args.file).name}: {s} Allan deviation")
            path = out if len(by_sensor) == 1 else out.with_name(f"{out.stem}_{s}{out.suffix}")
            save_figure(fig, path)
            print(f"# figure: {path}")
    return 0


def _root() -> Path:
    """The checkout root (config paths are relative to it); the working directory outside a checkout."""
    try:
        return checkout_root()
    except FileNotFoundError:
        return Path.cwd()


def read_records(config: str | Path, cores: int = 2) -> list[str]:
    """Read every record of a config's dataset sheet as a run reads it, without running the analysis.

    Runs the workflow's ``ingest`` stage (``snakemake --until ingest --keep-going``) in a scratch working
    directory that is removed afterwards: every channel the sheet names is read, converted to SI and checked
    exactly as in a run (values, timestamps, gaps, rate, units, gravity; docs/inputs.md). The checkout's
    ``results/`` is not touched.

    Returns
    -------
    list of str
        One line per record read (dataset, samples, rate, duration, from the ingest logs), then the reader's
        warnings (``warning: ...``: gaps split off, gaps the stamps cannot resolve).

    Raises
    ------
    ValueError
        Naming every record that failed, each with the reader's message (file, column or key, and what was
        expected), and every record read shorter than ``psd.window_s`` (``gap_policy: split`` keeps the longest
        segment, which the start-up check on the whole file cannot see); the records that read well are listed.
    """
    import os
    import tempfile

    config = Path(config).resolve()
    env = dict(os.environ)
    env.setdefault("OPENBLAS_NUM_THREADS", "1")
    with tempfile.TemporaryDirectory(prefix="imupipe-check-") as scratch:
        # (not "--quiet all": it also silences an error raised while Snakemake reads the workflow, e.g. the
        # start-up check of a record against the config)
        cmd = _snakemake_cmd(config, cores, Path(scratch), ["--until", "ingest", "--keep-going", "--quiet", "rules",
                                                            "host", "reason", "progress"])
        proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
        read, warned, short = [], [], []
        window_s = _window_s(config)
        for log in sorted(Path(scratch).glob("logs/*/ingest/*.log")):
            text = log.read_text()
            found = re.findall(r"INFO (\S+: \d+ samples at \S+ Hz \([^)]*\) from .*)$", text, re.M)
            if found and " done in " in text:  # run_job's last line of a job that succeeded
                read.append(found[0])
                # the reader's warnings (gaps split or not resolvable), each once (one per channel read)
                warned += [f"warning: {w}" for w in dict.fromkeys(re.findall(r"GapWarning: (.*)$", text, re.M))]
                n, rate = re.match(r"\S+: (\d+) samples at (\S+) Hz", found[0]).groups()
                if window_s and int(n) / float(rate) < window_s:  # the start-up check saw the whole file
                    kept = " (gap_policy split kept the longest segment)" if "Kept the longest" in text else ""
                    read.pop()
                    short.append(f"imupipe error: {found[0].split(':')[0]}: {int(n) / float(rate):.6g} s read{kept}, "
                                 f"shorter than psd.window_s = {window_s:g} s: the PSD job would stop; record longer, "
                                 "shorten psd.window_s, or fill the gaps (gap_policy fill)")
        # the jobs name a recording relative to their working directory (the scratch folder): name it as the
        # sheet does
        renamed = {os.path.relpath(full, scratch): shown for full, shown in _sheet_paths(config).items()}
    errors = [ln.strip() for ln in (proc.stderr + proc.stdout).splitlines() if ln.startswith("imupipe error:")]
    errors += short
    if proc.returncode != 0 and not errors:  # stopped before any job: the workflow's own message, without traceback
        errors = [ln.rstrip() for ln in proc.stderr.splitlines()
                  if ln.strip() and not ln.lstrip().startswith(("File ", "Traceback"))
                  and not re.match(r"\w+(Error|Exception) in file ", ln)]
    for rel, shown in sorted(renamed.items(), key=lambda kv: -len(kv[0])):
        errors = [e.replace(rel, shown) for e in errors]
        read = [r.replace(rel, shown) for r in read]
    if proc.returncode != 0 or short:
        raise ValueError("reading the records failed:\n  " + "\n  ".join(errors or ["(Snakemake gave no message)"])
                         + ("\nread well: " + "; ".join(read) if read else ""))
    return read + warned


def _window_s(config: Path) -> float | None:
    """The config's ``psd.window_s`` (s), None where it is not a number."""
    from imupipe import runconfig as rc
    from imupipe.io import read_yaml

    try:
        return float(rc.merged_config(read_yaml(config), _root(), where=str(config))["psd"]["window_s"])
    except (KeyError, TypeError, ValueError):
        return None


def _sheet_paths(config: Path) -> dict[str, str]:
    """{absolute path: the path as the dataset sheet writes it} of a config's recordings (empty without a sheet)."""
    from imupipe import runconfig as rc
    from imupipe.io import read_yaml

    root = _root()
    cfg = rc.merged_config(read_yaml(config), root, where=str(config))
    if not cfg.get("datasets"):
        return {}
    rows = rc.read_sheet(root / str(cfg["datasets"]), root / rc.SCHEMAS / "datasets.schema.yaml")
    return {str(root / row["path"]): row["path"] for row in rows.values()}


def _cmd_check(args) -> int:
    lines = check_config(args.config)
    for line in lines:
        print(f"warn {line[len('warning: '):]}" if line.startswith("warning: ") else f"ok  {line}")
    if args.read:
        if any(ln == "datasets: simulated" for ln in lines):
            print("ok  records: simulated by the run, nothing to read")
        else:
            for line in read_records(args.config):
                print(f"warn {line[len('warning: '):]}" if line.startswith("warning: ") else f"ok  read {line}")
    if not args.no_dry_run:
        cmd = _snakemake_cmd(Path(args.config).resolve(), 1, Path(args.directory).resolve() if args.directory else None,
                             ["--dry-run", "--quiet", "all"])
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0:
            raise ValueError("Snakemake dry run failed:\n" + _dry_run_error(proc.stderr or proc.stdout))
        print("ok  snakemake dry run: the workflow's DAG builds")
    return 0


def _dry_run_error(text: str, n_tail: int = 15) -> str:
    """The lines of a failed Snakemake dry run a user needs: every line that states an error (a config
    validation error names the key, e.g. "'windw_s' was unexpected", above a long schema dump), then the
    last `n_tail` lines."""
    lines = text.strip().splitlines()
    stated = [ln for ln in lines if re.search(r"Error\b|error:|was unexpected|is a required property", ln)]
    tail = [ln for ln in lines[-n_tail:] if ln not in stated]
    return "\n".join(stated + (["..."] if stated and tail else []) + tail)


def _cmd_summary(args) -> int:
    from imupipe.io import write_text_atomic
    from imupipe.stages.summary import summarise_results
    from imupipe.summary import markdown_to_html

    results = Path(args.results)
    if not results.is_dir():
        raise ValueError(f"{results}: no such results folder")
    text = summarise_results(results)  # the workflow's summary job's text, from the files the run left
    if not text:
        raise ValueError(f"{results}: no bound contract (bound/<spec>/<sensor>.yaml) found: has the run finished?")
    if args.markdown:
        write_text_atomic(text, args.markdown)
    if args.html:
        write_text_atomic(markdown_to_html(text, title="imupipe run summary"), args.html)
    if not args.quiet:
        print(text.rstrip())
    return 0


def _cmd_run(args) -> int:
    config = Path(args.config).resolve()
    if not config.is_file():
        raise ValueError(f"{args.config}: config file not found")
    # the workflow's start-up checks (config keys, spec sheets, dataset sheet, files, records against the config)
    # in this process first: a bad input is one line naming the file and key, not Snakemake's traceback
    check_config(config)
    extra = list(args.snakemake_args or [])
    if args.dry_run:
        extra.append("--dry-run")
    if args.keep_going:
        extra.append("--keep-going")
    if not args.dry_run and "--rerun-incomplete" not in extra and "--ri" not in extra:
        extra.append("--rerun-incomplete")  # an interrupted run's half-written outputs are re-made: the same command resumes
    if not args.verbose and not any(a in ("--quiet", "-q") or a.startswith("--quiet=") for a in extra):
        extra += ["--quiet", "rules", "host", "reason"]  # progress lines only; job details stay in logs/
    # the working directory (results/, logs/, .snakemake/): the checkout unless given, whatever the shell's current
    # directory, so that the same command finds the same finished run from anywhere
    cmd = _snakemake_cmd(config, args.cores, Path(args.directory).resolve() if args.directory else checkout_root(),
                         extra)
    import os

    env = dict(os.environ)
    env.setdefault("OPENBLAS_NUM_THREADS", "1")
    # the workflow itself prints the run summary at the end of a run (onsuccess / onerror of the Snakefile)
    return _call(cmd, env)


#: Exit status of an interrupted run (128 + SIGINT, the shell's convention).
INTERRUPTED_EXIT = 130
INTERRUPTED_MESSAGE = "imupipe: interrupted; run the same command again to resume"


def _call(cmd: Sequence[str], env: dict) -> int:
    """Run Snakemake; SIGINT (Ctrl-C) or SIGTERM stops it cleanly and returns :data:`INTERRUPTED_EXIT`.

    Snakemake runs in its own session, so the terminal's Ctrl-C reaches this process alone; the handler passes
    one SIGINT on, Snakemake's own graceful stop (it ends its jobs and releases its lock). Every run passes
    ``--rerun-incomplete`` (``_cmd_run``), so the next run removes and re-makes what the interrupted one left
    half-written: the same command resumes. Instead of a traceback, one line on stderr."""
    import signal

    proc = subprocess.Popen(list(cmd), env=env, start_new_session=True)
    got: list[int] = []

    def forward(signum, frame):
        if not got and proc.poll() is None:
            try:
                proc.send_signal(signal.SIGINT)
            except ProcessLookupError:
                pass
        got.append(signum)

    previous = {sig: signal.signal(sig, forward) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        rc = proc.wait()
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if got:
        print(INTERRUPTED_MESSAGE, file=sys.stderr, flush=True)
        return INTERRUPTED_EXIT
    return rc


def init_files(data: Sequence[str | Path], spec: str | Path, out: str | Path = ".", *, rate_hz: float | None = None,
               time_unit: str | None = None, force: bool = False,
               outage_s: float | None = None) -> tuple[Path, Path, list[str]]:
    """Write ``OUT/datasets.tsv`` and ``OUT/config.yaml`` for the records `data` and the spec sheet `spec`.

    Every record is probed (:func:`imupipe.init.inspect_record`), the settings derived
    (:func:`imupipe.init.derive_settings`: decimation, PSD window / step leaving at most 10 % of the shortest
    record unused, filter rate and outage, or the asked `outage_s` where the records hold it; the rules in
    :mod:`imupipe.init`), then both files are written. An outage shorter than the default 3600 s is said on
    stdout (what the run then verifies, and how to ask for more).
    Paths in the files are absolute (the workflow reads them relative to the checkout). Nothing is written when a
    check fails.

    Returns
    -------
    (sheet path, config path, list of the cells the user must fill)

    Raises
    ------
    ValueError
        Naming the file: a missing record or spec sheet, an unknown format, a spec sheet without a section for a
        sensor, a record too short, an existing output without `force`.
    """
    from imupipe.init import config_text, derive_settings, inspect_record, sheet_text
    from imupipe.io import write_text_atomic
    from imupipe.readers import validate_dataset_name
    from imupipe.specsheet import load_spec

    out = Path(out)
    sheet, cfg = out / "datasets.tsv", out / "config.yaml"
    if not force:
        exist = [str(p) for p in (sheet, cfg) if p.exists()]
        if exist:
            raise ValueError(f"{', '.join(exist)} already exist(s): not overwritten (--force to replace)")
    spec = Path(spec)
    if not spec.is_file():
        raise ValueError(f"--spec {spec}: spec sheet not found")
    if spec.suffix not in (".yaml", ".yml"):
        raise ValueError(f"--spec {spec}: expected a spec sheet .yaml (config/specs/ has examples)")
    model = load_spec(spec)
    if not data:
        raise ValueError("no record given (imupipe init DATA... --spec SPEC)")
    records, names = [], set()
    for path in data:
        path = Path(path)
        if not path.exists():
            raise ValueError(f"{path}: record not found")
        name = re.sub(r"[^A-Za-z0-9_.-]+", "_", path.stem if path.is_file() else path.name).strip("._") or "record"
        base, i = name, 2
        while name in names:
            name, i = f"{base}_{i}", i + 1
        names.add(name)
        validate_dataset_name(name)
        rec = inspect_record(path.resolve(), name, rate_hz, time_unit)
        records.append(rec)
    sensors = [s for s in ("gyro", "accel")
               if any(r.format == "rosbag" or r.row.get(f"{s}_x") not in (None, "", "FILL_ME") for r in records)]
    sensors = sensors or ["gyro", "accel"]
    missing = [s for s in sensors if s not in model.models]
    if missing:
        raise ValueError(f"--spec {spec}: no section for {', '.join(missing)} (the records have {', '.join(sensors)})")
    settings = derive_settings(records, outage_s=outage_s)
    run_name = re.sub(r"[^A-Za-z0-9_.-]+", "_", out.resolve().name).strip("._") or "mydata"
    spec_abs = spec.resolve()
    text = config_text(run_name, str(sheet.resolve()), str(spec_abs.parent), spec_abs.stem, sensors, settings)
    write_text_atomic(sheet_text(records), sheet)
    write_text_atomic(text, cfg)
    for note in (t for r in records for t in r.notes):
        print(f"note: {note}")
    from imupipe.defaults import DEFAULTS

    default_outage = float(DEFAULTS["application.outage_s"])
    if outage_s is None and settings.outage_s < default_outage:
        print(f"note: application.outage_s = {settings.outage_s:g} s, shorter than the default {default_outage:g} s: "
              f"by default the outage is at most the PSD window ({settings.window_s:g} s), so that the band the bound "
              "is checked over lies inside the spectra, and one fix period plus the outage fits in the shortest "
              f"record ({settings.shortest_s:.6g} s). The run verifies the model over that outage only. A filter "
              "that must bridge a longer one: imupipe init --outage-s asks for it, up to "
              f"{settings.longest_outage_s:.6g} s on these records (below 1/outage the bound then covers the "
              "identified envelope), and says how long the records must be beyond that")
    return sheet, cfg, [t for r in records for t in r.todo]


def _cmd_init(args) -> int:
    sheet, cfg, todo = init_files(args.data, args.spec, args.out, rate_hz=args.rate_hz, time_unit=args.time_unit,
                                 force=args.force, outage_s=args.outage_s)
    print(f"wrote {sheet}\nwrote {cfg}")
    if todo:
        print(f"fill in {len(todo)} cell(s) marked FILL_ME in {sheet} first:")
        for t in todo:
            print(f"  {t}")
        print(f"then: imupipe check {cfg} --read")
    else:
        print(f"next: imupipe check {cfg} --read   (optional: reads every record as the run will)")
    print(f"next: imupipe run {cfg}")
    return 0


def _parser() -> argparse.ArgumentParser:
    from imupipe import __version__

    p = argparse.ArgumentParser(prog="imupipe", description="Bounding IMU noise models from static records and a "
                                "spec sheet (PSD overbound, Gallon, Joerger & Pervan, ION GNSS+ 2021).")
    p.add_argument("--version", action="version", version=f"imupipe {__version__}")
    sub = p.add_subparsers(dest="command", required=True)

    r = sub.add_parser("run", help="run the Snakemake workflow on a config (arguments after -- go to snakemake)")
    r.add_argument("config", help="config YAML (e.g. config/config.yaml)")
    r.add_argument("--cores", type=int, default=2, help="cores for Snakemake (default 2)")
    r.add_argument("--directory", help="working directory for results/ and logs/ (default: the checkout)")
    r.add_argument("--dry-run", action="store_true", help="list the jobs without running them")
    r.add_argument("--keep-going", action="store_true", help="when a dataset fails, go on with the jobs that do "
                   "not need it (the other datasets' results are kept; the run still exits non-zero)")
    r.add_argument("--verbose", action="store_true", help="Snakemake's full job output (default: progress only, "
                   "details in logs/)")
    r.set_defaults(func=_cmd_run)

    a = sub.add_parser("allan", help="Allan deviation table (and figure) of one record")
    a.add_argument("file", help="record: CSV/TSV, netCDF, .npy/.npz, R .rda/.rds, ROS bag or MCAP")
    a.add_argument("--format", default="auto", help="reader format (default: from the extension)")
    a.add_argument("--rate-hz", type=float, help="sample rate, Hz (default: the file's or its timestamps')")
    a.add_argument("--channel", action="append", metavar="SENSOR_AXIS=COLUMN",
                   help="channel column, e.g. gyro_x=wx (repeatable; default columns gyro_x ... accel_z)")
    a.add_argument("--units", action="append", metavar="SENSOR=UNIT", help="stored unit, e.g. gyro=deg/s")
    a.add_argument("--time-column", help="timestamp column (default: a column named t, if any)")
    a.add_argument("--time-unit", help="timestamp unit: s, ms, us, ns (default: inferred from the stamps' spacing "
                   "against --rate-hz, else against 1 Hz .. 10 kHz, and stated)")
    a.add_argument("--delimiter", help="text delimiter: ',', tab, semicolon, space")
    a.add_argument("--variable", help="R object / npz array / netCDF variable")
    a.add_argument("--topic", help="bag topic of the sensor_msgs/Imu messages")
    a.add_argument("--sensor", choices=("gyro", "accel"), help="only this sensor's channels")
    a.add_argument("--plot", help="write a figure (format from the suffix: .png, .svg, .pdf)")
    a.add_argument("--si", action="store_true", help="figure axes in SI instead of spec-sheet units")
    a.set_defaults(func=_cmd_allan)

    m = sub.add_parser("summary", help="the run summary of a finished run (verdicts, inflation, flagged checks)")
    m.add_argument("results", nargs="?", default="results", help="results folder (default: results)")
    m.add_argument("--markdown", help="also write it to this file (markdown / plain text)")
    m.add_argument("--html", help="also write it as an HTML page (tables rendered)")
    m.add_argument("--quiet", action="store_true", help="do not print it")
    m.set_defaults(func=_cmd_summary)

    i = sub.add_parser("init", help="write a dataset sheet and a config fitted to your records")
    i.add_argument("data", nargs="+", help="records (any format 'imupipe allan' reads)")
    i.add_argument("--spec", required=True, help="spec sheet YAML of the IMU (config/specs/*.yaml for examples)")
    i.add_argument("--out", default=".", help="folder of datasets.tsv and config.yaml (default: .)")
    i.add_argument("--rate-hz", type=float, help="sample rate, Hz, of records without timestamps or a stored rate")
    i.add_argument("--time-unit", help="unit of the records' time column: s, ms, us, ns (default: from its name, the "
                   "file, or the stamps' spacing)")
    i.add_argument("--outage-s", type=float, help="the outage (s) your filter must bridge without fixes "
                   "(application.outage_s; default: min(3600 s, psd.window_s, shortest record - verify.fix_s)); "
                   "refused, with the longest the records hold, where one fix period plus it does not fit")
    i.add_argument("--force", action="store_true", help="overwrite existing datasets.tsv / config.yaml")
    i.set_defaults(func=_cmd_init)

    c = sub.add_parser("check", help="validate a config, its dataset sheet and spec sheets without running")
    c.add_argument("config")
    c.add_argument("--directory", help="working directory for the dry run")
    c.add_argument("--no-dry-run", action="store_true", help="skip the Snakemake dry run")
    c.add_argument("--read", action="store_true", help="also read every record as a run reads it (the ingest "
                   "stage, in a scratch folder removed afterwards): values, timestamps, units and gravity checked")
    c.set_defaults(func=_cmd_check)

    from imupipe.plan import add_subcommand  # imupipe plan: the logic in imupipe.plan
    add_subcommand(sub)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``imupipe`` console script; returns the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    passthrough = []
    if "--" in argv:  # everything after -- goes to snakemake as it is
        i = argv.index("--")
        argv, passthrough = argv[:i], argv[i + 1:]
    args = _parser().parse_args(argv)
    args.snakemake_args = passthrough
    try:
        return int(args.func(args) or 0)
    except (ValueError, OSError, KeyError) as exc:
        print(f"imupipe: error: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
