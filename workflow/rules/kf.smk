# Kalman-filter matrices of the exported model (one axis, SI): the bound's model, reduced by integrity when the
# verification accepted a reduction (verify), marked with the contract's verdict (a failing model is written
# for diagnosis, marked `bounded: false`).


rule kf:
    input:
        bound=f"{RESULTS}/bound/{{spec}}/{{sensor}}.yaml",
        verify=f"{RESULTS}/verify/{{spec}}/{{sensor}}.yaml",
        contract=f"{RESULTS}/contract/{{spec}}/{{sensor}}.yaml",
    output:
        kf=f"{RESULTS}/kf/{{spec}}/{{sensor}}.yaml",
    params:
        dt_s=1.0 / FILTER_RATE_HZ,
        outage_s=OUTAGE_S,
    threads: 1
    resources:
        mem_mb=MEM_MB["kf"],
        runtime=RUNTIME_MIN["kf"],
    log:
        f"{LOGS}/kf/{{spec}}/{{sensor}}.log",
    benchmark:
        f"{BENCHMARKS}/kf/{{spec}}/{{sensor}}.tsv"
    conda:
        "../envs/imupipe.yaml"
    script:
        "../scripts/kf.py"
