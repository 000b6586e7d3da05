"""The paper's hand inflation (Gallon et al. 2021, section II.2.e) on the engine's constraints."""

from __future__ import annotations

import math
import time
import warnings

from imupipe.bound.report import (  # noqa: F401
    BoundResult,
)
from imupipe.bound.engine import (  # noqa: F401
    _EPS_BOUND,
    _prepare,
    _result,
    _spec_components,
)


def paper_inflation(
    frequency,
    curves,
    spec_model,
    dt: float | None = None,
    step: float = 1.05,
    order=("sigma", "T", "K", "N"),
    min_gain: float = 0.5,
    max_steps: int = 5000,
) -> BoundResult:
    r"""The paper's hand procedure: multiplicative inflation of the spec until the PSD bounds.

    Gallon et al. 2021 (Appendix A.2, Figure 8) inflate :math:`\sigma`, deflate :math:`T`, inflate
    :math:`K`, then inflate :math:`N`, each "until its part of the curve is bounded". Here each phase
    multiplies its parameter by `step` (divides, for T) while that keeps paying off: for
    :math:`\sigma, K, N` a step must raise the worst margin
    :math:`\min_{c,k} S_m/\hat S_c` (raw ordinates and spec) by at least `min_gain` of the step's
    power factor in log (i.e. the component carries about that share of the model where the bound
    fails); for :math:`T` any increase of the margin is accepted. Phases repeat in `order` until
    bounded; if a full round makes no progress the parameter with the largest gain is stepped
    (white noise always gains, so the procedure ends).

    Parameters
    ----------
    frequency, curves, spec_model, dt :
        As in :func:`bound_psd` (raw targets). The spec supplies the starting point; components
        it lacks (a zero N or K, no GM) stay absent.
    step : float, optional
        Multiplicative step (> 1). Default 1.05.
    order : sequence of str, optional
        Phase order. Default ("sigma", "T", "K", "N") (the paper's).
    min_gain : float, optional
        Required effectiveness of a step (see above). Default 0.5.
    max_steps : int, optional
        Safety limit. Default 5000.

    Returns
    -------
    BoundResult
        ``mode = "paper"``; ``details["history"]`` lists (parameter, N, sigma, T, K, margin) after
        every accepted step (for the inflation-steps figure).
    """
    from imupipe.models import NoiseModel

    if not step > 1:
        raise ValueError("step must be > 1")
    t0 = time.perf_counter()
    prob = _prepare(frequency, curves, spec_model, dt, "raw", 0.95, None, None, None, None)
    gm = sorted(spec_model.gauss_markov, key=lambda st: st[1])
    state = {
        "N": float(spec_model.white),
        "sigma": float(gm[0][0]) if gm else 0.0,
        "T": float(gm[0][1]) if gm else 0.0,
        "K": float(spec_model.random_walk),
    }
    extra_gm = tuple(gm[1:])

    def model_of(s):
        g = ((s["sigma"], s["T"]),) + extra_gm if s["sigma"] > 0 else extra_gm
        return NoiseModel(white=s["N"], gauss_markov=g, random_walk=s["K"], dt=dt)

    def worst(s):
        return prob.worst_margin(model_of(s))

    def moved(s, p):
        s2 = dict(s)
        s2[p] = s[p] / step if p == "T" else s[p] * step
        return s2

    active = [p for p in order if state[p] > 0]
    cur = worst(state)
    history = [("spec", state["N"], state["sigma"], state["T"], state["K"], cur)]
    n = 0
    log_pow = math.log(step**2)
    while cur < 1 - _EPS_BOUND and n < max_steps:
        progress = False
        for p in active:
            while cur < 1 - _EPS_BOUND and n < max_steps:
                cand = moved(state, p)
                m = worst(cand)
                gain = math.log(m / cur) / log_pow if m > 0 and cur > 0 else 0.0
                ok = m > cur * (1 + 1e-12) if p == "T" else gain >= min_gain
                if not ok:
                    break
                state, cur = cand, m
                n += 1
                progress = True
                history.append((p, state["N"], state["sigma"], state["T"], state["K"], cur))
        if not progress and cur < 1 - _EPS_BOUND:
            best_p, best_m = None, cur
            for p in active:
                if p == "T":
                    continue
                m = worst(moved(state, p))
                if m > best_m:
                    best_p, best_m = p, m
            if best_p is None:
                if "N" not in active:  # a spec without white noise: white is the last resort
                    state["N"] = max(state["N"], 1e-30)
                    active.append("N")
                    continue
                break
            state, cur = moved(state, best_p), best_m
            n += 1
            history.append((best_p, state["N"], state["sigma"], state["T"], state["K"], cur))
    result = _result(
        prob, model_of(state), spec_model, t0,
        mode="paper",
        components=_spec_components(spec_model),
        decisions={"procedure": f"multiplicative steps of {step:g} in the order {list(order)}"},
        n_lp=0,
        details={"history": [list(h) for h in history], "n_steps": n, "step": step, "order": list(order),
                 "history_columns": ["parameter", "N", "sigma", "T", "K", "margin"]},
    )
    if not result.bounded:
        warnings.warn(f"paper_inflation stopped after {n} steps without a bound (margin {cur:.3g})",
                      RuntimeWarning, stacklevel=2)
    return result
