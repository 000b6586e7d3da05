r"""The bias a filter starts with: slow biases the records cannot resolve, and the exported initial variance.

A static record of length :math:`T_r`, its mean removed, cannot tell a random walk of intensity :math:`K` from a
first-order Gauss-Markov (GM) bias with a time constant beyond the record: over lags :math:`\tau \ll T` the GM's
increments have the variance :math:`2\sigma^2(1 - e^{-\tau/T}) \approx (2\sigma^2/T)\,\tau`, a random walk with

.. math::

    K_{\mathrm{eff}}^2 = 2\sigma^2 / T .

The records fix :math:`K_{\mathrm{eff}}` (the in-band drift); :math:`\sigma` is free. The data allow the whole
family :math:`\{(\sigma, T): \sigma^2 = K_{\mathrm{eff}}^2 T / 2,\ T_r \le T \le T_{\max}\}`, and every member has a
stationary variance :math:`\sigma^2` that a sensor's bias has at turn-on, which the mean-removed records never
show. A filter that starts its bias states below that variance under-states its error in the first minutes of an
outage even when its PSD bounds every record (the PSD bound says nothing about the initial state).

Two consequences (docs/method.md, section "The bias a filter starts with"):

* **The family's worst member is a truth of the verification.** For a fixed filter the error is a linear
  functional of the truth, so its mean square is :math:`\int |H_t(f)|^2 S(f)\,df`, increasing in the truth's PSD.
  The GM PSD :math:`2\sigma^2 T/(1 + (2\pi f T)^2) = K_{\mathrm{eff}}^2 T^2/(1 + (2\pi f T)^2)` increases with
  :math:`T` at every frequency, so the member with :math:`T = T_{\max}` is the worst one. The verification runs it,
  started at its stationary distribution (:func:`worst_member`).
* **The exported initial variance covers it.** The filter's bias states (its GM states and the random-walk
  state ``p``) start with a total variance at least the largest of: the spec sheet's stationary bias variance (its
  GM :math:`\sigma^2`, a random walk as the GM of :math:`T_{\max}` with the same drift, and the sheet's turn-on
  bias squared) and the family's worst member (the identified envelope's slow drift; the bound's when there is no
  envelope) plus the envelope's resolved GMs' :math:`\sigma^2`. The GM states keep their
  own :math:`\sigma^2`; the deficit goes on ``p`` (a random constant when :math:`K = 0`), which over an application
  horizon far below :math:`T_{\max}` is what a slow bias is (:func:`bias_initialisation`).
* **A flicker starts stationary too.** The verification gives a truth's flicker :math:`B` as a bank of GM states
  over the band :math:`[f_{lo}, f_{hi}]` (:func:`flicker_bank`: :math:`T_k = 1/(2\pi f_k)`, two per decade,
  :math:`\sigma_k^2 = B^2\Delta/\pi`), each started at its :math:`\sigma_k^2`: a total
  :math:`\sum_k\sigma_k^2 \approx (B^2/\pi)(\ln(f_{hi}/f_{lo}) + \Delta)` at turn-on. A filter on a bound without a
  flicker (its PSD covers the flicker with white noise, a GM and a random walk, none of which starts with that
  variance) must start its bias states that much higher, or its error in the first seconds of the fix phase exceeds
  its P while its PSD bounds the truth's (measured: one ADIS16405 record, an envelope with B = 7.6e-3 m/s^2 and no
  GM, MSE/P 1.004 at 1-7 s; the flicker's 3.0e-4 (m/s^2)^2 on top of the required variance brings it to 1). So the
  spec sheet's and the records' parts count their flicker's bank variance when the band is given.
* **A slow bias sits in a slow state.** The part of that variance from biases slower than the verified run (fixes
  + outage, :math:`W`: the slow family, a random walk, GMs with :math:`T \ge W`, the turn-on bias) cannot be
  carried by a filter GM state of :math:`T < W`: the filter lets such a state's estimate decay within the run
  while the true bias stays, and the error it then makes is not in its P (measured: the default run's accelerometer,
  a filter GM of 168 s holding 70 % of the initial variance, under-stated the envelope truth by 7 % at the outage's
  end). That part goes on ``p`` or on filter GM states at least as slow (:func:`filter_p0`).

:math:`T_{\max}`: ``identify.max_bias_time_s`` when the config gives it; else the spec sheet's longest GM time
constant when that is at least the longest record (the sheet admits a bias that slow); else ten times the longest
record (a stated assumption: the records cannot bound it). Whichever it is, the initial variance rests on
something the records cannot check, and the summary says what.

Units: rates in the sensor's SI unit u (rad/s, m/s^2); K in u/sqrt(s); sigma in u; times in s; variances in u^2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["SlowBiasFamily", "BiasInitialisation", "max_bias_time", "slow_bias_family", "worst_member",
           "stationary_bias_variance", "bias_initialisation", "filter_p0", "flicker_bank", "flicker_variance",
           "RECORD_FACTOR"]

#: T_max is this many times the longest record when neither the config nor the spec sheet gives a longer one.
RECORD_FACTOR = 10.0


def max_bias_time(spec_model=None, record_s: float | None = None, configured_s: float | None = None,
                  run_s: float | None = None):
    """The longest bias time constant the verification admits, s, and where it comes from.

    Returns
    -------
    (float, str)
        ``configured_s`` ("config: identify.max_bias_time_s"); else the spec sheet's longest GM T when it is at
        least `record_s` ("spec sheet: longest GM time constant"); else ``RECORD_FACTOR * record_s``
        ("assumption: 10 x the longest record"); with no records, the spec's GM T or ``RECORD_FACTOR * run_s``
        (the verified run, fixes and outage). Raises ValueError when none can be formed.
    """
    if configured_s is not None:
        v = float(configured_s)
        if not (math.isfinite(v) and v > 0):
            raise ValueError(f"identify.max_bias_time_s must be a positive time in s, got {configured_s!r}")
        return v, "config: identify.max_bias_time_s"
    t_spec = max((T for s, T in getattr(spec_model, "gauss_markov", ()) if s > 0), default=0.0)
    if record_s is None or not record_s > 0:
        if t_spec > 0:
            return float(t_spec), "spec sheet: longest GM time constant"
        if run_s:
            return RECORD_FACTOR * float(run_s), f"assumption: {RECORD_FACTOR:g} x the verified run (no records)"
        raise ValueError("the longest bias time constant needs identify.max_bias_time_s, a spec-sheet GM or the "
                         "records' length")
    if t_spec >= record_s:
        return float(t_spec), "spec sheet: longest GM time constant"
    return RECORD_FACTOR * float(record_s), f"assumption: {RECORD_FACTOR:g} x the longest record"


@dataclass(frozen=True)
class SlowBiasFamily:
    r"""The GM biases a set of records cannot tell apart: :math:`\sigma^2 = K_{\mathrm{eff}}^2 T/2`,
    :math:`T` in [`T_min_s`, `T_max_s`] (module docstring)."""

    k_eff: float  #: in-band drift, u/sqrt(s)
    T_min_s: float  #: the longest record, s (a slower bias is not resolved)
    T_max_s: float  #: the longest T admitted, s
    T_max_source: str  #: where T_max comes from
    components: tuple = ()  #: which model components it stands for (e.g. "random walk K", "GM T=5e5 s")

    def sigma(self, T: float) -> float:
        """Stationary standard deviation of the member of time constant `T` s, u."""
        return self.k_eff * math.sqrt(0.5 * T)

    @property
    def worst(self) -> tuple:
        """(sigma, T) of the worst member (T = T_max)."""
        return self.sigma(self.T_max_s), self.T_max_s

    def to_dict(self, unit: str = "u") -> dict:
        s_lo, s_hi = self.sigma(self.T_min_s), self.sigma(self.T_max_s)
        return {"k_eff": float(self.k_eff), "T_range_s": [float(self.T_min_s), float(self.T_max_s)],
                "sigma_range": [float(s_lo), float(s_hi)], "worst_member": {"sigma": float(s_hi),
                                                                            "T": float(self.T_max_s)},
                "T_max_source": self.T_max_source, "stands_for": list(self.components),
                "units": {"k_eff": f"{unit}/sqrt(s)", "sigma": unit, "T": "s"},
                "rule": "sigma^2 = k_eff^2 * T / 2: the records fix the drift 2 sigma^2 / T, not sigma"}


def _slow_drift(model, record_s: float):
    """K_eff^2 (u^2/s) of `model`'s random walk and of its GM terms with T >= `record_s`, and their names."""
    k2 = model.random_walk**2
    names = [f"random walk K={model.random_walk:.4g}"] if model.random_walk > 0 else []
    for s, T in model.gauss_markov:
        if s > 0 and T >= record_s:
            k2 += 2.0 * s * s / T
            names.append(f"GM sigma={s:.4g} T={T:.4g} s")
    return k2, names


