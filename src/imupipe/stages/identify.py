r"""The identification stage of one sensor type (rule ``identify``; :func:`imupipe.api.noise_model`).

From the Allan-variance curves of every included axis of every record (each at its own rate and length):

1. the pooled fit with every allowed component and its adequacy (:func:`imupipe.identify.fit_allan`), its GM time
   constants searched over the range the curves resolve (:func:`imupipe.identify.resolve.gm_T_range`, written as
   ``gm_T_search_s``);
2. the model selection for the application band (:func:`imupipe.identify.select_components`);
3. the SELECTED model refitted (:func:`imupipe.identify.refit_selected`: a random walk the selection dropped
   keeps its upper limit, the GM intervals their hull with the fit with a random walk): the parameters to
   report and bound; a GM term the curves do not resolve (its T interval reaching an end of the range, or T within
   an octave of its shortest T) re-assigned to the white noise or random walk it acts as
   (:func:`imupipe.identify.resolve.reassign_unresolved_gm`, written as ``gm_reassigned``);
4. its upper confidence envelope (:func:`imupipe.bound.upper_envelope`; a GM time constant the data leave
   open covered for :math:`f \ge 1/h`, h = ``span_s``: fix period + outage), the random walk and each GM term at
   most what the curves' Allan variances allow (:func:`imupipe.bound.random_walk_cap`,
   :func:`imupipe.bound.allan_check.gm_sigma_cap`; written as ``upper_envelope_gm_cap``);
5. the test whether the curves may be pooled (:func:`imupipe.identify.pooling_test`) and, where not, one
   identification per axis by the same rule, the envelope the bound reads then dominating the pooled and every
   per-axis envelope (:func:`imupipe.models.dominating_model`); where pooled under the joint envelope
   (``identify.envelope: joint``), each axis's own identification too (``axis_envelopes``, :data:`AXIS_ENVELOPE_KEYS`)
   and the model dominating the pooled envelope and them (``upper_envelope_model_axes``, the auto bound's envelope
   candidate's target): accepting one model does not show the axes equal;
6. slope-line readings (:func:`imupipe.identify.slope_line`) and, for simulated data, the truth beside the fit.

Plain values in (:class:`Curve` tuples, the config's numbers, the truth as a
:class:`~imupipe.models.NoiseModel` or None), a YAML-ready dict out (:func:`identification_stage`); the
workflow script reads the stacked Allan file (:func:`curves_of`) and writes the dict, the API keeps the objects
as well (:func:`identify_sensor`). SI units throughout.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

__all__ = ["AXIS_ENVELOPE_KEYS", "SEED_FIT", "SEED_POOLING", "Curve", "Identification", "axis_level", "curves_of",
           "envelope", "envelope_ratio", "fitted_model", "gm_cap_record", "identification_stage", "identify_sensor",
           "selected_and_envelope", "selected_model"]

#: Seeds of the fit's bootstrap and of the pooling test's (the workflow's and the API's).
SEED_FIT, SEED_POOLING = 20211, 20212

ENVELOPE_NOTE = (
    "kept components at the upper ends of the selected refit's statistical intervals (before any over-dispersion "
    "widening), each GM as GM terms above every GM of its interval box (one per sub-box of at most a decade in T), "
    "the random walk at its upper limit even when dropped, capped by what the recorded Allan variances allow, a GM "
    "time constant the data leave open covered for f >= 1/upper_envelope_horizon_s, each GM term's sigma at most "
    "what the recorded Allan variances allow over its T range (upper_envelope_gm_cap) (imupipe.bound.upper_envelope, "
    "random_walk_cap, gm_sigma_cap); SI; upper_envelope_horizon_s s")
UNITS = ("SI (u = rad/s or m/s^2): white u/sqrt(Hz), random_walk u/sqrt(s), flicker u, quantization u*s, "
         "ramp u/s, gm_sigma u, gm_T s; rate_hz Hz; chi2, p-values dimensionless")


def selected_model(doc: dict):
    """The identified model of an identify file (or of one of its ``per_axis`` entries) that the identification
    reports and inflation factors are read against: the selected refit (``model_selected``: the kept components, a GM
    the records do not resolve re-assigned to the white noise or random walk it acts as); ``model`` where there is
    no ``model_selected`` (a ``per_axis`` entry, whose ``model`` is the axis's). SI
    :class:`~imupipe.models.NoiseModel`."""
    from imupipe.models import NoiseModel

    return NoiseModel.from_dict(doc.get("model_selected") or doc["model"])


def fitted_model(doc: dict, kept=None):
    """The identified model a bound's components are compared with, each its own (the Allan-domain component check,
    Figure 6), and the components it kept: the selected refit as fitted, before any re-assignment (``model_refit``,
    ``model_refit_kept``), so that a GM the records do not resolve is checked as the GM the data gave (by the bound's
    GM, then GM + white, then GM + white + random walk) and not as the random walk it acts as only at taus well below
    its T. A file without ``model_refit``: :func:`selected_model` and `kept`. Returns (SI
    :class:`~imupipe.models.NoiseModel`, list of component names)."""
    from imupipe.models import NoiseModel

    if doc.get("model_refit"):
        return NoiseModel.from_dict(doc["model_refit"]), list(doc.get("model_refit_kept") or kept or [])
    return selected_model(doc), kept


class Curve(NamedTuple):
    """One Allan-variance curve: its label (``dataset/axis``), tau (s), Allan variance (u^2), equivalent
    degrees of freedom, record length (samples), record rate (Hz) and axis; finite entries only."""

    label: str
    tau: Any
    avar: Any
    edf: Any
    n_samples: int
    record_rate_hz: float
    axis: str


@dataclass
class Identification:
    """:func:`identify_sensor`'s result: ``record`` (the dict the workflow writes), the pooled ``fit``, the
    ``selection``, the ``selected`` refit (:class:`imupipe.identify.AllanFit`) and the ``envelope`` the bound
    reads (:class:`~imupipe.models.NoiseModel`, SI: the pooled one, or the dominating one when the axes differ)."""

    record: dict
    fit: Any
    selection: dict
    selected: Any
    envelope: Any


def curves_of(av) -> list[Curve]:
    """:class:`Curve` of every included curve of a :class:`imupipe.merge.Stacked` Allan-variance file, NaN
    entries removed (records of different lengths have different tau grids), each with its own record's rate."""
    out = []
    tau = av["tau"]
    for d, a in av.curves(included_only=True):
        avar, edf = av.at("avar", d, a), av.at("edf", d, a)
        ok = np.isfinite(avar) & np.isfinite(edf)
        out.append(Curve(f"{d}/{a}", tau[ok], avar[ok], edf[ok], int(av.at("n_samples", d, a)), av.rate_of(d, a), a))
    return out


