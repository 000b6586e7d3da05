"""A large workload against the default run: cost per sample and peak memory per rule.

    OPENBLAS_NUM_THREADS=1 nice -n 19 .venv/bin/python benchmarks/large_workload.py [--out DIR] [--cores 2]
        [--large config/large.yaml] [--default config/config.yaml]
    .venv/bin/python benchmarks/large_workload.py --read LARGE_WORKDIR DEFAULT_WORKDIR

Without ``--read``: for each of the two configurations (``--large``, on top of config/config.yaml: 2 simulated
datasets of 24 h at 200 Hz; ``--default``: 5 x 10 h at 125 Hz), a scratch copy of the workflow under ``--out``
(benchmarks/dag.py, ``make_scratch``) with nothing in it (no simulated records, no results), then one cold run
``snakemake --cores <cores> --configfile <config>`` with the Makefile's flags, simulation included; its wall
time. With ``--read``: two finished runs' working directories (the folders holding
``results/<name>/benchmarks/``) of the configurations ``--large`` and ``--default``, no wall time.

Printed (markdown): per rule, from Snakemake's benchmark files (``results/<name>/benchmarks/<rule>/...``):
jobs, total job wall time (sum of the files' ``s``) and CPU time (sum of ``cpu_time``: steadier than wall time
on a shared machine), largest ``max_rss`` (MB), for the large run and the default run, and the time per sample
of the large run over the default run's: per rule, a job's mean time over one record's samples (record length
x rate), so that a run stopped part way gives it too; for the whole run, the total job time over samples =
datasets x record length x rate (samples per axis summed over the datasets; the two runs have the same axes).
A ratio near 1 is cost linear in the record length; the rules after the per-axis stages (identify onwards)
work on decimated or summarised data and cost less per sample on longer records. ``max_rss`` is sampled by
Snakemake at 0 s and every 0.5 s after, so for sub-second jobs it mostly shows the launching process.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from dag import RUN_FLAGS, clean_all, make_scratch, read_benchmark_file, snakemake  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
MB = 1e6


def run_config(config: Path) -> dict:
    """The configuration a run of `config` uses (its keys on top of config/config.yaml)."""
    import yaml

    from imupipe.runconfig import merged_config

    return merged_config(yaml.safe_load(Path(config).read_text()) or {}, ROOT, where=str(config))


def samples_of(cfg: dict) -> int:
    """Samples per axis summed over the simulated datasets: n_datasets x duration_h x 3600 x record_rate_hz
    (an int)."""
    sim = cfg.get("simulation")
    if not sim:
        raise SystemExit("the configuration does not simulate its datasets: samples per axis unknown")
    return int(sim["n_datasets"] * round(sim["duration_h"] * 3600.0 * sim["record_rate_hz"]))


def per_rule(bench_dir: Path) -> dict:
    """rule -> {'jobs', 's' (sum of job wall times), 'cpu' (sum of the jobs' CPU times, s), 'rss' (largest
    max_rss, MB)} from a run's benchmark files."""
    if not bench_dir.is_dir():
        raise SystemExit(f"{bench_dir}: no benchmark files (not a finished run's working directory?)")
    out = {}
    for f in sorted(bench_dir.rglob("*.tsv")):
        rel = f.relative_to(bench_dir)
        rule = rel.parts[0] if len(rel.parts) > 1 else f.stem
        row = read_benchmark_file(f)
        r = out.setdefault(rule, {"jobs": 0, "s": 0.0, "cpu": 0.0, "rss": None})
        r["jobs"] += 1
        r["s"] += float(row.get("s", 0.0))
        cpu = row.get("cpu_time")
        r["cpu"] += float(cpu) if isinstance(cpu, float) else 0.0
        rss = row.get("max_rss")
        if isinstance(rss, float):
            rss_mb = rss * 2**20 / MB  # Snakemake's max_rss is in MiB
            r["rss"] = rss_mb if r["rss"] is None else max(r["rss"], rss_mb)
    return out


def cold_run(config: Path, out: Path, cores: int) -> tuple:
    """A scratch copy under `out` named after the config, emptied, and one cold run: (workdir, wall s)."""
    work = make_scratch(ROOT, out / config.stem)
    clean_all(work)
    rel = config.resolve().relative_to(ROOT)
    args = ["--cores", str(cores), "--configfile", str(rel), *RUN_FLAGS, "--quiet", "rules", "host", "reason"]
    t0 = time.perf_counter()
    snakemake(work, args, out / f"{config.stem}.log")
    return work, time.perf_counter() - t0


