# Every axis's PSD (kind = spectra) or Allan variance (kind = allan) of one sensor type in one file, dims
# (dataset, axis, frequency | tau), with the `included` flag of the stationarity summary.


rule stack:
    input:
        unpack(stack_inputs),
    output:
        stacked=f"{RESULTS}/{{kind}}/{{sensor}}.nc",
    params:
        join=stack_join,
    threads: 1
    resources:
        mem_mb=MEM_MB["stack"],
        runtime=RUNTIME_MIN["stack"],
    log:
        f"{LOGS}/stack/{{kind}}/{{sensor}}.log",
    benchmark:
        f"{BENCHMARKS}/stack/{{kind}}/{{sensor}}.tsv"
    conda:
        "../envs/imupipe.yaml"
    script:
        "../scripts/stack.py"