#: The upper envelope's constructions (``identify.envelope``): every kept component at its marginal upper limit
#: at once, or the joint band of the fit's bootstrap (:mod:`imupipe.identify.joint`).
ENVELOPE_KINDS = ("marginal", "joint")


def envelope(fit, kept, curves, confidence: float, span_s: float, kind: str = "marginal"):
    """The upper confidence envelope of the kept components of `fit`, SI :class:`~imupipe.models.NoiseModel`.

    `kind` ``"marginal"`` (default, the paper's): :func:`imupipe.bound.upper_envelope`, every component at its
    upper limit at once (a GM time constant the data leave open covered for f >= 1/span_s, span_s in s: fix period
    + outage), its random walk at most what the curves' Allan variances allow (:func:`imupipe.bound.random_walk_cap`
    at `confidence`). ``"joint"``: :func:`imupipe.identify.joint.joint_envelope`, the model above the simultaneous
    band of the fit's PSD over its bootstrap replicates at `confidence` (family-wise over 1/span_s .. half
    the records' rate); the marginal one where the fit has no bootstrap."""
    from imupipe.bound import random_walk_cap, upper_envelope
    from imupipe.bound.allan_check import gm_sigma_cap

    if kind not in ENVELOPE_KINDS:
        raise ValueError(f"identify.envelope: expected one of {ENVELOPE_KINDS}, got {kind!r}")
    avs = [(c[1], c[2], c[3]) for c in curves]
    cap = random_walk_cap(avs, confidence=confidence)
    record: list = []
    marginal = upper_envelope(fit, kept, random_walk_cap=cap, span_s=span_s, cap_record=record,
                              gm_cap=lambda lo, hi: gm_sigma_cap(avs, lo, hi, confidence=confidence))
    fit.gm_cap_record = record  # identify file: ``upper_envelope_gm_cap``
    if kind == "joint":
        from imupipe.identify.joint import joint_envelope

        # below the band: the marginal envelope's random walk (its upper limit, capped by the Allan variances)
        env, rec = joint_envelope(fit, kept, span_s, 0.5 * min(float(c[5]) for c in curves), confidence,
                                  random_walk_min=marginal.random_walk)
        fit.joint_envelope = rec  # the band's record (identify file: ``upper_envelope_joint``)
        if env is not None:
            return env
    return marginal


def selected_and_envelope(fit, selection, curves, fit_kw: dict, confidence: float, span_s: float,
                          seed: int = SEED_FIT, T_range: dict | None = None, envelope_kind: str = "marginal"):
    """The selected refit of `fit` on `curves` (:func:`imupipe.identify.refit_selected`: a random walk the
    selection dropped keeps its upper limit, the GM intervals their hull with the fit with a random walk) and its
    upper envelope (:func:`envelope`); the one rule of the pooled and the per-axis identification. `seed`: the
    refit's bootstrap. `T_range` (:func:`imupipe.identify.resolve.gm_T_range`): a GM term the records do not
    resolve is re-assigned to the white noise or random walk it acts as
    (:func:`imupipe.identify.resolve.reassign_unresolved_gm`; the result's ``reassigned`` and ``kept_after``), and
    the envelope is that of the re-assigned model, dominating the GM's own envelope (its box over the T interval)
    too where the statistical T interval is open above (:func:`imupipe.models.dominating_model`): the envelope only
    grows where the data leave it open. `envelope_kind`: :func:`envelope`'s `kind`; ``"joint"`` takes the band of
    the refit before any re-assignment (its replicates are of the model fitted to the data)."""
    from imupipe.identify import refit_selected
    from imupipe.identify.resolve import reassign_unresolved_gm

    taus, avars, edfs = ([c[i] for c in curves] for i in (1, 2, 3))
    selected = refit_selected(fit, selection, taus, avars, edfs, rng=seed, **fit_kw)
    kept = list(selection["kept"])
    if T_range is None:
        selected.envelope_fit, selected.envelope_kept = selected, kept
        return selected, envelope(selected, kept, curves, confidence, span_s, envelope_kind)
    # a GM the records do not resolve is reported and bounded as the white noise or random walk it acts as
    before = selected
    selected, kept, moved = reassign_unresolved_gm(selected, kept, T_range)
    selected.reassigned, selected.kept_after = moved, kept
    selected.envelope_fit, selected.envelope_kept = before, list(selection["kept"])
    if envelope_kind == "joint":
        env = envelope(before, list(selection["kept"]), curves, confidence, span_s, envelope_kind)
        selected.joint_envelope = getattr(before, "joint_envelope", None)
        return selected, env
    env = envelope(selected, kept, curves, confidence, span_s)
    if any(r["T_open_above"] for r in moved):
        # integrity first: where the data leave the GM's T open above, its box (every longer T, for f >= 1/span)
        # stays in the envelope; the re-assigned white noise or random walk is added to it, never in its place
        from imupipe.models import dominating_model

        env = dominating_model([env, envelope(before, list(selection["kept"]), curves, confidence, span_s)])
    return selected, env


