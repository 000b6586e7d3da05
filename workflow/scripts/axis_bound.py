"""Tightest model bounding one axis's sample PSD and the spec sheet (rule axis_bound)."""

from imupipe.io import run_job, write_yaml_atomic

# The per-axis bounds use the components the pooled identification kept (as the global bound does) and a
# coarser T grid (refined by a bounded search all the same): 30 of them re-run after every spec edit.
AXIS_T_PER_DECADE = 4


def main(path_psd: str, path_spec: str, path_identified: str, mode: str, n_gm: int, confidence: float,
         bands_per_decade: int, path_out: str, sensor: str, label: str) -> None:
    import xarray as xr

    from imupipe.bound import bound_psd
    from imupipe.io import read_yaml
    from imupipe.specsheet import display_units, load_spec

    spec = load_spec(path_spec)
    if sensor not in spec.models:
        raise ValueError(f"{path_spec}: no '{sensor}' section, but the config processes {sensor}")
    with xr.open_dataset(path_psd) as ds:
        ds = ds.load()
    dt = 1.0 / float(ds.attrs["rate_hz"])
    result = bound_psd(ds.frequency.values, {label: ds.psd.values}, spec.models[sensor], dt=dt, mode=mode,
                       n_gm=n_gm, confidence=confidence, bands_per_decade=bands_per_decade, edf=ds.edf.values,
                       taper=ds.attrs.get("taper", "hann"), keep=read_yaml(path_identified)["selection"]["kept"],
                       T_grid=AXIS_T_PER_DECADE)
    out = {"spec_name": spec.name, "curve": label, "sensor": sensor, "dt_s": dt,
           **result.to_dict(spec_units=display_units(spec, sensor), sensor=sensor)}
    write_yaml_atomic(out, path_out, header=f"per-axis bound of {label} against {spec.name}")


if __name__ == "__main__":
    p, w = snakemake.params, snakemake.wildcards
    run_job(main, snakemake.log[0], path_psd=snakemake.input.psd, path_spec=snakemake.input.spec,
            path_identified=snakemake.input.identified, mode=p.mode,
            n_gm=p.n_gm, confidence=p.confidence, bands_per_decade=p.bands_per_decade,
            path_out=snakemake.output.bound, sensor=w.sensor, label=f"{w.dataset}/{w.axis}")
