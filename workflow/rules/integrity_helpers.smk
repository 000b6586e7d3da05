# Helper functions and settings of the integrity rules (bound.smk, verify.smk; kf.smk uses none): the
# horizon of the all-frequency bound, the optional lines input, the verification's inputs and the run's verdict.
# In a file of their own (included by bound.smk) so that the rule files hold rules only.

VERDICT = f"{RESULTS}/contract/verdict.yaml"
# measured (tiny and default runs): verify ~100 MB (15 decimated axes of 10 h at 1 Hz are 4 MB), contract and
# integrity ~60 MB: about twice that, as the other small jobs
MEM_MB.update(contract=150, integrity=150)
RUNTIME_MIN.update(verify=10, contract=10, integrity=10)

# The replay runs the reference filter at verify.filter_rate_hz on the records block-averaged to that rate. When
# decimate.rate_hz is a whole multiple of it the decimated series serve (the same block averages); otherwise (a
# filter faster than the decimation, e.g. 100 Hz on 100 Hz records decimated to 1 Hz for the bound) the full-rate
# series are read, one at a time, and block-averaged to the filter rate on reading.
_REPLAY_RATIO = float(config["decimate"]["rate_hz"]) / float(config["verify"]["filter_rate_hz"])
REPLAY_FROM_DECIMATED = _REPLAY_RATIO >= 1.0 - 1e-9 and abs(_REPLAY_RATIO - round(_REPLAY_RATIO)) <= 1e-9 * _REPLAY_RATIO


def verify_records(wildcards):
    """The series the replay reads, of every dataset and axis of the job's sensor (the replay keeps the included
    ones): the decimated ones when decimate.rate_hz is a multiple of verify.filter_rate_hz, else the full-rate."""
    if REPLAY_FROM_DECIMATED:
        return per_axis("decimated", "nc")(wildcards)
    return [FULL_RATE_SERIES.format(dataset=d, sensor=wildcards.sensor, axis=a)
            for d in DATASETS for a in AXES_OF[d][wildcards.sensor]]


def verify_mem_mb(wildcards, input):
    """300 MB, plus one full-rate record (and its block average) and the records at the filter rate when the
    replay reads full-rate series: 300 + 2 x the largest file + the records' total / (record rate / filter rate)."""
    if REPLAY_FROM_DECIMATED:
        return 300
    sizes = [os.path.getsize(f) / 1e6 for f in input.records if os.path.exists(f)]
    return int(300 + 2 * max(sizes, default=0.0) + sum(sizes))


MEM_MB["verify"] = verify_mem_mb


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
