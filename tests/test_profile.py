"""The SLURM profile (workflow/profiles/slurm): its keys are options of Snakemake 9 and of the SLURM executor
plugin, the rules it names exist, and a dry run of the workflow with it plans the same jobs as a local one."""

import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

PROJECT_ROOT = Path(__file__).resolve().parents[1]
PROFILE = PROJECT_ROOT / "workflow" / "profiles" / "slurm"
SNAKEFILE = PROJECT_ROOT / "Snakefile"
HAVE_PLUGIN = importlib.util.find_spec("snakemake_executor_plugin_slurm") is not None
NO_PLUGIN = "snakemake-executor-plugin-slurm not installed (pip install '.[test]')"

# Settings of snakemake-executor-plugin-slurm 2.x (its ExecutorSettings, documented in the Snakemake plugin
# catalog), as profile keys: the check when the plugin itself is not installed.
SLURM_SETTINGS = {
    "slurm-array-jobs",
    "slurm-array-limit",
    "slurm-delete-logfiles-older-than",
    "slurm-disable-memory-fudge",
    "slurm-efficiency-report",
    "slurm-efficiency-report-path",
    "slurm-efficiency-threshold",
    "slurm-exclude-failed-nodes",
    "slurm-init-seconds-before-status-checks",
    "slurm-jobname-prefix",
    "slurm-keep-successful-logs",
    "slurm-logdir",
    "slurm-no-account",
    "slurm-no-requeue",
    "slurm-partition-config",
    "slurm-pass-command-as-script",
    "slurm-qos",
    "slurm-requeue",
    "slurm-reservation",
    "slurm-status-attempts",
    "slurm-status-command",
}
# Job resources the plugin turns into sbatch options (plugin docs, "Advanced Resource Specifications"),
# plus Snakemake's standard resources.
SLURM_RESOURCES = {
    "slurm_account",
    "slurm_partition",
    "slurm_extra",
    "slurm_cluster",
    "clusters",
    "runtime",
    "mem",
    "mem_mb",
    "mem_mb_per_cpu",
    "cpus_per_task",
    "tasks",
    "tasks_per_node",
    "nodes",
    "constraint",
    "qos",
    "gpu",
    "gres",
    "mpi",
    "tmpdir",
    "disk_mb",
}


@pytest.fixture(scope="module")
def profile() -> dict:
    return yaml.safe_load((PROFILE / "config.yaml").read_text())


def snakemake(*args: str, timeout: float = 300) -> subprocess.CompletedProcess:
    """Run ``python -m snakemake ARGS`` in the project root (the profile's and config's paths are relative)."""
    return subprocess.run(
        [sys.executable, "-m", "snakemake", *args],
        check=False,
        cwd=PROJECT_ROOT,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def job_counts(output: str) -> dict[str, int]:
    """The 'Job stats' table of a dry run: rule -> number of jobs."""
    table = output[output.index("Job stats:") :]
    counts = {}
    for line in table.splitlines()[3:]:
        fields = line.split()
        if len(fields) != 2 or not fields[1].isdigit():
            break
        counts[fields[0]] = int(fields[1])
    return counts


def test_executor_is_slurm(profile):
    assert profile["executor"] == "slurm"
    assert int(profile["jobs"]) >= 1


def test_keys_are_snakemake_or_plugin_options(profile):
    from snakemake.cli import get_argument_parser

    options = {s.lstrip("-") for action in get_argument_parser()._actions for s in action.option_strings}
    for key in profile:
        if key.startswith("slurm-") and not HAVE_PLUGIN:
            assert key in SLURM_SETTINGS, f"{key}: not a documented setting of the SLURM executor plugin"
        else:
            assert key in options, f"{key}: not a snakemake option (snakemake --help)"


def test_default_resources_are_slurm_resources(profile):
    resources = profile["default-resources"]
    assert {"runtime", "mem_mb"} <= set(resources)
    assert set(resources) <= SLURM_RESOURCES, set(resources) - SLURM_RESOURCES
    for name in ("runtime", "mem_mb"):  # a number, or an expression of `attempt` that gives one
        value = eval(str(resources[name]), {"__builtins__": {}}, {"attempt": 1})
        assert value > 0, name


def test_threads_are_positive_integers(profile):
    for rule, threads in profile.get("set-threads", {}).items():
        assert isinstance(threads, int) and threads >= 1, rule


@pytest.mark.skipif(not SNAKEFILE.exists(), reason="no Snakefile in the project root yet")
def test_rules_named_in_the_profile_exist(profile):
    listed = snakemake("--list-rules")
    assert listed.returncode == 0, listed.stderr
    rules = set(listed.stdout.split())
    named = set(profile.get("set-threads", {})) | set(profile.get("set-resources", {}))
    assert named <= rules, f"profile names rules the workflow does not have: {sorted(named - rules)}"


@pytest.mark.skipif(not SNAKEFILE.exists(), reason="no Snakefile in the project root yet")
@pytest.mark.skipif(not HAVE_PLUGIN, reason=NO_PLUGIN)
def test_dry_run_with_the_profile_plans_the_local_jobs():
    slurm = snakemake("-n", "--nolock", "--profile", str(PROFILE.relative_to(PROJECT_ROOT)))
    assert slurm.returncode == 0, slurm.stdout[-3000:] + slurm.stderr[-3000:]
    output = slurm.stdout + slurm.stderr
    assert "This was a dry-run" in output or "Nothing to be done" in output
    if "Job stats:" not in output:  # everything up to date
        return
    # the profile's resources reach the jobs ...
    assert re.search(r"resources: .*mem_mb=2000", output), output[-2000:]
    assert re.search(r"resources: .*runtime=30", output), output[-2000:]
    # ... and the plan is that of a local run
    local = snakemake("-n", "--nolock", "--cores", "1")
    assert local.returncode == 0, local.stderr[-3000:]
    assert job_counts(output) == job_counts(local.stdout + local.stderr)
