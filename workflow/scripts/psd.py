"""Two-sided Welch PSD of one decimated axis with chi-squared limits (rule psd); netCDF4 alone, no xarray. A
series cut into segments (events.policy split): the windows of every segment, none across a cut
(imupipe.segments.pooled_psd)."""

from imupipe.io import read_series, run_job
from imupipe.segments import Segments, pooled_psd


def main(path_decimated: str, window_s: float, step_s: float, taper: str, detrend: str, confidence: float,
         path_psd: str) -> None:
    y, rate, attrs = read_series(path_decimated)
    seg = Segments.from_attrs(attrs, y.size, rate, path_decimated)
    labels = {k: attrs[k] for k in ("dataset", "sensor", "axis", "n_filled", "filled_rows") if k in attrs}
    try:
        sp = pooled_psd(y, rate, seg, window_s=window_s, step_s=step_s, taper=taper,
                        detrend=None if detrend == "none" else detrend, confidence=confidence, units=attrs["units"])
    except ValueError as exc:  # e.g. a record shorter than psd.window_s: name the recording and the channel
        where = "/".join(str(labels.get(k, "?")) for k in ("dataset", "sensor", "axis"))
        raise ValueError(f"{attrs.get('source', path_decimated)} ({where}, config psd): {exc}") from exc
    sp.attrs.update(labels)
    sp.to_netcdf(path_psd)


if __name__ == "__main__":
    p = snakemake.params
    run_job(main, snakemake.log[0], path_decimated=snakemake.input.decimated, window_s=p.window_s,
            step_s=p.step_s, taper=p.taper, detrend=p.detrend, confidence=p.confidence, path_psd=snakemake.output.psd)
