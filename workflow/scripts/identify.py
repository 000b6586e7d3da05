"""Pooled Allan-variance fit of one sensor type, model selection for the application band, slope-line
readings for comparison, and (simulated data) the truth beside the fit (rule identify)."""

import logging

import numpy as np

from imupipe.io import run_job, write_yaml_atomic


def curves_of(av):
    """(label, tau, avar, edf, n_samples) of every included curve of a :class:`imupipe.merge.Stacked`
    Allan-variance file, NaN entries removed."""
    out = []
    tau = av["tau"]
    for d, a in av.curves(included_only=True):
        avar, edf = av.at("avar", d, a), av.at("edf", d, a)
        ok = np.isfinite(avar) & np.isfinite(edf)
        out.append((f"{d}/{a}", tau[ok], avar[ok], edf[ok], int(av.at("n_samples", d, a))))
    return out


def main(path_allan: str, components: list, n_gm: int, n_boot: int, confidence: float, significance: float,
         relevance: float, rate_hz: float, horizon_s: float, truth, path_out: str, sensor: str) -> None:
    from imupipe.identify import fit_allan, select_components, slope_line
    from imupipe.merge import Stacked

    av = Stacked(path_allan)
    curves = curves_of(av)
    taus = [c[1] for c in curves]
    avars = [c[2] for c in curves]
    edfs = [c[3] for c in curves]
    rate = float(av.attrs["rate_hz"])
    fit = fit_allan(taus, avars, edfs, components=components, n_gm=n_gm, n_boot=n_boot, confidence=confidence,
                    rng=20211, dt=1.0 / rate, rate=rate, n_samples=[c[4] for c in curves])
    selection = select_components(fit, taus, avars, edfs, rate_hz=rate_hz, horizon_s=horizon_s,
                                  significance=significance, relevance=relevance)
    logging.info("kept %s; dropped %s", selection["kept"], selection["dropped"])
    out = {
        "sensor": sensor,
        "curves": [c[0] for c in curves],
        "fit": fit.to_dict(),
        "model": fit.model.to_dict(),
        "selection": {k: selection[k] for k in ("kept", "dropped", "reasons", "reduced_model", "band_hz")},
        "slope_line": {},
    }
    out["selection"]["band_hz"] = [float(v) for v in out["selection"]["band_hz"]] if out["selection"]["band_hz"] else None
    for label, t, y, _, _ in curves:
        sl = slope_line(t, np.sqrt(y))
        out["slope_line"][label] = {k: (float(v) if isinstance(v, (float, np.floating)) else v) for k, v in sl.items()}
    if truth:
        from imupipe.specsheet import load_spec

        true = load_spec(truth).models[sensor]
        out["truth"] = true.to_dict()
        if true.white > 0:
            out["white_relative_error"] = float(fit.model.white / true.white - 1.0)
    write_yaml_atomic(out, path_out, header=f"{sensor}: Allan-variance identification, pooled over {len(curves)} curves; SI units")


if __name__ == "__main__":
    p = snakemake.params
    run_job(main, snakemake.log[0], path_allan=snakemake.input.allan, components=list(p.components), n_gm=p.n_gm,
            n_boot=p.n_boot, confidence=p.confidence, significance=p.significance, relevance=p.relevance,
            rate_hz=p.rate_hz, horizon_s=p.horizon_s, truth=snakemake.input.truth or None, path_out=snakemake.output.identified,
            sensor=snakemake.wildcards.sensor)
