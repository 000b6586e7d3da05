r"""How long, and how many records: the expected interval half-widths of N, B and K for a recording plan.

A plan is `records` static records of `hours` each at `record_rate_hz`, each with `axes` axes pooled (a 3-axis
IMU pools three curves per record when the pooling test accepts it). For a noise model (a spec sheet's, or the
identified model of a pilot run) the plan predicts the half-width (upper - lower) / 2 of the identification's
interval (:func:`imupipe.identify.fit_allan`, at the workflow's `confidence` 0.95) of

- N, the white noise (``white``, u/sqrt(Hz));
- B, the Gauss-Markov sigma (``gm_sigma_1``, u; "bias instability" on a spec sheet);
- K, the random walk (``random_walk``, u/sqrt(s)),

in SI and relative to the model's own value.

Derivation. The overlapping Allan-variance estimate at :math:`\tau_k = m_k/f_s` of one record of n samples is,
to second order, :math:`\hat\sigma^2_k \approx \sigma^2_k\,\chi^2_{\nu_k}/\nu_k` with the equivalent degrees of
freedom :math:`\nu_k` of Greenhall & Riley (2003) (:func:`imupipe.allan.edf_greenhall`, the noise type alpha at
each tau the model's own local slope :math:`\mu_k = d\ln\sigma^2/d\ln\tau`, :math:`\alpha = -1 - \mu` rounded and
clipped to the rate-data types -2..0), so its relative standard deviation is :math:`\sqrt{2/\nu_k}`; neighbouring
estimates are correlated by the exact covariance of :func:`imupipe.avcov.avar_covariance`. For a white noise alone,
:math:`\nu_1 \propto n` and :math:`\hat N^2` is a weighted mean of :math:`\tau_k\hat\sigma^2_k`, so the half-width
of N is :math:`z_{(1+c)/2}\,N/\sqrt{2\nu_{eff}}` with :math:`\nu_1 \le \nu_{eff} \le n` (the largest single-tau
edf; the Cramer-Rao limit of n white samples), hence proportional to
:math:`1/\sqrt{\mathrm{hours}\times\mathrm{records}\times\mathrm{axes}}`. With a GM term and a random walk the
parameters trade off along the fit's ridge and no closed form holds; the interval machinery that handles that
(the correlated parametric bootstrap, the profile limits of N, sigma, T and K, one-sided intervals where a
coefficient sits at 0) is the identification's own. So the plan evaluates it on the *expected* data: every
curve of the plan set to the model's Allan variance :math:`E[\hat\sigma^2_k] = \sigma^2_k` (exact for the
overlapping estimator) with its :math:`\nu_k` as weights, the bootstrap drawing replicates from the exact
covariance of `records` x `axes` independent curves of n samples. The interval of that fit is the median interval
of a record to first order (the interval's ends are smooth functions of the AV curve, and the AV estimates'
median is close to their mean for :math:`\nu_k \gg 1`). That holds where every interval is two-sided. Where the GM
and the random walk trade off (the expected-data fit labels an interval confounded or one-sided), the
half-width jumps between regimes from record to record (the fitted T on an end of the search or not, K fitted 0
or not) and the expected data sit in one of them; there the plan takes the median half-width over replicate
curve sets drawn from the AV's sampling distribution (chi-squared marginals with the exact covariance, the
generator of the fit's own bootstrap), each fitted like a record. benchmarks/plan_check.py checks both against
the median over simulated records; docs/performance.md gives the result.

The fit allows the components the model has (N, GM, K, flicker, quantization where non-zero; a pilot's spectral
lines and ramp are left out of the plan), one GM term, and runs no component selection: the plan answers how
well the records pin down the model's parameters, not which ones the application keeps (that depends on the
filter, :func:`imupipe.identify.select_components`).

References: W. J. Riley, NIST SP 1065 (2008), section 5.2; C. A. Greenhall and W. J. Riley, "Uncertainty of
stability variances based on finite differences", Proc. 35th PTTI (2003).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import replace

__all__ = ["PARAMS", "param_name", "expected_allan", "fit_components", "identify_intervals", "half_widths", "predict",
           "plan_table", "auto_prediction", "parse_target", "shortest_plan", "load_model", "format_table", "add_subcommand"]

#: Plan parameter -> fit_allan parameter name and the unit key of a spec sheet (imupipe.specsheet.display_units).
#: B is the GM sigma; for a model with a flicker and no GM (a sheet that states its bias instability as a flicker
#: floor) it is the flicker coefficient, same unit (:func:`param_name`).
PARAMS = {"N": ("white", "white"), "B": ("gm_sigma_1", "gm_sigma"), "K": ("random_walk", "random_walk")}


def param_name(p: str, model=None) -> str:
    """The fit parameter plan parameter `p` (N, B, K) stands for with `model`: :data:`PARAMS`, except B of a model
    with a flicker and no GM term, which is ``flicker``."""
    if p == "B" and model is not None and not model.gauss_markov and getattr(model, "flicker", 0.0) > 0:
        return "flicker"
    return PARAMS[p][0]

#: The workflow's identification settings (imupipe.defaults: identify.n_boot, identify.confidence,
#: identify.n_gm) and the fit's bootstrap seed (imupipe.stages.identify.SEED_FIT).
N_BOOT, CONFIDENCE, N_GM, SEED = 100, 0.95, 1, 20211


def _check_positive(value, flag, integer=False):
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{flag}: expected a positive number, got {value!r}") from None
    if not (math.isfinite(v) and v > 0) or (integer and v != int(v)):
        kind = "a positive integer" if integer else "a positive finite number"
        raise ValueError(f"{flag}: expected {kind}, got {value!r}")
    return int(v) if integer else v


def expected_allan(model, hours: float, record_rate_hz: float, taus="octave"):
    r"""The expected Allan variance of one record of `hours` h at `record_rate_hz` Hz under `model` (SI).

    Returns ``(tau, avar, edf, n_samples)``: tau (s) on the workflow's grid (:func:`imupipe.allan.tau_grid`,
    `taus`), :math:`\sigma^2(\tau)` of the model (u^2, :meth:`imupipe.models.NoiseModel.avar`), the Greenhall-Riley
    edf at the model's noise type :math:`\alpha = \mathrm{clip}(\mathrm{round}(-1 - d\ln\sigma^2/d\ln\tau), -2, 0)`
    (:func:`imupipe.allan.edf_greenhall`, d = 2, overlapping) and the record length in samples."""
    import numpy as np

    from imupipe.allan import edf_greenhall, tau_grid

    hours = _check_positive(hours, "--hours")
    rate = _check_positive(record_rate_hz, "--rate-hz")
    n = int(round(hours * 3600.0 * rate))
    grid = tau_grid(n, rate, taus)
    tau = grid.tau
    avar = np.asarray(model.avar(tau), dtype=np.float64)
    if not (np.isfinite(avar).all() and (avar > 0).all()):
        raise ValueError("the model's Allan variance is not positive at every tau: a model with no noise component")
    if tau.size >= 2:
        mu = np.gradient(np.log(avar), np.log(tau))
    else:
        mu = np.full(1, -1.0)
    alpha = np.clip(np.rint(-1.0 - mu), -2, 0).astype(int)
    edf = np.array([float(edf_greenhall(int(a), 2, int(m), n + 1)) for a, m in zip(alpha, grid.m)])
    return tau, avar, edf, n


def fit_components(model) -> tuple:
    """The components the identification of a plan allows: those `model` has (``white``, ``gauss_markov``,
    ``flicker``, ``random_walk``, ``quantization``), as :func:`imupipe.identify.fit_allan` names them."""
    comps = [c for c, on in (("white", model.white > 0), ("quantization", model.quantization > 0),
                             ("gauss_markov", bool(model.gauss_markov)), ("flicker", model.flicker > 0),
                             ("random_walk", model.random_walk > 0)) if on]
    if not comps:
        raise ValueError("the model has none of white, gauss_markov, flicker, random_walk, quantization")
    return tuple(comps)


def identify_intervals(curves, n_samples: int, record_rate_hz: float, components, *, n_boot: int = N_BOOT,
                       confidence: float = CONFIDENCE, seed=SEED):
    """The identification's fit (:func:`imupipe.identify.fit_allan`, the workflow's settings: one GM term,
    correlated bootstrap of `n_boot` replicates, intervals at `confidence`) of `curves`, a list of
    ``(tau, avar, edf)`` (s, u^2, 1) of records of `n_samples` at `record_rate_hz` Hz; the same call for the
    plan's expected curves and for a simulated record."""
    from imupipe.identify import fit_allan

    k = len(curves)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fit_allan([c[0] for c in curves], [c[1] for c in curves], [c[2] for c in curves],
                         components=tuple(components), n_gm=N_GM if "gauss_markov" in components else 0,
                         n_boot=int(n_boot), confidence=float(confidence), rng=seed, dt=1.0 / record_rate_hz,
                         record_rate_hz=[float(record_rate_hz)] * k, n_samples=[int(n_samples)] * k)


