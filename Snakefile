# imupipe: static IMU records + a spec sheet -> a noise model that bounds the data (Gallon et al. 2021).
#
# results/ layout (README "Output contract"):
#   series/{dataset}/{sensor}/{axis}.nc        full-rate channel, SI             (ingest)
#   decimated/{dataset}/{sensor}/{axis}.nc     block average to decimate.rate_hz (decimate)
#   stationarity/{dataset}/{sensor}/{axis}.yaml, stationarity/{sensor}.yaml      (stationarity, merge)
#   psd/{dataset}/{sensor}/{axis}.nc, spectra/{sensor}.nc   two-sided Welch PSD  (psd, merge)
#   allan/{dataset}/{sensor}/{axis}.nc, allan/{sensor}.nc   overlapping AV       (allan, merge)
#   identify/{sensor}.yaml                     fitted components, states kept    (identify)
#   bound/{spec}/axes/{dataset}/{sensor}/{axis}.yaml, bound/{spec}/{sensor}.yaml (bound)
#   kf/{spec}/{sensor}.yaml, kf/{spec}/kalibr_imu.yaml                           (kf)
#   figures/..., tables/{spec}/inflation.{md,csv}                                (figures, tables)
# Only bound, kf, figures and tables read config/specs/{spec}.yaml.

from snakemake.utils import min_version

min_version("9.0")


configfile: "config/config.yaml"


report: "workflow/report/workflow.rst"


include: "workflow/rules/common.smk"
include: "workflow/rules/ingest.smk"
include: "workflow/rules/spectra.smk"
include: "workflow/rules/allan.smk"
include: "workflow/rules/stationarity.smk"
include: "workflow/rules/identify.smk"
include: "workflow/rules/bound.smk"
include: "workflow/rules/outputs.smk"


rule all:
    input:
        final_outputs(),
