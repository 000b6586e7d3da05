"""Every axis's PSD or Allan variance of one sensor type in one file with the stationarity summary's
`included` flag (rule stack); netCDF4 alone, no xarray."""

from imupipe.io import read_yaml, run_job


def main(curves: list, path_summary: str, join: str, path_out: str, sensor: str) -> None:
    from imupipe.merge import Stacked

    stacked = Stacked.from_axis_files(curves, join=join)
    stacked.set_included(read_yaml(path_summary))
    stacked.attrs["sensor"] = sensor
    stacked.to_netcdf(path_out)


if __name__ == "__main__":
    run_job(main, snakemake.log[0], curves=list(snakemake.input.curves), path_summary=snakemake.input.summary,
            join=snakemake.params.join, path_out=snakemake.output.stacked, sensor=snakemake.wildcards.sensor)
