"""The figures of one spec sheet and sensor type (rule ``figures``).

Figures of one spec and sensor type (rule figures): PSD bounding (paper Fig. 5; sample PSDs as a min-max
envelope and their median, lines found by the lines stage marked at their aliases), Allan deviation per component
(Fig. 6), the paper's step-by-step hand inflation (Fig. 8), and the Allan deviations with the N, B, K read-offs.
Axes in the spec sheet's units (config figures.units: spec) or SI; each figure a PNG and, with figures.format
svg or pdf, a copy in that format.

Paths in, the figure files out (:func:`figures_stage`; :mod:`imupipe.plot` draws them).
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from imupipe.io import read_yaml

__all__ = ["bound_model", "figures_stage", "identified_shown", "line_aliases", "mark_aliases", "save_all"]


def bound_model(d):
    """The bound file's `bound` section as a :class:`~imupipe.models.NoiseModel` (SI)."""
    from imupipe.models import NoiseModel

    return NoiseModel(white=d["white"] or 0.0, random_walk=d["random_walk"] or 0.0,
                      gauss_markov=tuple((g["sigma"], g["T"]) for g in d["gauss_markov"]),
                      narrowband=tuple((n["sigma"], n["f0_hz"], n["zeta"]) for n in d.get("narrowband") or ()))


def identified_shown(identify: dict):
    """The identified model Figure 6 draws (SI :class:`~imupipe.models.NoiseModel`): the kept components of the
    selected refit as fitted (:func:`imupipe.stages.identify.fitted_model`, what the bound's component check
    compares with) and the components the selection dropped at their values in the fit with every component (drawn
    dotted)."""
    from dataclasses import replace

    from imupipe.models import NoiseModel
    from imupipe.stages.identify import fitted_model

    full = NoiseModel.from_dict(identify["model"])
    fitted = fitted_model(identify)[0]
    dropped = [c for c in identify["selection"]["dropped"] if hasattr(full, c)]
    # a GM re-assigned after the fit is in the refit as fitted, not dropped from it
    return replace(fitted, **{c: getattr(full, c) for c in dropped
                              if not (c == "gauss_markov" and fitted.gauss_markov)})


def line_aliases(paths: list, dt: float) -> list:
    """(alias in the decimated spectrum, full-rate frequency), Hz, of every line of the lines files, merged
    (imupipe.lines.merge_lines) and sorted by alias."""
    from imupipe.lines import Line, decimated_line, merge_lines

    found = [Line(**d) for p in paths for d in (read_yaml(p) or {}).get("lines") or []]
    return sorted((decimated_line(ln, dt)["alias_hz"], ln.frequency_hz) for ln in merge_lines(found))


def mark_aliases(fig, aliases: list, max_labelled: int = 6) -> None:
    """Vertical dotted lines at the aliases (one legend entry), each labelled with its full-rate frequency."""
    if not aliases:
        return
    ax = fig.axes[0]
    for i, (fa, f0) in enumerate(aliases):
        ax.axvline(fa, color="tab:purple", ls=":", lw=1.0, zorder=2, gid=f"line_alias:{i}",
                   label="spectral line (alias of the full-rate line)" if i == 0 else None)
        if i < max_labelled:
            ax.annotate(f"{f0:.4g} Hz", (fa, 0.98), xycoords=("data", "axes fraction"), rotation=90, va="top",
                        ha="right", fontsize="x-small", color="tab:purple")
    ax.legend(loc="lower left", fontsize="small")


def save_all(fig, path_png: str, copies: dict, name: str) -> None:
    """The PNG, then the copy in the configured format (a second render of the same figure)."""
    from imupipe.io import atomic_path
    from imupipe.plot import save_figure

    if name in copies:
        with atomic_path(copies[name]) as tmp:
            fig.savefig(str(tmp), format=Path(copies[name]).suffix.lstrip("."), dpi=150)
    save_figure(fig, path_png)


