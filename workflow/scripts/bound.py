"""The global bound of one sensor type against one spec sheet (rule bound): every included curve of every
dataset and axis and the spec sheet (the contract file results/{name}/bound/{spec}/{sensor}.yaml), the
Allan-domain check per component, a summary of the per-axis bounds (rule bound_axis), and the paper's hand
inflation for comparison."""

import logging

import numpy as np

from imupipe.io import read_yaml, run_job, write_yaml_atomic

HEADER = """global bound of one sensor type (README "Output contract").
SI: white N in u/sqrt(Hz), gauss_markov sigma in u and T in s, random_walk K in u/sqrt(s); u = rad/s (gyro), m/s^2 (accel).
PSDs two-sided; the model is compared as the PSD of its dt-block-averaged samples (NoiseModel.psd_sampled).
bound_spec_units: the same in the spec sheet's units. inflation: bound/spec per parameter.
margin: min over curves and frequencies of S_model/S_sample (>= 1 when bounded), margin_curve: where."""



def main(path_spectra: str, path_allan: str, path_identified: str, path_spec: str, axis_bounds: list, mode: str,
         n_gm: int, confidence: float, bands_per_decade: int, compare_paper: bool, path_out: str, sensor: str) -> None:
    from imupipe.bound import bound_psd, check_allan_components, looseness, paper_inflation
    from imupipe.merge import Stacked
    from imupipe.models import NoiseModel
    from imupipe.specsheet import display_units, load_spec

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
    identified = read_yaml(path_identified)
    kept = identified["selection"]["kept"]
    per_axis = [read_yaml(path) for path in axis_bounds]
    result = bound_psd(f, curves, spec_model, dt=dt, mode=mode, n_gm=n_gm, confidence=confidence,
                       bands_per_decade=bands_per_decade, edf=np.array(edf), keep=kept,
                       taper=sp.attrs.get("taper", "hann"))
    logging.info("bound %s: margin %.4g (%s), looseness %.4g", result.model, result.margin, result.margin_curve,
                 result.looseness)
    out = {"spec_name": spec.name, "spec_file": path_spec.rsplit("/", 1)[-1], "sensor": sensor, "dt_s": dt,
           "n_curves": len(curves), "curves": list(curves), "states_kept_by_identification": kept,
           **result.to_dict(spec_units=display_units(spec, sensor), sensor=sensor)}
    tau = Stacked(path_allan)["tau"]
    ident_model = NoiseModel.from_dict(identified["model"])
    out["allan_check"] = _plain(check_allan_components(result.model, ident_model, tau))
    out["allan_check_passed"] = all(v["passed"] is not False for v in out["allan_check"].values())
    out["per_axis"] = [{"curve": ax["curve"], "bounded": ax["bounded"], "margin": ax["margin"],
                        "inflation": ax["inflation"]} for ax in per_axis]
    if compare_paper:
        hand = paper_inflation(f, curves, spec_model, dt=dt)
        out["paper_hand_inflation"] = {
            "model": hand.model.to_dict(), "inflation": hand.inflation, "bounded": bool(hand.bounded),
            "margin": float(hand.margin), "looseness": float(looseness(hand.model, f, curves, spec_model, dt=dt)),
            "lp_looseness_raw": float(looseness(result.model, f, curves, spec_model, dt=dt)),
            "n_steps": int(hand.details.get("n_steps", 0)),
            "phases": _phase_ends(hand.details.get("history", [])),
        }
    write_yaml_atomic(out, path_out, header=HEADER)


def _phase_ends(history):
    """The hand procedure's state at the start and at the end of each phase (paper Figure 8)."""
    keys = ("parameter", "N", "sigma", "T", "K", "margin")
    ends = [h for i, h in enumerate(history) if i == 0 or i + 1 == len(history) or history[i + 1][0] != h[0]]
    return [dict(zip(keys, _plain(list(h)))) for h in ends]


def _plain(obj):
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, (np.floating, float)):
        return float(obj) if np.isfinite(obj) else None
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj


if __name__ == "__main__":
    p, i, o = snakemake.params, snakemake.input, snakemake.output
    run_job(main, snakemake.log[0], path_spectra=i.spectra, path_allan=i.allan, path_identified=i.identified,
            path_spec=i.spec, mode=p.mode, n_gm=p.n_gm, confidence=p.confidence, bands_per_decade=p.bands_per_decade,
            compare_paper=p.compare_paper, axis_bounds=list(i.axis_bounds), path_out=o.bound,
            sensor=snakemake.wildcards.sensor)
