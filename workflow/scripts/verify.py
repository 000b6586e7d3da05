"""Verification of one spec sheet's bound of one sensor type (rule verify): imupipe.stages.verify on the bound
file and the included curves' records (stacked spectra file), block-averaged to the reference filter's rate. Writes the report (SI) and the
figure sqrt(P) against the true / empirical RMS error of the exported model."""

import math

from imupipe.io import read_yaml, run_job, write_yaml_atomic


def main(path_bound: str, path_spectra: str, path_spec: str, path_truth, records: list, fix_s: float,
         horizon_s: float, sigma_fix_m: float, sigma_fix_rad: float, filter_rate_hz: float, reduce: bool,
         replay_z: float, path_out: str, path_figure: str, spec_name: str, sensor: str,
         max_bias_time_s: float | None = None, fix_rate_hz: float | None = None) -> None:
    from imupipe.io import read_series
    from imupipe.merge import Stacked
    from imupipe.spectra import decimate
    from imupipe.plot import plot_verification, save_figure
    from imupipe.specsheet import load_spec
    from imupipe.stages.verify import HEADER, records_at_one_rate, verify_sensor

    sheet = load_spec(path_spec)
    included = {f"{d}/{a}" for d, a in Stacked(path_spectra).curves(included_only=True)}
    series = {}
    for path in records:
        y, r, at = read_series(path)
        if (label := f"{at.get('dataset')}/{at.get('axis')}") in included:
            # block-averaged to the filter rate on reading (one full-rate record in memory at a time)
            series[label] = decimate(y, r, filter_rate_hz) if r > filter_rate_hz * (1 + 1e-9) else (y, r)
        del y
    series, rate = records_at_one_rate(series)  # one rate, or an error naming the record
    report, checks = verify_sensor(
        read_yaml(path_bound), sensor, spec=sheet.models[sensor], records=series, rate_hz=rate,
        truth=load_spec(path_truth).models[sensor] if path_truth else None,
        turn_on_bias=sheet.turn_on_bias.get(sensor, 0.0), fix_s=fix_s, horizon_s=horizon_s,
        sigma_fix=sigma_fix_m if sensor == "accel" else sigma_fix_rad, filter_rate_hz=filter_rate_hz,
        reduce=reduce, replay_z=replay_z, max_bias_time_s=max_bias_time_s, fix_rate_hz=fix_rate_hz)
    write_yaml_atomic(report, path_out, header=HEADER)
    unit, scale = ("m", 1.0) if sensor == "accel" else ("deg", math.degrees(1.0))
    what = "reduced model" if report["exported"]["reduced"] else "bound"
    save_figure(plot_verification(checks, unit=unit, scale=scale, fix_s=fix_s,
                                  title=f"{sensor}, {spec_name}: reference filter on the exported {what}",
                                  quantity="position error" if sensor == "accel" else "angle error"), path_figure)


if __name__ == "__main__":
    p, i, o = snakemake.params, snakemake.input, snakemake.output
    run_job(main, snakemake.log[0], path_bound=i.bound, path_spectra=i.spectra, path_spec=i.spec,
            path_truth=i.get("truth") or None, records=list(i.records), fix_s=p.fix_s, horizon_s=p.horizon_s,
            sigma_fix_m=p.sigma_fix_m, sigma_fix_rad=p.sigma_fix_rad, filter_rate_hz=p.filter_rate_hz,
            reduce=p.reduce, replay_z=p.replay_z, max_bias_time_s=p.max_bias_time_s, fix_rate_hz=p.fix_rate_hz,
            path_out=o.verify,
            path_figure=o.figure,
            spec_name=snakemake.wildcards.spec, sensor=snakemake.wildcards.sensor)
