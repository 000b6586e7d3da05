"""Full-rate stage of one dataset (rule reduce): per channel (sensor and axis), the overlapping Allan variance
of the full-rate series, the block average to the decimation rate and its Welch PSD. One channel at a time;
files written with netCDF4 alone (no xarray import in this job)."""

from imupipe.allan import _allan_variance
from imupipe.io import read_series, run_job, write_series
from imupipe.spectra import _psd, decimate


def main(series: list, allan_out: list, decimated_out: list, psd_out: list, taus, allan_confidence: float,
         rate_hz: float, window_s: float, step_s: float, taper: str, detrend: str, psd_confidence: float) -> None:
    for path_in, path_av, path_dec, path_psd in zip(series, allan_out, decimated_out, psd_out, strict=True):
        x, rate, attrs = read_series(path_in, pad_front=1)  # x = buffer[1:], integrated in place below
        units = attrs.pop("units")
        labels = {k: attrs[k] for k in ("dataset", "sensor", "axis") if k in attrs}

        y, new_rate = decimate(x, rate, rate_hz)  # first: the AV overwrites x with its integral
        attrs.pop("rate_hz", None)
        attrs["decimation"] = f"block average of {rate / new_rate:g} samples at {rate:g} Hz"
        write_series(path_dec, y, rate_hz=new_rate, units=units, attrs=attrs)

        av = _allan_variance(x, rate, taus=taus, confidence=allan_confidence, units=units, theta_buffer=x.base)
        del x  # one axis's samples (36 MB at paper scale) in memory at a time, and no copy of them
        av.attrs.update(labels)
        av.to_netcdf(path_av)

        sp = _psd(y, new_rate, window_s=window_s, step_s=step_s, taper=taper,
                  detrend=None if detrend == "none" else detrend, confidence=psd_confidence, units=units)
        sp.attrs.update(labels)
        sp.to_netcdf(path_psd)


if __name__ == "__main__":
    p, o = snakemake.params, snakemake.output
    run_job(main, snakemake.log[0], series=list(snakemake.input.series), allan_out=list(o.allan),
            decimated_out=list(o.decimated), psd_out=list(o.psd), taus=p.taus, allan_confidence=p.allan_confidence,
            rate_hz=p.rate_hz, window_s=p.window_s, step_s=p.step_s, taper=p.taper, detrend=p.detrend,
            psd_confidence=p.psd_confidence)
