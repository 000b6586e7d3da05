# Kalibr-style imu.yaml of both sensor types of one spec sheet.


rule kalibr:
    input:
        gyro=f"{RESULTS}/bound/{{spec}}/gyro.yaml",
        accel=f"{RESULTS}/bound/{{spec}}/accel.yaml",
    output:
        kalibr=f"{RESULTS}/kf/{{spec}}/kalibr_imu.yaml",
    params:
        rate_hz=config["application"]["rate_hz"],
    threads: 1
    resources:
        mem_mb=MEM_MB["kalibr"],
        runtime=RUNTIME_MIN["kalibr"],
    log:
        f"{LOGS}/kalibr/{{spec}}.log",
    benchmark:
        f"{BENCHMARKS}/kalibr/{{spec}}.tsv"
    conda:
        "../envs/imupipe.yaml"
    script:
        "../scripts/kalibr.py"
