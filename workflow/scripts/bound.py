"""The global bound of one sensor type against one spec sheet (rule bound): every included curve of every
dataset and axis, the spec sheet and, over all frequencies (down to 0.01 / horizon), the identified model's
upper confidence envelope; the sensor's spectral lines through its line policy; the Allan-domain check of the
kept components against the sample AVs' lower limits; a summary of the per-axis bounds (rule bound_axis); the
paper's hand inflation for comparison; when the identification's pooling test says the axes differ, a bounding
model per axis (imupipe.bound.bound_by_axis: each axis's curves of every dataset, the same LP and all-frequency
rules, that axis's identified envelope) with its own Allan check, for the KF export. Not the verdict: `psd_bounded` says only that the model's PSD is above
its targets; the verdict (`bounded`) is the contract file's (rule contract)."""

import logging

import numpy as np

from imupipe.io import plain, read_yaml, run_job, write_yaml_atomic

HEADER = """global bound of one sensor type (README "Output contract"); the verdict is in contract/{spec}/{sensor}.yaml.
SI: white N in u/sqrt(Hz), gauss_markov sigma in u and T in s, random_walk K in u/sqrt(s); u = rad/s (gyro), m/s^2 (accel).
PSDs two-sided; the model is compared as the PSD of its dt-block-averaged samples (NoiseModel.psd_sampled).
bound_spec_units: the same in the spec sheet's units. inflation: bound/spec per parameter.
margin: min over curves and frequencies of S_model/S_sample (>= 1 when psd_bounded), margin_curve: where.
all_frequency_margin: min of S_model/max(S_spec, S_upper) below the lowest bin (frequency 0: K asymptote, inf: N).
upper_envelope: the identified model at its upper confidence limits (SI), imposed at every frequency.
allan_check.total.tau_band_s: the application band of the total-AV check, [1/application.rate_hz, horizon] s.
per_axis_models: present when the pooling test rejected one model for all axes: per axis, the bound of that axis's
curves (same fields as the global bound, SI), its envelope and Allan check; null when the axes are pooled."""


