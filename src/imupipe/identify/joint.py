r"""A joint (simultaneous) upper confidence envelope of an Allan-variance fit, from its bootstrap replicates.

The marginal envelope (:func:`imupipe.bound.upper_envelope`) puts every kept component at the upper end of its own
interval at once (a GM as the box over its T interval). The fit's components trade against each other (a longer
GM against a random walk, a larger GM against a smaller white noise), so that model is far above every model the
data allow together. Here the statement is about the model's PSD :math:`S(f;\theta)` over a band of frequencies
at once.

**The band.** With :math:`\hat\theta` the fit and :math:`\theta^*_b`, b = 1..B, its parametric bootstrap refits
(``fit.bootstrap``: records drawn from the fitted model with the exact correlation of the AV estimates, refitted
the same way, :mod:`imupipe.identify.fit`), on a grid of frequencies F (log-spaced over the band):

* :math:`d_b(f) = \ln S(f;\theta^*_b) - \ln S(f;\hat\theta)`; per frequency its median :math:`m(f)` and its upper
  spread :math:`u(f) = q_{0.95}(f) - m(f)` over b (floored at 1e-3), :math:`q_p(f)` the p-quantile of
  :math:`d_b(f)`;
* the sup statistic :math:`z_b = \max_{f\in F} (d_b(f) - m(f))/u(f)` and :math:`c` its `confidence` quantile over
  b (the order statistic :math:`\lceil (B+1)c \rceil`);
* the **percentile** band :math:`U(f) = \hat S(f)\,\exp(\max(m(f) + c\,u(f), 0))`: it holds whole replicate curves
  in a fraction `confidence` of replicates (every curve with :math:`z_b \le c`), and never lies below the fit.

This is the directional quantile global envelope of Myllymaki et al. (2017, section 3): each frequency is put on
the scale of its own upper tail, so frequencies where the replicates' deviations are small but heavy-tailed (a
short GM that some replicates refit) do not set the level at the others. A symmetric scale (half the 16-84 %
range), used before, let such frequencies raise :math:`c` to 3.8 on a 10 h tactical-grade record, and with it the
band at the lowest frequencies, which set a filter's error over an outage, to 1.9x the fit where the replicates'
own 95th percentile there was 1.16x. The basic (pivot) band, :math:`\exp(c' s)` with :math:`c'` the quantile of
:math:`\max (-d_b/s)`, is not used: where a coefficient is fitted at its bound (a random walk fitted 0 in some
replicates) its sup statistic is set by those replicates and the band went 200x above the truth.

Below the band the envelope is its model's extrapolation; its random walk is at least `random_walk_min` (the
identification passes the marginal envelope's K: its upper limit at the same level, capped by the Allan variances),
so a random walk the records cannot exclude still rises below the band as in the marginal envelope (without it, a
plan's envelope of GM terms alone fell to 0.33 x a white + GM + random-walk model at 2e-5 Hz, and a filter on it
under-stated that model's error 2.3x over a 600 s fix + 3600 s outage).

The level is **family-wise over the grid F**: :math:`P(S(f;\theta_0) \le U(f)\ \forall f\in F) \approx`
`confidence` (a simultaneous band, by the bootstrap principle). **Between grid points** (spacing
:math:`\delta \le \ln 10/100` in ln f): the truth's and the envelope model's PSDs are positive sums of white, random
walk, flicker and GM terms, whose log-PSDs have slopes in [-2, 0] and curvatures in [-1, 0] in ln f, so each
log-PSD has curvature in [-1, 1] and their log ratio in [-2, 2]; a log ratio at least :math:`\delta^2/4` at two grid
points stays >= 0 between them. The envelope is therefore held at :math:`e^{\delta^2/4}` (1.00013) times U on F
(:data:`JOINT_PAD`), and the truth under U on F is under the envelope over the whole band.

**The model.** The bound and the verification need a :class:`~imupipe.models.NoiseModel`: the envelope is the
non-negative combination of white noise, a random walk, a flicker (when kept) and GM terms on a log grid of T
(:data:`T_PER_DECADE` per decade) that lies on or above the padded :math:`U` at every grid frequency and minimises
the mean of model / U over the grid (a linear programme, ``scipy.optimize.linprog``, HiGHS); it is then scaled so
that the minimum of model / U over F is at least the pad (the solver's tolerance).

References: A. C. Davison, D. V. Hinkley, "Bootstrap Methods and their Application", Cambridge University Press,
1997 (sections 4.2.4, 5.2); M. Myllymaki, T. Mrkvicka, P. Grabarnik, H. Seijo, U. Hahn, "Global envelope tests
for spatial processes", Journal of the Royal Statistical Society B 79(2), 381-404, 2017.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["joint_band", "joint_envelope", "JOINT_PAD", "PER_DECADE"]

#: Grid density of the band, frequencies per decade.
PER_DECADE = 100
#: The pad between grid points: :math:`e^{\delta^2/4}`, :math:`\delta = \ln 10` / PER_DECADE (module docstring).
JOINT_PAD = math.exp((math.log(10.0) / PER_DECADE) ** 2 / 4.0)
#: Upper quantile of the replicates' deviations that scales each frequency (module docstring).
UPPER_QUANTILE = 0.95
#: GM time constants per decade of the envelope model's basis.
T_PER_DECADE = 6


def _replicate_models(fit, kept):
    """NoiseModels (SI, continuous) of the fit and of its finite bootstrap replicates, kept components only
    (`kept` None: all). A row with a non-finite value is dropped."""
    from imupipe.identify.basis import _params_to_model

    names = list(getattr(fit, "param_names", []) or [])
    boots = np.asarray(getattr(fit, "bootstrap", np.zeros((0, 0))), dtype=np.float64)

    def keep(p):
        p = dict(p)
        for c in ("white", "random_walk", "flicker"):
            if kept is not None and c not in kept:
                p[c] = 0.0
        if kept is not None and "gauss_markov" not in kept:
            p = {k: v for k, v in p.items() if not k.startswith("gm_")}
        p["quantization"], p["ramp"] = 0.0, 0.0
        return p

    hat = _params_to_model(keep({k: float(v) for k, v in fit.params.items()}))
    reps = []
    if boots.ndim == 2 and boots.shape[0] and boots.shape[1] == len(names):
        for row in boots:
            p = dict(zip(names, (float(v) for v in row)))
            for k, v in fit.params.items():  # a parameter the replicate does not carry: the estimate's
                p.setdefault(k, float(v))
            vals = [v for k, v in p.items() if not k.startswith("gm_T")]
            if all(math.isfinite(v) for v in vals):
                reps.append(_params_to_model(keep(p)))
    return hat, reps


def joint_band(fit, kept, f_hz, confidence: float) -> dict:
    r"""The simultaneous upper band :math:`U(f)` of the fit's PSD over the frequencies `f_hz` (module docstring),
    u^2/Hz, two-sided.

    Returns
    -------
    dict
        ``f_hz``, ``upper`` (U), ``estimate`` (:math:`S(f;\hat\theta)`), ``c_percentile`` (c),
        ``n_replicates``, ``confidence``. With fewer than 20 replicates ``upper`` is None (no band).
    """
    f = np.asarray(f_hz, dtype=np.float64)
    hat, reps = _replicate_models(fit, kept)
    s_hat = np.maximum(hat.psd(f), 1e-300)
    out = {"f_hz": f, "estimate": s_hat, "n_replicates": len(reps), "confidence": float(confidence),
           "upper": None, "c_percentile": None}
    if len(reps) < 20:
        return out
    d = np.log(np.maximum(np.stack([m.psd(f) for m in reps]), 1e-300)) - np.log(s_hat)[None, :]
    m, q_up = np.percentile(d, [50.0, 100.0 * UPPER_QUANTILE], axis=0)
    u = np.maximum(q_up - m, 1e-3)
    B = d.shape[0]
    k = min(B, int(math.ceil((B + 1) * float(confidence))))  # the order statistic of the quantile
    c = float(np.sort(np.max((d - m) / u, axis=1))[k - 1])
    out.update(upper=s_hat * np.exp(np.maximum(m + c * u, 0.0)), c_percentile=c)
    return out


def _basis(f, T_grid, flicker: bool):
    """Columns of the envelope's LP: unit white, random walk, flicker (optional), GM of unit sigma at each T."""
    from imupipe.models import NoiseModel

    cols = [NoiseModel(white=1.0).psd(f), NoiseModel(random_walk=1.0).psd(f)]
    names = ["white", "random_walk"]
    if flicker:
        cols.append(NoiseModel(flicker=1.0).psd(f))
        names.append("flicker")
    for T in T_grid:
        cols.append(NoiseModel(gauss_markov=((1.0, float(T)),)).psd(f))
        names.append(float(T))
    return np.stack(cols, axis=1), names


