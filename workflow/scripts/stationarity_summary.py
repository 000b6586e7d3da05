"""Per sensor type (rule stationarity_summary): every axis's verdict with stationarity.on_fail applied,
i.e. which curves the stacked files mark `included`."""

import logging

from imupipe.io import read_yaml, run_job, write_yaml_atomic


def summarise(verdicts: list, on_fail: str, sensor: str) -> dict:
    """Per-sensor summary; raises for on_fail = fail, or when on_fail = exclude leaves no curve."""
    curves = [{"dataset": v["dataset"], "axis": v["axis"], "stationary": bool(v["stationary"]),
               "p_value": v["p_value"], "test": v["test"], "paper_stationary": bool(v["paper"]["stationary"])}
              for v in verdicts]
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


def main(verdicts: list, on_fail: str, path_out: str, sensor: str) -> None:
    write_yaml_atomic(summarise([read_yaml(p) for p in verdicts], on_fail, sensor), path_out)


if __name__ == "__main__":
    run_job(main, snakemake.log[0], verdicts=list(snakemake.input.verdicts), on_fail=snakemake.params.on_fail,
            path_out=snakemake.output.summary, sensor=snakemake.wildcards.sensor)
