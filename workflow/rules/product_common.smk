# Helpers of the rules that give the user the answer (kalibr.smk, figures.smk, tables.smk, summary.smk):
# names, input functions and the terminal summary. Functions only, no rules (included after common.smk).

SUMMARY_MD = f"{RESULTS}/summary.md"
# The report's first page: workflow/report/workflow.rst followed by the summary, written by rule summary (the
# `report:` directive of the Snakefile takes it when it exists, else the plain workflow.rst).
REPORT_FRONT = f"{RESULTS}/report/workflow.rst"


def kalibr_rates():
    """Dataset -> IMU sample rate (Hz): the dataset sheet's rate_hz, or simulation.rate_hz; None where the sheet
    leaves it empty (the kalibr job then takes the rate the timestamps gave from the identify files)."""
    return {name: (float(row["rate_hz"]) if row.get("rate_hz") is not None else None) for name, row in DATASETS.items()}


def kalibr_topics():
    """Dataset -> the sheet's topic cell (None where the sheet has none, e.g. CSV or netCDF files)."""
    return {name: row.get("topic") for name, row in DATASETS.items()}


FIGURES = config["figures"]
FIG_FORMAT = FIGURES["format"]
FIG_NAMES = ["psd_bound", "allan_components", "inflation_steps", "allan_readoffs"]


def lines_of_sensor(wildcards):
    """The lines stage's per-axis files of the job's sensor, once the workflow has a rule `lines`."""
    if any(r.name == "lines" for r in workflow.rules):
        return {"lines": per_axis("lines", "yaml")(wildcards)}
    return {}


def copies(pattern):
    """`pattern` (with {fig}) in figures.format, every figure, or [] for png (the PNG is always written)."""
    if FIG_FORMAT == "png":
        return []
    return [pattern.format(fig=fig, ext=FIG_FORMAT) for fig in FIG_NAMES]


def summary_inputs(wildcards):
    """Every file of SUMMARY_INPUTS by kind (duplicates dropped, order kept)."""
    return {kind: list(dict.fromkeys(paths)) for kind, paths in SUMMARY_INPUTS.items() if paths}


def print_summary(failed=False):
    """Print the run summary on the terminal (onsuccess / onerror): summary.md when this run wrote it, else the
    summary of whatever files the run left (imupipe.summary.summarise_run), and after a failure where the logs
    are. Never raises: a handler must not hide the run's own error."""
    try:
        from imupipe.summary import first_screen, summarise_run

        md = Path(SUMMARY_MD)
        if not failed and md.is_file():
            text = md.read_text()
        else:
            text = summarise_run(RESULTS) if Path(RESULTS).is_dir() else ""
            if text:
                text = f"(partial: from the files this run has written so far)\n{text}"
        if text:  # the first screen (verdicts, values to paste, checks); the details stay in summary.md
            print(f"\n{first_screen(text).rstrip()}", flush=True)
        if failed:
            print(f"\nRUN FAILED: the failed job's log is under {LOGS}/ (the error above names it); "
                  f"summary.md is written only by a complete run.", flush=True)
        elif md.is_file():
            print(f"\nSummary with the details: {md}; report: snakemake --report {RESULTS}/report.html (make report)", flush=True)
    except Exception as exc:  # pragma: no cover - a broken summary must not mask the run's status
        print(f"(run summary unavailable: {exc})", flush=True)


def report_text():
    """The report's first page (absolute path): the summary's front page when a run wrote it, else workflow.rst."""
    front = Path(REPORT_FRONT).resolve()
    return str(front) if front.is_file() else str(ROOT / "workflow" / "report" / "workflow.rst")


KALIBR_RATES = kalibr_rates()
KALIBR_TOPICS = kalibr_topics()