def gm_cap_record(selected) -> list:
    """What the GM cap (:func:`imupipe.bound.allan_check.gm_sigma_cap`) did to each GM term of the envelope of
    `selected` (and of its fit before a re-assignment, whose box the envelope keeps where the T interval is open
    above): T range (s, None for an open end), the box's sigma, the cap and the sigma used (u); for a box the data
    leave open, the bank of :func:`imupipe.bound.allan_check.gm_bank_envelope` (``bank``: sigma u, T s)."""
    out, seen = [], set()
    for f in (selected, getattr(selected, "envelope_fit", None)):
        if f is None or id(f) in seen:
            continue
        seen.add(id(f))
        for r in getattr(f, "gm_cap_record", None) or []:
            e = {"T_range_s": [float(r["T_range_s"][0]),
                               float(r["T_range_s"][1]) if math.isfinite(r["T_range_s"][1]) else None],
                 **{k: (float(r[k]) if math.isfinite(r[k]) else None)
                    for k in ("sigma_box", "sigma_cap", "sigma_used")},
                 "capped": bool(r["sigma_used"] < r["sigma_box"])}
            if "bank" in r:
                e["bank"] = r["bank"]
                e["note"] = ("T interval open: a bank of GM terms above every GM (min(sigma_box, sigma_max(T)), T) "
                             "of the box, weights by a linear programme; sigma_cap the least pointwise cap at the "
                             "bank's T")
            if "bank_failed" in r:
                e["sub_boxes"] = r["sub_boxes"]
                e["note"] = (f"T interval open; the bank's linear programme found no weights ({r['bank_failed']}): "
                             "the box covered by its uncapped sub-box terms (sub_boxes), above every GM of the box")
            out.append(e)
    return out


def _yaml_ready(rec):
    """The joint band's record with plain floats (non-finite as None)."""
    if rec is None:
        return None
    return {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in rec.items()}


def envelope_ratio(env: dict, model) -> dict:
    """Envelope over estimate of each amplitude (white, random_walk, flicker; gm_sigma_i with GM terms matched in
    order), dimensionless; None where the estimate is 0 (a component the envelope adds, e.g. a dropped random walk
    at its upper limit)."""
    est = {"white": model.white, "random_walk": model.random_walk, "flicker": model.flicker}
    out = {k: env.get(k, 0.0) for k in est}
    for i, term in enumerate(env.get("gauss_markov") or [], start=1):
        out[f"gm_sigma_{i}"] = term["sigma"]
        est[f"gm_sigma_{i}"] = model.gauss_markov[i - 1][0] if len(model.gauss_markov) >= i else 0.0
    return {k: (float(out[k] / est[k]) if est[k] > 0 else None) for k in out if out[k] > 0 or est[k] > 0}


def _subset_kw(fit_kw: dict, curves, index) -> dict:
    """`fit_kw` for the curves `curves` (a subset of the stage's, at positions `index` of its list): their rates,
    lengths and known line AVs."""
    kw = {**fit_kw, "record_rate_hz": [c[5] for c in curves], "n_samples": [c[4] for c in curves],
          "dt": 1.0 / curves[0][5]}
    if fit_kw.get("known_avar") is not None:
        kw["known_avar"] = [fit_kw["known_avar"][i] for i in index]
    return kw


def _known_of(curves, lines) -> list | None:
    """The known Allan variance of each curve's spectral lines (:func:`imupipe.lines.line_avar`, u^2 at its taus),
    None when no curve has a line. `lines`: curve label (``dataset/axis``) -> lines."""
    from imupipe.lines import line_avar

    if not lines:
        return None
    known = [line_avar(c.tau, lines.get(c.label, ())) for c in curves]
    return known if any(np.any(k > 0) for k in known) else None


def _calibrated_known(curves, known, lines, components, n_gm, T_grid, confidence) -> tuple:
    """Each curve's known line AV at the scale the Allan domain calibrates within its lines' power interval
    (:func:`imupipe.identify.known.calibrated_known`), and the record per curve label of the curves with lines
    ({} and `known` as it is without lines)."""
    from imupipe.identify.known import calibrated_known

    if known is None:
        return known, {}
    dofs = [[getattr(ln, "dof", None) for ln in lines.get(c.label, ())] for c in curves]
    scaled, records = calibrated_known([c.tau for c in curves], [c.avar for c in curves], [c.edf for c in curves],
                                       known, dofs, components=components, n_gm=n_gm, T_grid=T_grid,
                                       confidence=confidence)
    for c, r in zip(curves, records):
        if r and r["calibrated"]:
            logging.info("%s: the lines' Allan variance calibrated at %.3g x their PSD estimate (chi2 %.4g -> %.4g)",
                         c.label, r["scale"], r["chi2_unscaled"], r["chi2_scaled"])
    return scaled, {c.label: r for c, r in zip(curves, records) if r is not None}


def _adequacy_entry(fit) -> dict:
    """The adequacy numbers of a fit for the before/after table (chi2 and p dimensionless)."""
    a = fit.adequacy
    return {k: (float(a[k]) if isinstance(a.get(k), (float, np.floating)) else a.get(k))
            for k in ("chi2", "dof", "chi2_per_dof", "p_value", "adequate", "method")}


