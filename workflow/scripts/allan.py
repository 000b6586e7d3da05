"""Overlapping Allan variance of one full-rate axis with confidence limits (rule allan)."""

from imupipe.allan import allan_variance
from imupipe.io import read_series, run_job, write_netcdf_atomic


def main(path_in: str, taus, confidence: float, path_out: str) -> None:
    x, rate, attrs = read_series(path_in)
    ds = allan_variance(x, rate, taus=taus, confidence=confidence, units=attrs["units"])
    ds.attrs.update({k: attrs[k] for k in ("dataset", "sensor", "axis") if k in attrs})
    write_netcdf_atomic(ds, path_out)


if __name__ == "__main__":
    run_job(main, snakemake.log[0], path_in=snakemake.input.series, taus=snakemake.params.taus,
            confidence=snakemake.params.confidence, path_out=snakemake.output.allan)
