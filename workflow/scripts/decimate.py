"""Block-average one full-rate axis to the configured rate (rule decimate)."""

from imupipe.io import read_series, run_job, write_series
from imupipe.spectra import decimate


def main(path_in: str, rate_hz: float, path_out: str) -> None:
    x, rate, attrs = read_series(path_in)
    y, new_rate = decimate(x, rate, rate_hz)
    units = attrs.pop("units")
    attrs.pop("rate_hz", None)
    attrs["decimation"] = f"block average of {rate / new_rate:g} samples at {rate:g} Hz"
    write_series(path_out, y, rate_hz=new_rate, units=units, attrs=attrs)


if __name__ == "__main__":
    run_job(main, snakemake.log[0], path_in=snakemake.input.series, rate_hz=snakemake.params.rate_hz,
            path_out=snakemake.output.decimated)
