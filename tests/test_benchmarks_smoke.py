"""Smoke test of the benchmark harness (``make bench`` = ``benchmarks/run.py``) so that it cannot rot.

The core functions of ``run.py`` run on a tiny input (10 min at 125 Hz, 3 records, one timed run per setting):
every section must produce its rows and columns with finite numbers, and the markdown, CSV and figure writers
must work. No timing assertions. The DAG part (``benchmarks/dag.py``) is checked through its parsers and, as a
slow test, on a three-rule toy workflow.
"""

import csv
import math
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

PROJECT_ROOT = Path(__file__).resolve().parents[1]
BENCH = PROJECT_ROOT / "benchmarks"
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MPLBACKEND", "Agg")


@pytest.fixture(scope="module")
def bench():
    sys.path.insert(0, str(BENCH))
    try:
        import run

        yield run
    finally:
        sys.path.remove(str(BENCH))


@pytest.fixture(scope="module")
def tiny(bench):
    return bench.run_all(bench.TINY, repeats=1, seed=7, log=lambda s: None)


def _finite(v):
    return v is not None and math.isfinite(float(v))


def _table_rows(md_table):
    lines = [ln for ln in md_table.splitlines() if ln.startswith("|")]
    header = [c.strip() for c in lines[0].strip("|").split("|")]
    body = [[c.strip() for c in ln.strip("|").split("|")] for ln in lines[2:]]
    assert all(len(r) == len(header) for r in body), "ragged markdown table"
    return header, body


def test_every_setting_is_measured_with_finite_numbers(bench, tiny):
    sizes = bench.TINY
    S = tiny["settings"]
    by = {}
    for s in S:
        by.setdefault(s.section, []).append(s)
        assert s.timing.n >= 1 and _finite(s.timing.median) and s.timing.median >= 0, (s.section, s.method)
    assert {"av_paper", "av_sweep", "ident_rate", "tau_grid", "ident_grid", "psd", "bound"} <= set(by)

    # paper-scale AV: imupipe estimator, API, allantools; same numbers
    assert len(by["av_paper"]) == 3
    for s in by["av_paper"]:
        assert _finite(s.metrics["av_err_median"])
    assert by["av_paper"][0].metrics["max_rel_diff_allantools"] < 1e-9
    # growth sweep: 3 methods x every N, an exponent per method
    assert len(by["av_sweep"]) == 3 * len(sizes.sweep_n)
    assert all(_finite(s.metrics["growth_exponent"]) for s in by["av_sweep"])
    # identification per decimation rate
    assert [s.setting for s in by["ident_rate"]] == [f"{r:g} Hz" for r in sizes.rates]
    for s in by["ident_rate"]:
        assert _finite(s.metrics["err_white"]) and _finite(s.metrics["model_av_err"])
    # tau grids with the allantools peer, and three identification methods per grid
    assert [(s.setting, s.method.split()[0]) for s in by["tau_grid"]] == [
        (g, m) for g in ("octave", "10/decade", "all") for m in ("imupipe", "allantools")]
    assert all(s.metrics["max_rel_diff_allantools"] < 1e-9 for s in by["tau_grid"])
    assert len(by["ident_grid"]) == 9
    assert {s.method.split(" (")[0] for s in by["ident_grid"]} == {"fit_allan, 1 GM", "fit_allan, 2 GM", "slope line"}
    assert all(_finite(s.metrics["model_av_err"]) for s in by["ident_grid"])
    # PSD: 2 windows x (raw, smoothed) + scipy peer
    assert len(by["psd"]) == 5 and all(_finite(s.metrics["psd_err"]) for s in by["psd"])
    # bound: 2 windows x 3 modes x 2 GM + the paper's hand inflation per window
    assert len(by["bound"]) == 14
    for s in by["bound"]:
        for k in ("looseness_true", "min_model_true", "margin_samples"):
            assert _finite(s.metrics[k]) and s.metrics[k] > 0, (s.method, k)
        if s.method == "bound_psd raw":
            assert s.metrics["margin_samples"] >= 1 - 1e-6  # raw mode bounds every periodogram ordinate


def test_tables_csv_and_figure(bench, tiny, tmp_path):
    T = bench.tables(tiny)
    h, rows = _table_rows(T["ident_rate"])
    assert h[0] == "rate" and "N error" in h and "K error" in h and "model AV error" in h
    assert [r[0] for r in rows] == ["125 Hz", "25 Hz", "5 Hz", "1 Hz"]
    h, rows = _table_rows(T["bound"])
    assert "looseness: mean model/true PSD" in h and "margin: min model/sample PSD" in h and len(rows) == 14
    h, rows = _table_rows(T["ident_grid"])
    assert len(rows) == 9 and all("nan" not in c for r in rows for c in r)
    h, rows = _table_rows(T["av_sweep"].split("\n\n", 1)[1])
    assert rows[-1][0].startswith("growth exponent") and len(rows) == len(bench.TINY.sweep_n) + 1
    md = bench.markdown(tiny, "cmd", {"cpu": "test"})
    for heading in ("## 1. Allan variance", "## 2. Identification by decimation rate", "## 3. Tau grid",
                    "## 4. PSD window", "## 5. Bound mode", "## Targets"):
        assert heading in md
    rows = bench.csv_rows(tiny)
    path = tmp_path / "speed_vs_error.csv"
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    with open(path, newline="") as fh:
        back = list(csv.DictReader(fh))
    assert {"section", "setting", "method", "time_median_s", "time_min_s", "time_max_s", "metric", "value"} <= set(
        back[0])
    assert all(math.isfinite(float(r["time_median_s"])) for r in back)
    bench.plot(tiny, tmp_path / "speed_vs_error.png", "tiny")
    assert (tmp_path / "speed_vs_error.png").stat().st_size > 10_000


