# Verification of the exported model and the integrity contract (docs/method.md, "Integrity: what bounded must
# mean, and how to check it"). Per spec sheet and sensor type: the reference filter (paper eq. 17 position
# filter for accelerometers, an angle filter for gyros; `verify` section: fix_s of fixes, then an outage of
# application.outage_s) built on the bound's model, checked by exact covariance analysis against the
# identified upper envelope, the spec sheet and (simulated data) the truth, and by replay of the decimated
# records of that sensor (verify); the model reduction by integrity is tried there. The contract (contract)
# says `bounded` (every check passed and the verification ran), `verified` and each failed check with its
# numbers. One run-level job at the very end (integrity) fails the run when a contract is not bounded and
# verify.on_failure is fail, after every other output (figures, tables, summary) is written.


rule verify:
    input:
        bound=f"{RESULTS}/bound/{{spec}}/{{sensor}}.yaml",
        spectra=f"{RESULTS}/spectra/{{sensor}}.nc",
        spec=spec_file,
        truth=truth_file(),
        records=verify_records,
        segments=verify_segments,  # events.policy split: the full-rate records' segments (outliers.smk)
    output:
        verify=f"{RESULTS}/verify/{{spec}}/{{sensor}}.yaml",
        figure=report(
            f"{RESULTS}/figures/{{spec}}/verify_{{sensor}}.png",
            caption="../report/verify.rst",
            category="Verification",
            subcategory="{sensor}",
            labels={"figure": "verification", "spec": "{spec}", "sensor": "{sensor}"},
        ),
    params:
        fix_s=config["verify"]["fix_s"],
        outage_s=OUTAGE_S,
        sigma_fix_m=config["verify"]["sigma_fix_m"],
        sigma_fix_rad=config["verify"]["sigma_fix_rad"],
        # the reference filter runs at the exported filter's rate
        filter_rate_hz=FILTER_RATE_HZ,
        fix_rate_hz=config["verify"].get("fix_rate_hz"),
        reduce=config["verify"]["reduce"],
        replay_z=config["verify"]["replay_z"],
        max_bias_time_s=config["identify"].get("max_bias_time_s"),
    threads: 1
    resources:
        mem_mb=MEM_MB["verify"],
        runtime=RUNTIME_MIN["verify"],
    log:
        f"{LOGS}/verify/{{spec}}/{{sensor}}.log",
    benchmark:
        f"{BENCHMARKS}/verify/{{spec}}/{{sensor}}.tsv"
    conda:
        "../envs/imupipe.yaml"
    script:
        "../scripts/verify.py"


rule contract:
    input:
        bound=f"{RESULTS}/bound/{{spec}}/{{sensor}}.yaml",
        verify=f"{RESULTS}/verify/{{spec}}/{{sensor}}.yaml",
        spec=spec_file,
    output:
        contract=f"{RESULTS}/contract/{{spec}}/{{sensor}}.yaml",
    params:
        kf_file=f"{RESULTS}/kf/{{spec}}/{{sensor}}.yaml",
        kf_rate_hz=FILTER_RATE_HZ,
        # the application band of the in-band inflation, [1/outage_s, filter_rate_hz/2], as verify has them
        outage_s=OUTAGE_S,
        filter_rate_hz=FILTER_RATE_HZ,
        on_failure=config["verify"]["on_failure"],
    threads: 1
    resources:
        mem_mb=MEM_MB["contract"],
        runtime=RUNTIME_MIN["contract"],
    log:
        f"{LOGS}/contract/{{spec}}/{{sensor}}.log",
    benchmark:
        f"{BENCHMARKS}/contract/{{spec}}/{{sensor}}.tsv"
    conda:
        "../envs/imupipe.yaml"
    script:
        "../scripts/contract.py"


rule integrity:
    input:
        unpack(verdict_inputs),
    output:
        verdict=VERDICT,
    params:
        on_failure=config["verify"]["on_failure"],
    threads: 1
    resources:
        mem_mb=MEM_MB["integrity"],
        runtime=RUNTIME_MIN["integrity"],
    log:
        f"{LOGS}/contract/verdict.log",
    benchmark:
        f"{BENCHMARKS}/integrity/verdict.tsv"
    conda:
        "../envs/imupipe.yaml"
    script:
        "../scripts/contract.py"


EXTRA_TARGETS.extend(expand(f"{RESULTS}/verify/{{spec}}/{{sensor}}.yaml", spec=SPECS, sensor=SENSORS))
EXTRA_TARGETS.extend(expand(f"{RESULTS}/figures/{{spec}}/verify_{{sensor}}.png", spec=SPECS, sensor=SENSORS))
EXTRA_TARGETS.extend(expand(f"{RESULTS}/contract/{{spec}}/{{sensor}}.yaml", spec=SPECS, sensor=SENSORS))
EXTRA_TARGETS.append(VERDICT)
SUMMARY_INPUTS["verify"] = expand(f"{RESULTS}/verify/{{spec}}/{{sensor}}.yaml", spec=SPECS, sensor=SENSORS)
SUMMARY_INPUTS["contract"] = expand(f"{RESULTS}/contract/{{spec}}/{{sensor}}.yaml", spec=SPECS, sensor=SENSORS)
