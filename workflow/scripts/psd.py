"""Two-sided Welch PSD of one decimated axis with chi-squared limits (rule psd)."""

from imupipe.io import read_series, run_job, write_netcdf_atomic
from imupipe.spectra import psd


def main(path_in: str, window_s: float, step_s: float, taper: str, detrend: str, confidence: float,
         path_out: str) -> None:
    x, rate, attrs = read_series(path_in)
    ds = psd(x, rate, window_s=window_s, step_s=step_s, taper=taper,
             detrend=None if detrend == "none" else detrend, confidence=confidence, units=attrs["units"])
    ds.attrs.update({k: attrs[k] for k in ("dataset", "sensor", "axis") if k in attrs})
    write_netcdf_atomic(ds, path_out)


if __name__ == "__main__":
    p = snakemake.params
    run_job(main, snakemake.log[0], path_in=snakemake.input.decimated, window_s=p.window_s, step_s=p.step_s,
            taper=p.taper, detrend=p.detrend, confidence=p.confidence, path_out=snakemake.output.psd)
