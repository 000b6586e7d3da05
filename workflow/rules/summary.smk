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
# the per-axis PSDs: their n_samples / n_samples_used attrs give the share of each record the Welch segments leave
# out (FLAG above 10 %, imupipe.summary.psd_usage_flags)
SUMMARY_INPUTS.setdefault("psd", []).extend(
    f"{RESULTS}/psd/{d}/{s}/{a}.nc" for d in DATASETS for s in SENSORS for a in AXES_OF[d][s]
)


rule summary:
    input:
        unpack(summary_inputs),
        template=repo_path("workflow/report/workflow.rst"),
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
