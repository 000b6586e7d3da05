"""Per sensor type (rule collect): stationarity of every decimated axis -- the paper's Levene + KS and the
same statistics calibrated on a null simulated from the axis's own Allan-variance fit --, the summary with
stationarity.on_fail applied, then every axis's PSD and Allan variance in one file each with an
`included` flag. Imports scipy once for all the axes of the sensor type, and not xarray (netCDF4 alone)."""

import logging
import zlib

from imupipe.io import read_series, run_job, write_yaml_atomic

NULL_COMPONENTS = ("white", "gauss_markov", "flicker", "random_walk")


def verdict(path_decimated: str, allan, n_segments: int, alpha: float, test: str, n_sim: int) -> dict:
    """Stationarity verdict of one axis (plain dict); `allan`: every axis's Allan variance
    (:class:`imupipe.merge.Stacked`), for the null model of the calibrated test."""
    from imupipe.stationarity import calibrated_stationarity, stationarity_tests

    x, rate, attrs = read_series(path_decimated)
    out = {"dataset": attrs.get("dataset"), "sensor": attrs.get("sensor"), "axis": attrs.get("axis"),
           "rate_hz": rate, "n_samples": int(x.size), "test": test}
    if test == "calibrated":
        from imupipe.identify import fit_allan

        d, a = str(out["dataset"]), str(out["axis"])  # the grid's missing taus (NaN) are dropped by the fit
        fit = fit_allan(allan["tau"], allan.at("avar", d, a), allan.at("edf", d, a), components=NULL_COMPONENTS,
                        n_boot=0)
        label = f"{out['dataset']}/{out['sensor']}/{out['axis']}"
        cal = calibrated_stationarity(x, rate, fit.model, n_segments=n_segments, alpha=alpha, n_sim=n_sim,
                                      rng=zlib.crc32(label.encode()))  # reproducible per axis
        out["paper"] = cal.pop("paper")  # the paper's test on the same record, for comparison
        cal["null_model"] = fit.model.to_dict()
        out["calibrated"] = cal
        out["stationary"] = bool(cal["stationary"])
        out["p_value"] = float(cal["p_value"])
    else:
        out["paper"] = paper = stationarity_tests(x, n_segments=n_segments, alpha=alpha)
        out["stationary"] = bool(paper["stationary"])
        out["p_value"] = float(min(paper["levene_p"], min(paper["ks_p"])))
    return out


def summarise(verdicts: list, on_fail: str, sensor: str) -> dict:
    """Per-sensor summary; raises for on_fail = fail, or when on_fail = exclude leaves no curve."""
    curves = [{"dataset": v["dataset"], "axis": v["axis"], "stationary": bool(v["stationary"]),
               "p_value": v["p_value"], "test": v["test"], "paper_stationary": bool(v["paper"]["stationary"])}
              for v in verdicts]
    failing = [f"{c['dataset']}/{sensor}/{c['axis']} (p = {c['p_value']:.3g})" for c in curves if not c["stationary"]]
    if failing and on_fail == "fail":
        raise ValueError(f"non-stationary {sensor} records (stationarity.on_fail = fail): {', '.join(failing)}")
    for c in curves:
        c["included"] = c["stationary"] or on_fail == "warn"
    if failing:
        logging.warning("non-stationary: %s (%s)", ", ".join(failing),
                        "excluded from the bound" if on_fail == "exclude" else "kept, on_fail = warn")
    if not any(c["included"] for c in curves):
        raise ValueError(f"every {sensor} record failed the stationarity test and on_fail = exclude: nothing to bound")
    return {"sensor": sensor, "on_fail": on_fail, "n_curves": len(curves), "n_non_stationary": len(failing),
            "curves": curves}


def main(decimated: list, allan: list, psd: list, verdicts_out: list, n_segments: int, alpha: float, test: str,
         n_sim: int, on_fail: str, summary_out: str, spectra_out: str, allan_out: str, sensor: str) -> None:
    from imupipe.merge import Stacked

    # PSDs of one configuration share their frequencies; AV grids of records of different lengths do not
    # (missing entries NaN). Each per-axis file is read once: the AVs also give the null models.
    allan_stacked = Stacked.from_axis_files(allan, join="outer")
    verdicts = []
    for path_dec, path_out in zip(decimated, verdicts_out, strict=True):
        v = verdict(path_dec, allan_stacked, n_segments, alpha, test, n_sim)
        write_yaml_atomic(v, path_out, header="stationarity verdict; p-values are probabilities, rate in Hz")
        verdicts.append(v)
    summary = summarise(verdicts, on_fail, sensor)
    write_yaml_atomic(summary, summary_out)
    for stacked, path_out in ((Stacked.from_axis_files(psd, join="exact"), spectra_out), (allan_stacked, allan_out)):
        stacked.set_included(summary)
        stacked.attrs["sensor"] = sensor
        stacked.to_netcdf(path_out)


if __name__ == "__main__":
    i, o, p = snakemake.input, snakemake.output, snakemake.params
    run_job(main, snakemake.log[0], decimated=list(i.decimated), allan=list(i.allan), psd=list(i.psd),
            verdicts_out=list(o.verdicts), n_segments=p.n_segments, alpha=p.alpha, test=p.test, n_sim=p.n_sim,
            on_fail=p.on_fail, summary_out=o.summary, spectra_out=o.spectra, allan_out=o.allan,
            sensor=snakemake.wildcards.sensor)
