"""Outliers, stuck spans and events of one full-rate axis (rule outliers): imupipe.stages.outliers, a YAML report,
the cleaned series (outliers `remove`, events `exclude`), the axis's segments (events `split`: imupipe.segments)."""

import logging

from imupipe.io import read_series, run_job, write_series, write_yaml_atomic


def main(path_series: str, policy: str, k: float, window_samples: int, max_indices: int, path_report: str,
         path_cleaned=None, events: dict | None = None, min_segment_s: float = 0.0, path_segments=None) -> None:
    from imupipe.stages.outliers import outliers_stage

    x, rate, attrs = read_series(path_series)
    units = attrs.pop("units")
    out, x_out = outliers_stage(x, rate, units=units, dataset=attrs.get("dataset"), sensor=attrs.get("sensor"),
                                axis=attrs.get("axis"), policy=policy, k=k, window_samples=window_samples,
                                max_indices=max_indices, events=events, min_segment_s=min_segment_s,
                                series=path_series)
    label, ev_policy = out["label"], out["events_policy"]
    write_yaml_atomic(out, path_report, header=f"outliers and events of {label}: policies {policy}, {ev_policy}")
    logging.info("%s: %d outlier(s), %d event(s) of %d samples", label, out["n_outliers"], out["n_events"], x.size)
    for sp in out["stuck_spans"]:
        logging.warning("%s: stuck channel, constant at %.6g %s from %.6g s to %.6g s", label, sp["value"], units,
                        sp["start_s"], sp["stop_s"])
    if path_segments is not None:
        write_yaml_atomic(out["events_segments"], path_segments, header=f"segments of {label} (events.policy split)")
    if path_cleaned is not None:
        attrs.pop("rate_hz", None)
        attrs["outliers_removed"] = int(out["n_outliers"]) if policy == "remove" else 0
        attrs["outlier_rule"] = out["rule"] + ("; each outlier replaced by its block median" * (policy == "remove"))
        attrs["segment_start_s"] = float(out["events_segment"]["start_s"])
        write_series(path_cleaned, x if x_out is None else x_out, rate_hz=rate, units=units, attrs=attrs)


if __name__ == "__main__":
    p = snakemake.params
    run_job(main, snakemake.log[0], path_series=snakemake.input.series, policy=p.policy, k=float(p.k),
            window_samples=int(p.window_samples), max_indices=int(p.max_indices), events=dict(p.events),
            min_segment_s=float(p.min_segment_s), path_report=snakemake.output.report,
            path_cleaned=snakemake.output.get("cleaned"), path_segments=snakemake.output.get("segments"))
