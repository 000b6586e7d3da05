"""Figures of one spec and sensor type (rule figures): imupipe.stages.figures.figures_stage, each figure a PNG
and, with figures.format svg or pdf, a copy in that format."""

from pathlib import Path

from imupipe.io import run_job

if __name__ == "__main__":
    from imupipe.stages.figures import figures_stage

    i, o, w, p = snakemake.input, snakemake.output, snakemake.wildcards, snakemake.params
    # {figure name: path} of the copies: results/{name}/figures/{spec}/{figure}_{sensor}.{format}
    copies = {Path(path).stem[: -len(w.sensor) - 1]: path
              for path in (o.copies if not isinstance(o.copies, str) else [o.copies])}
    run_job(figures_stage, snakemake.log[0], path_spectra=i.spectra, path_allan=i.allan, path_identified=i.identified,
            path_bound=i.bound, path_spec=i.spec, out_psd=o.psd_bound, out_allan=o.allan_components,
            out_steps=o.inflation_steps, out_readoffs=o.allan_readoffs, copies=copies,
            lines=list(i.lines) if "lines" in i.keys() else [], units=p.units, decimate_rate_hz=p.decimate_rate_hz,
            sensor=w.sensor, spec=w.spec, path_contract=i.contract if "contract" in i.keys() else None)
