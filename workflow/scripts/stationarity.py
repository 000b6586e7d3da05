"""Stationarity verdict of one decimated axis (rule stationarity): imupipe.stages.stationarity on the decimated
series (each of its segments under events.policy split) and (calibrated test) the axis's Allan-variance file and
spectral lines, which its null holds."""

from imupipe.io import read_series, read_yaml, run_job, write_yaml_atomic


def main(path_decimated: str, path_allan: str, n_segments: int, alpha: float, test: str, n_sim: int,
         path_out: str, n_sim_max: int | None = None, close_z: float = 2.0, path_lines: str | None = None) -> None:
    from imupipe.stages.stationarity import stationarity_stage

    from imupipe.segments import Segments

    x, rate, attrs = read_series(path_decimated)
    seg = Segments.from_attrs(attrs, x.size, rate, path_decimated)
    allan = None
    if test == "calibrated":
        from imupipe.merge import Stacked

        st = Stacked.from_axis_files([path_allan], join="outer")
        d, a = str(attrs.get("dataset")), str(attrs.get("axis"))
        allan = (st["tau"], st.at("avar", d, a), st.at("edf", d, a))
    lines = ()
    if test == "calibrated" and path_lines:
        from imupipe.lines import lines_by_curve

        lines = next(iter(lines_by_curve({path_lines: read_yaml(path_lines)}).values()), ())
    out = stationarity_stage(x, rate, dataset=attrs.get("dataset"), sensor=attrs.get("sensor"),
                             axis=attrs.get("axis"), allan=allan, n_segments=n_segments, alpha=alpha, test=test,
                             n_sim=n_sim, n_sim_max=n_sim_max, close_z=close_z, segments=seg, lines=lines)
    write_yaml_atomic(out, path_out, header="stationarity verdict; p-values are probabilities, rate in Hz")


if __name__ == "__main__":
    p = snakemake.params
    run_job(main, snakemake.log[0], path_decimated=snakemake.input.decimated, path_allan=snakemake.input.allan,
            n_segments=p.n_segments, alpha=p.alpha, test=p.test, n_sim=p.n_sim, n_sim_max=p.n_sim_max,
            close_z=p.close_z, path_out=snakemake.output.verdict, path_lines=snakemake.input.get("lines"))
