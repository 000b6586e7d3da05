"""One file per sensor type: psd(dataset, axis, frequency), limits and an `included` flag (rule merge_spectra)."""

from imupipe.io import read_yaml, run_job, write_netcdf_atomic
from imupipe.merge import included_flags, stack_axis_files


def main(paths: list, path_stationarity: str, path_out: str, sensor: str) -> None:
    ds = stack_axis_files(paths, join="exact")
    ds["included"] = included_flags(read_yaml(path_stationarity), ds)
    ds.attrs["sensor"] = sensor
    write_netcdf_atomic(ds, path_out)


if __name__ == "__main__":
    run_job(main, snakemake.log[0], paths=list(snakemake.input.psd), path_stationarity=snakemake.input.stationarity,
            path_out=snakemake.output.spectra, sensor=snakemake.wildcards.sensor)
