# imupipe: static IMU records + a spec sheet -> a noise model that bounds the data (Gallon et al. 2021).
#
# results/ layout (README "Output contract"):
#   series/{dataset}/{sensor}/{axis}.nc        full-rate channel, SI             (ingest)
#   allan/{dataset}/{sensor}/{axis}.nc         overlapping AV of the full rate   (reduce)
#   decimated/{dataset}/{sensor}/{axis}.nc     block average to decimate.rate_hz (reduce)
#   psd/{dataset}/{sensor}/{axis}.nc           two-sided Welch PSD               (reduce)
#   stationarity/{dataset}/{sensor}/{axis}.yaml, stationarity/{sensor}.yaml      (collect)
#   spectra/{sensor}.nc, allan/{sensor}.nc     every curve of a sensor type      (collect)
#   identify/{sensor}.yaml                     fitted components, states kept    (identify)
#   bound/{spec}/axes/{dataset}/{sensor}/{axis}.yaml, bound/{spec}/{sensor}.yaml,
#   kf/{spec}/{sensor}.yaml                    per-axis and global bound, KF     (bound)
#   kf/{spec}/kalibr_imu.yaml                                                    (kalibr)
#   figures/..., tables/{spec}/inflation.{md,csv}                                (figures, tables)
# Only bound, kf, figures and tables read config/specs/{spec}.yaml.

from snakemake.utils import min_version

min_version("9.0")


configfile: "config/config.yaml"


report: "workflow/report/workflow.rst"


include: "workflow/rules/common.smk"
include: "workflow/rules/ingest.smk"
include: "workflow/rules/reduce.smk"
include: "workflow/rules/stationarity.smk"
include: "workflow/rules/identify.smk"
include: "workflow/rules/bound.smk"
include: "workflow/rules/outputs.smk"


rule all:
    input:
        final_outputs(),


# Snakemake's job-rate limiter (default 100 jobs per 1 s) re-evaluates the schedule through a threading.Timer
# after every scheduling round; the interpreter waits for the last one at exit (up to 1 s of every run). Once
# the run has ended nothing needs it, so cancel it. (A 0 s window avoids the wait but turns the re-evaluation
# into a busy loop that takes CPU from the jobs while they wait for a core.)
onsuccess:
    cancel_pending_timers()


onerror:
    cancel_pending_timers()