def figures_stage(path_spectra, path_allan, path_identified, path_bound, path_spec, out_psd, out_allan, out_steps,
                  out_readoffs, copies, lines, units, decimate_rate_hz, sensor, spec, path_contract=None) -> None:
    """The four figures of one spec sheet and sensor type from the stacked spectra and Allan files, the identify and
    bound files, the spec sheet and the lines files; `copies` {figure name: path} of the configured extra format,
    `units` ``spec`` or ``SI``, `decimate_rate_hz` (Hz) the decimated spectra's rate (the lines' aliases);
    `path_contract` (``bound.mode: auto``): the contract naming the exported candidate, which the figures show
    (:func:`imupipe.stages.tables.exported_bound`)."""
    from imupipe.merge import Stacked
    from imupipe.plot import plot_allan_components, plot_allan_deviation, plot_inflation_steps, plot_psd_bound
    from imupipe.specsheet import load_spec

    shown = "spec" if units == "spec" else None  # plot_psd_bound / plot_allan_components: None = SI
    from imupipe.stages.tables import exported_bound

    whole = read_yaml(path_bound)
    bound = exported_bound(whole, read_yaml(path_contract) if path_contract else None)
    model, spec_model = bound_model(bound["bound"]), load_spec(path_spec).models[sensor]
    identify = read_yaml(path_identified)
    identified, dropped = identified_shown(identify), identify["selection"]["dropped"]
    sp, av = Stacked(path_spectra), Stacked(path_allan)

    def every_curve(stacked, name):  # (dataset x axis, n): one row per curve
        values = stacked[name]
        return values.reshape(-1, values.shape[-1])

    dt = bound["dt_s"]
    title = f"{sensor}: {bound['spec_name']} spec vs {bound['mode']}-mode bound (margin {bound['margin']:.3g})"
    fig = plot_psd_bound(sp["frequency"], every_curve(sp, "psd"), spec_model, model, sensor=sensor, dt=dt,
                         title=title, display_unit=shown, samples="envelope")
    aliases = line_aliases(lines, 1.0 / float(decimate_rate_hz)) if lines else []
    logging.info("%d line(s) marked at their aliases: %s", len(aliases), aliases)
    mark_aliases(fig, aliases)
    raised = bound.get("noisiest_stretch") or {}
    if raised:  # the bound's raised copies are not drawn: the legend says they are there
        from matplotlib.lines import Line2D

        ax = fig.axes[0]
        handles, names = ax.get_legend_handles_labels()
        size = ax.get_legend().get_texts()[0].get_fontsize() if ax.get_legend() else None
        ax.legend(handles + [Line2D([], [], linestyle="none")],
                  names + [f"bound also above {len(raised)} curve(s) raised to their noisiest stretch\n(up to "
                           f"{max(float(v['max_gain']) for v in raised.values()):.3g}x; not drawn)"],
                  loc="lower left", fontsize=size)
    save_all(fig, out_psd, copies, "psd_bound")
    save_all(plot_allan_components(av["tau"], every_curve(av, "avar"), identified, model, sensor=sensor,
                                   avar_lower=every_curve(av, "avar_lower"),
                                   avar_upper=every_curve(av, "avar_upper"), dropped=dropped, display_unit=shown,
                                   title=f"{sensor}: Allan deviation, identified vs bound components ({spec})"),
             out_allan, copies, "allan_components")
    hand = whole.get("paper_hand_inflation")  # the paper's hand inflation (Fig. 8): the bound file's, in every mode
    history = [[p["parameter"], p["N"], p["sigma"], p["T"], p["K"], p["margin"]] for p in hand["phases"]] if hand else []
    curves = np.stack([sp.at("psd", *c.split("/")) for c in bound["curves"]])
    save_all(plot_inflation_steps(sp["frequency"], curves, spec_model, history, sensor=sensor, dt=dt,
                                  title=f"{sensor}: the paper's hand inflation of {spec}, step by step",
                                  display_unit=shown),
             out_steps, copies, "inflation_steps")
    save_all(plot_allan_deviation(av["tau"], every_curve(av, "avar"), sensor=sensor, display_unit=units,
                                  title=f"{sensor}: Allan deviation with the N, B, K read-offs"),
             out_readoffs, copies, "allan_readoffs")
