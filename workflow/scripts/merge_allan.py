"""One file per sensor type: avar(dataset, axis, tau) with limits and EDF (rule merge_allan).
Records of different lengths have different largest taus: missing entries are NaN."""

from imupipe.io import read_yaml, run_job, write_netcdf_atomic
from imupipe.merge import included_flags, stack_axis_files


def main(paths: list, path_stationarity: str, path_out: str, sensor: str) -> None:
    ds = stack_axis_files(paths, join="outer")
    ds["included"] = included_flags(read_yaml(path_stationarity), ds)
    ds.attrs["sensor"] = sensor
    write_netcdf_atomic(ds, path_out)


if __name__ == "__main__":
    run_job(main, snakemake.log[0], paths=list(snakemake.input.allan), path_stationarity=snakemake.input.stationarity,
            path_out=snakemake.output.allan, sensor=snakemake.wildcards.sensor)
