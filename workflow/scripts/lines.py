"""Spectral lines of one full-rate axis (rule lines): imupipe.lines.find_lines (under events.policy split with cuts
on each segment: imupipe.segments.segment_lines), written as LineSearch.to_dict() with the dataset, sensor and axis
(YAML, every key's unit under `units`). Under events.policy warn (`events`: the burst scan's settings) the axis's
bursts are filled first: imupipe.stages.outliers.line_search_series."""

import logging
from dataclasses import replace

from imupipe.io import read_series, run_job, write_yaml_atomic
from imupipe.segments import read_segments, segment_lines
from imupipe.stages.outliers import line_search_series


def main(path_series: str, resolution_hz: float, alpha: float, floor_window_bins: int, path_lines: str,
         path_segments: str | None = None, scales=(1,), low_band_resolution_hz=None,
         events: dict | None = None) -> None:
    x, rate, attrs = read_series(path_series)
    x, filled = line_search_series(x, rate, events)
    units = attrs.pop("units")
    label = "/".join(str(attrs[key]) for key in ("dataset", "sensor", "axis") if key in attrs) or path_series
    seg = read_segments(path_segments, x.size, rate, path_series)
    try:
        search = segment_lines(x, rate, seg, resolution_hz=resolution_hz, alpha=alpha,
                               floor_window_bins=floor_window_bins, units=units, label=label, scales=scales,
                               low_band_resolution_hz=low_band_resolution_hz)
        search = replace(search, bursts_filled_s=filled)
    except ValueError as exc:
        raise ValueError(f"{path_series} ({x.size} samples at {rate:g} Hz): config lines.resolution_hz = "
                         f"{resolution_hz} Hz, lines.floor_window_bins = {floor_window_bins}, "
                         f"lines.low_band_resolution_hz = {low_band_resolution_hz} Hz: {exc}") from None
    out = {"dataset": attrs.get("dataset"), "sensor": attrs.get("sensor"), "axis": attrs.get("axis"),
           "series": path_series, **search.to_dict(), **({} if seg.is_whole else {"segments": seg.describe()})}
    write_yaml_atomic(out, path_lines, header=f"spectral lines of {label} (full rate, before decimation)")
    logging.info("%s: %d line(s) at %s Hz%s", label, len(search.lines),
                 ", ".join(f"{ln.frequency_hz:.4g}" for ln in search.lines) or "-",
                 f" ({len(filled)} burst stretch(es) filled)" if filled else "")


if __name__ == "__main__":
    p = snakemake.params
    run_job(main, snakemake.log[0], path_series=snakemake.input.series, resolution_hz=float(p.resolution_hz),
            alpha=float(p.alpha), floor_window_bins=int(p.floor_window_bins), path_lines=snakemake.output.lines,
            path_segments=snakemake.input.get("segments"), scales=tuple(int(v) for v in p.scales),
            low_band_resolution_hz=None if p.low_band_resolution_hz is None else float(p.low_band_resolution_hz),
            events=None if p.events is None else dict(p.events))
