"""Outliers of one full-rate axis (rule outliers): imupipe.outliers.screen_outliers with the configured policy,
a YAML report, and under `remove` the cleaned series (netCDF4 alone, no xarray)."""

import logging

from imupipe.io import read_series, run_job, write_series, write_yaml_atomic
from imupipe.outliers import removal_effect, screen_outliers, stuck_spans

EFFECT_NOTE = {
    "remove": "the cleaned series (outliers replaced by their block median) feeds allan, decimate and lines",
    "warn": "data kept as recorded: the effect is what `remove` would change",
    "fail": "no outlier found (any outlier stops the run)",
}


def main(path_series: str, policy: str, k: float, window_samples: int, max_indices: int, path_report: str,
         path_cleaned: str | None = None) -> None:
    x, rate, attrs = read_series(path_series)
    units = attrs.pop("units")
    label = "/".join(str(attrs[key]) for key in ("dataset", "sensor", "axis") if key in attrs) or path_series
    try:
        x_out, report = screen_outliers(x, policy=policy, k=k, window=window_samples, label=label, units=units)
    except ValueError as exc:
        raise ValueError(f"{path_series}: {exc} (config key outliers.policy = 'fail')") from None
    if report.n_outliers and policy != "remove":
        x_out, _ = screen_outliers(x, policy="remove", k=k, window=window_samples, label=label, units=units)
    effect = removal_effect(x, x_out, rate)
    effect["note"] = EFFECT_NOTE[policy]
    effect["units"] = {"tau0_s": "s", "avar_tau0_before": f"({units})^2", "avar_tau0_after": f"({units})^2",
                       "avar_ratio": "1", "white_noise_ratio": "1"}
    out = {"dataset": attrs.get("dataset"), "sensor": attrs.get("sensor"), "axis": attrs.get("axis"),
           "series": path_series, "rate_hz": float(rate), **report.to_dict(max_indices=max_indices),
           "threshold": float(k), "effect": effect}
    stuck = stuck_spans(x, rate)  # on the record as read: a stuck stretch is no outlier, the rule leaves it
    out["stuck_spans"] = stuck["spans"]
    out["n_stuck_spans"] = stuck["n_stuck_spans"]
    out["stuck_rule"] = (f"runs of >= {stuck['min_run_samples']} identical samples ({stuck['min_run_s']:g} s): "
                         f"expected chance runs (n - 1) p0 q^(r - 2) < {stuck['alpha']:g} with p0 = {stuck['p0']:.4g}, "
                         f"q = {stuck['q']:.4g}, and at least 1 s")
    out["units"] = {**out["units"], "rate_hz": "Hz", "threshold": "robust standard deviations (1.4826 MAD)",
                    "stuck_spans": {"start_s": "s from the record's start", "stop_s": "s from the record's start",
                                    "value": units, "n_samples": "samples", "fraction": "of the record's samples"}}
    write_yaml_atomic(out, path_report, header=f"outliers of {label}: Hampel/MAD rule, policy {policy}")
    logging.info("%s: %d outlier(s) of %d samples (policy %s)", label, report.n_outliers, report.n_samples, policy)
    for sp in stuck["spans"]:
        logging.warning("%s: stuck channel, constant at %.6g %s from %.6g s to %.6g s (%.3g %% of the record)", label,
                        sp["value"], units, sp["start_s"], sp["stop_s"], 100.0 * sp["fraction"])
    if path_cleaned is not None:
        attrs.pop("rate_hz", None)
        attrs["outliers_removed"] = int(report.n_outliers)
        attrs["outlier_rule"] = out["rule"] + "; each outlier replaced by its block median"
        write_series(path_cleaned, x_out, rate_hz=rate, units=units, attrs=attrs)


if __name__ == "__main__":
    p = snakemake.params
    run_job(main, snakemake.log[0], path_series=snakemake.input.series, policy=p.policy, k=float(p.k),
            window_samples=int(p.window_samples), max_indices=int(p.max_indices),
            path_report=snakemake.output.report, path_cleaned=snakemake.output.get("cleaned"))