def _adequacy_with_lines(curves, fit, components, n_gm, fit_kw, seed) -> dict:
    """chi2/dof and the adequacy verdict of the full fit (every allowed component) per axis and pooled, before
    (no line terms) and after (the lines' AV a known term). The per-axis fits and the pooled fit without the
    lines run without a bootstrap (p from the generalised statistic with the exact AV covariance,
    :func:`imupipe.identify.bootstrap._adequacy`); the pooled fit with them is the identification's own."""
    from imupipe.identify import fit_allan

    def fitted(idx, known):
        sub = [curves[i] for i in idx]
        kw = {**_subset_kw(fit_kw, sub, idx), "n_boot": 0, "known_avar": None}
        if known:
            kw["known_avar"] = [fit_kw["known_avar"][i] for i in idx]
        return fit_allan([c[1] for c in sub], [c[2] for c in sub], [c[3] for c in sub], components=components,
                         n_gm=n_gm, rng=seed, **kw)

    all_idx = list(range(len(curves)))
    out = {"pooled": {"before": _adequacy_entry(fitted(all_idx, False)), "after": _adequacy_entry(fit)},
           "per_axis": {}}
    for axis in sorted({c[6] for c in curves}):
        idx = [i for i, c in enumerate(curves) if c[6] == axis]
        out["per_axis"][axis] = {"curves": [curves[i][0] for i in idx],
                                 "before": _adequacy_entry(fitted(idx, False)),
                                 "after": _adequacy_entry(fitted(idx, True))}
    out["note"] = ("the full fit (every allowed component) before (no line terms) and after (each curve's lines "
                   "as a known Allan-variance term); per axis without a bootstrap (p from the exact-covariance "
                   "statistic), pooled after: the identification's fit (bootstrap p)")
    return out


def _fin(x):
    """A finite float, or None (YAML)."""
    return float(x) if x is not None and np.isfinite(x) else None


def _record_consistency(curves, selection, components, n_gm, fit_kw, confidence, level, seed) -> dict:
    """Each record's (dataset's) own fit, its axes pooled, of the selected components with the random walk (and
    the known lines), and the test whether one record disagrees with the others beyond its intervals
    (:func:`imupipe.identify.consistency.record_consistency` at family-wise level `level`)."""
    from imupipe.identify import fit_allan
    from imupipe.identify.consistency import CONSISTENCY_PARAMS, record_consistency

    comps = [c for c in components if c in selection["kept"] or c == "random_walk"]
    datasets = sorted({c[0].split("/")[0] for c in curves})
    fits = {}
    for d in datasets:
        idx = [i for i, c in enumerate(curves) if c[0].split("/")[0] == d]
        sub = [curves[i] for i in idx]
        f = fit_allan([c[1] for c in sub], [c[2] for c in sub], [c[3] for c in sub], components=comps,
                      n_gm=n_gm, rng=seed, **_subset_kw(fit_kw, sub, idx))
        fits[d] = {p: (f.params[p], *f.intervals.get(p, (float("nan"), float("nan"))))
                   for p in CONSISTENCY_PARAMS if p in f.params}
        fits[d]["_adequate"] = bool(f.adequacy.get("adequate", True))
    adequate = {d: fits[d].pop("_adequate") for d in datasets}
    out = {"components": comps, "datasets": datasets, "adequate": adequate,
           "units": "estimate, lower, upper, others: SI (white u/sqrt(Hz), flicker u, random_walk u/sqrt(s)); z 1"}
    if len(datasets) < 2:
        out["note"] = "one record: nothing to compare"
        out["rows"] = {d: {p: {"estimate": _fin(v[0]), "lower": _fin(v[1]), "upper": _fin(v[2]), "z": None,
                               "flagged": False,
                               "note": "one record"} for p, v in fits[d].items()} for d in datasets}
        out["flagged"] = []
        return out
    res = record_consistency(fits, confidence=confidence, alpha=level)
    for row in res["rows"].values():  # YAML: non-finite ends (a one-sided interval, a missing term) as null
        for v in row.values():
            v.update({k: (float(x) if x is not None and np.isfinite(x) else None)
                      for k, x in v.items() if k in ("estimate", "lower", "upper", "others")})
    res["flagged"] = [{"dataset": r, "param": p, "z": z, "estimate": est, "others": oth}
                      for r, p, z, est, oth in res["flagged"]]
    return {**out, **res}


#: What the identify file keeps of each axis's own identification where the curves are pooled under the joint
#: envelope (``axis_envelopes``: the envelope candidate's target dominates each axis's): its curves, refit,
#: adequacy and envelope with its band's record.
AXIS_ENVELOPE_KEYS = ("curves", "model", "model_refit", "model_refit_kept", "params", "adequacy",
                      "upper_envelope_model", "upper_envelope_joint")


def _per_axis(curves, components, n_gm, selection, fit_kw, confidence, span, seed, T_range=None,
              envelope_kind="marginal"):
    """One identification per axis (its datasets pooled; one dataset: one curve) by the pooled path's rule: the
    axis's fit with every allowed component (no bootstrap: it only sets the components and the T search), then
    the pooled selection refitted on the axis; axis -> its identify-file entry. Under the joint envelope each
    axis's band is at `confidence` (the caller's per-axis level, :func:`axis_level`: the Bonferroni level with
    replicates to match where the pooling test rejects), recorded as the entry's ``upper_envelope_joint``. A band
    at the Bonferroni level from the pooled fit's 100 replicates would be their largest sup statistic: one outlying
    replicate raised an axis's envelope, and with it the exported random walk, 16x above its own interval)."""
    from imupipe.identify import fit_allan

    per_axis = {}
    axes = sorted({c[6] for c in curves})
    for axis in axes:
        idx = [i for i, c in enumerate(curves) if c[6] == axis]
        ax_curves = [curves[i] for i in idx]
        kw = _subset_kw(fit_kw, ax_curves, idx)
        full = fit_allan([c[1] for c in ax_curves], [c[2] for c in ax_curves], [c[3] for c in ax_curves],
                         components=components, n_gm=n_gm, rng=seed, **{**kw, "n_boot": 0})
        fa, env_a = selected_and_envelope(full, selection, ax_curves, kw, confidence, span, seed=seed,
                                          T_range=T_range, envelope_kind=envelope_kind)
        d = fa.to_dict()
        per_axis[axis] = {"curves": [c[0] for c in ax_curves], "model": fa.model.to_dict(),
                          "model_refit": getattr(fa, "envelope_fit", fa).model.to_dict(),
                          "model_refit_kept": list(getattr(fa, "envelope_kept", selection["kept"])),
                          "params": d["params"], "intervals": d["intervals"], "adequacy": d["adequacy"],
                          "on_boundary": d["on_boundary"], "interval_kind": d["interval_kind"],
                          "conservative": d["conservative"],
                          **({"intervals_statistical": d["intervals_statistical"]}
                             if "intervals_statistical" in d else {}),
                          **({"T_search_s": d["T_search_s"]} if "T_search_s" in d else {}),
                          "random_walk_profile": d["random_walk_profile"],
                          "upper_envelope_model": env_a.to_dict(), "upper_envelope_gm_cap": gm_cap_record(fa),
                          "notes": d["notes"],
                          **({"gm_reassigned": fa.reassigned} if getattr(fa, "reassigned", None) else {}),
                          **({"upper_envelope_joint": _yaml_ready(getattr(fa, "joint_envelope", None))}
                             if envelope_kind != "marginal" else {})}
    return per_axis


