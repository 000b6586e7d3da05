"""Per sensor type (rule stationarity_summary): every axis's verdict with stationarity.on_fail applied,
i.e. which curves the stacked files mark `included`, and the paper's test (Levene + KS with asymptotic
p-values) on each decimated axis beside the calibrated verdict: computed here, once per sensor type, so that
only this job imports scipy.stats."""

import logging

from imupipe.io import read_series, read_yaml, run_job, write_yaml_atomic


def paper_tests(verdicts: list, decimated: list) -> list:
    """The paper's test of each axis: the per-axis verdict's own (test = paper), else run here on the axis's
    decimated record (test = calibrated), with the verdict's segments and level."""
    out = []
    for v, path in zip(verdicts, decimated, strict=True):
        if isinstance(v.get("paper"), dict):
            out.append(v["paper"])
            continue
        from imupipe.stationarity import stationarity_tests

        x, _, attrs = read_series(path)
        if (str(attrs.get("dataset")), str(attrs.get("axis"))) != (str(v["dataset"]), str(v["axis"])):
            raise ValueError(f"{path}: holds {attrs.get('dataset')}/{attrs.get('axis')}, expected the verdict's "
                             f"{v['dataset']}/{v['axis']}")
        cal = v["calibrated"]
        out.append(stationarity_tests(x, n_segments=int(cal["n_segments"]), alpha=float(cal["alpha"])))
    return out


def summarise(verdicts: list, on_fail: str, sensor: str, papers: list | None = None) -> dict:
    """Per-sensor summary; raises for on_fail = fail, or when on_fail = exclude leaves no curve. `papers`: the
    paper's test of each curve (default: each verdict's own ``paper``)."""
    papers = [v["paper"] for v in verdicts] if papers is None else papers
    curves = [{"dataset": v["dataset"], "axis": v["axis"], "stationary": bool(v["stationary"]),
               "p_value": v["p_value"], "test": v["test"], "paper_stationary": bool(paper["stationary"]),
               "paper": paper}
              for v, paper in zip(verdicts, papers, strict=True)]
    failing = [f"{c['dataset']}/{sensor}/{c['axis']} (p = {c['p_value']:.3g})" for c in curves if not c["stationary"]]
    if failing and on_fail == "fail":
        raise ValueError(f"non-stationary {sensor} records (stationarity.on_fail = fail): {', '.join(failing)}")
    for c in curves:
        c["included"] = c["stationary"] or on_fail == "warn"
    if failing:
        logging.warning("non-stationary: %s (%s)", ", ".join(failing),
                        "excluded from the bound" if on_fail == "exclude" else "kept, on_fail = warn")
    if not any(c["included"] for c in curves):
        raise ValueError(f"every {sensor} record failed the stationarity test and on_fail = exclude: nothing to bound")
    return {"sensor": sensor, "on_fail": on_fail, "n_curves": len(curves), "n_non_stationary": len(failing),
            "curves": curves}


def main(verdicts: list, decimated: list, on_fail: str, path_out: str, sensor: str) -> None:
    loaded = [read_yaml(p) for p in verdicts]
    write_yaml_atomic(summarise(loaded, on_fail, sensor, paper_tests(loaded, decimated)), path_out,
                      header="stationarity of every axis of one sensor type; p-values are probabilities")


if __name__ == "__main__":
    run_job(main, snakemake.log[0], verdicts=list(snakemake.input.verdicts),
            decimated=list(snakemake.input.decimated), on_fail=snakemake.params.on_fail,
            path_out=snakemake.output.summary, sensor=snakemake.wildcards.sensor)
