"""Figures of one spec and sensor type (rule figures): PSD bounding (paper Fig. 5), Allan deviation per
component (Fig. 6), the paper's step-by-step hand inflation (Fig. 8)."""

import numpy as np

from imupipe.io import read_yaml, run_job


def bound_model(d):
    from imupipe.models import NoiseModel

    return NoiseModel(white=d["white"] or 0.0, random_walk=d["random_walk"] or 0.0,
                      gauss_markov=tuple((g["sigma"], g["T"]) for g in d["gauss_markov"]))


def main(path_spectra, path_allan, path_identified, path_bound, path_spec, out_psd, out_allan, out_steps, sensor, spec):
    from imupipe.merge import Stacked
    from imupipe.models import NoiseModel
    from imupipe.plot import plot_allan_components, plot_inflation_steps, plot_psd_bound, save_figure
    from imupipe.specsheet import load_spec

    bound = read_yaml(path_bound)
    model, spec_model = bound_model(bound["bound"]), load_spec(path_spec).models[sensor]
    identify = read_yaml(path_identified)
    identified, dropped = NoiseModel.from_dict(identify["model"]), identify["selection"]["dropped"]
    sp, av = Stacked(path_spectra), Stacked(path_allan)

    def every_curve(stacked, name):  # (dataset x axis, n): one row per curve
        values = stacked[name]
        return values.reshape(-1, values.shape[-1])

    dt = bound["dt_s"]
    title = f"{sensor}: {bound['spec_name']} spec vs {bound['mode']}-mode bound (margin {bound['margin']:.3g})"
    save_figure(plot_psd_bound(sp["frequency"], every_curve(sp, "psd"), spec_model, model, sensor=sensor, dt=dt,
                               title=title), out_psd)
    save_figure(plot_allan_components(av["tau"], every_curve(av, "avar"), identified, model, sensor=sensor,
                                      avar_lower=every_curve(av, "avar_lower"),
                                      avar_upper=every_curve(av, "avar_upper"), dropped=dropped,
                                      title=f"{sensor}: Allan deviation, identified vs bound components ({spec})"),
                out_allan)
    hand = bound.get("paper_hand_inflation")
    history = [[p["parameter"], p["N"], p["sigma"], p["T"], p["K"], p["margin"]] for p in hand["phases"]] if hand else []
    curves = np.stack([sp.at("psd", *c.split("/")) for c in bound["curves"]])
    save_figure(plot_inflation_steps(sp["frequency"], curves, spec_model, history, sensor=sensor, dt=dt,
                                     title=f"{sensor}: the paper's hand inflation of {spec}, step by step"),
                out_steps)


if __name__ == "__main__":
    i, o, w = snakemake.input, snakemake.output, snakemake.wildcards
    run_job(main, snakemake.log[0], path_spectra=i.spectra, path_allan=i.allan, path_identified=i.identified,
            path_bound=i.bound, path_spec=i.spec, out_psd=o.psd_bound, out_allan=o.allan_components, out_steps=o.inflation_steps,
            sensor=w.sensor, spec=w.spec)
