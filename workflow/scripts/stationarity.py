"""Stationarity verdict of one decimated axis (rule stationarity): the paper's Levene + KS, or the same
statistics calibrated on a null simulated from the axis's own Allan-variance fit. The calibrated verdict gives
its p-value's Monte Carlo standard error, the draws used and how close p was to the level; the paper's test on
the same record is reported beside it by the sensor's summary (rule stationarity_summary), so that this job
does not import scipy.stats for its asymptotic p-values (about 1.2 s per axis)."""

from imupipe.io import read_series, run_job, write_yaml_atomic

NULL_COMPONENTS = ("white", "gauss_markov", "flicker", "random_walk")


def main(path_decimated: str, path_allan: str, n_segments: int, alpha: float, test: str, n_sim: int,
         path_out: str, n_sim_max: int | None = None, close_z: float = 2.0) -> None:
    x, rate, attrs = read_series(path_decimated)
    out = {"dataset": attrs.get("dataset"), "sensor": attrs.get("sensor"), "axis": attrs.get("axis"),
           "rate_hz": rate, "n_samples": int(x.size), "test": test}
    if test == "calibrated":
        from imupipe.identify import fit_allan
        from imupipe.stationarity import calibrated_stationarity
        from imupipe.merge import Stacked

        allan = Stacked.from_axis_files([path_allan], join="outer")
        d, a = str(out["dataset"]), str(out["axis"])  # the grid's missing taus (NaN) are dropped by the fit
        fit = fit_allan(allan["tau"], allan.at("avar", d, a), allan.at("edf", d, a), components=NULL_COMPONENTS,
                        n_boot=0)
        # the null draws are seeded from the record itself (common random numbers): identical records give
        # identical verdicts whatever their axis or dataset; close verdicts draw more (up to n_sim_max)
        cal = calibrated_stationarity(x, rate, fit.model, n_segments=n_segments, alpha=alpha, n_sim=n_sim,
                                      rng="data", n_sim_max=n_sim_max, close_z=close_z, paper=False)
        out["paper"] = "the paper's test on this record: in the sensor's stationarity summary"
        cal["null_model"] = fit.model.to_dict()
        out["calibrated"] = cal
        out["stationary"] = bool(cal["stationary"])
        out["p_value"] = float(cal["p_value"])
        out["p_value_mc_se"] = float(cal["p_value_mc_se"])  # Monte Carlo standard error of p
        out["n_sim_run"] = int(cal["n_sim_run"])
        out["closeness"] = float(cal["closeness"])  # (p - alpha) / p_value_mc_se
        out["close_to_level"] = bool(abs(cal["closeness"]) <= close_z)
    else:
        from imupipe.stationarity import stationarity_tests

        out["paper"] = paper = stationarity_tests(x, n_segments=n_segments, alpha=alpha)
        out["stationary"] = bool(paper["stationary"])
        out["p_value"] = float(min(paper["levene_p"], min(paper["ks_p"])))
    write_yaml_atomic(out, path_out, header="stationarity verdict; p-values are probabilities, rate in Hz")


if __name__ == "__main__":
    p = snakemake.params
    run_job(main, snakemake.log[0], path_decimated=snakemake.input.decimated, path_allan=snakemake.input.allan,
            n_segments=p.n_segments, alpha=p.alpha, test=p.test, n_sim=p.n_sim, n_sim_max=p.n_sim_max,
            close_z=p.close_z, path_out=snakemake.output.verdict)
