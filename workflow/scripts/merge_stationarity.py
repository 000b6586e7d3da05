"""Per-sensor stationarity summary; applies stationarity.on_fail (rule merge_stationarity)."""

import logging

from imupipe.io import read_yaml, run_job, write_yaml_atomic


def main(paths: list, on_fail: str, path_out: str, sensor: str) -> None:
    curves = []
    for path in paths:
        v = read_yaml(path)
        curves.append({"dataset": v["dataset"], "axis": v["axis"], "stationary": bool(v["stationary"]),
                       "p_value": v["p_value"], "test": v["test"],
                       "paper_stationary": bool(v["paper"]["stationary"])})
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
    write_yaml_atomic({"sensor": sensor, "on_fail": on_fail, "n_curves": len(curves),
                       "n_non_stationary": len(failing), "curves": curves}, path_out)


if __name__ == "__main__":
    run_job(main, snakemake.log[0], paths=list(snakemake.input.verdicts), on_fail=snakemake.params.on_fail,
            path_out=snakemake.output.summary, sensor=snakemake.wildcards.sensor)