def slow_bias_family(models, record_s: float, T_max_s: float, T_max_source: str) -> SlowBiasFamily | None:
    """The family of the slowest components of `models` (the bound's model, the identified upper envelope, ...).

    K_eff is the largest over the models of sqrt(K^2 + sum over GM terms with T >= record_s of 2 sigma^2/T).
    None when no model has such a component (the records resolve every bias). `T_max_s` below `record_s` is
    raised to `record_s` (the family then has one member).
    """
    best, names = 0.0, ()
    for m in models:
        if m is None:
            continue
        k2, nm = _slow_drift(m, record_s)
        if k2 > best:
            best, names = k2, tuple(nm)
    if best <= 0:
        return None
    return SlowBiasFamily(math.sqrt(best), float(record_s), max(float(T_max_s), float(record_s)), T_max_source,
                          names)


def worst_member(model, family: SlowBiasFamily | None):
    """`model` with its random walk and its GM terms slower than the records replaced by the family's worst
    member, a GM (sigma_max, T_max) (a truth for the verification, started stationary). `model` unchanged when
    `family` is None."""
    from imupipe.models import NoiseModel

    if family is None:
        return model
    fast = tuple((s, T) for s, T in model.gauss_markov if s > 0 and T < family.T_min_s)
    return NoiseModel(white=model.white, gauss_markov=fast + (family.worst,), random_walk=0.0,
                      flicker=getattr(model, "flicker", 0.0), narrowband=getattr(model, "narrowband", ()))


