# Kalibr imu.yaml of both sensor types of one spec sheet: the smallest white noise and random walk whose PSD bounds
# the exported model's over the application band (an LP per exported axis model, the largest of each), the IMU's
# sample rate as update_rate (one rate for every dataset, or the one kalibr.update_rate_hz names among theirs; else
# the job refuses, naming each) and the topic of the
# dataset sheet. The values follow the exported KF model (kf rule: the bound after the verified reduction). An
# exported model with a narrowband line state is refused (no Kalibr fields written, the reason in the file and in
# the run summary): Kalibr's two terms cannot carry the line, and values without it would not bound.


rule kalibr:
    input:
        gyro=f"{RESULTS}/bound/{{spec}}/gyro.yaml",
        accel=f"{RESULTS}/bound/{{spec}}/accel.yaml",
        identified_gyro=f"{RESULTS}/identify/gyro.yaml",
        identified_accel=f"{RESULTS}/identify/accel.yaml",
        kf_gyro=f"{RESULTS}/kf/{{spec}}/gyro.yaml",
        kf_accel=f"{RESULTS}/kf/{{spec}}/accel.yaml",
        contract_gyro=f"{RESULTS}/contract/{{spec}}/gyro.yaml",
        contract_accel=f"{RESULTS}/contract/{{spec}}/accel.yaml",
    output:
        kalibr=report(
            f"{RESULTS}/kf/{{spec}}/kalibr_imu.yaml",
            caption="../report/kalibr.rst",
            category="Exports",
            labels={"file": "Kalibr imu.yaml", "spec": "{spec}"},
        ),
    params:
        rates=KALIBR_RATES,
        topics=KALIBR_TOPICS,
        update_rate_hz=config["kalibr"]["update_rate_hz"],
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


if set(SENSORS) == {"gyro", "accel"}:
    SUMMARY_INPUTS.setdefault("kalibr", []).extend(expand(f"{RESULTS}/kf/{{spec}}/kalibr_imu.yaml", spec=SPECS))
