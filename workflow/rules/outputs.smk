# Kalibr-style imu.yaml, figures (paper Figures 5-8) and the inflation table (paper Table 2).


rule kalibr:
    input:
        gyro="results/bound/{spec}/gyro.yaml",
        accel="results/bound/{spec}/accel.yaml",
    output:
        kalibr="results/kf/{spec}/kalibr_imu.yaml",
    params:
        rate_hz=config["application"]["rate_hz"],
    log:
        "logs/kalibr/{spec}.log",
    script:
        "../scripts/kalibr.py"


rule figures:
    # before kalibr and table when both are ready: the figures are the longer jobs at the end of a run
    priority: 1
    input:
        spectra="results/spectra/{sensor}.nc",
        allan="results/allan/{sensor}.nc",
        identified="results/identify/{sensor}.yaml",
        bound="results/bound/{spec}/{sensor}.yaml",
        spec=spec_file,
    output:
        psd_bound=report(
            "results/figures/{spec}/psd_bound_{sensor}.png",
            caption="../report/psd_bound.rst",
            category="Bound",
            subcategory="{sensor}",
            labels={"figure": "PSD bound (Fig. 5)", "spec": "{spec}", "sensor": "{sensor}"},
        ),
        allan_components=report(
            "results/figures/{spec}/allan_components_{sensor}.png",
            caption="../report/allan_components.rst",
            category="Bound",
            subcategory="{sensor}",
            labels={"figure": "Allan components (Fig. 6)", "spec": "{spec}", "sensor": "{sensor}"},
        ),
        inflation_steps=report(
            "results/figures/{spec}/inflation_steps_{sensor}.png",
            caption="../report/inflation_steps.rst",
            category="Bound",
            subcategory="{sensor}",
            labels={"figure": "hand inflation (Fig. 8)", "spec": "{spec}", "sensor": "{sensor}"},
        ),
    log:
        "logs/figures/{spec}/{sensor}.log",
    script:
        "../scripts/figures.py"


rule inflation_effect:
    output:
        figure=report(
            "results/figures/inflation_effect.png",
            caption="../report/inflation_effect.rst",
            category="Method",
            labels={"figure": "effect of each parameter (Fig. 7)"},
        ),
    log:
        "logs/inflation_effect.log",
    script:
        "../scripts/inflation_effect.py"


rule table:
    input:
        bounds=expand("results/bound/{{spec}}/{sensor}.yaml", sensor=SENSORS),
        spec=spec_file,
    output:
        markdown=report(
            "results/tables/{spec}/inflation.md",
            caption="../report/table.rst",
            category="Bound",
            labels={"table": "spec vs bound (Table 2)", "spec": "{spec}"},
        ),
        csv="results/tables/{spec}/inflation.csv",
    params:
        sensors=SENSORS,
    log:
        "logs/table/{spec}.log",
    script:
        "../scripts/table.py"
