"""Speed against error: every setting a user can choose, timed and scored against a known truth, in one run.

``make bench`` runs this script::

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/run.py [--quick] [--repeats N] [--out DIR] [--dag]

Input: simulated records of a STIM-300-like gyro with known truth (white noise N = 0.15 deg/sqrt(h), one
Gauss-Markov term sigma = 1.5 deg/h, T = 300 s, rate random walk K = 2e-2 (deg/h)/sqrt(s), in SI), at the
paper's scale: 10 h at 125 Hz = 4.5e6 samples per record, 15 independent records (``--quick``: 1 h, 4 records).
Records are simulated one at a time and reduced at once (AVs, 1 Hz block means), so at most one full-rate
record (36 MB) and its temporaries are alive.

Measured side by side, in one run, on the same input:

1. Allan variance at paper scale: ``imupipe.allan.overlapping_avar`` / ``allan_variance`` against
   ``allantools.oadev`` on 100 log-spaced averaging times of a 4.5e6-sample record (time ratio, max relative
   difference, error against the exact ``NoiseModel.avar``); and every averaging time ("all") of 1 Hz series of
   N = 9000 ... 72000 points, with the fitted growth exponent of both.
2. Identification, decimation rate (125, 25, 5, 1 Hz): ``decimate`` + ``allan_variance`` (10 per decade) +
   ``fit_allan`` (1 GM term): time and relative error of N, sigma, T, K and of the fitted model's AV.
3. Identification, tau grid (octave, 10/decade, all; 1 Hz series) and number of GM terms (1, 2): AV time and
   error against the exact AV, allantools on the same taus, ``fit_allan`` against the peers' slope-line
   reading (``slope_line``).
4. PSD window (paper 7 h every 10 h; 1 h windows with 50 % overlap) and smoothing (none; 10 log bands per
   decade): time and error against the exact PSD of the block-averaged process (``psd_sampled``); scipy.signal
   .welch as a peer.
5. Bound mode (raw, smoothed, confidence) x GM terms (1, 2) x PSD window over the 15 sample PSDs at 1 Hz:
   time, looseness (mean over log frequency of model PSD / true PSD), min model/true PSD and margin (min model
   / sample PSD); the paper's hand inflation (``paper_inflation``) as the peer.

Times are medians [min-max] of ``--repeats`` runs on record 0 (a run slower than 20 s is repeated at most
3 times). Errors are medians over the records of |estimate/true - 1| (so they are the estimators' typical
statistical error, not one draw). Output: markdown tables on stdout and ``<out>/speed_vs_error.md``, tidy
numbers in ``<out>/speed_vs_error.csv``, the figure ``<out>/speed_vs_error.png`` (``<out>`` defaults to
``benchmarks/results``, git-ignored). ``--dag`` (off by default) also runs ``benchmarks/dag.py``.
"""

from __future__ import annotations

import os

# Per-job numerics must not start BLAS threads (docs performance.md); set before numpy is imported.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MPLBACKEND", "Agg")

import argparse
import csv
import math
import shlex
import sys
import time
import warnings
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))  # sibling helper modules (this folder is not a package)

from timing import Timing, fmt, fmt_s, machine_info, md_table, pct, timed

REPO = HERE.parent
DEG = math.pi / 180.0

# STIM-300-like gyro (the truth), in SI:
#   white 0.15 deg/sqrt(h)        -> N = 0.15/60 deg/s/sqrt(Hz)    = 4.363e-5 rad/s/sqrt(Hz)
#   GM sigma 1.5 deg/h, T 300 s   -> sigma = 1.5/3600 deg/s        = 7.272e-6 rad/s
#   RW 2e-2 (deg/h)/sqrt(s)       -> K = 2e-2/3600 deg/s/sqrt(s)   = 9.696e-8 rad/s/sqrt(s)
TRUTH = {"white": 0.15 / 60.0 * DEG, "gm_sigma": 1.5 / 3600.0 * DEG, "gm_T": 300.0,
         "random_walk": 2e-2 / 3600.0 * DEG}
FIT_COMPONENTS = ("white", "gauss_markov", "random_walk")  # the paper's model (its eq. 17)
PARAMS = ("white", "gm_sigma", "gm_T", "random_walk")
PARAM_LABEL = {"white": "N", "gm_sigma": "GM sigma", "gm_T": "GM T", "random_walk": "K"}
TAU_GRIDS = (("octave", "octave"), ("10/decade", 10), ("all", "all"))
BOUND_MODES = ("raw", "smoothed", "confidence")
SMOOTH_BANDS = 10  # log bands per decade of the smoothed PSD


@dataclass(frozen=True)
class Sizes:
    """Scale of one benchmark run."""

    name: str
    duration_s: float
    rate: float
    n_records: int
    sweep_n: tuple  # 1 Hz series lengths of the "all"-taus growth sweep
    rates: tuple = (125.0, 25.0, 5.0, 1.0)  # decimation rates of the identification
    n_log_taus: int = 100  # log-spaced averaging times of the paper-scale AV comparison

    @property
    def n(self) -> int:
        return round(self.duration_s * self.rate)

    @property
    def low(self) -> float:
        return self.rates[-1]

    @property
    def windows(self) -> dict:
        """PSD (window, step) in s: the paper's 7 h every 10 h on a 10 h record, and 1 h windows at 50 %
        overlap; as fractions of the record so that smaller scales keep the same shape."""
        d = self.duration_s
        return {"paper 7h/10h": (0.7 * d, 1.0 * d), "1h, 50% overlap": (0.1 * d, 0.05 * d)}


PAPER = Sizes("paper scale: 10 h at 125 Hz (4.5e6 samples), 15 records", 36000.0, 125.0, 15,
              (9000, 18000, 36000, 72000))
QUICK = Sizes("quick: 1 h at 125 Hz (4.5e5 samples), 4 records; windows scaled to the record", 3600.0, 125.0, 4,
              (2250, 4500, 9000, 18000))
TINY = Sizes("tiny (smoke test): 10 min at 125 Hz, 3 records", 600.0, 125.0, 3, (500, 1000, 2000), n_log_taus=20)


# ---------------------------------------------------------------------------------------------
# truth, input, error measures
# ---------------------------------------------------------------------------------------------
def truth_model(dt: float | None = None):
    from imupipe.models import NoiseModel

    return NoiseModel(white=TRUTH["white"], gauss_markov=((TRUTH["gm_sigma"], TRUTH["gm_T"]),),
                      random_walk=TRUTH["random_walk"], dt=dt)