def test_command_lines_have_help():
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    for script, flag in (("run.py", "--quick"), ("dag.py", "--cores"), ("line_integrity.py", "--broadband"),
                         ("line_looks.py", "--set"), ("plan_auto.py", "--records"), ("line_resolution.py", "seeds")):
        r = subprocess.run([sys.executable, str(BENCH / script), "--help"], cwd=PROJECT_ROOT, env=env,
                           capture_output=True, text=True, timeout=60, check=False)
        assert r.returncode == 0 and flag in r.stdout, r.stderr[-2000:]


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


@pytest.mark.slow
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


def test_the_dag_benchmark_runs_snakemake_as_make_run_does(dag_module):
    # the measured run must be the one users get: the Makefile's SNAKEMAKE_FLAGS are the benchmark's RUN_FLAGS
    makefile = (BENCH.parent / "Makefile").read_text()
    line = next(ln for ln in makefile.splitlines() if ln.startswith("SNAKEMAKE_FLAGS"))
    assert line.split("=", 1)[1].split() == dag_module.RUN_FLAGS


def test_critical_path_is_the_longest_chain_of_job_walls(dag_module):
    # a -> b -> d and a -> c -> d: with unlimited cores the run lasts a + max(b, c) + d = 1 + 5 + 1 s, along a, c, d
    jobs = [
        {"rule": "a", "input": "", "output": "x", "bench": {"s": 1.0}},
        {"rule": "b", "input": "x", "output": "y", "bench": {"s": 2.0}},
        {"rule": "c", "input": "x", "output": "z", "bench": {"s": 5.0}},
        {"rule": "d", "input": "y, z", "output": "w", "bench": {"s": 1.0}},
        {"rule": "all", "input": "w"},  # no benchmark file: 0 s
    ]
    cp = dag_module.critical_path(jobs)
    assert cp["s"] == 7.0
    assert cp["chain"] == ["a", "c", "d", "all"]


def test_clean_outputs_keeps_the_simulated_recordings(dag_module, tmp_path):
    sim = tmp_path / "results" / "paper" / "simulated"
    sim.mkdir(parents=True)
    (sim / "sim01.nc").write_text("data")
    (tmp_path / "results" / "paper" / "psd").mkdir()
    (tmp_path / "logs").mkdir()
    dag_module.clean_outputs(tmp_path)
    assert (sim / "sim01.nc").read_text() == "data"
    assert not (tmp_path / "results" / "paper" / "psd").exists() and not (tmp_path / "logs").exists()


def test_axis_memory_table():
    """benchmarks/axis_memory.py's table: per rule the two peaks (MB) and the larger over one axis."""
    sys.path.insert(0, str(BENCH))
    try:
        import axis_memory
    finally:
        sys.path.remove(str(BENCH))
    rows = {rule: {"bench": 50.0, "hwm": 72.0} for rule in axis_memory.RULES}
    rows["psd"] = {"bench": None, "hwm": 18.0}
    text = axis_memory.table({10.0: {"axis_mb": 36.0, **rows}})
    assert "| ingest | 50 / 72 | 2.00 |" in text
    assert "| psd | n/a / 18 | 0.50 |" in text
    assert axis_memory.targets("m")[0] == "results/m/allan/sim01/gyro/x.nc"


def test_axis_memory_csv_mode(tmp_path):
    """benchmarks/axis_memory.py --csv: the CSV it writes reads back at its rate with its row count (a 40 s
    record at 25 Hz: 1000 rows), and its table gives the peak rise over one axis."""
    sys.path.insert(0, str(BENCH))
    try:
        import axis_memory
    finally:
        sys.path.remove(str(BENCH))
    from imupipe.readers import read_channel

    n = axis_memory.write_csv(tmp_path / "imu.csv", 40.0 / 3600.0, 25.0)
    rec = read_channel(("gyro", "x"), tmp_path / "imu.csv", time_column="time", rate_hz=25.0,
                       units={"gyro": "rad/s", "accel": "m/s^2"})
    assert n == 1000 and rec["gyro", "x"].size == n and rec.rate_hz == 25.0
    text = axis_memory.csv_table({10.0: {"axis_mb": 36.0, "rise_mb": 123.0}})
    assert "| 10 h | 36 | 123 | 3.42 |" in text
