"""Allan-variance identification of one sensor type (rule identify): imupipe.stages.identify on the included
curves of the stacked Allan file (each at its own record's rate and length), the simulation's truth beside it."""

from imupipe.io import run_job, write_yaml_atomic


def main(path_allan: str, path_out: str, sensor: str, truth=None, lines=(), lines_params=None, **settings) -> None:
    """`settings`: the keyword arguments of imupipe.stages.identify.identify_sensor (the rule's params); `lines`:
    the per-axis lines files, read under the sensor's line policy."""
    from imupipe.io import read_yaml
    from imupipe.lines import lines_by_curve
    from imupipe.merge import Stacked
    from imupipe.specsheet import load_spec
    from imupipe.stages import identify

    curves = identify.curves_of(Stacked(path_allan))
    if not curves:
        raise ValueError(f"{path_allan}: no included curve (stationarity.on_fail = exclude left none)")
    true = load_spec(truth).models[sensor] if truth else None
    policy = (lines_params or {}).get("policy", {}).get(sensor, "model")
    known = lines_by_curve({p: read_yaml(p) for p in lines}, policy)
    out = identify.identification_stage(curves, sensor=sensor, truth=true, lines=known,
                                        envelope_lines=policy == "model", **settings)
    write_yaml_atomic(out, path_out, header=f"{sensor}: Allan-variance identification of {len(curves)} curves; SI units")


if __name__ == "__main__":
    p = snakemake.params
    run_job(main, snakemake.log[0], path_allan=snakemake.input.allan, components=list(p.components), n_gm=p.n_gm,
            n_boot=p.n_boot, confidence=p.confidence, significance=p.significance, relevance=p.relevance,
            adequacy_level=p.adequacy_level, pooling_level=p.pooling_level, pooling_n_boot=p.pooling_n_boot,
            envelope_kind=p.envelope_kind,
            filter_rate_hz=p.filter_rate_hz, outage_s=p.outage_s, span_s=p.span_s,
            fit_tau_min_samples=p.fit_tau_min_samples, envelope_lines_below_hz=p.envelope_lines_below_hz,
            truth=snakemake.input.truth or None,
            lines=list(snakemake.input.get("lines", [])), lines_params=p.lines,
            path_out=snakemake.output.identified, sensor=snakemake.wildcards.sensor)