def half_widths(fit, model=None) -> dict:
    """``{"N" | "B" | "K": (upper - lower) / 2}`` of `fit`'s intervals (SI; inf where the upper end is unbounded,
    NaN where the fit has no interval of that parameter, e.g. B without a GM term or flicker; B of `model` by
    :func:`param_name`)."""
    import numpy as np

    out = {}
    for p in PARAMS:
        lo, hi = fit.intervals.get(param_name(p, model), (np.nan, np.nan))
        out[p] = float((hi - lo) / 2.0) if np.isfinite(lo) and not np.isnan(hi) else float("nan")
    return out


def _truth_values(model) -> dict:
    b = model.gauss_markov[0][0] if model.gauss_markov else (model.flicker if model.flicker > 0 else float("nan"))
    return {"N": float(model.white), "B": float(b), "K": float(model.random_walk)}


def predict(model, hours: float, records: int, record_rate_hz: float, axes: int = 1, *, replicates: int = 0,
            n_boot: int = N_BOOT, confidence: float = CONFIDENCE, seed=SEED, sensor: str | None = None) -> dict:
    """The predicted half-widths of one plan (module docstring): ``{"hours", "records", "axes",
    "record_rate_hz", "half_width": {N, B, K} (SI), "relative": {N, B, K} (half-width / the model's value; NaN
    where the model has no such term), "interval_kind": {N, B, K} (the expected-data fit's label), "confounded":
    {N, B, K} (bool: one-sided or confounded interval on the expected data), "method"}``.

    `replicates` > 0: where the expected-data fit finds an interval one-sided or confounded, the half-widths are
    instead the median over `replicates` draws of the plan's curves from their sampling distribution (each curve
    :func:`imupipe.avcov.correlated_replicates`: chi-squared marginals, the exact covariance of
    :func:`imupipe.avcov.avar_covariance`), each fitted like a record (`replicates` fits more).

    `sensor` ("gyro" or "accel"): the row also gets ``auto``, :func:`auto_prediction` (the auto bound's expected
    effective inflation and conservatism, from the run's identification of the expected data)."""
    import numpy as np

    records = _check_positive(records, "--records", integer=True)
    axes = _check_positive(axes, "--axes", integer=True)
    # spectral lines and a ramp are no part of the plan's fit (lines are modelled by the bound, a ramp is no noise)
    model = replace(model, narrowband=(), ramp=0.0)
    replicates = int(replicates)
    if replicates < 0:
        raise ValueError(f"--replicates: expected 0 or a positive integer, got {replicates}")
    tau, avar, edf, n = expected_allan(model, hours, record_rate_hz)
    comps = fit_components(model)
    k = records * axes
    fit = identify_intervals([(tau, avar, edf)] * k, n, record_rate_hz, comps, n_boot=n_boot,
                             confidence=confidence, seed=seed)
    hw, truth = half_widths(fit, model), _truth_values(model)
    kind = {p: fit.interval_kind.get(param_name(p, model), "none") for p in PARAMS}
    confounded = {p: _confounded(fit, param_name(p, model)) for p in PARAMS}
    method = "expected Allan variance"
    if replicates and any(confounded.values()):
        from imupipe.avcov import avar_covariance, correlated_replicates

        m = np.rint(tau * record_rate_hz).astype(np.int64)
        cov = avar_covariance(model, m, n, record_rate_hz)
        rng = np.random.default_rng(seed)
        draws = []
        for _ in range(replicates):
            ys = correlated_replicates(avar, cov, k, rng)  # k independent curves, each with the exact covariance
            f = identify_intervals([(tau, y, edf) for y in ys], n, record_rate_hz, comps, n_boot=n_boot,
                                   confidence=confidence, seed=seed)
            draws.append([half_widths(f, model)[p] for p in PARAMS])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN column: the model has no such term
            med = np.nanmedian(np.array(draws, dtype=float), axis=0)
        hw = {p: float(v) for p, v in zip(PARAMS, med)}
        method = f"median over {replicates} replicate Allan-variance curve sets"
    rel = {p: (hw[p] / truth[p] if truth[p] > 0 else float("nan")) for p in hw}
    out = {"hours": float(hours), "records": records, "axes": axes, "record_rate_hz": float(record_rate_hz),
           "half_width": hw, "relative": rel, "interval_kind": kind, "confounded": confounded, "method": method,
           "B_is": param_name("B", model)}
    if sensor is not None:
        out["auto"] = auto_prediction(model, hours, records, axes, record_rate_hz, sensor, confidence=confidence,
                                      n_boot=n_boot, seed=seed)
    return out