def axis_level(confidence: float, k: int, pooled: bool, envelope_kind: str, n_boot: int) -> dict:
    r"""The level of each axis's own identification (its intervals and joint band) and its bootstrap replicates.

    Where the pooling test rejects one model and the envelope is the joint one, each axis's model is a statement of
    its own (the KF file gives an axis its own model) and every statement must hold at once: each axis's band at the
    Bonferroni level :math:`c_a = 1 - (1 - c)/k` over k axes, so that all hold together with probability at least c
    (at :math:`c_a = c` each, only :math:`1 - k(1 - c)`, 0.85 for three axes at 0.95). The band's level is the
    order statistic :math:`\lceil (B + 1) c_a \rceil` of B replicates, so the replicates grow to
    :math:`B_a = k (B + 1) - 1`: as many lie beyond it as beyond the pooled band's (5 of 99 at 0.95; 5 of 299 at
    0.9833), not its largest one. Elsewhere (the pooled path's per-axis guard, or the marginal envelope, every
    component at its own upper limit at once) each axis stays at c with B replicates. Returns ``confidence``
    (:math:`c_a`), ``n_boot`` (:math:`B_a`), ``family_confidence`` (c) and ``rule`` (one sentence)."""
    if pooled or envelope_kind == "marginal" or k < 2:
        return {"confidence": float(confidence), "n_boot": int(n_boot), "family_confidence": None,
                "rule": "each axis at the identification's level (the pooled model is the statement)"
                if pooled else "each axis at the identification's level (marginal envelope)"}
    c_a = 1.0 - (1.0 - float(confidence)) / k
    return {"confidence": c_a, "n_boot": k * (int(n_boot) + 1) - 1 if n_boot > 0 else 0,
            "family_confidence": float(confidence),
            "rule": f"Bonferroni over {k} axes: each axis's band at 1 - (1 - {confidence:g}) / {k} = {c_a:.4g}, "
                    f"all {k} together at least {confidence:g}"}


def _axes_identified(out: dict, env, curves, components, n_gm, selection, fit_kw, confidence, span, seed, T_range,
                     envelope_kind) -> None:
    """Step 5 of the module docstring, into the identify record `out` (its ``pooling`` done; `env` the pooled
    envelope, :class:`~imupipe.models.NoiseModel`): where the pooling test rejects one model, one identification per
    axis (``per_axis``) and the envelope the bound reads (``upper_envelope_model``) dominating the pooled
    (``upper_envelope_model_pooled``) and every axis's; where it accepts under the joint envelope with more than one
    axis, each axis's own identification (``axis_envelopes``, :data:`AXIS_ENVELOPE_KEYS`) and the model dominating
    the pooled envelope and every axis's (``upper_envelope_model_axes``): the target of the auto bound's envelope
    candidate, which the sample PSDs do not hold up (:func:`imupipe.bound.auto.candidate_modes`). The envelope the
    other candidates and the verification read stays the pooled one there: they bound every curve's own spectrum
    in band, and on the outside evaluation's case below they bounded z with room (raw and smoothed: MSE/P 0.988)."""
    from imupipe.models import NoiseModel, dominating_model

    pooled = out["pooling"]["consistent"]
    if pooled and (envelope_kind == "marginal" or len({c.axis for c in curves}) < 2):
        out["identification"] = "pooled: the curves are consistent with one model (pooling test)"
        return
    level = axis_level(confidence, len({c.axis for c in curves}), pooled, envelope_kind, int(fit_kw["n_boot"]))
    axes = _per_axis(curves, components, n_gm, selection, {**fit_kw, "n_boot": level["n_boot"],
                                                           "confidence": level["confidence"]},
                     level["confidence"], span, seed, T_range=T_range, envelope_kind=envelope_kind)
    for entry in axes.values():
        entry["level"] = dict(level)
    dominating = dominating_model([env] + [NoiseModel.from_dict(v["upper_envelope_model"]) for v in axes.values()])
    if pooled:
        # the test's acceptance does not show the axes equal: a gyro z whose drift was 20 % above x and y's (two
        # 1.5 h records per axis) passed it (p 0.28), the pooled joint band lay below z's random walk and a filter
        # on the envelope candidate under-stated z's error (MSE/P 1.07). The band each axis has of its own is at
        # level c whatever the others do, so the envelope candidate's target dominates them all.
        out["axis_envelopes"] = {ax: {k: e[k] for k in AXIS_ENVELOPE_KEYS if k in e} for ax, e in axes.items()}
        out["upper_envelope_model_axes"] = dominating.to_dict()
        out["identification"] = ("pooled: the curves are consistent with one model (pooling test); "
                                 "`upper_envelope_model_axes` dominates the pooled joint envelope and each axis's own "
                                 "(`axis_envelopes`), the envelope candidate's target: accepting one model does not "
                                 "show the axes equal")
        return
    out["per_axis"] = axes
    out["identification"] = ("per axis: the curves are not consistent with one model (pooling test); the pooled "
                             "fit is kept for reference, `per_axis` gives each axis's parameters and "
                             "`upper_envelope_model` dominates the pooled and every per-axis envelope")
    # the pooled envelope need not cover an axis that differs: the envelope the bound reads covers each
    out["upper_envelope_model_pooled"] = env.to_dict()
    out["upper_envelope_model"] = dominating.to_dict()


