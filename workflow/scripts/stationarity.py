"""Stationarity of one decimated axis: the paper's Levene + KS, and the same statistics calibrated on a
null simulated from the axis's own Allan-variance fit (rule stationarity)."""

import zlib

from imupipe.io import read_series, run_job, write_yaml_atomic

NULL_COMPONENTS = ("white", "gauss_markov", "flicker", "random_walk")


def main(path_decimated: str, path_allan: str, n_segments: int, alpha: float, test: str, n_sim: int,
         path_out: str, label: str) -> None:
    from imupipe.stationarity import calibrated_stationarity, stationarity_tests

    x, rate, attrs = read_series(path_decimated)
    out = {"dataset": attrs.get("dataset"), "sensor": attrs.get("sensor"), "axis": attrs.get("axis"),
           "rate_hz": rate, "n_samples": int(x.size), "test": test}
    paper = stationarity_tests(x, n_segments=n_segments, alpha=alpha)
    out["paper"] = paper
    if test == "calibrated":
        import xarray as xr

        from imupipe.identify import fit_allan

        with xr.open_dataset(path_allan) as av:
            av = av.load()
        fit = fit_allan(av.tau.values, av.avar.values, av.edf.values, components=NULL_COMPONENTS, n_boot=0)
        seed = zlib.crc32(label.encode())  # reproducible per axis
        cal = calibrated_stationarity(x, rate, fit.model, n_segments=n_segments, alpha=alpha, n_sim=n_sim,
                                      rng=seed)
        cal.pop("paper", None)
        cal["null_model"] = fit.model.to_dict()
        out["calibrated"] = cal
        out["stationary"] = bool(cal["stationary"])
        out["p_value"] = float(cal["p_value"])
    else:
        out["stationary"] = bool(paper["stationary"])
        out["p_value"] = float(min(paper["levene_p"], min(paper["ks_p"])))
    write_yaml_atomic(out, path_out, header="stationarity verdict; p-values are probabilities, rate in Hz")


if __name__ == "__main__":
    p, w = snakemake.params, snakemake.wildcards
    run_job(main, snakemake.log[0], path_decimated=snakemake.input.decimated, path_allan=snakemake.input.allan,
            n_segments=p.n_segments, alpha=p.alpha, test=p.test, n_sim=p.n_sim, path_out=snakemake.output.verdict,
            label=f"{w.dataset}/{w.sensor}/{w.axis}")
