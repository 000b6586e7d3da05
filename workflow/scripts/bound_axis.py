"""The tightest model of one axis of one dataset against one spec sheet (rule bound_axis): the components the
pooled identification kept, on a coarser T grid than the global bound (refined by a bounded search all the
same), over all frequencies as the global bound (spec sheet and identified upper envelope below the lowest
bin), with the sensor's line policy."""

import logging

from imupipe.io import plain, read_yaml, run_job, write_yaml_atomic

AXIS_T_PER_DECADE = 4


def main(path_psd: str, path_identified: str, path_spec: str, mode: str, n_gm: int, confidence: float,
         bands_per_decade: int, horizon_s: float, lines: list, lines_params: dict, path_out: str,
         sensor: str) -> None:
    from imupipe.bound import bound_psd, upper_envelope_from_identification
    from imupipe.merge import Stacked
    from imupipe.specsheet import display_units, load_spec
    from imupipe.verify import line_policy_from_files


    spec = load_spec(path_spec)
    if sensor not in spec.models:
        raise ValueError(f"{path_spec}: no '{sensor}' section, but the config processes {sensor}")
    identified = read_yaml(path_identified)
    kept = identified["selection"]["kept"]
    sp = Stacked.from_axis_files([path_psd], join="exact")
    dt = 1.0 / float(sp.attrs["rate_hz"])
    ((d, a),) = sp.curves()
    label = f"{d}/{a}"
    f = sp["frequency"]
    pol = line_policy_from_files({path: read_yaml(path) for path in lines}, dt, f, lines_params["policy"][sensor],
                                 lines_params["application_band_hz"])
    result = bound_psd(f, {label: sp.at("psd", d, a)}, spec.models[sensor], dt=dt, mode=mode,
                       n_gm=n_gm, confidence=confidence, bands_per_decade=bands_per_decade, edf=sp.at("edf", d, a),
                       taper=sp.attrs.get("taper", "hann"), keep=kept, T_grid=AXIS_T_PER_DECADE, horizon_s=horizon_s,
                       upper_model=upper_envelope_from_identification(identified), **(pol.bound_kwargs() if pol is not None else {}))
    logging.info("bound of %s: margin %.4g, %d LPs in %.3g s", label, result.margin, result.n_lp, result.solve_time_s)
    body = result.to_dict(spec_units=display_units(spec, sensor), sensor=sensor)
    body["psd_bounded"] = body.pop("bounded")
    body.pop("solve_time_s", None)  # wall clock: in the log only
    out = {"spec_name": spec.name, "curve": label, "sensor": sensor, "dt_s": dt, "horizon_s": float(horizon_s), **body,
           "lines": pol.to_dict() if pol is not None else {"policy": None, "note": "no lines files (lines stage not run)"}}
    write_yaml_atomic(plain(out), path_out, header=f"per-axis bound of {label} against {spec.name}")




if __name__ == "__main__":
    p, i = snakemake.params, snakemake.input
    run_job(main, snakemake.log[0], path_psd=i.psd, path_identified=i.identified, path_spec=i.spec, mode=p.mode,
            n_gm=p.n_gm, confidence=p.confidence, bands_per_decade=p.bands_per_decade, horizon_s=p.horizon_s,
            lines=list(i.get("lines", [])), lines_params=p.lines, path_out=snakemake.output.bound,
            sensor=snakemake.wildcards.sensor)
