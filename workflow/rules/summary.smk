# The run summary (results/{name}/summary.md, summary.html on the report's first page): per spec sheet and sensor
# type, bounded yes/no and margin, the inflation table in spec-sheet units, states kept and why, and every failed
# or flagged check with where it is (imupipe.summary). Reads the files that the stage files put in SUMMARY_INPUTS
# (common.smk; kind -> list of paths); bound, identify and stationarity are added here. Included last.

SUMMARY_INPUTS.setdefault("bound", []).extend(
    expand(f"{RESULTS}/bound/{{spec}}/{{sensor}}.yaml", spec=SPECS, sensor=SENSORS)
)
SUMMARY_INPUTS.setdefault("identify", []).extend(expand(f"{RESULTS}/identify/{{sensor}}.yaml", sensor=SENSORS))
SUMMARY_INPUTS.setdefault("stationarity", []).extend(
    expand(f"{RESULTS}/stationarity/{{sensor}}.yaml", sensor=SENSORS)
)
SUMMARY_MD = f"{RESULTS}/summary.md"
# The report's first page: workflow/report/workflow.rst followed by the summary, written by rule summary (the
# `report:` directive of the Snakefile takes it when it exists, else the plain workflow.rst).
REPORT_FRONT = f"{RESULTS}/report/workflow.rst"
MEM_MB["summary"] = 100
RUNTIME_MIN["summary"] = 10
MEM_MB["report_file"] = 100
RUNTIME_MIN["report_file"] = 10


def summary_inputs(wildcards):
    """Every file of SUMMARY_INPUTS by kind (duplicates dropped, order kept)."""
    return {kind: list(dict.fromkeys(paths)) for kind, paths in SUMMARY_INPUTS.items() if paths}


def print_summary(failed=False):
    """Print the run summary on the terminal (onsuccess / onerror): summary.md when this run wrote it, else the
    summary of whatever files the run left (imupipe.summary.summarise_run), and after a failure where the logs
    are. Never raises: a handler must not hide the run's own error."""
    try:
        from imupipe.summary import summarise_run

        md = Path(SUMMARY_MD)
        if not failed and md.is_file():
            text = md.read_text()
        else:
            text = summarise_run(RESULTS) if Path(RESULTS).is_dir() else ""
            if text:
                text = "(partial: from the files this run has written so far)\n" + text
        if text:
            print("\n" + text.rstrip(), flush=True)
        if failed:
            print(f"\nRUN FAILED: the failed job's log is under {LOGS}/ (the error above names it); "
                  f"summary.md is written only by a complete run.", flush=True)
        elif md.is_file():
            print(f"\nSummary: {md}; report: snakemake --report {RESULTS}/report.html (make report)", flush=True)
    except Exception as exc:  # pragma: no cover - a broken summary must not mask the run's status
        print(f"(run summary unavailable: {exc})", flush=True)


def report_text():
    """The report's first page (absolute path): the summary's front page when a run wrote it, else workflow.rst."""
    front = Path(REPORT_FRONT).resolve()
    return str(front) if front.is_file() else str(ROOT / "workflow" / "report" / "workflow.rst")


rule summary:
    input:
        unpack(summary_inputs),
    output:
        markdown=SUMMARY_MD,
        html=report(
            f"{RESULTS}/summary.html",
            caption="../report/summary.rst",
            category="0 Summary",
            labels={"page": "run summary"},
        ),
        front=REPORT_FRONT,
    params:
        template=str(ROOT / "workflow" / "report" / "workflow.rst"),
        kinds=list(SUMMARY_INPUTS),
        specs=SPECS,
        sensors=SENSORS,
        name=NAME,
    threads: 1
    resources:
        mem_mb=MEM_MB["summary"],
        runtime=RUNTIME_MIN["summary"],
    log:
        f"{LOGS}/summary.log",
    benchmark:
        f"{BENCHMARKS}/summary.tsv"
    conda:
        "../envs/imupipe.yaml"
    script:
        "../scripts/summary.py"


EXTRA_TARGETS.extend([SUMMARY_MD, f"{RESULTS}/summary.html", REPORT_FRONT])


# Copies of the Kalman-filter and bound YAML files for the HTML report (the originals stay under kf/ and bound/).
rule report_file:
    input:
        f"{RESULTS}/{{folder}}/{{spec}}/{{sensor}}.yaml",
    output:
        report(
            f"{RESULTS}/report/{{folder}}/{{spec}}/{{sensor}}.yaml",
            caption="../report/yaml_file.rst",
            category="Exports",
            labels={"file": "{folder} YAML", "spec": "{spec}", "sensor": "{sensor}"},
        ),
    wildcard_constraints:
        folder="kf|bound",
    threads: 1
    resources:
        mem_mb=MEM_MB["report_file"],
        runtime=RUNTIME_MIN["report_file"],
    log:
        f"{LOGS}/report_file/{{folder}}/{{spec}}/{{sensor}}.log",
    benchmark:
        f"{BENCHMARKS}/report_file/{{folder}}/{{spec}}/{{sensor}}.tsv"
    conda:
        "../envs/imupipe.yaml"
    shell:
        "cp {input:q} {output:q} 2> {log:q}"


EXTRA_TARGETS.extend(
    expand(f"{RESULTS}/report/{{folder}}/{{spec}}/{{sensor}}.yaml", folder=["kf", "bound"], spec=SPECS, sensor=SENSORS)
)
