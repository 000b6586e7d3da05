# imupipe: static IMU records + a spec sheet -> a noise model that bounds the data (Gallon et al. 2021).
#
# results/{name}/ layout (README "Output contract"; `name` is the config's top-level key, logs/{name}/ alike):
#   simulated/{dataset}.nc                     simulated recording (default config) (simulate)
#   series/{dataset}/{sensor}/{axis}.nc        full-rate channel, SI                (ingest)
#   allan/{dataset}/{sensor}/{axis}.nc         overlapping AV of the full rate      (allan)
#   decimated/{dataset}/{sensor}/{axis}.nc     block average to decimate.rate_hz    (decimate)
#   psd/{dataset}/{sensor}/{axis}.nc           two-sided Welch PSD                  (psd)
#   stationarity/{dataset}/{sensor}/{axis}.yaml                                     (stationarity)
#   stationarity/{sensor}.yaml                 verdicts with on_fail applied        (stationarity_summary)
#   spectra/{sensor}.nc, allan/{sensor}.nc     every curve of a sensor type         (stack)
#   identify/{sensor}.yaml                     fitted components, states kept       (identify)
#   bound/{spec}/axes/{dataset}/{sensor}/{axis}.yaml                                (bound_axis)
#   bound/{spec}/{sensor}.yaml                 global bound (the contract file)     (bound)
#   kf/{spec}/{sensor}.yaml, kf/{spec}/kalibr_imu.yaml                              (kf, kalibr)
#   figures/..., tables/{spec}/inflation.{md,csv,html}                              (figures, tables)
#   summary.md, summary.html, report/...       run summary, report's first page     (summary, report_file)
#   benchmarks/{rule}/...tsv                   Snakemake's per-job wall time and peak memory
# Only bound_axis, bound, verify, contract, figures and tables read config/specs/{spec}.yaml.

from snakemake.utils import min_version

min_version("9.0")


configfile: "config/config.yaml"


include: "workflow/rules/common.smk"
include: "workflow/rules/ingest.smk"
include: "workflow/rules/outliers.smk"
include: "workflow/rules/lines.smk"
include: "workflow/rules/allan.smk"
include: "workflow/rules/decimate.smk"
include: "workflow/rules/psd.smk"
include: "workflow/rules/stationarity.smk"
include: "workflow/rules/stack.smk"
include: "workflow/rules/identify.smk"
include: "workflow/rules/bound.smk"
include: "workflow/rules/kf.smk"
include: "workflow/rules/verify.smk"
include: "workflow/rules/kalibr.smk"
include: "workflow/rules/figures.smk"
include: "workflow/rules/tables.smk"
include: "workflow/rules/summary.smk"


# The report's first page: the workflow description and the run summary (summary.smk).
report: report_text()


# start-up cleanup of stale outputs and temp files, end-of-run temp removal (workflow/rules/common.smk,
# docs/inputs.md "Stale outputs"), then the run summary on the terminal (workflow/rules/summary.smk)
onstart:
    on_start()


onsuccess:
    on_finish()
    print_summary()


onerror:
    on_finish()
    print_summary(failed=True)


rule all:
    default_target: True
    input:
        final_outputs(),