def identify_sensor(curves, *, sensor: str, components, n_gm: int, n_boot: int, confidence: float,
                    significance: float, relevance: float, filter_rate_hz: float, outage_s: float,
                    adequacy_level: float = 0.01, pooling_level: float = 0.01, pooling_n_boot: int = 99,
                    span_s: float | None = None, fit_tau_min_samples: float | None = None,
                    truth=None, seed: int = SEED_FIT, lines=None, envelope_lines: bool = False,
                    envelope_lines_below_hz: float | None = None,
                    consistency_level: float = 0.01, envelope_kind: str = "marginal") -> Identification:
    """The identification of one sensor type (module docstring, steps 1-6) on `curves` (:class:`Curve` or
    tuples in its order), with the workflow's settings: ``identify.*`` (`components`, `n_gm`, `n_boot`,
    `confidence`, `significance`, `relevance`, `adequacy_level`, `pooling_level`, `pooling_n_boot`,
    `fit_tau_min_samples`: the GM search's shortest T at least that many sample intervals, else the range the curves
    resolve alone), the filter's update rate `filter_rate_hz` (Hz) and the outage `outage_s` (s) for the
    selection, and `span_s` (s; fix period + outage, the window the bound must hold over, written as
    ``upper_envelope_horizon_s``; default `outage_s`). `truth`: the simulation's
    :class:`~imupipe.models.NoiseModel` or None. `seed`: of the fit's bootstrap and refit (the pooling test's is
    :data:`SEED_POOLING`). `lines`: curve label (``dataset/axis``) -> the curve's spectral lines
    (:func:`imupipe.lines.lines_by_curve`: :class:`imupipe.lines.Line` or (sigma, f0_hz, zeta)), whose Allan
    variance enters every fit as a known term (``known_avar`` of :func:`imupipe.identify.fit_allan`); None: no
    lines. `envelope_lines`: the lines (merged over the curves as the bound merges them,
    :func:`imupipe.lines.merge_lines`) also enter the upper envelope as its narrowband terms, so that the envelope
    the bound covers and the verification runs against holds them as lines (line policy ``model``; under
    ``exclude`` the bound has no column for an excluded line, and the envelope leaves them out); with
    `envelope_lines_below_hz` (the workflow: half the decimation rate, Hz) only the lines below it. A line above the
    decimated Nyquist frequency reaches the bound's LP only through its alias, attenuated by the block average (by
    6.3e-9 for a 22 Hz gyro line of one ADIS16405 record at 1 Hz): covering the envelope's line there inflated the
    bound's line to 0.91 rad/s at the filter's 100 Hz. Such a line is covered from the sample spectra alone.
    `consistency_level`: the family-wise false-alarm level of the record-consistency test. `envelope_kind`
    (``identify.envelope``): the upper envelope's construction, :func:`envelope`'s `kind` (``marginal``, the
    paper's, or ``joint``).

    Raises ValueError when `curves` is empty."""
    from imupipe.identify import fit_allan, pooling_test, select_components, slope_line
    from imupipe.models import NoiseModel

    curves = [Curve(*c) for c in curves]
    if not curves:
        raise ValueError("identification: no included curve")
    labels = [c.label for c in curves]
    taus, avars, edfs = [c.tau for c in curves], [c.avar for c in curves], [c.edf for c in curves]
    ns, rates = [c.n_samples for c in curves], [c.record_rate_hz for c in curves]
    components = list(components)
    known = _known_of(curves, lines)
    T_range, T_grid = _T_search_of(taus, edfs, confidence, fit_tau_min_samples, 1.0 / rates[0])
    if T_grid is None and "gauss_markov" in components:
        components = [c for c in components if c != "gauss_markov"]
        logging.info("no GM time constant resolvable (%s): the fit has no GM", T_range["statement"])
    known, known_scales = _calibrated_known(curves, known, lines, components, n_gm, T_grid, confidence)
    fit_kw = dict(n_boot=n_boot, confidence=confidence, dt=1.0 / rates[0], record_rate_hz=rates, n_samples=ns,
                  adequacy_level=adequacy_level, T_grid=T_grid, known_avar=known)
    fit = fit_allan(taus, avars, edfs, components=components, n_gm=n_gm, rng=seed, **fit_kw)
    selection = select_components(fit, taus, avars, edfs, filter_rate_hz=filter_rate_hz, outage_s=outage_s,
                                  significance=significance, relevance=relevance)
    kept = list(selection["kept"])
    logging.info("kept %s; dropped %s", kept, selection["dropped"])
    span = float(span_s if span_s is not None else outage_s)
    selected, env = selected_and_envelope(fit, selection, curves, fit_kw, confidence, span, seed=seed,
                                          T_range=T_range, envelope_kind=envelope_kind)
    moved = getattr(selected, "reassigned", [])
    if moved:
        selection = _selection_after(selection, moved, selected.kept_after)
    pooling = pooling_test(taus, avars, edfs, components=tuple(kept), n_gm=n_gm, record_rate_hz=rates, n_samples=ns,
                           labels=labels, n_boot=pooling_n_boot, level=pooling_level, rng=SEED_POOLING,
                           known_avar=known)
    logging.info("pooling: %s", pooling["note"])

    out = {
        "sensor": sensor,
        "curves": labels,
        "rate_hz": {lab: float(r) for lab, r in zip(labels, rates)},
        "n_samples": {lab: int(n) for lab, n in zip(labels, ns)},
        # the bootstrap behind every interval and so behind the upper envelope the bound covers (the contract's
        # identification_intervals check: without it the envelope is the point fit)
        "intervals_bootstrap": {"n_boot": int(n_boot), "confidence": float(confidence)},
        "fit": fit.to_dict(),  # the full fit (every allowed component); `selected` inside: the refit
        "model": fit.model.to_dict(),
        "model_selected": selected.model.to_dict(),  # the parameters to report and bound
        # the same refit before any re-assignment: what the bound's component check compares with (fitted_model)
        "model_refit": getattr(selected, "envelope_fit", selected).model.to_dict(),
        "model_refit_kept": list(getattr(selected, "envelope_kept", kept)),
        "selection": {k: selection[k] for k in ("kept", "dropped", "reasons", "reduced_model", "band_hz")},
        "adequacy": {"pooled": selected.to_dict()["adequacy"], "full_fit": fit.to_dict()["adequacy"],
                     "per_curve": {c["label"]: {k: c[k] for k in ("chi2", "dof", "chi2_per_dof", "p_value",
                                                                  "adequate")} for c in pooling["per_curve"]}},
        "on_boundary": {k: bool(v) for k, v in selected.on_boundary.items()},
        "conservative": selected.to_dict()["conservative"],
        "pooling": pooling,
        "upper_envelope_model": env.to_dict(),
        "upper_envelope_horizon_s": span,
        "upper_envelope_gm_cap": gm_cap_record(selected),
        **({"upper_envelope_kind": envelope_kind,
            "upper_envelope_joint": _yaml_ready(getattr(selected, "joint_envelope", None))}
           if envelope_kind != "marginal" else {}),
        "gm_T_search_s": T_range,
        "gm_reassigned": moved,
        "slope_line": {},
    }
    if known is not None:
        out["lines_known"] = _lines_record(curves, lines, known, known_scales)
    out["adequacy_lines"] = (_adequacy_with_lines(curves, fit, components, n_gm, fit_kw, seed)
                             if known is not None else None)
    # what the envelope's level rests on: the bootstrap's model describing the data (the contract's confidence)
    out["intervals_bootstrap"]["model_adequate"] = bool(out["adequacy"]["pooled"].get("adequate", True))
    out["record_consistency"] = _record_consistency(curves, selection, components, n_gm, fit_kw, confidence,
                                                    consistency_level, seed)
    band = out["selection"]["band_hz"]
    out["selection"]["band_hz"] = [float(v) for v in band] if band else None
    _axes_identified(out, env, curves, components, n_gm, fit.selection or selection, fit_kw, confidence, span, seed,
                     T_range, envelope_kind)
    if known is not None and envelope_lines:
        out["upper_envelope_model"] = _with_lines(out["upper_envelope_model"], lines, envelope_lines_below_hz,
                                                  confidence)
        # each axis's envelope holds that axis's lines too: its own bound and the verification of its model's
        # reduction run against it (an outside evaluation saw a line state dropped from an axis's model, checked
        # against an envelope without the line)
        for entry in (out.get("per_axis") or {}).values():
            mine = {lab: lines[lab] for lab in entry["curves"] if lab in lines}
            if mine:
                entry["upper_envelope_model"] = _with_lines(entry["upper_envelope_model"], mine,
                                                            envelope_lines_below_hz, confidence)
        # the model above the pooled envelope and each axis's (the auto bound's target where the axes are pooled)
        # carries the pooled envelope's lines, which hold every axis's at least (merged: the largest power)
        if out.get("upper_envelope_model_axes") and out["upper_envelope_model"].get("narrowband"):
            out["upper_envelope_model_axes"] = {**out["upper_envelope_model_axes"],
                                                "narrowband": out["upper_envelope_model"]["narrowband"]}
    out["upper_envelope_ratio"] = envelope_ratio(out["upper_envelope_model"], selected.model)
    if not out["adequacy"]["pooled"].get("adequate", True):
        out["upper_envelope_note"] = (
            "the selected model does not describe the data (adequacy): its reported intervals are widened by the "
            f"over-dispersion factor {out['adequacy']['pooled'].get('widening')}, but the envelope uses the model's "
            "statistical limits (not widened), so below the lowest PSD bin the bound rests on a model the data "
            "reject; the verification's replay of the records is the model-free check over the horizon")
    out["upper_envelope"] = ENVELOPE_NOTE
    for c in curves:
        sl = slope_line(c.tau, np.sqrt(c.avar))
        out["slope_line"][c.label] = {k: (float(v) if isinstance(v, (float, np.floating)) else v)
                                      for k, v in sl.items()}
    if truth is not None:
        out["truth"] = truth.to_dict()
        if truth.white > 0:
            out["white_relative_error"] = float(selected.model.white / truth.white - 1.0)
    out["units"] = UNITS
    return Identification(record=out, fit=fit, selection=selection, selected=selected,
                          envelope=NoiseModel.from_dict(out["upper_envelope_model"]))


