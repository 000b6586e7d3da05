"""Allan-variance identification of one sensor type (rule identify): the pooled fit with its adequacy, model
selection for the application band, the SELECTED model refitted (the parameters to report and bound), the test
whether the curves may be pooled at all (and, where not, one identification per axis), the conservative (upper)
ends and the identified upper envelope for the bound, slope-line readings for comparison, and (simulated data)
the truth beside the fit. Each curve is fitted at its own record's rate and length."""

import logging

import numpy as np

from imupipe.io import run_job, write_yaml_atomic

SEED_FIT, SEED_POOLING = 20211, 20212


def curves_of(av):
    """(label, tau, avar, edf, n_samples, rate_hz, axis) of every included curve of a
    :class:`imupipe.merge.Stacked` Allan-variance file, NaN entries removed (records of different lengths
    have different tau grids), each with its own record's rate."""
    out = []
    tau = av["tau"]
    for d, a in av.curves(included_only=True):
        avar, edf = av.at("avar", d, a), av.at("edf", d, a)
        ok = np.isfinite(avar) & np.isfinite(edf)
        out.append((f"{d}/{a}", tau[ok], avar[ok], edf[ok], int(av.at("n_samples", d, a)), av.rate_of(d, a), a))
    return out


def _envelope(fit, kept, curves, confidence, horizon_s):
    """The upper confidence envelope of the kept components of `fit` (imupipe.bound.upper_envelope; a GM time
    constant the data leave open covered for f >= 1/horizon_s), its random walk at most what the curves' Allan
    variances allow (imupipe.bound.random_walk_cap)."""
    from imupipe.bound import random_walk_cap, upper_envelope

    cap = random_walk_cap([(c[1], c[2], c[3]) for c in curves], confidence=confidence)
    return upper_envelope(fit, kept, random_walk_cap=cap, horizon_s=horizon_s)


def _selected_and_envelope(fit, selection, curves, fit_kw, confidence, horizon_s):
    """The selected refit of `fit` on `curves` (imupipe.identify.refit_selected: a random walk the selection
    dropped keeps its upper limit, the GM intervals their hull with the fit with a random walk) and its upper
    envelope (:func:`_envelope`); the one rule of the pooled and the per-axis identification."""
    from imupipe.identify import refit_selected

    taus, avars, edfs = ([c[i] for c in curves] for i in (1, 2, 3))
    selected = refit_selected(fit, selection, taus, avars, edfs, rng=SEED_FIT, **fit_kw)
    return selected, _envelope(selected, list(selection["kept"]), curves, confidence, horizon_s)


def _envelope_ratio(envelope: dict, model) -> dict:
    """Envelope over estimate of each amplitude (white, random_walk, flicker; gm_sigma_i with GM terms matched in
    order), dimensionless; None where the estimate is 0 (a component the envelope adds, e.g. a dropped random walk
    at its upper limit)."""
    est = {"white": model.white, "random_walk": model.random_walk, "flicker": model.flicker}
    env = {k: envelope.get(k, 0.0) for k in est}
    for i, term in enumerate(envelope.get("gauss_markov") or [], start=1):
        env[f"gm_sigma_{i}"] = term["sigma"]
        est[f"gm_sigma_{i}"] = model.gauss_markov[i - 1][0] if len(model.gauss_markov) >= i else 0.0
    return {k: (float(env[k] / est[k]) if est[k] > 0 else None) for k in env if env[k] > 0 or est[k] > 0}


