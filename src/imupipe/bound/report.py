"""Reporting of a bound: :class:`BoundResult`, inflation factors, YAML-ready dicts in SI and spec units."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from imupipe.io import plain
from imupipe.specsheet import model_in_units



def _inflation(bound, spec):
    """Inflation factors bound/spec per parameter; None where the spec has no such component."""

    def ratio(b, s):
        if s is None or s == 0:
            return None
        return float(b / s)

    out = {
        "N": ratio(bound.white, spec.white if spec is not None else None),
        "K": ratio(bound.random_walk, spec.random_walk if spec is not None else None),
    }
    sgm = sorted(spec.gauss_markov, key=lambda st: st[1]) if spec is not None else []
    bgm = sorted(bound.gauss_markov, key=lambda st: st[1])
    n = max(len(sgm), len(bgm), 1)
    for i in range(n):
        sfx = "" if n == 1 else f"_{i + 1}"
        s = sgm[i] if i < len(sgm) else None
        b = bgm[i] if i < len(bgm) else (0.0, None)
        out["sigma" + sfx] = ratio(b[0], s[0]) if s is not None else None
        out["T" + sfx] = ratio(b[1], s[1]) if (s is not None and b[1] is not None) else None
    return out


# ---------------------------------------------------------------------------------------------
# result
# ---------------------------------------------------------------------------------------------
@dataclass
class BoundResult:
    r"""Result of :func:`bound_psd` or :func:`paper_inflation` (SI throughout).

    Attributes
    ----------
    model : imupipe.models.NoiseModel
        The bound: white N (u/sqrt(Hz)), GM terms (sigma u, T s), random walk K (u/sqrt(s)).
    spec : imupipe.models.NoiseModel or None
        The spec-sheet model the bound was asked to dominate.
    inflation : dict
        bound/spec per parameter (``N``, ``K``, ``sigma``, ``T``; ``sigma_i``/``T_i`` for several
        GM terms, matched by increasing T); None where the spec has no such component.
    bounded : bool
        Model >= every target and >= the spec at every compared frequency (to 1e-9).
    margin : float
        :math:`\min_{c,k} S_m(f_k)/\hat S_c(f_k)` over the mode's targets (>= 1 - 1e-9 when bounded).
    margin_curve, margin_frequency :
        Label of the curve and frequency (Hz) that set `margin`.
    raw_margin, raw_margin_curve, raw_margin_frequency :
        The same against the raw periodograms (below 1 in smoothed/confidence modes, by design).
    spec_margin, spec_margin_frequency :
        :math:`\min S_m/S_{spec}` and where.
    data_check : dict or None
        The records against the model: the largest ratio of a sample PSD's lower confidence limit (family-wise at
        the bound's confidence over every curve and bin) to the model's PSD, where, and ``passed`` (ratio <= 1);
        :mod:`imupipe.bound.datacheck` (docs/method.md, "The data check").
    looseness : float
        LP objective: log-frequency mean of :math:`S_m/E` (E = envelope of targets and spec).
    mode : str
        ``raw``, ``smoothed``, ``confidence`` or ``paper`` (hand inflation, raw targets).
    components : list of str
        Components the bound was allowed to use.
    decisions : dict
        Component -> reason it was used or not.
    T_profile : tuple of numpy.ndarray
        (T grid, looseness) of the single-GM profile.
    n_lp : int
        Linear programs solved.
    solve_time_s : float
        Wall time, s.
    details : dict
        Mode settings (bands, edf, confidence, number of tests) and, for the hand procedure, the
        step history.
    """

    model: object
    spec: object
    inflation: dict
    bounded: bool
    margin: float
    margin_curve: str
    margin_frequency: float
    raw_margin: float
    raw_margin_curve: str
    raw_margin_frequency: float
    spec_margin: float
    spec_margin_frequency: float | None
    looseness: float
    mode: str
    components: list
    decisions: dict
    T_profile: tuple = field(repr=False, default=(np.zeros(0), np.zeros(0)))
    n_lp: int = 0
    solve_time_s: float = 0.0
    details: dict = field(default_factory=dict)
    allf_margin: float = float("inf")
    allf_margin_frequency: float | None = None
    data_check: dict | None = None

    def to_dict(self, spec_units: dict | None = None, sensor: str | None = None) -> dict:
        """Plain dict for YAML: bound and spec in SI and, with `spec_units`, in the spec's units.

        Parameters
        ----------
        spec_units : dict, optional
            Unit per quantity as written in the spec sheet, keys among ``white``, ``gm_sigma``,
            ``time``, ``random_walk`` (e.g. ``{"white": "deg/sqrt(h)", "gm_sigma": "deg/h",
            "time": "s", "random_walk": "(deg/h)/sqrt(s)"}``). Converted with
            :func:`imupipe.specsheet.model_in_units`; without it only SI is written.
        sensor : str, optional
            ``gyro`` or ``accel`` (passed to the unit conversion).
        """

        def fl(x):
            if x is None:
                return None
            x = float(x)
            return x if math.isfinite(x) else None

        def params(m):
            if m is None:
                return None
            return {
                "white": fl(m.white),
                "gauss_markov": [{"sigma": fl(s), "T": fl(T)} for s, T in m.gauss_markov],
                "random_walk": fl(m.random_walk),
                "narrowband": [{"sigma": fl(sg), "f0_hz": fl(f0), "zeta": fl(z)}
                               for sg, f0, z in getattr(m, "narrowband", ())],
            }

        out = {
            "units": "SI: white u/sqrt(Hz), gauss_markov sigma u and T s, random_walk u/sqrt(s); "
            "u = rad/s (gyro) or m/s^2 (accel); PSDs two-sided",
            "bound": params(self.model),
            "spec": params(self.spec),
            "inflation": {k: fl(v) for k, v in self.inflation.items()},
            "bounded": bool(self.bounded),
            "margin": fl(self.margin),
            "margin_curve": self.margin_curve,
            "margin_frequency_hz": fl(self.margin_frequency),
            "raw_margin": fl(self.raw_margin),
            "raw_margin_curve": self.raw_margin_curve,
            "raw_margin_frequency_hz": fl(self.raw_margin_frequency),
            "spec_margin": fl(self.spec_margin),
            "spec_margin_frequency_hz": fl(self.spec_margin_frequency),
            "looseness": fl(self.looseness),
            "all_frequency_margin": fl(self.allf_margin),
            "all_frequency_margin_frequency_hz": fl(self.allf_margin_frequency),
            "data_check": plain(self.data_check) if self.data_check else None,
            "mode": self.mode,
            "components": list(self.components),
            "decisions": dict(self.decisions),
            "n_lp": int(self.n_lp),
            "solve_time_s": fl(self.solve_time_s),
            "details": plain(self.details),
        }
        if spec_units:
            out["bound_spec_units"], note = model_in_units(self.model, spec_units, sensor)
            if self.spec is not None:
                out["spec_spec_units"], _ = model_in_units(self.spec, spec_units, sensor)
            if note:
                out["unit_note"] = note
        return out
