"""Verification of one spec sheet's bound of one sensor type (rule verify): the reference filter built on the
bound's model (accel: paper eq. 17 position filter; gyro: angle filter), exact covariance analysis against the
identified upper envelope, the spec sheet and, for simulated data, the truth; replay of the decimated records of
that sensor (the included axes); model reduction by integrity (imupipe.verify.verification_stage). Writes the
report (SI) and the figure sqrt(P) against the true / empirical RMS error. When the bound file carries per-axis
models (the axes differ), each is verified the same way against its own envelope and the records of its axis."""

import logging
import math

from imupipe.io import read_yaml, run_job, write_yaml_atomic

HEADER = """verification of the bound in the reference filter (docs/method.md, "Integrity: what bounded must mean").
SI: times s; sigma_fix m (accel) or rad (gyro); ratio = true (or replayed) MSE / filter variance P, dimensionless.
worst_outage_ratio: the largest MSE/P after the fixes end (the informative number), at worst_outage_t_s s;
worst_ratio at worst_t_s: the same over the whole run (fixes included); mean_conservatism: mean P/MSE
over the outage. exported: the model the KF file carries (the bound's, or its reduction when every check passes).
per_axis_models: the same per axis (each against that axis's envelope, the spec sheet and that axis's records), when
the bound file has per-axis models; null otherwise."""


def model_of(b: dict):
    """A NoiseModel from a bound file's `bound` block (SI; None stands for an absent component)."""
    from imupipe.models import NoiseModel

    return NoiseModel.from_dict({"white": b.get("white") or 0.0, "random_walk": b.get("random_walk") or 0.0,
                                 "gauss_markov": b.get("gauss_markov") or [], "narrowband": b.get("narrowband") or []})


def main(path_bound: str, path_spectra: str, path_spec: str, path_truth, records: list, fix_s: float,
         horizon_s: float, sigma_fix_m: float, sigma_fix_rad: float, filter_rate_hz: float, reduce: bool,
         replay_z: float, path_out: str, path_figure: str, spec_name: str, sensor: str,
         max_bias_time_s: float | None = None, fix_rate_hz: float | None = None) -> None:
    import numpy as np

    from imupipe.io import read_series
    from imupipe.merge import Stacked
    from imupipe.models import NoiseModel
    from imupipe.plot import plot_verification, save_figure
    from imupipe.specsheet import load_spec
    from imupipe.verify import verification_stage

    bound = read_yaml(path_bound)
    filt = model_of(bound["bound"])
    upper = NoiseModel.from_dict(bound["upper_envelope"]) if bound.get("upper_envelope") else None
    sheet = load_spec(path_spec)
    spec = sheet.models[sensor]
    bias_kw = dict(max_bias_time_s=max_bias_time_s, turn_on_bias=sheet.turn_on_bias.get(sensor, 0.0),
                   fix_rate_hz=fix_rate_hz)
    truth = load_spec(path_truth).models[sensor] if path_truth else None
    included = {f"{d}/{a}" for d, a in Stacked(path_spectra).curves(included_only=True)}
    series, rate, used = [], None, []
    for path in records:
        y, r, attrs = read_series(path)
        label = f"{attrs.get('dataset')}/{attrs.get('axis')}"
        if label not in included:
            continue
        if rate is not None and abs(r - rate) > 1e-9 * rate:
            raise ValueError(f"{path}: decimated rate {r} Hz differs from {rate} Hz of the other records")
        rate = r
        series.append(np.asarray(y, dtype=np.float64))
        used.append(label)
    sigma_fix = sigma_fix_m if sensor == "accel" else sigma_fix_rad
    report, checks = verification_stage(filt, sensor, spec=spec, upper=upper, truth=truth,
                                        records=series or None, rate_hz=rate, fix_s=fix_s, horizon_s=horizon_s,
                                        sigma_fix=sigma_fix, filter_rate_hz=filter_rate_hz, reduce=reduce,
                                        replay_z=replay_z, **bias_kw)
    report["spec_name"] = bound["spec_name"]
    report["replayed_curves"] = used
    report["bound_file_psd_bounded"] = bound.get("psd_bounded")
    report["per_axis_models"] = None
    if bound.get("per_axis_models"):
        report["per_axis_models"] = {}
        for ax, pa in bound["per_axis_models"].items():
            recs = [y for y, lab in zip(series, used) if lab.rsplit("/", 1)[-1] == ax]
            up_ax = NoiseModel.from_dict(pa["upper_envelope"]) if pa.get("upper_envelope") else None
            rep_ax, _ = verification_stage(model_of(pa["bound"]), sensor, spec=spec, upper=up_ax, truth=truth,
                                           records=recs or None, rate_hz=rate, fix_s=fix_s, horizon_s=horizon_s,
                                           sigma_fix=sigma_fix, filter_rate_hz=filter_rate_hz, reduce=reduce,
                                           replay_z=replay_z, **bias_kw)
            rep_ax["replayed_curves"] = [lab for lab in used if lab.rsplit("/", 1)[-1] == ax]
            report["per_axis_models"][ax] = rep_ax
            logging.info("per-axis model %s: verification %s", ax, "pass" if rep_ax["passed"] else "FAIL")
    for name, c in report["exported"]["verification"]["checks"].items():
        logging.info("%s: worst MSE/P %.4g at %.0f s, outage worst %.4g at %s s, mean P/MSE %.3g, %s", name,
                     c["worst_ratio"], c["worst_t_s"], c["worst_outage_ratio"], c.get("worst_outage_t_s"),
                     c["mean_conservatism"],
                     "pass" if c["passed"] else "FAIL")
    write_yaml_atomic(report, path_out, header=HEADER)
    unit, scale = ("m", 1.0) if sensor == "accel" else ("deg", math.degrees(1.0))
    what = "reduced model" if report["exported"]["reduced"] else "bound"
    fig = plot_verification(checks, unit=unit, scale=scale, fix_s=fix_s,
                            title=f"{sensor}, {spec_name}: reference filter on the exported {what}",
                            quantity="position error" if sensor == "accel" else "angle error")
    save_figure(fig, path_figure)


if __name__ == "__main__":
    p, i, o = snakemake.params, snakemake.input, snakemake.output
    run_job(main, snakemake.log[0], path_bound=i.bound, path_spectra=i.spectra, path_spec=i.spec,
            path_truth=i.get("truth") or None, records=list(i.records), fix_s=p.fix_s, horizon_s=p.horizon_s,
            sigma_fix_m=p.sigma_fix_m, sigma_fix_rad=p.sigma_fix_rad, filter_rate_hz=p.filter_rate_hz,
            reduce=p.reduce, replay_z=p.replay_z, max_bias_time_s=p.max_bias_time_s, fix_rate_hz=p.fix_rate_hz,
            path_out=o.verify,
            path_figure=o.figure,
            spec_name=snakemake.wildcards.spec, sensor=snakemake.wildcards.sensor)