def main(path_allan: str, components: list, n_gm: int, n_boot: int, confidence: float, significance: float,
         relevance: float, rate_hz: float, horizon_s: float, truth, path_out: str, sensor: str,
         adequacy_level: float = 0.01, pooling_level: float = 0.01, pooling_n_boot: int = 99,
         envelope_horizon_s: float | None = None, fit_tau_min_samples: float | None = None) -> None:
    """`envelope_horizon_s`: the window the bound must hold over, s (verify.fix_s + application.horizon_s; default
    `horizon_s`): the upper envelope covers a GM whose T the data leave open above for f >= 1/envelope_horizon_s."""
    from imupipe.identify import dominating_model, fit_allan, pooling_test, select_components, slope_line
    from imupipe.merge import Stacked

    av = Stacked(path_allan)
    curves = curves_of(av)
    if not curves:
        raise ValueError(f"{path_allan}: no included curve (stationarity.on_fail = exclude left none)")
    labels = [c[0] for c in curves]
    taus, avars, edfs = [c[1] for c in curves], [c[2] for c in curves], [c[3] for c in curves]
    ns, rates = [c[4] for c in curves], [c[5] for c in curves]
    fit_kw = dict(n_boot=n_boot, confidence=confidence, dt=1.0 / rates[0], rate=rates, n_samples=ns,
                  adequacy_level=adequacy_level, T_min_samples=fit_tau_min_samples)
    fit = fit_allan(taus, avars, edfs, components=components, n_gm=n_gm, rng=SEED_FIT, **fit_kw)
    selection = select_components(fit, taus, avars, edfs, rate_hz=rate_hz, horizon_s=horizon_s,
                                  significance=significance, relevance=relevance)
    kept = list(selection["kept"])
    logging.info("kept %s; dropped %s", kept, selection["dropped"])
    env_h = float(envelope_horizon_s if envelope_horizon_s is not None else horizon_s)
    selected, envelope = _selected_and_envelope(fit, selection, curves, fit_kw, confidence, env_h)
    pooling = pooling_test(taus, avars, edfs, components=tuple(kept), n_gm=n_gm, rate=rates, n_samples=ns,
                           labels=labels, n_boot=pooling_n_boot, level=pooling_level, rng=SEED_POOLING)
    logging.info("pooling: %s", pooling["note"])

    out = {
        "sensor": sensor,
        "curves": labels,
        "rate_hz": {lab: float(r) for lab, r in zip(labels, rates)},
        "n_samples": {lab: int(n) for lab, n in zip(labels, ns)},
        "fit": fit.to_dict(),  # the full fit (every allowed component); `selected` inside: the refit
        "model": fit.model.to_dict(),
        "model_selected": selected.model.to_dict(),  # the parameters to report and bound
        "selection": {k: selection[k] for k in ("kept", "dropped", "reasons", "reduced_model", "band_hz")},
        "adequacy": {"pooled": selected.to_dict()["adequacy"], "full_fit": fit.to_dict()["adequacy"],
                     "per_curve": {c["label"]: {k: c[k] for k in ("chi2", "dof", "chi2_per_dof", "p_value",
                                                                  "adequate")} for c in pooling["per_curve"]}},
        "on_boundary": {k: bool(v) for k, v in selected.on_boundary.items()},
        "conservative": selected.to_dict()["conservative"],
        "pooling": pooling,
        "upper_envelope_model": envelope.to_dict(),
        "upper_envelope_horizon_s": env_h,
        "slope_line": {},
    }
    out["selection"]["band_hz"] = [float(v) for v in out["selection"]["band_hz"]] if out["selection"]["band_hz"] else None
    if not pooling["consistent"]:
        # one identification per axis (its datasets pooled; one dataset: one curve) by the pooled path's rule: the
        # axis's fit with every allowed component (no bootstrap: it only sets the components and the T search),
        # then the pooled selection refitted on the axis (a dropped random walk keeps its upper limit, the GM
        # intervals their hull with the fit with a random walk); the per-axis bounds use the pooled kept list
        per_axis = {}
        for axis in sorted({c[6] for c in curves}):
            idx = [i for i, c in enumerate(curves) if c[6] == axis]
            ax_curves = [curves[i] for i in idx]
            kw = {**fit_kw, "rate": [rates[i] for i in idx], "n_samples": [ns[i] for i in idx],
                  "dt": 1.0 / rates[idx[0]]}
            full = fit_allan([taus[i] for i in idx], [avars[i] for i in idx], [edfs[i] for i in idx],
                             components=components, n_gm=n_gm, rng=SEED_FIT, **{**kw, "n_boot": 0})
            fa, env_a = _selected_and_envelope(full, selection, ax_curves, kw, confidence, env_h)
            d = fa.to_dict()
            per_axis[axis] = {"curves": [labels[i] for i in idx], "model": fa.model.to_dict(),
                              "params": d["params"], "intervals": d["intervals"], "adequacy": d["adequacy"],
                              "on_boundary": d["on_boundary"], "interval_kind": d["interval_kind"],
                              "conservative": d["conservative"],
                              **({"intervals_statistical": d["intervals_statistical"]}
                                 if "intervals_statistical" in d else {}),
                              **({"T_search_s": d["T_search_s"]} if "T_search_s" in d else {}),
                              "random_walk_profile": d["random_walk_profile"],
                              "upper_envelope_model": env_a.to_dict(), "notes": d["notes"]}
        out["per_axis"] = per_axis
        # the pooled envelope need not cover the axis that differs: the envelope the bound reads covers each
        from imupipe.models import NoiseModel

        out["upper_envelope_model"] = dominating_model(
            [envelope] + [NoiseModel.from_dict(v["upper_envelope_model"]) for v in per_axis.values()]).to_dict()
        out["identification"] = ("per axis: the curves are not consistent with one model (pooling test); the "
                                 "pooled fit is kept for reference, `per_axis` gives each axis's parameters and "
                                 "`upper_envelope_model` dominates the pooled and every per-axis envelope")
    else:
        out["identification"] = "pooled: the curves are consistent with one model (pooling test)"
    out["upper_envelope_ratio"] = _envelope_ratio(out["upper_envelope_model"], selected.model)
    if not out["adequacy"]["pooled"].get("adequate", True):
        out["upper_envelope_note"] = (
            "the selected model does not describe the data (adequacy): its reported intervals are widened by the "
            f"over-dispersion factor {out['adequacy']['pooled'].get('widening')}, but the envelope uses the model's "
            "statistical limits (not widened), so below the lowest PSD bin the bound rests on a model the data "
            "reject; the verification's replay of the records is the model-free check over the horizon")
    out["upper_envelope"] = ("kept components at the upper ends of the selected refit's statistical intervals (before any "
                             "over-dispersion widening), each GM as GM terms above every GM of its interval box "
                             "(one per sub-box of at most a decade in T), the random walk at its upper limit even when "
                             "dropped, capped by what the recorded Allan variances allow, a GM time constant the data "
                             "leave open covered for f >= 1/upper_envelope_horizon_s (imupipe.bound.upper_envelope, "
                             "random_walk_cap); SI; upper_envelope_horizon_s s")
    for label, t, y, *_ in curves:
        sl = slope_line(t, np.sqrt(y))
        out["slope_line"][label] = {k: (float(v) if isinstance(v, (float, np.floating)) else v) for k, v in sl.items()}
    if truth:
        from imupipe.specsheet import load_spec

        true = load_spec(truth).models[sensor]
        out["truth"] = true.to_dict()
        if true.white > 0:
            out["white_relative_error"] = float(selected.model.white / true.white - 1.0)
    out["units"] = ("SI (u = rad/s or m/s^2): white u/sqrt(Hz), random_walk u/sqrt(s), flicker u, quantization u*s, "
                    "ramp u/s, gm_sigma u, gm_T s; rate_hz Hz; chi2, p-values dimensionless")
    write_yaml_atomic(out, path_out, header=f"{sensor}: Allan-variance identification of {len(curves)} curves; SI units")


if __name__ == "__main__":
    p = snakemake.params
    run_job(main, snakemake.log[0], path_allan=snakemake.input.allan, components=list(p.components), n_gm=p.n_gm,
            n_boot=p.n_boot, confidence=p.confidence, significance=p.significance, relevance=p.relevance,
            adequacy_level=p.adequacy_level, pooling_level=p.pooling_level, pooling_n_boot=p.pooling_n_boot,
            rate_hz=p.rate_hz, horizon_s=p.horizon_s, envelope_horizon_s=p.envelope_horizon_s,
            fit_tau_min_samples=p.fit_tau_min_samples,
            truth=snakemake.input.truth or None,
            path_out=snakemake.output.identified, sensor=snakemake.wildcards.sensor)