def table(large: dict, default: dict, n_large: int, n_default: int, rec_large: int, rec_default: int) -> str:
    """Per rule: the sums, the largest max_rss, and the time per sample of a job: the mean job time over one
    record's samples (`rec_*`, samples per axis of one dataset), large over default (a mean, so it holds for a
    run stopped part way too). The last row: the run's total job time over its samples (`n_*`, over the
    datasets), large over default."""
    def mb(v):
        return "-" if v is None else f"{v:.0f}"

    def per_job(a, b, key):
        if not (a.get(key) and b.get(key)):
            return "-"
        return f"{(a[key] / a['jobs'] / rec_large) / (b[key] / b['jobs'] / rec_default):.2f}"

    def total(a, b, key):
        return f"{(a[key] / n_large) / (b[key] / n_default):.2f}" if a.get(key) and b.get(key) else "-"

    rows = ["| rule | jobs (large / default) | job wall, large / default (s) | job CPU, large / default (s) "
            "| max RSS, large / default (MB) | wall per sample of a job, large / default "
            "| CPU per sample of a job, large / default |",
            "|---|---|---|---|---|---|---|"]
    rules = sorted(set(large) | set(default), key=lambda r: -(large.get(r, {}).get("cpu", 0.0)))
    for rule in rules:
        a, b = large.get(rule, {}), default.get(rule, {})
        rows.append(f"| {rule} | {a.get('jobs', 0)} / {b.get('jobs', 0)} "
                    f"| {a.get('s', 0.0):.1f} / {b.get('s', 0.0):.1f} "
                    f"| {a.get('cpu', 0.0):.1f} / {b.get('cpu', 0.0):.1f} "
                    f"| {mb(a.get('rss'))} / {mb(b.get('rss'))} "
                    f"| {per_job(a, b, 's')} | {per_job(a, b, 'cpu')} |")
    tot = [{"jobs": sum(r["jobs"] for r in d.values()), "s": sum(r["s"] for r in d.values()),
            "cpu": sum(r["cpu"] for r in d.values()),
            "rss": max((r["rss"] for r in d.values() if r["rss"]), default=None)} for d in (large, default)]
    a, b = tot
    rows.append(f"| **all** (per sample: the run's job time over its samples) | {a['jobs']} / {b['jobs']} "
                f"| {a['s']:.1f} / {b['s']:.1f} | {a['cpu']:.1f} / {b['cpu']:.1f} "
                f"| {mb(a['rss'])} / {mb(b['rss'])} | {total(a, b, 's')} | {total(a, b, 'cpu')} |")
    return "\n".join(rows)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--large", type=Path, default=ROOT / "config" / "large.yaml")
    ap.add_argument("--default", type=Path, default=ROOT / "config" / "config.yaml")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "large_workload")
    ap.add_argument("--cores", type=int, default=2)
    ap.add_argument("--read", nargs=2, type=Path, metavar=("LARGE_WORKDIR", "DEFAULT_WORKDIR"),
                    help="read two finished runs' benchmark files instead of running")
    args = ap.parse_args(argv)

    walls = {}
    if args.read:  # the runs of --large and --default
        works = list(args.read)
    else:
        args.out.mkdir(parents=True, exist_ok=True)
        works = []
        for cfg in (args.large, args.default):
            work, wall = cold_run(cfg, args.out, args.cores)
            works.append(work)
            walls[cfg.stem] = wall
            print(f"{cfg.stem}: cold run {wall:.1f} s wall", flush=True)

    cfgs = [run_config(c) for c in (args.large, args.default)]
    n = [samples_of(c) for c in cfgs]
    rules = [per_rule(w / "results" / c.get("name", "paper") / "benchmarks") for w, c in zip(works, cfgs)]
    for label, c, k in zip(("large", "default"), cfgs, n):
        sim = c["simulation"]
        wall = walls.get((args.large if label == "large" else args.default).stem)
        print(f"{label} ({c.get('name')}): {sim['n_datasets']} x {sim['duration_h']:g} h at "
              f"{sim['record_rate_hz']:g} Hz = {k / sim['n_datasets'] / 1e6:.2f} M samples per axis and "
              "dataset, "
              f"{k / 1e6:.2f} M over the datasets" + (f"; cold run {wall:.1f} s wall" if wall else ""))
    if len(walls) == 2:
        wl, wd = walls[args.large.stem], walls[args.default.stem]
        print(f"wall time per sample, large / default: {(wl / n[0]) / (wd / n[1]):.2f}")
    print()
    rec = [n_ // c["simulation"]["n_datasets"] for n_, c in zip(n, cfgs)]
    print(table(rules[0], rules[1], n[0], n[1], rec[0], rec[1]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
