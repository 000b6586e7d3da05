"""Outliers of one full-rate axis (rule outliers): imupipe.outliers.screen_outliers with the configured policy,
a YAML report, and under `remove` the cleaned series (netCDF4 alone, no xarray)."""

import logging

from imupipe.io import read_series, run_job, write_series, write_yaml_atomic
from imupipe.outliers import removal_effect, screen_outliers

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
    out["units"] = {**out["units"], "rate_hz": "Hz", "threshold": "robust standard deviations (1.4826 MAD)"}
    write_yaml_atomic(out, path_report, header=f"outliers of {label}: Hampel/MAD rule, policy {policy}")
    logging.info("%s: %d outlier(s) of %d samples (policy %s)", label, report.n_outliers, report.n_samples, policy)
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