def simulate_record(sizes: Sizes, seed: int, i: int) -> np.ndarray:
    """Record i (reproducible on its own: seed sequence [seed, i])."""
    from imupipe.simulate import simulate

    return simulate(truth_model(1.0 / sizes.rate), sizes.n, sizes.rate, np.random.default_rng([seed, i]))


def relerr(est, true: float) -> float:
    """|est/true - 1|; NaN when the method gave no value (None or NaN)."""
    if est is None:
        return math.nan
    est = float(est)
    return abs(est / true - 1.0) if math.isfinite(est) else math.nan


def signed_relerr(est, true: float) -> float:
    if est is None or not math.isfinite(float(est)):
        return math.nan
    return float(est) / true - 1.0


def nanmedian(values) -> float:
    a = np.asarray([np.nan if v is None else v for v in values], dtype=float)
    a = a[np.isfinite(a)]
    return float(np.median(a)) if a.size else math.nan


def n_missing(values) -> int:
    return sum(1 for v in values if v is None or not math.isfinite(float(v)))


def fit_params(fit, n_gm: int) -> dict:
    """N, K and the GM term standing for the true one of a fit_allan result: with several terms, the one whose
    time constant is closest to the true T in log (scoring needs a match; the fit itself does not know T)."""
    p = fit.params
    gms = [(p.get(f"gm_sigma_{i}"), p.get(f"gm_T_{i}")) for i in range(1, n_gm + 1)]
    gms = [g for g in gms if g[0] is not None and g[0] > 0 and g[1] is not None and math.isfinite(g[1])]
    s, T = min(gms, key=lambda g: abs(math.log(g[1] / TRUTH["gm_T"]))) if gms else (None, None)
    return {"white": p.get("white"), "gm_sigma": s, "gm_T": T, "random_walk": p.get("random_walk")}


def slope_model(sl: dict):
    """The peers' reading as a model: white N, random walk K and a flicker floor B (None -> absent)."""
    from imupipe.models import NoiseModel

    return NoiseModel(white=sl.get("white") or 0.0, random_walk=sl.get("random_walk") or 0.0,
                      flicker=sl.get("flicker") or 0.0)


def model_av_error(model, truth, tau) -> float:
    """Median over log-spaced tau of |AV_model/AV_true - 1|."""
    return float(np.median(np.abs(model.avar(tau) / truth.avar(tau) - 1.0)))


def logf_mean(f, values) -> float:
    """Mean of `values` over log frequency (each point weighted by the log-frequency width it covers)."""
    f = np.asarray(f, float)
    v = np.asarray(values, float)
    if f.size == 1:
        return float(v[0])
    w = np.gradient(np.log(f))
    return float(np.sum(w * v) / np.sum(w))


def warm_up(sizes: Sizes) -> float:
    """Call every timed function once on a small record so that lazy imports (xarray, scipy.optimize ...)
    and first-call costs are not charged to the first timed setting; returns seconds."""
    t0 = time.perf_counter()
    from imupipe.allan import allan_variance, overlapping_avar
    from imupipe.bound import bound_psd, margin
    from imupipe.identify import fit_allan, slope_line
    from imupipe.simulate import simulate
    from imupipe.spectra import decimate, psd, smooth_log_bands

    x = simulate(truth_model(1.0 / sizes.rate), 40000, sizes.rate, np.random.default_rng(0))
    overlapping_avar(x, sizes.rate, np.array([1, 2, 4]))
    ds = allan_variance(x, sizes.rate, taus="octave")
    fit_allan(ds["tau"].values, ds["avar"].values, ds["edf"].values, components=FIT_COMPONENTS, n_boot=0)
    slope_line(ds["tau"].values, np.sqrt(ds["avar"].values))
    y, r = decimate(x, sizes.rate, sizes.rate / 5)
    p = psd(y, r, window_s=0.5 * y.size / r, step_s=0.25 * y.size / r)
    smooth_log_bands(p["frequency"].values, p["psd"].values, edf=p["edf"].values, taper="hann")
    res = bound_psd(p["frequency"].values, p["psd"].values[None, :], dt=1 / r, keep=FIT_COMPONENTS,
                    edf=p["edf"].values)
    margin(res.model, p["frequency"].values, p["psd"].values[None, :], dt=1 / r)
    try:
        import allantools

        allantools.oadev(x, rate=sizes.rate, data_type="freq", taus=ds["tau"].values)
    except ImportError:
        pass
    return time.perf_counter() - t0


def _allantools():
    try:
        import allantools

        return allantools
    except ImportError:
        return None


def oadev_avar(at, x, rate, m) -> np.ndarray:
    """allantools.oadev on the averaging factors m, as an Allan variance; checks it used the same factors."""
    taus, adev, _, _ = at.oadev(x, rate=rate, data_type="freq", taus=np.asarray(m) / rate)
    got = np.rint(np.asarray(taus) * rate).astype(np.int64)
    if not np.array_equal(got, np.asarray(m)):
        raise RuntimeError("allantools used other averaging factors than imupipe")
    return np.asarray(adev) ** 2


# ---------------------------------------------------------------------------------------------
# results container
# ---------------------------------------------------------------------------------------------
@dataclass
class Setting:
    """One row: a setting's timing (per record / per curve unless said) and its error metrics."""

    section: str
    setting: str
    method: str
    timing: Timing
    metrics: dict = field(default_factory=dict)


class Acc:
    """Timing on record 0 (repeated), one call on every other record; metrics appended per record."""

    def __init__(self, repeats: int):
        self.repeats = repeats
        self.t: dict = {}
        self.m: dict = defaultdict(lambda: defaultdict(list))

    def run(self, key, fn, first: bool):
        if first:
            t, res = timed(fn, self.repeats)
            self.t[key] = t
            return res
        return fn()

    def add(self, key, **metrics):
        for k, v in metrics.items():
            self.m[key][k].append(v)

    def timing(self, *keys) -> Timing:
        """Sum of the timings of several stages (element-wise over the runs) as one Timing."""
        ts = [self.t[k] for k in keys if k in self.t]
        if not ts:
            return Timing()
        n = min(t.n for t in ts)
        return Timing([sum(t.values[i] for t in ts) for i in range(n)])


