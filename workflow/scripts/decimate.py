"""Block average of one full-rate axis to decimate.rate_hz (rule decimate); netCDF4 alone, no xarray. Under
events.policy split each segment is averaged on its own and the file carries the segments (imupipe.segments)."""

from imupipe.io import read_series, run_job, write_series
from imupipe.segments import decimate_segments, read_segments


def main(path_series: str, rate_hz: float, path_decimated: str, path_segments: str | None = None) -> None:
    x, rate, attrs = read_series(path_series)
    units = attrs.pop("units")
    seg = read_segments(path_segments, x.size, rate, path_series)
    y, new_rate, seg_y = decimate_segments(x, rate, rate_hz, seg)
    attrs.pop("rate_hz", None)
    attrs["decimation"] = f"block average of {rate / new_rate:g} samples at {rate:g} Hz"
    if not seg_y.is_whole:
        attrs.update(seg_y.to_attrs())
        attrs["decimation"] += f" within each of {len(seg_y.bounds)} segments ({seg_y.describe()})"
    write_series(path_decimated, y, rate_hz=new_rate, units=units, attrs=attrs)


if __name__ == "__main__":
    run_job(main, snakemake.log[0], path_series=snakemake.input.series, rate_hz=snakemake.params.rate_hz,
            path_decimated=snakemake.output.decimated, path_segments=snakemake.input.get("segments"))
