"""The global bound of one sensor type against one spec sheet (rule bound): imupipe.stages.bound.bound_stage on the
included curves of the stacked spectra and Allan files, the identify, spec, lines and per-axis bound files, and the
noisiest stretches the stationarity summary marks."""

from pathlib import Path

from imupipe.io import read_yaml, run_job, write_yaml_atomic


def main(path_spectra: str, path_allan: str, path_identified: str, path_spec: str, axis_bounds: list, mode: str,
         n_gm: int, confidence: float, bands_per_decade: int, compare_paper: bool, span_s: float, lines: list,
         lines_params: dict, path_out: str, sensor: str, filter_rate_hz: float = 1.0,
         path_stationarity: str | None = None) -> None:
    from imupipe.merge import Stacked
    from imupipe.specsheet import display_units, load_spec
    from imupipe.stages.bound import HEADER, bound_stage
    from imupipe.stages.stationarity import marked_stretches

    spec = load_spec(path_spec)  # a missing sensor section: refused at start-up (imupipe.runconfig.check_specs)
    sp, al = Stacked(path_spectra), Stacked(path_allan)
    psd, edf = ({f"{d}/{a}": sp.at(k, d, a) for d, a in sp.curves(included_only=True)} for k in ("psd", "edf"))
    allan = (al["tau"], {f"{d}/{a}": (al.at("avar", d, a), al.at("edf", d, a)) for d, a in al.curves(True)})
    out = bound_stage(sp["frequency"], psd, edf, spec.models[sensor], read_yaml(path_identified),
                      dt=1.0 / float(sp.attrs["rate_hz"]), sensor=sensor, mode=mode, n_gm=n_gm, confidence=confidence,
                      bands_per_decade=bands_per_decade, span_s=span_s, filter_rate_hz=filter_rate_hz,
                      taper=sp.attrs.get("taper", "hann"), allan=allan,
                      lines={f"{Path(p).parent.parent.name}/{Path(p).stem}": read_yaml(p) for p in lines},
                      line_policy=lines_params["policy"][sensor],
                      application_band_hz=lines_params["application_band_hz"],
                      axis_bounds=[read_yaml(path) for path in axis_bounds], compare_paper=compare_paper,
                      spec_units=display_units(spec, sensor), spec_name=spec.name,
                      spec_file=path_spec.rsplit("/", 1)[-1],
                      stretches=marked_stretches(read_yaml(path_stationarity) if path_stationarity else None))
    write_yaml_atomic(out, path_out, header=HEADER)


if __name__ == "__main__":
    p, i, o = snakemake.params, snakemake.input, snakemake.output
    run_job(main, snakemake.log[0], path_spectra=i.spectra, path_allan=i.allan, path_identified=i.identified,
            path_spec=i.spec, mode=p.mode, n_gm=p.n_gm, confidence=p.confidence, bands_per_decade=p.bands_per_decade,
            compare_paper=p.compare_paper, span_s=p.span_s, lines=list(i.get("lines", [])),
            lines_params=p.lines, axis_bounds=list(i.axis_bounds), path_out=o.bound,
            sensor=snakemake.wildcards.sensor, filter_rate_hz=p.filter_rate_hz, path_stationarity=i.stationarity)
