"""Block average of one full-rate axis to decimate.rate_hz (rule decimate); netCDF4 alone, no xarray."""

from imupipe.io import read_series, run_job, write_series
from imupipe.spectra import decimate


def main(path_series: str, rate_hz: float, path_decimated: str) -> None:
    x, rate, attrs = read_series(path_series)
    units = attrs.pop("units")
    y, new_rate = decimate(x, rate, rate_hz)
    attrs.pop("rate_hz", None)
    attrs["decimation"] = f"block average of {rate / new_rate:g} samples at {rate:g} Hz"
    write_series(path_decimated, y, rate_hz=new_rate, units=units, attrs=attrs)


if __name__ == "__main__":
    run_job(main, snakemake.log[0], path_series=snakemake.input.series, rate_hz=snakemake.params.rate_hz,
            path_decimated=snakemake.output.decimated)