def flicker_bank(B: float, f_lo: float, f_hi: float, per_decade: int = 2) -> tuple:
    r"""GM terms ((sigma u, T s), ...) approximating a flicker PSD :math:`B^2/(2\pi f)` (two-sided, u^2/Hz) on
    [f_lo, f_hi] Hz: corners :math:`f_k` on a log grid of `per_decade` per decade (at least 2 terms), spacing
    :math:`\Delta = \ln(f_{k+1}/f_k)`, :math:`T_k = 1/(2\pi f_k)`, :math:`\sigma_k^2 = B^2\Delta/\pi`; then
    :math:`\sum_k 2\sigma_k^2 T_k/(1 + (f/f_k)^2) \approx B^2/(2\pi f)` inside the band (the sum approximates
    :math:`\int u/(1+u^2)\, d\ln u = \pi/2`). How the verification and the exported filter carry a flicker."""
    if not B > 0:
        return ()
    n = max(2, int(math.ceil(math.log10(f_hi / f_lo) * per_decade)) + 1)
    r = (f_hi / f_lo) ** (1.0 / (n - 1))
    s2 = B * B * math.log(r) / math.pi
    return tuple((math.sqrt(s2), 1.0 / (2 * math.pi * f_lo * r**k)) for k in range(n))


def flicker_variance(model, band_hz, slower_than_s: float = 0.0) -> float:
    r"""Turn-on variance of `model`'s flicker as :func:`flicker_bank` over `band_hz` = (f_lo, f_hi) Hz gives it,
    :math:`\sum_k\sigma_k^2` over the terms with :math:`T_k \ge` `slower_than_s` (s; default all), u^2; 0 without a
    flicker or a band."""
    B = float(getattr(model, "flicker", 0.0) or 0.0)
    if band_hz is None or not B > 0:
        return 0.0
    return float(sum(s * s for s, T in flicker_bank(B, float(band_hz[0]), float(band_hz[1])) if T >= slower_than_s))