def main(path_spectra: str, path_allan: str, path_identified: str, path_spec: str, axis_bounds: list, mode: str,
         n_gm: int, confidence: float, bands_per_decade: int, compare_paper: bool, horizon_s: float, lines: list,
         lines_params: dict, path_out: str, sensor: str, application_rate_hz: float = 1.0) -> None:
    from imupipe.bound import (bound_by_axis, bound_psd, check_allan, looseness, paper_inflation,
                               upper_envelope_from_identification)
    from imupipe.merge import Stacked
    from imupipe.models import NoiseModel
    from imupipe.specsheet import display_units, load_spec
    from imupipe.verify import line_policy_from_files

    spec = load_spec(path_spec)
    if sensor not in spec.models:
        raise ValueError(f"{path_spec}: no '{sensor}' section, but the config processes {sensor}")
    spec_model = spec.models[sensor]
    sp = Stacked(path_spectra)
    dt = 1.0 / float(sp.attrs["rate_hz"])
    f = sp["frequency"]
    curves, edf = {}, []
    for d, a in sp.curves(included_only=True):
        curves[f"{d}/{a}"] = sp.at("psd", d, a)
        edf.append(np.broadcast_to(sp.at("edf", d, a), f.shape))
    edf_of = dict(zip(curves, edf))
    identified = read_yaml(path_identified)
    kept = identified["selection"]["kept"]
    upper = upper_envelope_from_identification(identified)
    pol = line_policy_from_files({path: read_yaml(path) for path in lines}, dt, f, lines_params["policy"][sensor],
                                 lines_params["application_band_hz"])
    per_axis = [read_yaml(path) for path in axis_bounds]
    result = bound_psd(f, curves, spec_model, dt=dt, mode=mode, n_gm=n_gm, confidence=confidence,
                       bands_per_decade=bands_per_decade, edf=np.array(edf), keep=kept,
                       taper=sp.attrs.get("taper", "hann"), horizon_s=horizon_s, upper_model=upper,
                       **(pol.bound_kwargs() if pol is not None else {}))
    logging.info("bound %s: margin %.4g (%s), all-frequency margin %.4g, looseness %.4g, %d LPs in %.3g s",
                 result.model, result.margin, result.margin_curve, result.allf_margin, result.looseness,
                 result.n_lp, result.solve_time_s)
    body = result.to_dict(spec_units=display_units(spec, sensor), sensor=sensor)
    body["psd_bounded"] = body.pop("bounded")
    body.pop("solve_time_s", None)  # wall clock: in the log, not in the file (identical runs, identical files)
    out = {"spec_name": spec.name, "spec_file": path_spec.rsplit("/", 1)[-1], "sensor": sensor, "dt_s": dt,
           "horizon_s": float(horizon_s), "n_curves": len(curves), "curves": list(curves),
           "states_kept_by_identification": kept, **body,
           "upper_envelope": upper.to_dict(),
           "lines": pol.to_dict() if pol is not None else {"policy": None, "note": "no lines files (lines stage not run)"}}
    al = Stacked(path_allan)
    labels, avars, edfs = [], [], []
    for d, a in al.curves(included_only=True):
        labels.append(f"{d}/{a}")
        avars.append(al.at("avar", d, a))
        edfs.append(al.at("edf", d, a))
    tau_min_s = 1.0 / float(application_rate_hz)
    allan = check_allan(result.model, NoiseModel.from_dict(identified["model"]), al["tau"], kept=kept,
                        sample_avar=np.array(avars), sample_edf=np.array(edfs), labels=labels, horizon_s=horizon_s,
                        tau_min_s=tau_min_s)
    out["allan_check"] = plain(allan)
    out["allan_check_passed"] = bool(allan["passed"])
    # per-axis models where the pooling test says the axes differ (docs/method.md, "Per-axis models")
    pooled = (identified.get("pooling") or {}).get("consistent", True) is not False
    axes_fit = identified.get("per_axis") or {}
    out["per_axis_models"] = None
    if not pooled and axes_fit:
        uppers = {ax: NoiseModel.from_dict(v["upper_envelope_model"]) for ax, v in axes_fit.items()
                  if v.get("upper_envelope_model")}
        line_kw = {}
        for ax in axes_fit:
            mine = {path: read_yaml(path) for path in lines if path.rsplit("/", 1)[-1] == f"{ax}.yaml"}
            p_ax = line_policy_from_files(mine, dt, f, lines_params["policy"][sensor],
                                          lines_params["application_band_hz"])
            line_kw[ax] = (p_ax.bound_kwargs() if p_ax is not None else {}, p_ax)
        per = bound_by_axis(f, curves, spec_model, upper_models=uppers, edf=edf_of,
                            line_kwargs={ax: kw for ax, (kw, _) in line_kw.items()}, dt=dt, mode=mode, n_gm=n_gm,
                            confidence=confidence, bands_per_decade=bands_per_decade, keep=kept,
                            taper=sp.attrs.get("taper", "hann"), horizon_s=horizon_s)
        out["per_axis_models"] = {}
        for ax, (labs, res) in per.items():
            if ax not in axes_fit:
                continue  # an axis without its own fit keeps the global model
            b_ax = res.to_dict(spec_units=display_units(spec, sensor), sensor=sensor)
            b_ax["psd_bounded"] = b_ax.pop("bounded")
            b_ax.pop("solve_time_s", None)
            b_ax.pop("details", None)
            sel = [labels.index(lab) for lab in labs if lab in labels]
            al_ax = check_allan(res.model, NoiseModel.from_dict(axes_fit[ax]["model"]), al["tau"], kept=kept,
                                sample_avar=np.array(avars)[sel], sample_edf=np.array(edfs)[sel],
                                labels=[labels[j] for j in sel], horizon_s=horizon_s, tau_min_s=tau_min_s)
            pol_ax = line_kw.get(ax, ({}, None))[1]
            out["per_axis_models"][ax] = {
                "axis": ax, "curves": labs, **b_ax,
                "upper_envelope": uppers[ax].to_dict() if ax in uppers else None,
                "lines": pol_ax.to_dict() if pol_ax is not None else None,
                "allan_check": plain(al_ax), "allan_check_passed": bool(al_ax["passed"])}
            logging.info("per-axis bound %s: %s, margin %.4g, all-frequency margin %.4g", ax, res.model, res.margin,
                         res.allf_margin)
    out["per_axis"] = [{"curve": ax["curve"], "psd_bounded": ax["psd_bounded"], "margin": ax["margin"],
                        "all_frequency_margin": ax.get("all_frequency_margin"), "inflation": ax["inflation"]}
                       for ax in per_axis]
    if compare_paper:
        hand = paper_inflation(f, curves, spec_model, dt=dt)
        out["paper_hand_inflation"] = {
            "model": hand.model.to_dict(), "inflation": hand.inflation, "psd_bounded": bool(hand.bounded),
            "margin": float(hand.margin), "looseness": float(looseness(hand.model, f, curves, spec_model, dt=dt)),
            "lp_looseness_raw": float(looseness(result.model, f, curves, spec_model, dt=dt)),
            "n_steps": int(hand.details.get("n_steps", 0)),
            "phases": _phase_ends(hand.details.get("history", [])),
        }
    write_yaml_atomic(plain(out), path_out, header=HEADER)


def _phase_ends(history):
    """The hand procedure's state at the start and at the end of each phase (paper Figure 8)."""
    keys = ("parameter", "N", "sigma", "T", "K", "margin")
    ends = [h for i, h in enumerate(history) if i == 0 or i + 1 == len(history) or history[i + 1][0] != h[0]]
    return [dict(zip(keys, plain(list(h)))) for h in ends]




if __name__ == "__main__":
    p, i, o = snakemake.params, snakemake.input, snakemake.output
    run_job(main, snakemake.log[0], path_spectra=i.spectra, path_allan=i.allan, path_identified=i.identified,
            path_spec=i.spec, mode=p.mode, n_gm=p.n_gm, confidence=p.confidence, bands_per_decade=p.bands_per_decade,
            compare_paper=p.compare_paper, horizon_s=p.horizon_s, lines=list(i.get("lines", [])),
            lines_params=p.lines, axis_bounds=list(i.axis_bounds), path_out=o.bound,
            sensor=snakemake.wildcards.sensor, application_rate_hz=p.application_rate_hz)
