"""The tightest model of one axis of one dataset against one spec sheet (rule bound_axis): the components the
pooled identification kept, on a coarser T grid than the global bound (refined by a bounded search all the
same)."""

from imupipe.io import read_yaml, run_job, write_yaml_atomic

AXIS_T_PER_DECADE = 4


def main(path_psd: str, path_identified: str, path_spec: str, mode: str, n_gm: int, confidence: float,
         bands_per_decade: int, path_out: str, sensor: str) -> None:
    from imupipe.bound import bound_psd
    from imupipe.merge import Stacked
    from imupipe.specsheet import display_units, load_spec

    spec = load_spec(path_spec)
    if sensor not in spec.models:
        raise ValueError(f"{path_spec}: no '{sensor}' section, but the config processes {sensor}")
    kept = read_yaml(path_identified)["selection"]["kept"]
    sp = Stacked.from_axis_files([path_psd], join="exact")
    dt = 1.0 / float(sp.attrs["rate_hz"])
    ((d, a),) = sp.curves()
    label = f"{d}/{a}"
    result = bound_psd(sp["frequency"], {label: sp.at("psd", d, a)}, spec.models[sensor], dt=dt, mode=mode,
                       n_gm=n_gm, confidence=confidence, bands_per_decade=bands_per_decade, edf=sp.at("edf", d, a),
                       taper=sp.attrs.get("taper", "hann"), keep=kept, T_grid=AXIS_T_PER_DECADE)
    out = {"spec_name": spec.name, "curve": label, "sensor": sensor, "dt_s": dt,
           **result.to_dict(spec_units=display_units(spec, sensor), sensor=sensor)}
    write_yaml_atomic(out, path_out, header=f"per-axis bound of {label} against {spec.name}")


if __name__ == "__main__":
    p, i = snakemake.params, snakemake.input
    run_job(main, snakemake.log[0], path_psd=i.psd, path_identified=i.identified, path_spec=i.spec, mode=p.mode,
            n_gm=p.n_gm, confidence=p.confidence, bands_per_decade=p.bands_per_decade,
            path_out=snakemake.output.bound, sensor=snakemake.wildcards.sensor)