def stationary_bias_variance(model, T_max_s: float, turn_on_bias: float = 0.0, flicker_band_hz=None) -> float:
    r"""Total initial variance of the bias a sensor described by `model` has at turn-on, u^2:
    :math:`\sum\sigma_i^2 + K^2 T_{\max}/2 + b_{on}^2 + \sum_k\sigma_{B,k}^2` (a random walk counted as the GM of
    :math:`T_{\max}` with its drift; `turn_on_bias` the sheet's turn-on bias or bias repeatability, 1 sigma, u; the
    flicker's bank over `flicker_band_hz` (Hz), :func:`flicker_variance`, when that is given). Narrowband terms are
    not counted (they are states of their own in the filter)."""
    v = sum(s * s for s, _ in model.gauss_markov) + model.random_walk**2 * 0.5 * T_max_s
    return float(v + turn_on_bias**2 + flicker_variance(model, flicker_band_hz))


@dataclass(frozen=True)
class BiasInitialisation:
    """The least total initial variance of a filter's bias states, u^2, and what it rests on."""

    required: float  #: least total initial variance of the bias states (GM states + p), u^2
    parts: dict  #: source -> its stationary bias variance, u^2
    rests_on: str  #: the part that sets `required`
    T_max_s: float  #: longest bias time constant admitted, s
    T_max_source: str  #: where it comes from
    record_s: float | None  #: the longest record, s
    family: SlowBiasFamily | None = None
    required_slow: float = 0.0  #: the part of it from biases slower than the verified run, u^2
    window_s: float | None = None  #: the verified run (fixes + outage), s: "slower" means T >= this

    def p0(self, model, wander_s: float | None = None) -> float:
        """Initial variance of the filter's ``p`` state for `model`, u^2 (:func:`filter_p0`; `wander_s` default
        the verified run)."""
        w = self.window_s if wander_s is None else wander_s
        if w is None:
            raise ValueError("BiasInitialisation.p0 needs wander_s (no verified run given)")
        return filter_p0(model, self.required, w, self.required_slow)

    def statement(self, unit: str = "u") -> str:
        """One line for a summary: the value, what it rests on, and whether the records can check it."""
        checked = self.record_s is not None and self.T_max_s <= self.record_s
        what = {"spec sheet": "the spec sheet's stationary bias (GM sigma^2, K^2 T_max/2, turn-on bias^2)",
                "records": "the records' slow drift extrapolated to the longest admitted time constant",
                "model": "the exported model's own GM states"}.get(self.rests_on, self.rests_on)
        if checked:
            tail = (f"T_max = {self.T_max_s:.4g} s ({self.T_max_source}) is within the longest record "
                    f"({self.record_s:.4g} s), which checks it (the drift taken over that record)")
        elif self.record_s:
            tail = (f"T_max = {self.T_max_s:.4g} s ({self.T_max_source}) is beyond what the records "
                    f"({self.record_s:.4g} s) can check")
        else:
            tail = f"T_max = {self.T_max_s:.4g} s ({self.T_max_source}), not checked by records"
        return (f"initial bias variance >= {self.required:.3g} ({unit})^2 (std {math.sqrt(self.required):.3g} "
                f"{unit}): rests on {what}; {tail}")

    def to_dict(self, unit: str = "u") -> dict:
        return {"required_variance": float(self.required), "required_std": math.sqrt(self.required),
                "parts": {k: float(v) for k, v in self.parts.items()}, "rests_on": self.rests_on,
                "T_max_s": float(self.T_max_s), "T_max_source": self.T_max_source,
                "record_s": None if self.record_s is None else float(self.record_s),
                "checked_by_records": bool(self.record_s is not None and self.T_max_s <= self.record_s),
                "slow_bias_family": None if self.family is None else self.family.to_dict(unit),
                "required_slow_variance": float(self.required_slow),
                "window_s": None if self.window_s is None else float(self.window_s),
                "units": {"required_variance": f"({unit})^2", "required_std": unit, "T_max_s": "s",
                          "required_slow_variance": f"({unit})^2", "window_s": "s"},
                "rule": "sum of the bias states' P0 (GM sigma^2 + p0) >= required_variance, and the states at least "
                        "as slow as the verified run (p, GMs with T >= window_s) >= required_slow_variance; GM "
                        "states keep sigma^2, p0 = max(K^2 * wander_s, required - sum GM sigma^2, "
                        "required_slow - sum of GM sigma^2 with T >= wander_s)"}