def _T_search_of(taus, edfs, confidence, fit_tau_min_samples, dt):
    """The GM time constants the curves resolve (:func:`imupipe.identify.resolve.gm_T_range` over every AV point of
    every curve, at `confidence`; its shortest T at least `fit_tau_min_samples` * `dt` s when that is set) and the
    search grid over it (8 per decade, s), or None when the range is empty (no GM resolvable). Returns
    (range dict with a ``statement``, grid)."""
    from imupipe.identify.resolve import gm_T_range
    from imupipe.search import log_grid

    rng = gm_T_range(np.concatenate([np.ravel(t) for t in taus]), np.concatenate([np.ravel(e) for e in edfs]),
                     confidence)
    if fit_tau_min_samples is not None:
        rng["T_min_config_s"] = float(fit_tau_min_samples) * float(dt)
        rng["T_min_s"] = max(rng["T_min_s"], rng["T_min_config_s"])
    lo, hi = rng["T_min_s"], rng["T_max_s"]
    rng["statement"] = (f"GM time constants searched {lo:.4g}-{hi:.4g} s: {lo / rng['tau_min_s']:.3g} x the shortest "
                        f"tau ({rng['tau_min_s']:.4g} s) to {hi / rng['tau_max_s']:.3g} x the longest "
                        f"({rng['tau_max_s']:.4g} s); a GM whose T interval reaches an end, or whose T is below "
                        f"{2 * lo:.4g} s, is re-assigned to the white noise or random walk it acts as")
    if not hi > 2.0 * lo:  # fewer than an octave: no T the records resolve
        return rng, None
    return rng, log_grid(np.log10(lo), np.log10(hi), 8, min_points=3)