# ---------------------------------------------------------------------------------------------
# section 1: Allan variance at paper scale, and the "all"-taus growth sweep
# ---------------------------------------------------------------------------------------------
def bench_av_paper(x: np.ndarray, sizes: Sizes, truth, repeats: int) -> list:
    """imupipe vs allantools on `n_log_taus` log-spaced averaging times of one full-rate record."""
    from imupipe.allan import allan_variance, overlapping_avar

    rate = sizes.rate
    k = sizes.n_log_taus  # log-spaced factors 1 .. n/4; more points asked until `n_log_taus` are distinct
    while True:
        m = np.unique(np.rint(np.logspace(0, math.log10(x.size // 4), k)).astype(np.int64))
        if m.size >= sizes.n_log_taus or k > 10 * sizes.n_log_taus:
            break
        k += 1
    tau = m / rate
    exact = truth.avar(tau)
    t_core, av_core = timed(lambda: overlapping_avar(x, rate, m), repeats)
    t_api, ds = timed(lambda: allan_variance(x, rate, taus=tau), repeats)
    av_api = ds["avar"].values
    err = np.abs(av_core / exact - 1.0)
    base = {"n_samples": int(x.size), "n_taus": int(m.size), "av_err_median": float(np.median(err)),
            "av_err_max": float(np.max(err))}
    setting = f"{x.size:.3g} samples at {fmt(rate)} Hz, {m.size} log-spaced taus"
    out = [Setting("av_paper", setting, "imupipe overlapping_avar (estimator)", t_core, dict(base)),
           Setting("av_paper", setting, "imupipe allan_variance (API: + EDF, CI, noise ID)", t_api,
                   dict(base, max_rel_diff_vs_estimator=float(np.max(np.abs(av_api / av_core - 1.0)))))]
    at = _allantools()
    if at is not None:
        t_at, av_at = timed(lambda: oadev_avar(at, x, rate, m), repeats)
        diff = float(np.max(np.abs(av_core / av_at - 1.0)))
        out[0].metrics.update(speedup_vs_allantools=t_at.median / t_core.median, max_rel_diff_allantools=diff)
        out[1].metrics.update(speedup_vs_allantools=t_at.median / t_api.median,
                              max_rel_diff_allantools=float(np.max(np.abs(av_api / av_at - 1.0))))
        err_at = np.abs(av_at / exact - 1.0)
        out.append(Setting("av_paper", setting, "allantools oadev", t_at,
                           dict(base, av_err_median=float(np.median(err_at)), av_err_max=float(np.max(err_at)))))
    return out


def growth_exponent(n, t) -> float:
    """Least-squares slope of log t against log n."""
    n, t = np.asarray(n, float), np.asarray(t, float)
    ok = np.isfinite(t) & (t > 0)
    if ok.sum() < 2:
        return math.nan
    return float(np.polyfit(np.log(n[ok]), np.log(t[ok]), 1)[0])


def bench_av_sweep(sizes: Sizes, seed: int, repeats: int) -> list:
    """Every averaging time (taus="all": m = 1 .. N/4) of 1 Hz series of growing length N."""
    from imupipe.allan import allan_variance, overlapping_avar, tau_grid
    from imupipe.simulate import simulate

    truth1 = truth_model(1.0)
    x = simulate(truth1, max(sizes.sweep_n), 1.0, np.random.default_rng([seed, 10_000]))
    at = _allantools()
    out = []
    for n in sizes.sweep_n:
        y = np.ascontiguousarray(x[:n])
        m = tau_grid(n, 1.0, "all").m
        t_api, ds = timed(lambda y=y: allan_variance(y, 1.0, taus="all"), repeats)
        t_core, av = timed(lambda y=y, m=m: overlapping_avar(y, 1.0, m, method="auto"), repeats)
        exact = truth1.avar(m / 1.0)
        base = {"N": n, "n_taus": int(m.size), "av_err_median": float(np.median(np.abs(av / exact - 1.0)))}
        setting = f"N = {n}, all {m.size} taus"
        s_api = Setting("av_sweep", setting, "imupipe allan_variance", t_api, dict(base))
        s_core = Setting("av_sweep", setting, "imupipe overlapping_avar (auto: FFT)", t_core, dict(base))
        out += [s_api, s_core]
        if at is not None:
            t_at, av_at = timed(lambda y=y, m=m: oadev_avar(at, y, 1.0, m), repeats)
            diff = float(np.max(np.abs(ds["avar"].values / av_at - 1.0)))
            s_api.metrics.update(speedup_vs_allantools=t_at.median / t_api.median, max_rel_diff_allantools=diff)
            s_core.metrics.update(speedup_vs_allantools=t_at.median / t_core.median,
                                  max_rel_diff_allantools=float(np.max(np.abs(av / av_at - 1.0))))
            out.append(Setting("av_sweep", setting, "allantools oadev", t_at, dict(base)))
    for method in {s.method for s in out}:
        rows = [s for s in out if s.method == method]
        k = growth_exponent([s.metrics["N"] for s in rows], [s.timing.median for s in rows])
        for s in rows:
            s.metrics["growth_exponent"] = k
    return out


# ---------------------------------------------------------------------------------------------
# sections 2 and 3: per-record loop (identification by decimation rate and by tau grid)
# ---------------------------------------------------------------------------------------------
def _fit(ds, rate, n_gm):
    from imupipe.identify import fit_allan

    return fit_allan(ds["tau"].values, ds["avar"].values, ds["edf"].values, components=FIT_COMPONENTS,
                     n_gm=n_gm, n_boot=0, dt=1.0 / rate)


def _add_fit_errors(acc, key, params: dict, model, truth, tau_eval):
    errs = {f"err_{p}": relerr(params.get(p), TRUTH[p]) for p in PARAMS}
    signed = {f"bias_{p}": signed_relerr(params.get(p), TRUTH[p]) for p in PARAMS}
    acc.add(key, model_av_err=model_av_error(model, truth, tau_eval), **errs, **signed)


def process_record(x: np.ndarray, sizes: Sizes, truth, acc: Acc, first: bool) -> np.ndarray:
    """All per-record settings of sections 2 and 3; returns the 1 Hz series (kept for the PSD sections)."""
    from imupipe.allan import allan_variance
    from imupipe.identify import slope_line
    from imupipe.spectra import decimate

    tau_eval = np.logspace(0.0, math.log10(sizes.duration_s / 4.0), 60)
    y_low = None
    # section 2: decimation rate -> AV (10/decade) -> fit_allan (1 GM)
    for r in sizes.rates:
        if r == sizes.rate:
            y = x
        else:
            y = acc.run(("rate", r, "decimate"), lambda r=r: decimate(x, sizes.rate, r)[0], first)
        ds = acc.run(("rate", r, "av"), lambda y=y, r=r: allan_variance(y, r, taus=10), first)
        fit = acc.run(("rate", r, "fit"), lambda ds=ds, r=r: _fit(ds, r, 1), first)
        _add_fit_errors(acc, ("rate", r), fit_params(fit, 1), fit.model, truth, tau_eval)
        if r == sizes.low:
            y_low = y
        del y, ds
    # section 3: tau grid on the 1 Hz series; fit_allan with 1 and 2 GM terms; slope line
    low = sizes.low
    at = _allantools()
    for label, taus in TAU_GRIDS:
        ds = acc.run(("grid", label, "av"), lambda taus=taus: allan_variance(y_low, low, taus=taus), first)
        tau, av = ds["tau"].values, ds["avar"].values
        err = np.abs(av / truth.avar(tau) - 1.0)
        acc.add(("grid", label), av_err_median=float(np.median(err)), av_err_max=float(np.max(err)),
                n_taus=tau.size)
        if first and at is not None:
            m = ds["m"].values.astype(np.int64)
            av_at = acc.run(("grid", label, "allantools"), lambda m=m: oadev_avar(at, y_low, low, m), True)
            acc.add(("grid", label), max_rel_diff_allantools=float(np.max(np.abs(av / av_at - 1.0))))
        for n_gm in (1, 2):
            fit = acc.run(("grid", label, f"fit{n_gm}"), lambda ds=ds, n_gm=n_gm: _fit(ds, low, n_gm), first)
            _add_fit_errors(acc, ("grid", label, f"fit{n_gm}"), fit_params(fit, n_gm), fit.model, truth, tau_eval)
        sl = acc.run(("grid", label, "slope"), lambda tau=tau, av=av: slope_line(tau, np.sqrt(av)), first)
        params = {"white": sl.get("white"), "random_walk": sl.get("random_walk")}
        _add_fit_errors(acc, ("grid", label, "slope"), params, slope_model(sl), truth, tau_eval)
    return np.array(y_low, dtype=np.float64, copy=True)


def identification_settings(acc: Acc, sizes: Sizes) -> list:
    out = []
    for r in sizes.rates:
        stages = ([("rate", r, "decimate")] if r != sizes.rate else []) + [("rate", r, "av"), ("rate", r, "fit")]
        met = {k: nanmedian(v) for k, v in acc.m[("rate", r)].items()}
        met["missing_K"] = n_missing(acc.m[("rate", r)]["err_random_walk"])
        met["missing_GM"] = n_missing(acc.m[("rate", r)]["err_gm_sigma"])
        met.update({f"t_{k[2]}": acc.t[k].median for k in stages})
        out.append(Setting("ident_rate", f"{fmt(r)} Hz", "decimate + allan_variance (10/decade) + fit_allan, 1 GM",
                           acc.timing(*stages), met))
    for label, _ in TAU_GRIDS:
        g = acc.m[("grid", label)]
        t_av = acc.t[("grid", label, "av")]
        met = {k: nanmedian(v) for k, v in g.items()}
        out.append(Setting("tau_grid", label, "imupipe allan_variance", t_av, dict(met)))
        if ("grid", label, "allantools") in acc.t:
            t_at = acc.t[("grid", label, "allantools")]
            out[-1].metrics["speedup_vs_allantools"] = t_at.median / t_av.median
            out.append(Setting("tau_grid", label, "allantools oadev", t_at,
                               {"av_err_median": met["av_err_median"], "av_err_max": met["av_err_max"],
                                "n_taus": met["n_taus"], "max_rel_diff_allantools": met["max_rel_diff_allantools"]}))
        for key, method in (("fit1", "fit_allan, 1 GM"), ("fit2", "fit_allan, 2 GM"),
                            ("slope", "slope line (IEEE 952 / Kalibr / MATLAB)")):
            e = acc.m[("grid", label, key)]
            met = {k: nanmedian(v) for k, v in e.items()}
            met["missing_K"] = n_missing(e["err_random_walk"])
            met["missing_GM"] = n_missing(e["err_gm_sigma"]) if key != "slope" else math.nan
            met["t_av"] = t_av.median
            out.append(Setting("ident_grid", label, method, acc.t[("grid", label, key)], met))
    return out


# ---------------------------------------------------------------------------------------------
# sections 4 and 5: PSD windows and smoothing; bound modes
# ---------------------------------------------------------------------------------------------
def bench_psd(ys: list, sizes: Sizes, truth, repeats: int):
    """Returns (settings, {window: (frequency, curves (n, F), edf)})."""
    from imupipe.spectra import psd, smooth_log_bands

    low = sizes.low
    dt = 1.0 / low
    f_lo = 3.0 / min(w for w, _ in sizes.windows.values())  # above the Hann main lobe of every window
    out, spectra = [], {}
    for wlabel, (win, step) in sizes.windows.items():
        t_psd, p0 = timed(lambda win=win, step=step: psd(ys[0], low, window_s=win, step_s=step), repeats)
        ps = [p0] + [psd(y, low, window_s=win, step_s=step) for y in ys[1:]]
        f = p0["frequency"].values
        curves = np.stack([p["psd"].values for p in ps])
        edf = p0["edf"].values
        spectra[wlabel] = (f, curves, edf)
        s_true = truth.psd_sampled(f, dt)
        band = (f >= f_lo) & (f > 0)
        errs = [logf_mean(f[band], np.abs(c[band] / s_true[band] - 1.0)) for c in curves]
        info = {"n_segments": int(p0.attrs.get("n_segments", -1)), "n_bins": int(f.size),
                "f_min_hz": float(f[1]), "edf_interior": float(p0.attrs.get("edf", np.nan))}
        out.append(Setting("psd", wlabel, "psd, no smoothing", t_psd,
                           dict(info, psd_err=float(np.median(errs)))))
        t_sm, _ = timed(lambda f=f, c=curves[0], edf=edf: smooth_log_bands(f, c, SMOOTH_BANDS, edf=edf, taper="hann"),
                        repeats)
        lb = smooth_log_bands(f, curves, SMOOTH_BANDS, edf=edf, taper="hann")
        lb_true = smooth_log_bands(f, s_true, SMOOTH_BANDS)  # what each band average estimates
        bb = lb.frequency >= f_lo
        errs = [logf_mean(lb.frequency[bb], np.abs(c[bb] / lb_true.psd[bb] - 1.0)) for c in lb.psd]
        t_tot = Timing([a + b for a, b in zip(t_psd.values, t_sm.values)])
        out.append(Setting("psd", wlabel, f"psd + smooth_log_bands ({SMOOTH_BANDS}/decade)", t_tot,
                           dict(info, psd_err=float(np.median(errs)), t_smooth=t_sm.median,
                                n_bands=int(lb.frequency.size))))
    # peer: scipy.signal.welch on the overlapping setting (scipy cannot skip samples between segments)
    try:
        import scipy.signal

        wlabel = "1h, 50% overlap"
        win, step = sizes.windows[wlabel]
        nper, nstep = round(win * low), round(step * low)
        t_sp, (_, p_sp) = timed(lambda: scipy.signal.welch(ys[0], fs=low, window="hann", nperseg=nper,
                                                           noverlap=nper - nstep, detrend="constant"), repeats)
        s2 = spectra[wlabel][1][0]
        interior = slice(1, -1 if nper % 2 == 0 else None)
        diff = float(np.max(np.abs(s2[interior] / (0.5 * p_sp[interior]) - 1.0)))
        f = spectra[wlabel][0]
        band = f >= f_lo
        err = logf_mean(f[band], np.abs(0.5 * p_sp[band] / truth.psd_sampled(f[band], dt) - 1.0))
        ip = next(s for s in out if s.setting == wlabel and "no smoothing" in s.method)
        ip.metrics["speedup_vs_scipy"] = t_sp.median / ip.timing.median
        out.append(Setting("psd", wlabel, "scipy.signal.welch (peer, curve 0)", t_sp,
                           {"psd_err": err, "max_rel_diff_imupipe": diff}))
    except ImportError:
        pass
    return out, spectra


def bench_bound(spectra: dict, sizes: Sizes, truth, repeats: int) -> list:
    from imupipe.bound import bound_psd, looseness, margin, paper_inflation

    dt = 1.0 / sizes.low
    f_lo = 1.0 / min(w for w, _ in sizes.windows.values())  # band every window resolves
    f_eval = np.logspace(math.log10(f_lo), math.log10(0.5 / dt), 400)
    s_true = truth.psd_sampled(f_eval, dt)
    out = []
    for wlabel, (f, curves, edf) in spectra.items():
        runs = [(mode, n_gm) for mode in BOUND_MODES for n_gm in (1, 2)] + [("paper", 1)]
        for mode, n_gm in runs:
            if mode == "paper":
                fn = lambda f=f, curves=curves: paper_inflation(f, curves, truth, dt=dt)
                method = "paper_inflation (peer: hand inflation of the spec = truth)"
            else:
                fn = (lambda mode=mode, n_gm=n_gm, f=f, curves=curves, edf=edf:
                      bound_psd(f, curves, dt=dt, mode=mode, n_gm=n_gm, keep=FIT_COMPONENTS, edf=edf, taper="hann"))
                method = f"bound_psd {mode}"
            t, res = timed(fn, repeats)
            ratio = res.model.psd_sampled(f_eval, dt) / s_true
            mdl = res.model
            out.append(Setting("bound", wlabel, method, t, {
                "n_gm": n_gm, "n_curves": int(curves.shape[0]), "looseness_true": logf_mean(f_eval, ratio),
                "min_model_true": float(np.min(ratio)), "margin_samples": float(margin(mdl, f, curves, dt=dt)[0]),
                "margin_own_targets": float(res.margin), "looseness_lp": float(looseness(mdl, f, curves, dt=dt)),
                "N": mdl.white, "K": mdl.random_walk,
                "gm": ";".join(f"{s:.3g}@{T:.3g}s" for s, T in mdl.gauss_markov)}))
    return out


# ---------------------------------------------------------------------------------------------
# the whole measurement
# ---------------------------------------------------------------------------------------------
def run_all(sizes: Sizes, repeats: int = 5, seed: int = 20211101, log=print) -> dict:
    """Every measurement; returns {'settings': [Setting], 'notes': {...}}."""
    truth = truth_model(1.0 / sizes.rate)
    notes = {}
    settings: list = []
    seen: Counter = Counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        notes["warm_up_s"] = warm_up(sizes)
        acc = Acc(repeats)
        ys = []
        t_sim = 0.0
        for i in range(sizes.n_records):
            t0 = time.perf_counter()
            x = simulate_record(sizes, seed, i)
            t_sim += time.perf_counter() - t0
            if i == 0:
                settings += bench_av_paper(x, sizes, truth, repeats)
                log(f"  [{time.perf_counter() - T_START:6.1f} s] paper-scale AV vs allantools done")
            ys.append(process_record(x, sizes, truth, acc, first=(i == 0)))
            del x
            if i == 0 or i == sizes.n_records - 1:
                log(f"  [{time.perf_counter() - T_START:6.1f} s] record {i + 1}/{sizes.n_records} reduced")
        notes["simulate_s_all_records"] = t_sim
        settings += identification_settings(acc, sizes)
        s_psd, spectra = bench_psd(ys, sizes, truth, repeats)
        settings += s_psd
        log(f"  [{time.perf_counter() - T_START:6.1f} s] PSD settings done")
        settings += bench_bound(spectra, sizes, truth, repeats)
        log(f"  [{time.perf_counter() - T_START:6.1f} s] bound settings done")
        settings += bench_av_sweep(sizes, seed, repeats)
        log(f"  [{time.perf_counter() - T_START:6.1f} s] 'all'-taus sweep done")
        for w in caught:
            seen[(w.category.__name__, str(w.message).split("\n")[0][:140])] += 1
    notes["warnings"] = seen
    return {"settings": settings, "notes": notes, "sizes": sizes, "repeats": repeats, "seed": seed}


T_START = time.perf_counter()


def peak_rss_mb() -> float:
    """Peak resident set of this process, MB (Linux ru_maxrss is in kB)."""
    try:
        import resource

        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3
    except (ImportError, OSError):
        return math.nan


# ---------------------------------------------------------------------------------------------
# rendering: markdown tables, CSV, targets
# ---------------------------------------------------------------------------------------------
def _sel(settings, section):
    return [s for s in settings if s.section == section]


def _x(v, digits=3) -> str:
    return f"{fmt(v, digits)}x" if v is not None and math.isfinite(v) else "n/a"


def _e(v) -> str:
    return "n/a" if v is None or not math.isfinite(v) else f"{v:.1e}"


def _err_cell(met, p) -> str:
    v = met.get(f"err_{p}")
    cell = pct(v) if v is not None and math.isfinite(v) else "n/a"
    if p == "random_walk" and met.get("missing_K"):
        cell += f" ({met['missing_K']} none)"
    if p.startswith("gm") and met.get("missing_GM") and met["missing_GM"] == met["missing_GM"]:
        cell += f" ({met['missing_GM']} none)"
    return cell


def tables(res: dict) -> dict:
    S = res["settings"]
    sizes: Sizes = res["sizes"]
    nrec = sizes.n_records
    out = {}
    rows = []
    for s in _sel(S, "av_paper"):
        m = s.metrics
        rows.append([s.method, s.timing.cell(), _x(m.get("speedup_vs_allantools")),
                     _e(m.get("max_rel_diff_allantools")), f"{pct(m['av_err_median'])} / {pct(m['av_err_max'])}"])
    setting = _sel(S, "av_paper")[0].setting
    out["av_paper"] = (f"**{setting}** (record 0; same input, same averaging factors)\n\n" + md_table(
        ["method", "time", "allantools time / this", "max rel. diff to allantools",
         "AV error vs exact, median / max over taus"], rows))

    rows = []
    sw = _sel(S, "av_sweep")
    methods = list(dict.fromkeys(s.method for s in sw))
    for n in sizes.sweep_n:
        r = [f"{n}", f"{n // 4}"]
        for meth in methods:
            s = next((s for s in sw if s.metrics["N"] == n and s.method == meth), None)
            r.append(s.timing.cell() if s else "n/a")
        api = next(s for s in sw if s.metrics["N"] == n and s.method == "imupipe allan_variance")
        r += [_x(api.metrics.get("speedup_vs_allantools")), _e(api.metrics.get("max_rel_diff_allantools"))]
        rows.append(r)
    expo = ["growth exponent (fit of log t on log N)", ""]
    for meth in methods:
        expo.append(fmt(next(s for s in sw if s.method == meth).metrics["growth_exponent"], 3))
    rows.append(expo + ["", ""])
    out["av_sweep"] = ("**every averaging time (taus=\"all\", m = 1 .. N/4) of a 1 Hz series of N points** "
                       "(prefixes of one simulated series)\n\n" + md_table(
                           ["N", "taus"] + methods + ["allantools / allan_variance", "max rel. diff"], rows))

    rows = []
    for s in _sel(S, "ident_rate"):
        m = s.metrics
        rows.append([s.setting, fmt_s(m["t_decimate"]) if "t_decimate" in m else "- (input rate)",
                     fmt_s(m["t_av"]), fmt_s(m["t_fit"]),
                     s.timing.cell()] + [_err_cell(m, p) for p in PARAMS] + [pct(m["model_av_err"])])
    out["ident_rate"] = md_table(
        ["rate", "decimate", "AV (10/decade)", "fit_allan (1 GM)", "total per record"]
        + [f"{PARAM_LABEL[p]} error" for p in PARAMS] + ["model AV error"], rows)

    rows = []
    for s in _sel(S, "tau_grid"):
        m = s.metrics
        rows.append([s.setting, s.method, int(m["n_taus"]), s.timing.cell(), _x(m.get("speedup_vs_allantools")),
                     _e(m.get("max_rel_diff_allantools")), f"{pct(m['av_err_median'])} / {pct(m['av_err_max'])}"])
    out["tau_grid"] = md_table(["tau grid (1 Hz)", "method", "taus", "AV time", "allantools time / this",
                                "max rel. diff to allantools", "AV error vs exact, median / max over taus"], rows)

    rows = []
    for s in _sel(S, "ident_grid"):
        m = s.metrics
        rows.append([s.setting, s.method, s.timing.cell(), fmt_s(m["t_av"] + s.timing.median)]
                    + [_err_cell(m, p) for p in PARAMS] + [pct(m["model_av_err"])])
    out["ident_grid"] = md_table(["tau grid (1 Hz)", "method", "fit time", "AV + fit (medians)"]
                                 + [f"{PARAM_LABEL[p]} error" for p in PARAMS] + ["model AV error"], rows)

    rows = []
    for s in _sel(S, "psd"):
        m = s.metrics
        seg = f"{m['n_segments']}" if "n_segments" in m else ""
        res_ = f"{fmt(m['f_min_hz'], 3)} Hz" if "f_min_hz" in m else ""
        extra = []
        if "speedup_vs_scipy" in m:
            extra.append(f"scipy time / this {_x(m['speedup_vs_scipy'])}")
        if "max_rel_diff_imupipe" in m:
            extra.append(f"max rel. diff to imupipe {_e(m['max_rel_diff_imupipe'])}")
        if "n_bands" in m:
            extra.append(f"{m['n_bands']} bands")
        rows.append([s.setting, s.method, seg, res_, s.timing.cell(), pct(m["psd_err"]), "; ".join(extra)])
    out["psd"] = md_table(["window", "method", "segments", "lowest freq.", "time per curve",
                           "PSD error vs exact", "note"], rows)

    rows = []
    for s in _sel(S, "bound"):
        m = s.metrics
        rows.append([s.setting, s.method.replace("bound_psd ", ""), m["n_gm"], s.timing.cell(),
                     fmt(m["looseness_true"], 3), fmt(m["min_model_true"], 3), fmt(m["margin_samples"], 3),
                     fmt(m["margin_own_targets"], 3)])
    out["bound"] = md_table(["PSD window", "bound mode", "GM", f"time ({nrec} curves)",
                             "looseness: mean model/true PSD", "min model/true PSD",
                             "margin: min model/sample PSD", "margin vs own targets"], rows)
    return out


def targets(res: dict) -> list:
    S = res["settings"]
    out = []
    for s in _sel(S, "av_paper"):
        if "speedup_vs_allantools" in s.metrics:
            v = s.metrics["speedup_vs_allantools"]
            out.append([f"AV >= 10x allantools, {s.setting}: {s.method}", _x(v), "PASS" if v >= 10 else "FAIL"])
    diffs = [s.metrics.get("max_rel_diff_allantools") for s in S if s.section in ("av_paper", "tau_grid", "av_sweep")]
    diffs = [d for d in diffs if d is not None and math.isfinite(d)]
    if diffs:
        d = max(diffs)
        out.append(["AV equal to allantools to ~1e-12 (max over every comparison)", _e(d),
                    "PASS" if d <= 5e-12 else "FAIL"])
    sw = _sel(S, "av_sweep")
    for meth in dict.fromkeys(s.method for s in sw):
        k = next(s for s in sw if s.method == meth).metrics["growth_exponent"]
        if meth.startswith("imupipe"):
            out.append([f"'all' taus O(N log N): {meth}", f"t ~ N^{fmt(k, 3)}", "PASS" if k < 1.5 else "FAIL"])
        else:
            out.append([f"'all' taus, peer: {meth} (O(N^2))", f"t ~ N^{fmt(k, 3)}", "(reference)"])
    return out


def csv_rows(res: dict) -> list:
    rows = []
    for s in res["settings"]:
        for k, v in s.metrics.items():
            rows.append({"section": s.section, "setting": s.setting, "method": s.method,
                         "time_median_s": s.timing.median, "time_min_s": s.timing.min, "time_max_s": s.timing.max,
                         "time_runs": s.timing.n, "metric": k, "value": v})
    return rows


def markdown(res: dict, command: str, machine: dict, total_s: float | None = None) -> str:
    sizes: Sizes = res["sizes"]
    T = tables(res)
    notes = res["notes"]
    md = ["# imupipe benchmark: speed against error", "", f"Command: `{command}`", "",
          "Machine: " + "; ".join(f"{k} {v}" for k, v in machine.items()), "",
          (f"Input: {sizes.name}: simulated STIM-300-like gyro, truth N {fmt(TRUTH['white'], 4)} rad/s/sqrt(Hz) "
           f"(0.15 deg/sqrt(h)), GM sigma {fmt(TRUTH['gm_sigma'], 4)} rad/s (1.5 deg/h) T {fmt(TRUTH['gm_T'])} s, "
           f"K {fmt(TRUTH['random_walk'], 4)} rad/s/sqrt(s) (2e-2 (deg/h)/sqrt(s)); seed {res['seed']}. "
           f"Simulating the {sizes.n_records} records took {fmt_s(notes['simulate_s_all_records'])} (not in any "
           f"time below); warm-up of every timed function before timing: {fmt_s(notes['warm_up_s'])}."), "",
          (f"Times: median [min-max] of {res['repeats']} runs on record 0 (one record / one curve, one core). "
           f"Errors: median over the {sizes.n_records} records of |estimate/true - 1| (typical error of one "
           "record, not the error of an average). 'none' = records where the method returned no value "
           "(K fitted as 0 counts as a 100 % error, not as none)."), ""]
    md += ["## 1. Allan variance: imupipe against allantools", "", T["av_paper"], "", T["av_sweep"], ""]
    md += ["## 2. Identification by decimation rate", "",
           ("Each record block-averaged to the rate (`imupipe.spectra.decimate`), AV on 10 taus per decade "
            "(`allan_variance`), `fit_allan` with white + 1 GM + random walk, no bootstrap. Model AV error: median "
            "over 60 log-spaced taus from 1 s to a quarter of the record of |AV_fit/AV_true - 1|."), "",
           T["ident_rate"], ""]
    md += ["## 3. Tau grid on the 1 Hz series, number of GM terms, and the slope-line peer", "",
           ("AV error is the estimator's statistical scatter against the exact `NoiseModel.avar` (allantools "
            "computes the same numbers, so has the same error); allantools timed on record 0 on the same taus."),
           "", T["tau_grid"], "",
           ("Identification from those AVs. With 2 GM terms the GM columns score the term whose T is closest (in log) to the true T. "
            "The slope line reads N (slope -1/2) and K (slope +1/2) only; its model AV error uses N, K and the "
            "bias-instability floor B = min ADEV/0.664 it also reports."), "", T["ident_grid"], ""]
    md += ["## 4. PSD window and smoothing (1 Hz series)", "",
           (f"Two-sided Welch PSD (`imupipe.spectra.psd`, Hann, constant detrend); smoothing = "
            f"`smooth_log_bands` ({SMOOTH_BANDS} bands/decade). PSD error: mean over log frequency (from 3 bins "
            "of the shortest window to Nyquist) of |S_hat/S_true - 1| against the exact PSD of the block-averaged "
            "process (`NoiseModel.psd_sampled`; band averages of it for the smoothed PSD), median over records. "
            "scipy's one-sided PSD is halved for the comparison."), "", T["psd"], ""]
    md += [f"## 5. Bound mode x GM terms x PSD window, over {sizes.n_records} simulated curves", "",
           ("`bound_psd` (white + GM + random walk, no spec sheet: data-driven) on the sample PSDs of all records "
            "together. Looseness: mean over 400 log-spaced frequencies (lowest bin of the shortest window to "
            "Nyquist) of model PSD / true PSD (block-averaged forms); min model/true < 1 means the bound is below the "
            "truth somewhere. Margin: min over every raw periodogram ordinate of model/sample PSD (`bound.margin`; "
            ">= 1 for raw mode; smoothed and confidence modes bound band averages or their upper confidence "
            "limits, so < 1 by design; last column: against the mode's own targets). `paper_inflation` starts "
            "from the spec sheet, here equal to the truth: an advantage no real user has."), "", T["bound"], ""]
    md += ["## Targets", "", md_table(["target", "measured", "verdict"], targets(res)), ""]
    if notes.get("warnings"):
        md += ["Warnings raised by the library during the run (count):", ""]
        md += [f"- {cat}: {msg} ({n})" for (cat, msg), n in notes["warnings"].most_common(8)] + [""]
    if total_s is not None:
        md += [(f"Benchmark wall time: {fmt_s(total_s)}; peak resident memory of the benchmark process: "
                f"{fmt(peak_rss_mb(), 3)} MB (one full-rate record is {sizes.n * 8 / 1e6:.3g} MB)."), ""]
    return "\n".join(md)


# ---------------------------------------------------------------------------------------------
# figure
# ---------------------------------------------------------------------------------------------
def plot(res: dict, path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    S = res["settings"]
    fig, axes = plt.subplots(2, 3, figsize=(19, 11.5))

    pending = defaultdict(list)  # axis -> labels, placed once the axis limits are final

    def point(ax, x, y, label, **kw):
        if x is None or y is None or not (math.isfinite(x) and math.isfinite(y)) or x <= 0 or y <= 0:
            return
        ax.scatter(x, y, s=kw.pop("s", 40), zorder=3, **kw)
        pending[ax].append((x, y, label))

    def place_labels():
        """Annotate every marker; a label that would overlap one already placed is moved down a line."""
        fig.canvas.draw()
        to_pt = 72.0 / fig.dpi
        for ax, items in pending.items():
            placed = []  # in points
            for x, y, label in sorted(items, key=lambda it: -it[1]):
                px, py = (v * to_pt for v in ax.transData.transform((x, y)))
                dy = 3
                width = 3.6 * len(label) + 4
                while any(abs((py + dy) - qy) < 9 and (px < qx + qw and qx < px + width) for qx, qy, qw in placed):
                    dy -= 9
                placed.append((px, py + dy, width))
                ax.annotate(label, (x, y), xytext=(4, dy), textcoords="offset points", fontsize=6.5,
                            arrowprops={"arrowstyle": "-", "lw": 0.4, "color": "0.5"} if dy < -6 else None)

    def loglog(ax, xl, yl, t):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(xl)
        ax.set_ylabel(yl)
        ax.set_title(t, fontsize=9)
        ax.grid(True, which="both", alpha=0.25)
        ax.margins(x=0.12, y=0.08)

    ax = axes[0, 0]
    for s in _sel(S, "av_paper") + _sel(S, "tau_grid"):
        peer = s.method.startswith("allantools")
        lab = (f"{fmt(res['sizes'].rate)} Hz, {s.metrics['n_taus']} log taus" if s.section == "av_paper"
               else f"1 Hz {s.setting}")
        lab += ", " + ("allantools" if peer else s.method.replace("imupipe ", "").split(" (")[0])
        point(ax, s.timing.median, s.metrics["av_err_median"], lab, marker="s" if peer else "o",
              color="C3" if peer else "C0")
    loglog(ax, "median wall time (s), one record", "AV error vs exact, median over taus",
           "Allan variance (blue imupipe, red allantools: same numbers)")

    ax = axes[0, 1]
    for s in _sel(S, "ident_rate"):
        point(ax, s.timing.median, s.metrics["model_av_err"], f"{s.setting}: fit 1 GM, 10/dec", marker="o",
              color="C0")
    for s in _sel(S, "ident_grid"):
        mk = {"fit_allan, 1 GM": ("^", "C1"), "fit_allan, 2 GM": ("v", "C2")}.get(s.method, ("s", "C3"))
        short = s.method.split(" (")[0].replace("fit_allan, ", "fit ")
        point(ax, s.metrics["t_av"] + s.timing.median, s.metrics["model_av_err"], f"1 Hz {s.setting}: {short}",
              marker=mk[0], color=mk[1])
    loglog(ax, "median wall time (s): decimate + AV + fit, one record", "model AV error (median over log tau)",
           "identification: rate (blue), tau grid x method (1 GM orange, 2 GM green, slope line red)")

    ax = axes[0, 2]
    sw = _sel(S, "av_sweep")
    for i, meth in enumerate(dict.fromkeys(s.method for s in sw)):
        rows = [s for s in sw if s.method == meth]
        n = [s.metrics["N"] for s in rows]
        ax.plot(n, [s.timing.median for s in rows], "o-", color=f"C{i}",
                label=f"{meth}: t ~ N^{fmt(rows[0].metrics['growth_exponent'], 3)}")
    ax.legend(fontsize=7)
    loglog(ax, "N (1 Hz points)", "median wall time (s)", "every averaging time (taus='all'): growth with N")

    ax = axes[1, 0]
    for s in _sel(S, "psd"):
        peer = s.method.startswith("scipy")
        smooth = "smooth_log_bands" in s.method
        lab = f"{s.setting}, " + ("scipy welch" if peer else ("smoothed" if smooth else "raw"))
        point(ax, s.timing.median, s.metrics["psd_err"], lab, marker="s" if peer else "o",
              color="C3" if peer else ("C1" if smooth else "C0"))
    loglog(ax, "median wall time (s), one curve", "PSD error: log-f mean |S/S_true - 1|",
           "PSD window x smoothing (red: scipy peer)")

    ax = axes[1, 1]
    for s in _sel(S, "bound"):
        mode = s.method.split()[1] if s.method.startswith("bound_psd") else "paper"
        mk = {"raw": "o", "smoothed": "s", "confidence": "^", "paper": "*"}[mode]
        col = "C0" if s.setting.startswith("paper") else "C1"
        unsafe = s.metrics["min_model_true"] < 1.0
        point(ax, s.timing.median, s.metrics["looseness_true"],
              f"{'7h' if s.setting.startswith('paper') else '1h'} {mode} {s.metrics['n_gm']}GM", marker=mk,
              facecolors="none" if unsafe else col, edgecolors=col, s=60 if mode == "paper" else 40)
    loglog(ax, "median wall time (s), all curves", "looseness: log-f mean of model/true PSD",
           "bound: blue 7h/10h, orange 1h 50%; o raw, s smoothed, ^ confidence, * paper_inflation;\n"
           "hollow: bound below the true PSD somewhere")

    ax = axes[1, 2]
    ax.set_axis_off()
    import textwrap

    txt = ["Targets:"]
    for t in targets(res):
        txt += textwrap.wrap(f"{t[2]}: {t[0]}: {t[1]}", 70, initial_indent="- ", subsequent_indent="    ")
    ax.text(0.0, 1.0, "\n".join(txt), va="top", ha="left", fontsize=7.5, family="monospace")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    place_labels()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ---------------------------------------------------------------------------------------------
def main(argv=None) -> int:
    global T_START
    T_START = time.perf_counter()
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="small smoke variant (1 h at 125 Hz, 4 records)")
    ap.add_argument("--repeats", type=int, default=None, help="timed runs per setting (default 5; quick 3)")
    ap.add_argument("--seed", type=int, default=20211101, help="seed of the simulated records")
    ap.add_argument("--out", type=Path, default=HERE / "results", help="output folder (default benchmarks/results)")
    ap.add_argument("--dag", action="store_true", help="also run benchmarks/dag.py (Snakemake DAG; off by default)")
    ap.add_argument("--cores", type=int, default=2, help="snakemake --cores for --dag (default 2)")
    args = ap.parse_args(argv)

    sizes = QUICK if args.quick else PAPER
    repeats = args.repeats or (3 if args.quick else 5)
    args.out.mkdir(parents=True, exist_ok=True)
    command = "OPENBLAS_NUM_THREADS={} .venv/bin/python benchmarks/run.py {}".format(
        os.environ.get("OPENBLAS_NUM_THREADS"), " ".join(shlex.quote(a) for a in (argv or sys.argv[1:]))).strip()
    machine = machine_info()
    print(f"# {sizes.name}; {repeats} repeats; {machine['cpu']}", flush=True)
    res = run_all(sizes, repeats=repeats, seed=args.seed, log=lambda s: print(s, flush=True))
    md = markdown(res, command, machine, total_s=time.perf_counter() - T_START)
    if args.dag:
        import dag as dagbench

        d = dagbench.run(REPO, args.out, cores=args.cores, repeats=3)
        md += "\n## 6. Whole workflow (Snakemake DAG, benchmarks/dag.py)\n\n" + d["markdown"] + "\n"
    print()
    print(md, flush=True)
    (args.out / "speed_vs_error.md").write_text(md)
    rows = csv_rows(res)
    with open(args.out / "speed_vs_error.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    plot(res, args.out / "speed_vs_error.png", f"imupipe speed against error ({sizes.name}; {repeats} repeats); "
         f"{machine['cpu']}, numpy {machine['numpy']}, scipy {machine['scipy']}")
    print(f"wrote {args.out / 'speed_vs_error.md'}, speed_vs_error.csv, speed_vs_error.png "
          f"({fmt_s(time.perf_counter() - T_START)} in all)", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