def auto_prediction(model, hours: float, records: int, axes: int, record_rate_hz: float, sensor: str, *,
                    confidence: float = CONFIDENCE, n_boot: int = N_BOOT, seed=SEED) -> dict:
    r"""The expected effective inflation and conservatism of the auto bound for the plan of `records` records of
    `hours` h at `record_rate_hz` Hz with `axes` axes each, from the run's own identification of the expected data.

    The auto bound under ``identify.envelope: joint`` (what ``imupipe init`` writes) lies on or above the upper
    envelope its identification builds (it must pass the check against it; in docs/performance.md its candidates'
    mean P/MSE against the envelope are 1.0-1.4 where the envelope sets the level), and the envelope is what the
    records' statistics move. So the plan runs the workflow's identification,
    :func:`imupipe.stages.identify.identify_sensor` with the workflow's ``identify`` defaults
    (:data:`imupipe.defaults.DEFAULTS`: every component it tries, the selection for the reference filter, the GM
    time constants the records resolve and a GM beyond them re-assigned to what it acts as) and the joint envelope,
    on the plan's expected curves (every curve the model's Allan variance, :func:`expected_allan`), and evaluates
    its envelope over the reference scenario (:func:`imupipe.verify.reference_scenario`):

    - ``inflation``: the median over [1/outage, filter_rate/2] (100 frequencies per decade) of
      :math:`\sqrt{S_{env}(f)/S_{model}(f)}` (the in-band effective inflation of the summary, against the model);
    - ``conservatism``: the mean P/MSE over the outage of the reference filter built on the envelope with the model
      as the truth (:func:`imupipe.verify.covariance_analysis`): the auto bound's conservatism to first order (the
      exported model is at or above its run's envelope, which scatters about this one from record to record);
    - ``worst``: that filter's worst MSE/P (<= 1 when the envelope dominates the model).

    An earlier version built the envelope from the plan's own fit of the model's terms: a GM beyond the records' T
    range then traded off with the random walk, and the envelope's K upper limit made the column 23x the run's
    (an outside evaluation: 52.3 against 2.27 for 2 records of 4 h). Returns ``{"inflation", "conservatism",
    "worst", "c_percentile"}`` (NaN without a joint envelope)."""
    import numpy as np

    from imupipe.defaults import DEFAULTS as D
    from imupipe.stages.identify import identify_sensor
    from imupipe.verify import covariance_analysis, reference_scenario

    sc = reference_scenario(sensor)
    m = replace(model, narrowband=(), ramp=0.0)
    tau, avar, edf, n = expected_allan(m, hours, record_rate_hz)
    names = list("xyz"[: int(axes)]) if int(axes) <= 3 else [f"a{j + 1}" for j in range(int(axes))]
    curves = [(f"r{i + 1}/{a}", tau, avar, edf, n, float(record_rate_hz), a) for i in range(int(records))
              for a in names]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ident = identify_sensor(curves, sensor=sensor, components=D["identify.components"], n_gm=D["identify.n_gm"],
                                n_boot=int(n_boot), confidence=float(confidence),
                                significance=D["identify.significance"], relevance=D["identify.relevance"],
                                filter_rate_hz=1.0 / float(sc.dt), outage_s=float(sc.outage_s),
                                adequacy_level=D["identify.adequacy_level"], pooling_level=D["identify.pooling_level"],
                                pooling_n_boot=D["identify.pooling_n_boot"], span_s=float(sc.fix_s + sc.outage_s),
                                seed=seed, envelope_kind="joint")
    nan = float("nan")
    rec = ident.record.get("upper_envelope_joint") or {}
    if ident.envelope is None:
        return {"inflation": nan, "conservatism": nan, "worst": nan, "c_percentile": nan}
    env = ident.envelope
    f_hi = 0.5 / float(sc.dt)
    f = np.geomspace(1.0 / float(sc.outage_s), f_hi, int(100 * np.log10(f_hi * sc.outage_s)) + 1)
    m = replace(m, quantization=0.0)
    infl = float(np.median(np.sqrt(env.psd(f) / m.psd(f))))
    v = covariance_analysis(env, m, sc)
    return {"inflation": infl, "conservatism": float(v.mean_conservatism), "worst": float(v.worst_outage_ratio),
            "c_percentile": rec.get("c_percentile", nan) if isinstance(rec, dict) else nan}