def bias_initialisation(filter_model, *, spec=None, upper=None, turn_on_bias: float = 0.0,
                        record_s: float | None = None, max_bias_time_s: float | None = None,
                        run_s: float | None = None, flicker_band_hz=None) -> BiasInitialisation:
    """The least initial bias variance of a filter built on `filter_model` (module docstring).

    Parameters
    ----------
    filter_model, spec, upper : imupipe.models.NoiseModel or None
        The exported model, the spec sheet's, the identified upper envelope (SI).
    turn_on_bias : float
        The spec sheet's turn-on bias (bias repeatability), 1 sigma, u; 0 when the sheet gives none.
    record_s : float or None
        The longest record, s (the slowest bias it resolves).
    max_bias_time_s : float or None
        ``identify.max_bias_time_s``; None: :func:`max_bias_time`'s default.
    run_s : float or None
        The verified run (fixes + outage), s: the fallback of :func:`max_bias_time` without records.
    flicker_band_hz : (float, float) or None
        The band (Hz) over which a truth's flicker is a GM bank (:func:`flicker_bank`; the verification's
        ``f_floor_hz`` to half the filter rate): the spec sheet's and the envelope's flicker then count their bank's
        turn-on variance (module docstring). None: flicker not counted.
    """
    T_max, src = max_bias_time(spec, record_s, max_bias_time_s, run_s)
    # the family is the identified envelope's slow drift (the bound's own K is larger: it also pays for the
    # envelope's faster terms at low frequency, which the worst member keeps beside it); the bound's without one
    family = slow_bias_family([upper if upper is not None else filter_model], record_s, T_max, src) \
        if record_s else None
    parts = {"model": float(sum(s * s for s, _ in filter_model.gauss_markov))}
    if spec is not None:
        parts["spec sheet"] = stationary_bias_variance(spec, T_max, turn_on_bias, flicker_band_hz)
    elif turn_on_bias:
        parts["spec sheet"] = float(turn_on_bias**2)
    rec = rec_slow = 0.0
    W = float(run_s) if run_s else math.inf  # without a verified run nothing counts as slower than it
    if family is not None:
        rec += family.worst[0] ** 2
        rec_slow += family.worst[0] ** 2
    base = upper if upper is not None else filter_model
    for s, T in base.gauss_markov:
        if s > 0 and (record_s is None or T < record_s):
            rec += s * s
            rec_slow += s * s if T >= W else 0.0
    rec += flicker_variance(base, flicker_band_hz)
    rec_slow += flicker_variance(base, flicker_band_hz, W)
    if family is not None or upper is not None:
        parts["records"] = float(rec)
    slow = [rec_slow]
    if spec is not None:
        slow.append(sum(s * s for s, T in spec.gauss_markov if T >= W) + spec.random_walk**2 * 0.5 * T_max
                    + turn_on_bias**2 + flicker_variance(spec, flicker_band_hz, W))
    elif turn_on_bias:
        slow.append(turn_on_bias**2)
    rests_on = max(parts, key=parts.get)
    return BiasInitialisation(float(parts[rests_on]), parts, rests_on, T_max, src, record_s, family,
                              required_slow=float(max(slow)), window_s=None if run_s is None else float(run_s))


def filter_p0(model, required: float, wander_s: float, required_slow: float = 0.0) -> float:
    r"""Initial variance of the random-walk state ``p`` of a filter on `model`, u^2:

    .. math::

        \max\Big(K^2 t_w,\; V - \sum_i \sigma_i^2,\; V_s - \sum_{T_i \ge t_w} \sigma_i^2\Big)

    with :math:`V` = `required`, :math:`V_s` = `required_slow` (the part from biases slower than the run, which only
    states at least as slow may carry: module docstring) and :math:`t_w` = `wander_s` (the verified run, fixes +
    outage: the time the random walk has wandered before the filter starts, and the "slow" threshold). Positive
    with :math:`K = 0`: ``p`` is then a random constant the filter must carry
    (:func:`imupipe.kf.continuous_model` with ``reduced=False``)."""
    gm = [(s, T) for s, T in model.gauss_markov if s > 0]
    deficit = float(required) - sum(s * s for s, _ in gm)
    slow_deficit = float(required_slow) - sum(s * s for s, T in gm if T >= wander_s)
    return float(max(model.random_walk**2 * float(wander_s), deficit, slow_deficit, 0.0))