def joint_envelope(fit, kept, span_s: float, f_max_hz: float, confidence: float, f_min_hz: float | None = None,
                   random_walk_min: float = 0.0):
    r"""The joint upper envelope (module docstring) as a :class:`~imupipe.models.NoiseModel` (SI) and its record.

    Parameters
    ----------
    fit : imupipe.identify.AllanFit
        With its bootstrap (``bootstrap``, ``param_names``).
    kept : sequence of str or None
        Components kept by the selection (others are left out of every replicate model).
    span_s : float
        The window the filter must be right over (fix period + outage), s.
    f_max_hz : float
        Highest frequency of the band, Hz (half the records' or the filter's rate).
    confidence : float
        Family-wise level of the band over its frequencies.
    random_walk_min : float, optional
        Least random walk of the envelope, u/sqrt(s): below the band the envelope is its model's extrapolation,
        and a random walk the records cannot exclude rises there (the identification passes the marginal
        envelope's K, its upper limit at `confidence` capped by the Allan variances). Default 0.
    f_min_hz : float, optional
        Lowest frequency of the band, Hz; default 1/`span_s`: below it the records of a GM or random walk the data
        leave open say nothing the filter needs (the marginal envelope's statement too), and a band taken lower
        is set by the replicates' extrapolation of the random walk, far above anything the records show.

    Returns
    -------
    tuple (NoiseModel or None, dict)
        The envelope (None when the fit has fewer than 20 finite replicates) and a record: band ends (Hz),
        level, the two sup-statistic quantiles, replicates, and the envelope's worst and mean ratio to the band.
    """
    from scipy.optimize import linprog

    from imupipe.models import NoiseModel

    if isinstance(kept, dict):
        kept = kept.get("kept", [])
    f_lo = float(f_min_hz) if f_min_hz is not None else 1.0 / float(span_s)
    f_hi = float(f_max_hz)
    if not (0 < f_lo < f_hi):
        raise ValueError(f"joint_envelope: the band needs 0 < f_min_hz < f_max_hz, got [{f_lo}, {f_hi}] Hz")
    n = max(int(math.ceil(PER_DECADE * math.log10(f_hi / f_lo))), 2) + 1
    f = np.geomspace(f_lo, f_hi, n)
    band = joint_band(fit, kept, f, confidence)
    rec = {"band_hz": [f_lo, f_hi], "confidence": float(confidence), "per_decade": PER_DECADE, "pad": JOINT_PAD,
           "n_replicates": band["n_replicates"], "c_percentile": band["c_percentile"],
           "upper_quantile": UPPER_QUANTILE}
    if band["upper"] is None:
        rec["note"] = "fewer than 20 finite bootstrap replicates: no joint band"
        return None, rec
    U = band["upper"] * JOINT_PAD
    T_lo = 1.0 / (2.0 * math.pi * f_hi)
    T_hi = 10.0 / (2.0 * math.pi * f_lo)  # a GM of longer T acts as a random walk over the band
    T_grid = np.geomspace(T_lo, T_hi, max(int(math.ceil(T_PER_DECADE * math.log10(T_hi / T_lo))), 1) + 1)
    fl = kept is None or "flicker" in kept
    A, names = _basis(f, T_grid, fl)
    An = A / U[:, None]  # rows scaled by U: constraint An a >= 1, objective mean(An a)
    col = np.max(An, axis=0)
    An_s = An / col[None, :]  # columns scaled for the solver's conditioning
    bounds = [(0.0, None)] * A.shape[1]
    bounds[1] = (float(random_walk_min) ** 2 * col[1], None)  # the random walk's column (a = x / col)
    res = linprog(An_s.mean(axis=0), A_ub=-An_s, b_ub=-np.ones(n), bounds=bounds, method="highs")
    if res.status != 0:
        raise RuntimeError(f"joint_envelope: the envelope's linear programme failed: {res.message}")
    a = np.maximum(res.x, 0.0) / col
    # every grid frequency at least the pad, the LP's tolerance included (between them: the module docstring)
    ratio = (A @ a) / band["upper"]
    a = a * max(1.0, JOINT_PAD / float(ratio.min()))
    ratio = (A @ a) / band["upper"]
    gm = tuple((math.sqrt(v), T) for v, T in zip(a[len(names) - len(T_grid):], T_grid) if v > 0)
    model = NoiseModel(white=math.sqrt(a[0]), random_walk=math.sqrt(a[1]),
                       flicker=math.sqrt(a[2]) if fl else 0.0, gauss_markov=gm)
    rec.update(worst_ratio_to_band=float(ratio.min()), mean_ratio_to_band=float(ratio.mean()),
               n_gm_terms=len(gm))
    return model, rec