def _confounded(fit, name: str) -> bool:
    """Whether `name`'s interval on the expected data is not a plain two-sided one: one-sided (fitted 0 or reaching
    0), confounded (GM and random walk trading off) or its GM time constant on an end of the search. There the
    half-width varies widely from record to record (quartiles a factor 2-3 apart in benchmarks/plan_check.py) and
    the expected-data value is a rough guide only."""
    kind = fit.interval_kind.get(name)
    if kind is None:
        return False
    gm_T = fit.interval_kind.get("gm_T_1", "two-sided")
    return kind != "two-sided" or (name == "gm_sigma_1" and gm_T != "two-sided")


def plan_table(model, hours, records, record_rate_hz: float, axes: int = 1, progress=None, **kw) -> list:
    """:func:`predict` for every (hours, records) pair, hours (h) outer, records inner. `progress`: None, or a
    callable given one line of text before each row and after it (with its time, s); the library prints nothing."""
    import time

    if not len(hours):
        raise ValueError("--hours: expected at least one record length (h)")
    if not len(records):
        raise ValueError("--records: expected at least one number of records")
    rows, pairs, start = [], [(h, r) for h in hours for r in records], time.perf_counter()
    for i, (h, r) in enumerate(pairs, 1):
        t0 = time.perf_counter()
        if progress is not None:
            progress(f"plan: row {i}/{len(pairs)}: {r} record(s) of {h:g} h ...")
        rows.append(predict(model, h, r, record_rate_hz, axes, **kw))
        if progress is not None:
            now = time.perf_counter()
            left = (now - start) / i * (len(pairs) - i)  # at the mean pace of the rows so far
            progress(f"plan: row {i}/{len(pairs)} done in {now - t0:.1f} s ({rows[-1]['method']})"
                     + (f"; at least {left:.0f} s left at the pace so far (rows with longer or more records take "
                        "longer)" if i < len(pairs) else ""))
    return rows


