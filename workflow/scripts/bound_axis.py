"""The tightest model of one axis of one dataset against one spec sheet (rule bound_axis):
imupipe.stages.bound.axis_bound_stage on the axis's PSD file, the identify file, the spec sheet and the sensor's
lines files."""

from pathlib import Path

from imupipe.io import read_yaml, run_job, write_yaml_atomic


def main(path_psd: str, path_identified: str, path_spec: str, mode: str, n_gm: int, confidence: float,
         bands_per_decade: int, span_s: float, lines: list, lines_params: dict, path_out: str,
         sensor: str) -> None:
    from imupipe.merge import Stacked
    from imupipe.specsheet import display_units, load_spec
    from imupipe.stages.bound import axis_bound_stage

    spec = load_spec(path_spec)
    if sensor not in spec.models:
        raise ValueError(f"{path_spec}: no '{sensor}' section, but the config processes {sensor}")
    sp = Stacked.from_axis_files([path_psd], join="exact")
    ((d, a),) = sp.curves()
    out = axis_bound_stage(sp["frequency"], sp.at("psd", d, a), sp.at("edf", d, a), f"{d}/{a}", spec.models[sensor],
                           read_yaml(path_identified), dt=1.0 / float(sp.attrs["rate_hz"]), sensor=sensor, mode=mode,
                           n_gm=n_gm, confidence=confidence, bands_per_decade=bands_per_decade, span_s=span_s,
                           taper=sp.attrs.get("taper", "hann"),
                           # results/<name>/lines/{dataset}/{sensor}/{axis}.yaml by label dataset/axis
                           lines={f"{Path(p).parent.parent.name}/{Path(p).stem}": read_yaml(p) for p in lines},
                           line_policy=lines_params["policy"][sensor],
                           application_band_hz=lines_params["application_band_hz"],
                           spec_units=display_units(spec, sensor), spec_name=spec.name)
    write_yaml_atomic(out, path_out, header=f"per-axis bound of {d}/{a} against {spec.name}")


if __name__ == "__main__":
    p, i = snakemake.params, snakemake.input
    run_job(main, snakemake.log[0], path_psd=i.psd, path_identified=i.identified, path_spec=i.spec, mode=p.mode,
            n_gm=p.n_gm, confidence=p.confidence, bands_per_decade=p.bands_per_decade, span_s=p.span_s,
            lines=list(i.get("lines", [])), lines_params=p.lines, path_out=snakemake.output.bound,
            sensor=snakemake.wildcards.sensor)