def _selection_after(selection: dict, moved: list, kept_after: list) -> dict:
    """`selection` with the re-assigned GM terms (`moved`, :func:`imupipe.identify.resolve.reassign_unresolved_gm`)
    out of ``kept`` and what they act as in; their reasons say so."""
    sel = {**selection, "reasons": dict(selection["reasons"])}
    sel["kept"] = list(kept_after)
    sel["dropped"] = [c for c in selection["dropped"] if c not in kept_after]
    if "gauss_markov" not in kept_after and "gauss_markov" not in sel["dropped"]:
        sel["dropped"].append("gauss_markov")
    for r in moved:
        sel["reasons"]["gauss_markov"] = (
            f"re-assigned: GM term {r['term']} (sigma {r['sigma']:.3g} u, T {r['T_s']:.3g} s) is not a GM the "
            f"records resolve ({r['why']}); it acts as {'white noise' if r['acts_as'] == 'white' else 'a random walk'}"
            f" and is reported and bounded as one ({r['acts_as']} = {r['value']:.3g} SI); was: "
            + selection["reasons"].get("gauss_markov", ""))
        tgt = r["acts_as"]
        if tgt not in selection["kept"]:
            sel["reasons"][tgt] = "kept: a re-assigned GM term acts as it (see gauss_markov); was: " + \
                selection["reasons"].get(tgt, "")
    sel["reduced_model"] = "random_walk" not in sel["kept"]
    return sel


def _with_lines(env: dict, lines, below_hz: float | None = None, confidence: float = 0.95) -> dict:
    r"""The envelope `env` (:meth:`NoiseModel.to_dict`, SI) with the curves' lines as narrowband terms: merged as
    the bound's line policy merges them (:func:`imupipe.lines.merge_lines`: one term per group of overlapping lines,
    its power the largest member's, its width covering every member), each at the upper confidence limit of its power
    at `confidence`, :math:`P_1\,\nu / \chi^2_\nu(1 - c)` with the line's degrees of freedom :math:`\nu`
    (:attr:`imupipe.lines.Line.dof`; its point estimate where the lines file records none); sigma = sqrt(power) /
    g u (g the sample interval's gain at the line, :attr:`imupipe.lines.Line.block_gain`: the model's continuous
    oscillator), f0 Hz, zeta. Like every other term of the envelope, a line is held at what the records do not
    exclude: an outside evaluation's 150 deg/h line (two 2 h records) was estimated at 141 deg/h, and a filter on the
    bound that carried the estimate under-stated its error in the first step (MSE/P 1.003)."""
    from imupipe.lines import Line, line_power_upper, merge_lines

    found = [ln for group in lines.values() for ln in group if isinstance(ln, Line)
             and (below_hz is None or ln.frequency_hz < below_hz)]
    merged = merge_lines(found) if found else []
    if not merged:
        return env

    return {**env, "narrowband": [{"sigma": math.sqrt(line_power_upper(ln.power, ln.dof, confidence)) / ln.block_gain,
                                   "f0_hz": float(ln.frequency_hz), "zeta": float(ln.zeta)} for ln in merged]}


def _lines_record(curves, lines, known, scales=None) -> dict:
    """Per curve: the lines known to the fit (f0 Hz, amplitude and sigma u of the model's continuous oscillator,
    :attr:`imupipe.lines.Line.narrowband`, zeta 1; their PSD estimates), the largest share of the curve's Allan
    variance they carry (1, at the fit's scale) and ``av_scale``: the scale of their Allan variance in the fit
    (:func:`_calibrated_known`; 1 unless the Allan domain calibrates it)."""
    from imupipe.lines import Line

    out = {}
    for c, k in zip(curves, known):
        terms = [ln.narrowband if isinstance(ln, Line) else tuple(float(v) for v in ln)
                 for ln in lines.get(c.label, ())]
        if not terms:
            continue
        out[c.label] = {"lines": [{"f0_hz": float(f0), "amplitude": float(math.sqrt(2.0) * s), "sigma": float(s),
                                   "zeta": float(z)} for s, f0, z in terms],
                        "max_avar_share": float(np.max(k / np.asarray(c.avar, dtype=np.float64)))}
        if (scales or {}).get(c.label):
            out[c.label]["av_scale"] = {
                **scales[c.label], "units": {"scale": "1", "interval": "1", "chi2_unscaled": "1", "chi2_scaled": "1",
                                             "threshold": "1"},
                "statement": "the lines' Allan variance in every fit is their PSD estimate's times `scale`: the scale "
                             "within the lines' power interval that minimises the curve's own fit statistic, kept "
                             "at 1 unless the fit improves by more than `threshold` (chi2 with 1 dof at level 0.01)"
                             + ("; at an end of its interval: the Allan variance asks for more than the lines' "
                                "power allows, and chi2_scaled says how far the fit stays from the data"
                                if scales[c.label].get("at_interval_end") else "")}
    return out


def identification_stage(curves, **settings) -> dict:
    """The identify file's content (a YAML-ready dict, SI) of :func:`identify_sensor` with the same arguments."""
    return identify_sensor(curves, **settings).record
