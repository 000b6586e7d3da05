"""Overlapping Allan variance of one full-rate axis (rule allan). The series is read into a buffer one sample
longer than the record and integrated in place: one axis's samples in memory, no copy; files written with
netCDF4 alone (no xarray import in this job). Under events.policy split with cuts: the estimator pooled over the
segments (imupipe.segments.pooled_allan)."""

from imupipe.allan import allan_variance_labelled
from imupipe.io import read_series, run_job
from imupipe.segments import pooled_allan, read_segments


def main(path_series: str, taus, confidence: float, path_allan: str, path_segments: str | None = None) -> None:
    x, rate, attrs = read_series(path_series, pad_front=1)  # x = buffer[1:], overwritten by its integral
    # the gap fill of the record travels with its AV (docs/inputs.md, "Timestamps and gaps": its effect on the AV)
    labels = {k: attrs[k] for k in ("dataset", "sensor", "axis", "n_filled", "filled_rows") if k in attrs}
    seg = read_segments(path_segments, x.size, rate, path_series)
    if seg.is_whole:
        av = allan_variance_labelled(x, rate, taus=taus, confidence=confidence, units=attrs["units"],
                                     theta_buffer=x.base)
    else:
        av = pooled_allan(x, rate, seg, taus=taus, confidence=confidence, units=attrs["units"])
    av.attrs.update(labels)
    av.to_netcdf(path_allan)


if __name__ == "__main__":
    p = snakemake.params
    run_job(main, snakemake.log[0], path_series=snakemake.input.series, taus=p.taus, confidence=p.confidence,
            path_allan=snakemake.output.allan, path_segments=snakemake.input.get("segments"))