def parse_target(text: str) -> tuple:
    """``"K:0.25"`` -> ``("K", 0.25)``: parameter N, B or K within +/- the fraction of its value."""
    name, sep, frac = str(text).partition(":")
    name = name.strip().upper()
    if not sep or name not in PARAMS:
        raise ValueError(f"--target: expected PARAM:FRACTION with PARAM one of N, B, K (e.g. K:0.25), got {text!r}")
    try:
        f = float(frac)
    except ValueError:
        raise ValueError(f"--target: the fraction after ':' must be a number (0.25 = +/-25 %), got {frac!r}") from None
    if not (math.isfinite(f) and f > 0):
        raise ValueError(f"--target: the fraction must be positive (0.25 = +/-25 %), got {frac!r}")
    return name, f


def shortest_plan(rows: list, target: tuple):
    """The row of `rows` (:func:`plan_table`) with the least total recording time (hours x records; ties: fewer
    records) whose relative half-width of ``target[0]`` is at most ``target[1]``; None when none is."""
    import numpy as np

    p, f = target
    ok = [r for r in rows if np.isfinite(r["relative"][p]) and r["relative"][p] <= f]
    if not ok:
        return None
    return min(ok, key=lambda r: (r["hours"] * r["records"], r["records"]))


def load_model(sensor: str, spec=None, identify=None):
    """The model a plan is for, and the units to report it in: ``(NoiseModel (SI), units dict, source)``.

    `spec`: a spec sheet (:func:`imupipe.specsheet.load_spec`; its `sensor` block, its own units); `identify`: a
    pilot run's ``results/<name>/identify/<sensor>.yaml`` (its ``model_selected``; customary units). Exactly one.
    Raises ValueError naming the flag, file or key."""
    from imupipe.models import NoiseModel
    from imupipe.specsheet import SpecSheet, display_units, load_spec

    if sensor not in ("gyro", "accel"):
        raise ValueError(f"--sensor: expected gyro or accel, got {sensor!r}")
    if (spec is None) == (identify is None):
        raise ValueError("give exactly one of --spec (a spec sheet) and --from (a pilot run's identify file)")
    if spec is not None:
        sheet = load_spec(spec)
        if sensor not in sheet.models:
            raise ValueError(f"--spec {spec}: no {sensor!r} block (has {sorted(sheet.models)})")
        return sheet.models[sensor], display_units(sheet, sensor), f"spec sheet {spec}"
    import yaml

    try:
        with open(identify) as fh:
            doc = yaml.safe_load(fh)
    except OSError as exc:
        raise ValueError(f"--from {identify}: cannot read ({exc.strerror})") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("model_selected"), dict):
        raise ValueError(f"--from {identify}: expected an identify file with a 'model_selected' mapping")
    if doc.get("sensor") not in (None, sensor):
        raise ValueError(f"--from {identify}: the file is of sensor {doc.get('sensor')!r}, --sensor is {sensor!r}")
    model = NoiseModel.from_dict(doc["model_selected"])
    return model, display_units(SpecSheet(name="", path="", models={}, units={}), sensor), f"pilot {identify}"


