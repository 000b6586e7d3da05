"""The stationarity verdict of one decimated axis (rule ``stationarity``).

The paper's Levene + KS test of consecutive segments (:func:`imupipe.stationarity.stationarity_tests`), or the
same statistics calibrated on a null simulated from the axis's own Allan-variance fit
(:func:`imupipe.stationarity.calibrated_stationarity` with ``paper=False``, the null model
:func:`imupipe.identify.fit_allan` of white, GM, flicker and random walk, the draws seeded from the record
itself so that identical records give identical verdicts whatever their axis or dataset). The calibrated verdict
gives its p-value's Monte Carlo standard error, the draws used and how close p was to the level; the paper's
test on the same record is reported beside it by the sensor's summary (rule ``stationarity_summary``), so that
this job does not import scipy.stats for its asymptotic p-values (about 1.2 s per axis).

Plain values in (the decimated record, its rate and labels, its Allan curve), the verdict file's dict out
(:func:`stationarity_stage`). p-values are probabilities, the rate in Hz.
"""

from __future__ import annotations

__all__ = ["NULL_COMPONENTS", "stationarity_stage"]

#: Components of the calibrated null's model (the axis's Allan fit).
NULL_COMPONENTS = ("white", "gauss_markov", "flicker", "random_walk")


def stationarity_stage(x, rate: float, *, dataset=None, sensor=None, axis=None, allan=None, n_segments: int = 2,
                       alpha: float = 0.05, test: str = "calibrated", n_sim: int = 199, n_sim_max: int | None = None,
                       close_z: float = 2.0) -> dict:
    """The verdict of the decimated record `x` (u) at `rate` (Hz) of `dataset`/`sensor`/`axis`: the
    ``stationarity`` settings (`n_segments`, `alpha`, `test` ``calibrated`` or ``paper``, `n_sim`, `n_sim_max`,
    `close_z`), `allan` the axis's (tau s, avar u^2, edf) on its grid (NaN where missing: the fit drops them;
    needed by ``calibrated``)."""
    out = {"dataset": dataset, "sensor": sensor, "axis": axis, "rate_hz": rate, "n_samples": int(x.size),
           "test": test}
    if test == "calibrated":
        from imupipe.identify import fit_allan
        from imupipe.stationarity import calibrated_stationarity

        tau, avar, edf = allan
        fit = fit_allan(tau, avar, edf, components=NULL_COMPONENTS, n_boot=0)
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
    return out
