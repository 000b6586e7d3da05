# Helper functions and settings of the integrity rules (bound.smk, verify.smk; kf.smk uses none): the
# horizon of the all-frequency bound, the optional lines input, the verification's inputs and the run's verdict.
# In a file of their own (included by bound.smk) so that the rule files hold rules only.

VERDICT = f"{RESULTS}/contract/verdict.yaml"
# measured (tiny and default runs): verify ~100 MB (15 decimated axes of 10 h at 1 Hz are 4 MB), contract and
# integrity ~60 MB: about twice that, as the other small jobs
MEM_MB.update(verify=300, contract=150, integrity=150)
RUNTIME_MIN.update(verify=10, contract=10, integrity=10)


def verify_records(wildcards):
    """The decimated series of every dataset and axis of the job's sensor (the replay keeps the included ones)."""
    return per_axis("decimated", "nc")(wildcards)


def verify_truth(wildcards):
    """The simulation's truth (spec-sheet format), or nothing for real data."""
    return truth_file()


def verdict_inputs(wildcards):
    """Every contract, and every other target of the run (the verdict is the last job: when it fails the run,
    the figures, tables and summary of the failure are already written)."""
    contracts = expand(f"{RESULTS}/contract/{{spec}}/{{sensor}}.yaml", spec=SPECS, sensor=SENSORS)
    others = [t for t in final_outputs() if t != VERDICT and t not in contracts]
    return {"contracts": contracts, "others": others}


def bound_horizon_s():
    """The window a filter must be right over, s: the reference filter's fix period plus the outage."""
    return float(config["verify"]["fix_s"]) + float(config["application"]["horizon_s"])


def lines_files_of(wildcards):
    """The lines files of every dataset and axis of the job's sensor, when a `lines` rule exists (optional
    input: an empty list until the lines stage is included)."""
    if "lines" not in {r.name for r in workflow.rules}:
        return []
    return per_axis_files("lines", "yaml", wildcards.sensor)


def lines_params():
    """The line policy per sensor and the application band (Hz of the decimated spectrum; None: all of it)."""
    section = config.get("lines") or {}
    policy = section.get("policy") or {}
    return {"policy": {s: policy.get(s, "model") for s in ("gyro", "accel")},
            "application_band_hz": section.get("application_band_hz")}
