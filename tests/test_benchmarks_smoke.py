"""Smoke test of the benchmark harness (``make bench``) so that it cannot rot: a tiny-size run of
``benchmarks/run.py --quick`` and a run of the DAG part on a three-rule toy workflow. No timing assertions:
only that every section runs and writes its table, numbers and figure."""

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

PROJECT_ROOT = Path(__file__).resolve().parents[1]
BENCH = PROJECT_ROOT / "benchmarks"


def _env():
    env = dict(os.environ)
    env["OPENBLAS_NUM_THREADS"] = "1"
    env.setdefault("MPLBACKEND", "Agg")
    return env


def test_quick_run_writes_table_numbers_and_figure(tmp_path):
    r = subprocess.run(
        [sys.executable, str(BENCH / "run.py"), "--quick", "--repeats", "1", "--skip-dag", "--out", str(tmp_path)],
        cwd=PROJECT_ROOT, env=_env(), capture_output=True, text=True, timeout=600, check=False,
    )
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    md = (tmp_path / "benchmark.md").read_text()
    for heading in ("## 1. Allan variance", "## 2. Identification", "## 3. PSD and bound path",
                    "## 4. Whole workflow", "## Targets"):
        assert heading in md, f"section {heading!r} missing from the table"
    assert "Library sections not measured" not in md
    results = json.loads((tmp_path / "benchmark.json").read_text())
    assert set(results["allan"]) == {"octave", "10/decade", "all (1 Hz series)"}
    for entry in results["allan"].values():
        assert entry["imupipe_allan_variance"]["n"] == 1
        assert entry["av_relerr_median"] >= 0
    bound_keys = [k for k in results["bound"] if not k.startswith("_")]
    assert any(k.startswith("25 Hz") for k in bound_keys) and any("confidence" in k for k in bound_keys)
    assert all(results["bound"][k]["looseness_vs_true"] > 0 for k in bound_keys)
    verdicts = {t["target"]: t["verdict"] for t in results["targets"]}
    assert verdicts["spec-sheet rerun <= 5 s"] == "NOT MEASURED"  # --skip-dag
    assert (tmp_path / "benchmark.png").stat().st_size > 0


# a toy workflow with the shape the DAG benchmark expects: a simulate rule, per-axis script jobs with
# benchmark files, and a rule that alone depends on the spec sheet
TOY_SNAKEFILE = textwrap.dedent(
    """
    configfile: "config/config.yaml"
    AXES = config["axes"]

    rule all:
        input:
            expand("results/allan/{axis}.txt", axis=AXES),
            "results/bound/bound.txt",

    rule simulate:
        output:
            "data/simulated/d1.txt",
        shell:
            "mkdir -p data/simulated && echo 1 > {output}"

    rule allan:
        input:
            "data/simulated/d1.txt",
        output:
            "results/allan/{axis}.txt",
        log:
            "logs/allan/{axis}.log",
        benchmark:
            "benchmarks/allan/{axis}.tsv"
        script:
            "workflow/scripts/allan.py"

    rule bound:
        input:
            allan=expand("results/allan/{axis}.txt", axis=AXES),
            spec="config/specs/stim300.yaml",
        output:
            "results/bound/bound.txt",
        benchmark:
            "benchmarks/bound/bound.tsv"
        shell:
            "cat {input.allan} > {output}"
    """
)
TOY_SCRIPT = textwrap.dedent(
    """
    import numpy as np

    x = np.ones(2_000_000)  # 16 MB resident for the memory sampler to see
    with open(snakemake.output[0], "w") as fh:
        fh.write(str(x.sum()))
    """
)


@pytest.fixture
def dag_module(monkeypatch):
    monkeypatch.syspath_prepend(str(BENCH))
    import dag

    return dag


def test_dag_benchmark_on_a_toy_workflow(tmp_path, dag_module):
    repo = tmp_path / "repo"
    (repo / "workflow" / "scripts").mkdir(parents=True)
    (repo / "config" / "specs").mkdir(parents=True)
    (repo / "Snakefile").write_text(TOY_SNAKEFILE)
    (repo / "workflow" / "scripts" / "allan.py").write_text(TOY_SCRIPT)
    (repo / "config" / "config.yaml").write_text("axes: [x, y]\n")
    (repo / "config" / "specs" / "stim300.yaml").write_text("gyro: {}\n")
    out = tmp_path / "out"
    res = dag_module.run(repo, out, cores=2, repeats=1)
    assert "skipped" not in res, res.get("markdown")
    assert res["jobs_cold"]["allan"] == 2 and res["jobs_cold"]["bound"] == 1
    assert res["jobs_rerun"].get("bound") == 1 and "allan" not in res["jobs_rerun"]  # only what needs the spec
    assert res["per_rule"]["allan"]["axis_rule"] and res["per_rule"]["allan"]["benchmarked_jobs"] == 2
    assert res["per_rule"]["allan"]["script"] == "allan.py"
    assert res["imports"]["allan"]["modules"] == ["numpy"]
    assert 0 < res["orchestration"]["fraction"]
    assert "Per rule" in res["markdown"]
    assert not (out / "dag_scratch").exists()  # scratch removed unless --keep-scratch
    assert not (repo / "results").exists()  # the checkout is never run in


def test_parsers_on_snakemake_output(dag_module):
    text = textwrap.dedent(
        """
        Job stats:
        job      count
        -----  -------
        a            2
        all          1
        total        3

        [Mon Nov 23 02:52:17 2026]
        localrule a:
            output: out/2.txt
            log: logs/a/2.log
            jobid: 2
            benchmark: bench/a/2.tsv
            reason: Missing output files: out/2.txt
            wildcards: dataset=d1, axis=y
            resources: tmpdir=/tmp
        [Mon Nov 23 02:52:17 2026]
        Finished jobid: 2 (Rule: a)
        """
    )
    assert dag_module.parse_job_stats(text) == {"a": 2, "all": 1, "total": 3}
    (job,) = dag_module.parse_jobs(text)
    assert job["rule"] == "a" and job["benchmark"] == "bench/a/2.tsv"
    assert job["wildcards"] == {"dataset": "d1", "axis": "y"}
