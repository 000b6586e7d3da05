# Spec sheet vs bound parameters in the spec sheet's units (paper Table 2), markdown, CSV and HTML (the report's).


rule tables:
    input:
        unpack(bounds_of_sensors),
        spec=spec_file,
    output:
        markdown=f"{RESULTS}/tables/{{spec}}/inflation.md",
        csv=f"{RESULTS}/tables/{{spec}}/inflation.csv",
        # the same table as a page of its own, so the report shows it as a table, not as markdown source
        html=report(
            f"{RESULTS}/tables/{{spec}}/inflation.html",
            caption="../report/table.rst",
            category="Bound",
            labels={"table": "spec vs bound (Table 2)", "spec": "{spec}"},
        ),
    params:
        sensors=SENSORS,
    threads: 1
    resources:
        mem_mb=MEM_MB["tables"],
        runtime=RUNTIME_MIN["tables"],
    log:
        f"{LOGS}/tables/{{spec}}.log",
    benchmark:
        f"{BENCHMARKS}/tables/{{spec}}.tsv"
    conda:
        "../envs/imupipe.yaml"
    script:
        "../scripts/tables.py"
