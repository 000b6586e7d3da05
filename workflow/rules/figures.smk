# Figures of one spec sheet and sensor type (paper Figures 5, 6, 8) and the effect of each parameter (Fig. 7).


rule figures:
    # before kf, kalibr and tables when both are ready: the figures are the longer jobs at the end of a run
    priority: 1
    input:
        spectra=f"{RESULTS}/spectra/{{sensor}}.nc",
        allan=f"{RESULTS}/allan/{{sensor}}.nc",
        identified=f"{RESULTS}/identify/{{sensor}}.yaml",
        bound=f"{RESULTS}/bound/{{spec}}/{{sensor}}.yaml",
        spec=spec_file,
    output:
        psd_bound=report(
            f"{RESULTS}/figures/{{spec}}/psd_bound_{{sensor}}.png",
            caption="../report/psd_bound.rst",
            category="Bound",
            subcategory="{sensor}",
            labels={"figure": "PSD bound (Fig. 5)", "spec": "{spec}", "sensor": "{sensor}"},
        ),
        allan_components=report(
            f"{RESULTS}/figures/{{spec}}/allan_components_{{sensor}}.png",
            caption="../report/allan_components.rst",
            category="Bound",
            subcategory="{sensor}",
            labels={"figure": "Allan components (Fig. 6)", "spec": "{spec}", "sensor": "{sensor}"},
        ),
        inflation_steps=report(
            f"{RESULTS}/figures/{{spec}}/inflation_steps_{{sensor}}.png",
            caption="../report/inflation_steps.rst",
            category="Bound",
            subcategory="{sensor}",
            labels={"figure": "hand inflation (Fig. 8)", "spec": "{spec}", "sensor": "{sensor}"},
        ),
    threads: 1
    resources:
        mem_mb=MEM_MB["figures"],
        runtime=RUNTIME_MIN["figures"],
    log:
        f"{LOGS}/figures/{{spec}}/{{sensor}}.log",
    benchmark:
        f"{BENCHMARKS}/figures/{{spec}}/{{sensor}}.tsv"
    conda:
        "../envs/imupipe.yaml"
    script:
        "../scripts/figures.py"


rule inflation_effect:
    output:
        figure=report(
            f"{RESULTS}/figures/inflation_effect.png",
            caption="../report/inflation_effect.rst",
            category="Method",
            labels={"figure": "effect of each parameter (Fig. 7)"},
        ),
    threads: 1
    resources:
        mem_mb=MEM_MB["inflation_effect"],
        runtime=RUNTIME_MIN["inflation_effect"],
    log:
        f"{LOGS}/inflation_effect.log",
    benchmark:
        f"{BENCHMARKS}/inflation_effect.tsv"
    conda:
        "../envs/imupipe.yaml"
    script:
        "../scripts/inflation_effect.py"