def format_table(rows: list, units: dict, sensor: str) -> str:
    """A markdown table of :func:`plan_table` rows: hours, records, then per parameter the half-width in `units`
    (the spec sheet's) and relative to the model's value (%), marked ``~`` where the interval is one-sided or
    confounded (:func:`predict`'s ``confounded``), with a footnote."""
    import numpy as np

    from imupipe.units import from_si

    head = ["hours", "records"]
    flick = bool(rows) and rows[0].get("B_is") == "flicker"  # B of a flicker-only model: its flicker coefficient
    for p, (_, q) in PARAMS.items():
        name = "B (flicker)" if p == "B" and flick else p
        head += [f"{name} +/- ({units[q]})", f"{name} +/- %"]
    if rows and "auto" in rows[0]:
        head += ["auto: in-band inflation", "auto: P/MSE"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        cells = [f"{r['hours']:g}", f"{r['records']}"]
        for p, (_, q) in PARAMS.items():
            hw, rel = r["half_width"][p], r["relative"][p]
            cells.append("unbounded" if hw == np.inf else
                         f"{float(from_si(hw, units[q], q, sensor)):.3g}" if np.isfinite(hw) else "-")
            mark = " ~" if r.get("confounded", {}).get(p) else ""
            cells.append(f"{100 * rel:.3g}{mark}" if not np.isnan(rel) else "-")
        if "auto" in r:
            low = " !" if r["auto"].get("worst", 0.0) > 1.0 else ""
            cells += [f"{r['auto']['inflation']:.3g}", f"{r['auto']['conservatism']:.3g}{low}"]
        lines.append("| " + " | ".join(cells) + " |")
    if any(any(r.get("confounded", {}).values()) for r in rows):
        how = next((r["method"] for r in rows if r.get("method", "").startswith("median")), None)
        lines.append("\n~ the interval on the expected data is one-sided or confounded (GM and random walk trade "
                     "off): the half-width varies widely from record to record; "
                     + (f"such a row's values are the {how}" if how else "a rough guide only (--replicates)"))
    if any(r.get("auto", {}).get("worst", 0.0) > 1.0 for r in rows):
        lines.append("\n! the expected envelope alone lies below the model somewhere (a filter on it would under-state "
                     "the model's error: worst MSE/P above 1), at frequencies below the band the records speak for (a "
                     "flicker's 1/f or a GM beyond the records): the run's export adds the initial bias variance and "
                     "the spec sheet there, which this column leaves out; read it as the in-band tightness only")
    if rows and "auto" in rows[0]:
        lines.append("\nauto columns: the pooled joint envelope of the run's identification (every component it tries) "
                     "of the expected data, once per row, so they can step between rows where its regime changes (a GM "
                     "the records do not resolve re-assigned); not a record-to-record median, and a first-order "
                     "guide only: a run exports the tightest candidate that passes every check, which also lies "
                     "above the spec sheet and, on several axes, each axis's own envelope, or above every sample "
                     "PSD. On three-axis records of 2-2.5 h at 100 Hz the runs' median mean P/MSE was 0.8-2.4x the "
                     "column and their inflation 1.0-1.4x (benchmarks/plan_auto_axes.py). The half-widths are of a fit "
                     "of the model's own terms: a run that also keeps a flicker or a quantization reports wider ones")
    return "\n".join(lines)



def add_subcommand(sub) -> None:
    """Register ``imupipe plan`` on the command line's sub-parsers (:mod:`imupipe.cli`)."""
    p = sub.add_parser("plan", help="how long, and how many records, to record: expected interval half-widths of "
                       "N, B (GM sigma) and K per plan")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--spec", help="spec sheet YAML (config/specs/*.yaml): the model the plan is for")
    src.add_argument("--from", dest="identify", metavar="IDENTIFY_YAML",
                     help="a pilot run's results/<name>/identify/<sensor>.yaml: its identified model")
    p.add_argument("--sensor", required=True, choices=("gyro", "accel"))
    p.add_argument("--rate-hz", type=float, help="record sample rate, Hz (default with --from: the pilot's)")
    p.add_argument("--hours", type=float, nargs="+", default=[1.0, 2.0, 6.0, 20.0], help="record lengths, h")
    p.add_argument("--records", type=int, nargs="+", default=[1, 5], help="numbers of records")
    p.add_argument("--axes", type=int, default=3, help="axes pooled per record (default 3; 1 when the pooling "
                   "test splits the axes)")
    p.add_argument("--replicates", type=int, default=50, help="where an interval is one-sided or confounded, the "
                   "median over this many replicate Allan-variance curve sets (default 50; 0: the expected curve "
                   "only, fast)")
    p.add_argument("--target", help="PARAM:FRACTION, e.g. K:0.25 (K within +/-25 %%): the shortest plan of the "
                   "table that meets it")
    p.set_defaults(func=_cmd_plan)


def _cmd_plan(args) -> int:
    model, units, source = load_model(args.sensor, spec=args.spec, identify=args.identify)
    rate = args.rate_hz
    if rate is None and args.identify is not None:
        import yaml

        with open(args.identify) as fh:
            rates = (yaml.safe_load(fh) or {}).get("rate_hz") or {}
        rate = next(iter(rates.values()), None) if isinstance(rates, dict) else None
    if rate is None:
        raise ValueError("--rate-hz: the record sample rate (Hz) is needed" +
                         (f" ({args.identify} has no rate_hz)" if args.identify else ""))
    rate = _check_positive(rate, "--rate-hz")
    target = parse_target(args.target) if args.target is not None else None
    if target is not None and not _truth_values(model)[target[0]] > 0:
        raise ValueError(f"--target {args.target}: the {source} model has no {target[0]} term "
                         f"({param_name(target[0], model)} = 0), so no plan can pin it down to a fraction of its value; "
                         "target another parameter, or plan from a spec sheet (--spec) that states it")
    for h in args.hours:
        _check_positive(h, "--hours")
    for r in args.records:
        _check_positive(r, "--records", integer=True)
    import sys

    def progress(line):  # on stderr, so that the table on stdout stays clean for a file or a pipe
        print(line, file=sys.stderr, flush=True)

    rows = plan_table(model, args.hours, args.records, rate, args.axes, replicates=args.replicates,
                      sensor=args.sensor, progress=progress)
    print(f"# plan for the {args.sensor} model of the {source}, records at {rate:g} Hz, {args.axes} axis curve(s) "
          f"pooled per record: expected half-width of the {100 * CONFIDENCE:g} % interval (imupipe.plan)")
    print(format_table(rows, units, args.sensor))
    if target is not None:
        best = shortest_plan(rows, target)
        p, f = target
        if best is None:
            print(f"no plan of the table gives {p} within +/-{100 * f:g} %: add longer --hours or more --records")
            return 1
        print(f"shortest plan with {p} within +/-{100 * f:g} %: {best['records']} record(s) of {best['hours']:g} h "
              f"({p} +/-{100 * best['relative'][p]:.3g} %"
              + ("; ~ one-sided or confounded)" if best["confounded"][p] else ")")
              + ("; a rough guide: --replicates 50 gives the median over replicate records" if best["confounded"][p]
                 and not best["method"].startswith("median") else ""))
    return 0
