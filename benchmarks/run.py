"""Speed against error: every setting a user can choose, timed and scored against a known truth, in one run.

``make bench`` runs this script. On simulated records of a STIM-300-like gyro (white noise + one Gauss-Markov
term + rate random walk, values of the paper's Table 2 spec column; default 10 h at 125 Hz, three axes) it
measures, side by side:

* Allan variance: imupipe against allantools (``oadev``) on the same averaging times (octave and 10 per
  decade on the full-rate series, "all" on the 1 Hz series): wall time, ratio, error against the exact AV
  (``NoiseModel.avar``) and agreement between the two estimators;
* identification: ``imupipe.identify.fit_allan`` per tau grid and number of GM terms, and the peers'
  slope-line reading (``imupipe.identify.slope_line``): wall time and relative error of N, K, sigma, T and of
  the fitted model's AV;
* the PSD/bound path: decimation rate (125, 25, 5, 1 Hz), PSD windows (paper 7 h / 10 h; Welch 1 h, 50 %
  overlap), bound mode (raw, smoothed, confidence) and number of GM terms: wall time of each stage, the
  bound's looseness against the true PSD (mean over log frequency of bound/true) and its margins;
* the whole Snakemake DAG (``benchmarks/dag.py``): cold paper-scale run and spec-sheet-only rerun in a
  scratch copy, jobs, peak memory per rule, orchestration cost, and the floor it is compared with;

and prints PASS/FAIL for the project's speed targets. Output: a markdown table on stdout and in
``<out>/benchmark.md``, raw numbers in ``<out>/benchmark.json``, a figure ``<out>/benchmark.png``
(``<out>`` defaults to ``benchmarks/results``, git-ignored).

Usage::

    OPENBLAS_NUM_THREADS=1 python benchmarks/run.py [--quick] [--repeats N] [--skip-dag] [--out DIR]

Times are medians of ``--repeats`` runs (min-max shown); a setting slower than 20 s per run is run 3 times,
one slower than 60 s once (shown as n=1).
Errors are deterministic for a given seed (``--seed``); they are medians over the simulated axes of
absolute relative errors, i.e. one draw of the estimators' statistical scatter, not an average over many.
"""

from __future__ import annotations

import os

# Per-job numerics must not start BLAS threads (docs performance.md); set before numpy is imported.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import json
import math
import shlex
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))  # sibling helper modules (this folder is not a package)

from timing import Timing, fmt, fmt_s, machine_info, md_table, pct, timed

REPO = HERE.parent
DEG = math.pi / 180.0

# STIM-300-like gyro, the paper's Table 2 spec column (method.md section 8), converted to SI:
#   RW 0.15 deg/sqrt(h)       -> N = 0.15/60 deg/s/sqrt(Hz)            = 4.363e-5 rad/s/sqrt(Hz)
#   sigma_bs 1.5 deg/h, 1500 s -> sigma = 1.5/3600 deg/s                = 7.272e-6 rad/s, T = 1500 s
#   K 2e-2 (deg/h)/sqrt(s)    -> K = 2e-2/3600 deg/s/sqrt(s)           = 9.696e-8 rad/s/sqrt(s)
TRUTH = {"white": 0.15 / 60.0 * DEG, "gm_sigma": 1.5 / 3600.0 * DEG, "gm_T": 1500.0,
         "random_walk": 2e-2 / 3600.0 * DEG}
FIT_COMPONENTS = ("white", "gauss_markov", "random_walk")  # the paper's model (its eq. 17)


@dataclass(frozen=True)
class Sizes:
    """Record length and rates of one benchmark scale."""

    name: str
    duration_s: float
    rate: float
    rates: tuple  # decimation rates of the PSD/bound path, Hz
    n_axes: int

    @property
    def n(self) -> int:
        return round(self.duration_s * self.rate)

    # PSD windows: the paper's 7 h windows every 10 h on a 10 h record, and a 1 h Welch at 50 % overlap;
    # as fractions of the record so that the quick scale keeps the same shape.
    @property
    def windows(self) -> dict:
        d = self.duration_s
        return {"paper 7h/10h": (0.7 * d, 1.0 * d), "Welch 1h 50%": (0.1 * d, 0.05 * d)}


PAPER = Sizes("paper scale: 10 h at 125 Hz", 36000.0, 125.0, (125.0, 25.0, 5.0, 1.0), 3)
QUICK = Sizes("quick: 1 h at 25 Hz (smoke test; windows scaled to the record)", 3600.0, 25.0, (25.0, 5.0, 1.0), 2)


# ---------------------------------------------------------------------------------------------
# truth and input
# ---------------------------------------------------------------------------------------------
def truth_model(rate: float):
    from imupipe.models import NoiseModel

    return NoiseModel(white=TRUTH["white"], gauss_markov=((TRUTH["gm_sigma"], TRUTH["gm_T"]),),
                      random_walk=TRUTH["random_walk"], dt=1.0 / rate)


def relerr(est, true) -> float:
    """|est/true - 1|; NaN when the estimate is missing (None: the method found no value)."""
    if est is None or true == 0:
        return math.nan
    est = float(est)
    return abs(est / true - 1.0) if math.isfinite(est) else math.nan


def nanmedian(values) -> float:
    a = np.asarray([v for v in values if v is not None], dtype=float)
    a = a[np.isfinite(a)]
    return float(np.median(a)) if a.size else math.nan


def n_missing(values) -> int:
    return sum(1 for v in values if v is None or not math.isfinite(float(v)))


def err_cell(values) -> str:
    """Median over axes of a relative error, with the number of axes where the method gave no value."""
    med = nanmedian(values)
    miss = n_missing(values)
    cell = pct(med) if math.isfinite(med) else "n/a"
    return cell + (f" ({miss}/{len(values)} none)" if miss else "")


def warm_up(truth, rate: float) -> float:
    """Call every timed function once on a small record so that lazy imports (xarray, scipy.special,
    scipy.optimize) and first-call costs are not charged to the first timed setting; returns seconds."""
    t0 = time.perf_counter()
    from imupipe.allan import allan_variance
    from imupipe.bound import bound_psd
    from imupipe.identify import fit_allan, slope_line
    from imupipe.simulate import simulate
    from imupipe.spectra import decimate, psd

    x = simulate(truth, 20000, rate, np.random.default_rng(0))
    ds = allan_variance(x, rate, taus="octave")
    fit_allan(ds["tau"].values, ds["avar"].values, ds["edf"].values, components=FIT_COMPONENTS, n_boot=0)
    slope_line(ds["tau"].values, np.sqrt(ds["avar"].values))
    y, r = decimate(x, rate, rate / 5)
    p = psd(y, r, window_s=0.5 * y.size / r, step_s=0.25 * y.size / r)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        bound_psd(p["frequency"].values, p["psd"].values[None, :], dt=1 / r, keep=FIT_COMPONENTS,
                  edf=p["edf"].values)
    try:
        import allantools

        allantools.oadev(x, rate=rate, data_type="freq", taus=ds["tau"].values)
    except ImportError:
        pass
    return time.perf_counter() - t0


# ---------------------------------------------------------------------------------------------
# section 1: Allan variance against allantools
# ---------------------------------------------------------------------------------------------
def tau_settings(sizes: Sizes):
    """(label, series key, taus argument) of the three tau grids a user can choose."""
    return [
        ("octave", "full", "octave"),
        ("10/decade", "full", 10),
        ("all (1 Hz series)", "1Hz", "all"),
    ]


def bench_allan(series, sizes: Sizes, truth, repeats: int, record: dict):
    """AV time (imupipe, allantools) and error against the exact AV, per tau grid."""
    from imupipe.allan import allan_variance, overlapping_avar, tau_grid

    try:
        import allantools
    except ImportError:
        allantools = None
    rows, out = [], {}
    for label, key, taus in tau_settings(sizes):
        xs, rate = series[key]
        x0 = xs[0]
        grid = tau_grid(x0.size, rate, taus)
        t_api, ds0 = timed(lambda x0=x0, rate=rate, taus=taus: allan_variance(x0, rate, taus=taus), repeats)
        t_core, _ = timed(lambda x0=x0, rate=rate, m=grid.m: overlapping_avar(x0, rate, m), repeats)
        avs = [ds0] + [allan_variance(x, rate, taus=taus) for x in xs[1:]]
        exact = truth.avar(grid.tau)
        rel = np.abs(np.stack([d["avar"].values for d in avs]) / exact - 1.0)
        entry = {"n_taus": int(grid.m.size), "rate": rate, "imupipe_allan_variance": t_api.to_dict(),
                 "imupipe_overlapping_avar": t_core.to_dict(),
                 "av_relerr_median": float(np.median(rel)), "av_relerr_max": float(np.max(rel))}
        if allantools is not None:
            def peer(x0=x0, rate=rate, tau=grid.tau):
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    return allantools.oadev(x0, rate=rate, data_type="freq", taus=tau)

            t_peer, res = timed(peer, repeats)
            t_at, dev_at = np.asarray(res[0]), np.asarray(res[1])
            common = np.isin(np.rint(t_at * rate).astype(np.int64), grid.m)
            av_at = dev_at[common] ** 2
            av_ip = ds0["avar"].values[np.isin(grid.m, np.rint(t_at * rate).astype(np.int64))]
            agree = float(np.max(np.abs(av_ip / av_at - 1.0))) if av_at.size else math.nan
            entry.update(allantools=t_peer.to_dict(), n_taus_allantools=int(common.sum()),
                         agreement_max_rel=agree, speedup_api=t_peer.median / t_api.median,
                         speedup_core=t_peer.median / t_core.median)
        else:
            t_peer, agree = Timing(), math.nan
        out[label] = entry
        rows.append([
            label, f"{fmt(rate)} Hz, {grid.m.size}", f"{t_api.cell()}; 1st {fmt_s(t_api.values[0])}",
            t_core.cell(), t_peer.cell(),
            fmt(entry.get("speedup_api", math.nan), 3) + "x", fmt(entry.get("speedup_core", math.nan), 3) + "x",
            f"{pct(entry['av_relerr_median'])} / {pct(entry['av_relerr_max'])}", fmt(agree, 2),
        ])
        record.setdefault("_avs", {})[label] = (grid, avs, rate)
    table = md_table(
        ["tau grid", "series, taus", "imupipe allan_variance", "imupipe overlapping_avar", "allantools oadev",
         "speed-up (API)", "speed-up (estimator)", "AV error vs exact, median / max", "max rel. diff to allantools"],
        rows,
    )
    return table, out


# ---------------------------------------------------------------------------------------------
# section 2: identification (fit_allan) and the slope-line peer
# ---------------------------------------------------------------------------------------------
def model_av_error(model, truth, tau) -> tuple[float, float]:
    """Median and max over a log tau grid of |AV_model/AV_true - 1|."""
    r = np.abs(model.avar(tau) / truth.avar(tau) - 1.0)
    return float(np.median(r)), float(np.max(r))


def bench_identify(series, sizes: Sizes, truth, repeats: int, record: dict):
    from imupipe.identify import fit_allan, slope_line

    rows, out = [], {}
    tau_eval = np.logspace(math.log10(1.0 / sizes.rate), math.log10(sizes.duration_s / 4.0), 60)
    for label, _key, _taus in tau_settings(sizes):
        _grid, avs, rate = record["_avs"][label]
        t_av = Timing(record["allan"][label]["imupipe_allan_variance"]["values_s"])
        for n_gm in (1, 2):
            def fit(ds, n_gm=n_gm, rate=rate):
                return fit_allan(ds["tau"].values, ds["avar"].values, ds["edf"].values,
                                 components=FIT_COMPONENTS, n_gm=n_gm, n_boot=0, dt=1.0 / rate)

            t_fit, _ = timed(lambda fit=fit, ds=avs[0]: fit(ds), repeats)
            fits = [fit(ds) for ds in avs]
            e = {"white": [], "random_walk": [], "gm_sigma": [], "gm_T": [], "av_med": [], "av_max": []}
            for f in fits:
                p = f.params
                e["white"].append(relerr(p.get("white"), TRUTH["white"]))
                e["random_walk"].append(relerr(p.get("random_walk"), TRUTH["random_walk"]))
                # GM: the term with the largest sigma (the one that stands for the true GM term)
                gms = [(p.get(f"gm_sigma_{i}"), p.get(f"gm_T_{i}")) for i in range(1, n_gm + 1)]
                gms = [g for g in gms if g[0] is not None and g[0] > 0 and math.isfinite(g[1])]
                s, T = max(gms) if gms else (None, None)
                e["gm_sigma"].append(relerr(s, TRUTH["gm_sigma"]))
                e["gm_T"].append(relerr(T, TRUTH["gm_T"]))
                med, mx = model_av_error(f.model, truth, tau_eval)
                e["av_med"].append(med)
                e["av_max"].append(mx)
            name = f"fit_allan, {n_gm} GM"
            out[f"{label} | {name}"] = {"t_av": t_av.to_dict(), "t_fit": t_fit.to_dict(),
                                        "errors_per_axis": e}
            rows.append([label, name, t_av.cell(), t_fit.cell(), err_cell(e["white"]),
                         err_cell(e["random_walk"]), err_cell(e["gm_sigma"]), err_cell(e["gm_T"]),
                         f"{pct(nanmedian(e['av_med']))} / {pct(nanmedian(e['av_max']))}"])
        # the peers' slope-line reading on the same AV
        t_sl, _ = timed(lambda ds=avs[0]: slope_line(ds["tau"].values, np.sqrt(ds["avar"].values)), repeats)
        sls = [slope_line(ds["tau"].values, np.sqrt(ds["avar"].values)) for ds in avs]
        ew = [relerr(s.get("white"), TRUTH["white"]) for s in sls]
        ek = [relerr(s.get("random_walk"), TRUTH["random_walk"]) for s in sls]
        out[f"{label} | slope line"] = {"t_av": t_av.to_dict(), "t_fit": t_sl.to_dict(),
                                        "errors_per_axis": {"white": ew, "random_walk": ek}}
        rows.append([label, "slope line (peers: IEEE/Kalibr/MATLAB)", t_av.cell(), t_sl.cell(), err_cell(ew),
                     err_cell(ek), "n/a (no GM)", "n/a", "n/a"])
    table = md_table(
        ["tau grid", "method", "AV time (1 axis)", "fit time (1 axis)", "N error", "K error", "GM sigma error",
         "GM T error", "model AV error, median / max over log tau"],
        rows,
    )
    return table, out


# ---------------------------------------------------------------------------------------------
# section 3: decimation, PSD windows, bound modes, GM terms
# ---------------------------------------------------------------------------------------------
def bound_settings(sizes: Sizes):
    """(rate, window label, mode, n_gm): decimation rates with the paper's settings, then every window x mode
    x GM-count combination at the lowest rate (the paper's 1 Hz)."""
    low = sizes.rates[-1]
    out = [(r, "paper 7h/10h", "raw", 1) for r in sizes.rates[:-1]]
    for w in sizes.windows:
        for mode in ("raw", "smoothed", "confidence"):
            for n_gm in (1, 2):
                out.append((low, w, mode, n_gm))
    return out


def bench_bound(raw_axes, sizes: Sizes, truth, repeats: int, record: dict):
    from imupipe.bound import bound_psd
    from imupipe.spectra import decimate, psd

    f_lo = 1.0 / sizes.windows["paper 7h/10h"][0]
    f_hi = 0.5 * sizes.rates[-1]
    f_eval = np.logspace(math.log10(f_lo), math.log10(f_hi), 400)  # common band of every setting
    s_true = truth.psd(f_eval)
    cache_dec, cache_psd = {}, {}
    rows, out = [], {}
    for rate, wlabel, mode, n_gm in bound_settings(sizes):
        if rate not in cache_dec:
            if rate == sizes.rate:
                t_dec, dec = Timing([0.0] * repeats), list(raw_axes)
            else:
                t_dec, dec = timed(lambda rate=rate: [decimate(x, sizes.rate, rate)[0] for x in raw_axes], repeats)
            cache_dec[rate] = (t_dec, dec)
        t_dec, dec = cache_dec[rate]
        if (rate, wlabel) not in cache_psd:
            win, step = sizes.windows[wlabel]
            t_psd, pss = timed(lambda rate=rate, win=win, step=step, dec=dec:
                               [psd(x, rate, window_s=win, step_s=step) for x in dec], repeats)
            cache_psd[(rate, wlabel)] = (t_psd, pss)
        t_psd, pss = cache_psd[(rate, wlabel)]
        freq = pss[0]["frequency"].values
        curves = np.stack([p["psd"].values for p in pss])
        edf = pss[0]["edf"].values

        def run_bound(mode=mode, n_gm=n_gm, rate=rate, freq=freq, curves=curves, edf=edf):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                return bound_psd(freq, curves, spec_model=None, dt=1.0 / rate, mode=mode, n_gm=n_gm,
                                 keep=FIT_COMPONENTS, edf=edf, taper="hann")

        t_bound, res = timed(run_bound, repeats)
        ratio = res.model.psd(f_eval) / s_true
        loose = float(np.mean(ratio))
        true_margin = float(np.min(ratio))
        total = t_dec.median + t_psd.median + t_bound.median
        key = f"{fmt(rate)} Hz | {wlabel} | {mode} | {n_gm} GM"
        out[key] = {"t_decimate": t_dec.to_dict(), "t_psd": t_psd.to_dict(), "t_bound": t_bound.to_dict(),
                    "total_median_s": total, "looseness_vs_true": loose, "margin_vs_true": true_margin,
                    "margin_vs_targets": res.margin, "raw_margin": res.raw_margin, "bounded_samples": bool(res.bounded),
                    "n_frequencies": int(freq.size), "n_lp": int(res.n_lp),
                    "model": {"white": res.model.white, "gauss_markov": [list(g) for g in res.model.gauss_markov],
                              "random_walk": res.model.random_walk}}
        rows.append([fmt(rate) + " Hz", wlabel, mode, n_gm, f"{freq.size - 1}", t_dec.cell(), t_psd.cell(),
                     t_bound.cell(), fmt_s(total), fmt(loose, 3), fmt(true_margin, 3),
                     f"{fmt(res.raw_margin, 3)} ({'yes' if res.bounded else 'NO'})"])
    table = md_table(
        ["rate", "PSD window", "bound mode", "GM", "bins x curves", "decimate (all axes)", "PSD (all axes)",
         "bound", "total (medians)", "looseness vs true PSD", "margin vs true PSD",
         "margin vs raw periodograms (own targets bounded?)"],
        [r[:4] + [f"{r[4]} x {sizes.n_axes}"] + r[5:] for r in rows],
    )
    # the Welch peer: scipy.signal.welch on the same 1 Hz input and paper settings (one-sided -> /2)
    peer = None
    try:
        import scipy.signal

        low = sizes.rates[-1]
        x1 = cache_dec[low][1][0]
        win, step = sizes.windows["paper 7h/10h"]
        nper, nstep = round(win * low), round(step * low)
        t_ip, p_ip = timed(lambda: psd(x1, low, window_s=win, step_s=step), repeats)
        if nstep >= nper:  # scipy cannot skip samples between segments: give it the segments we use
            k = (x1.size - nper) // nstep + 1
            segs = np.concatenate([x1[i * nstep: i * nstep + nper] for i in range(k)])
            t_sp, (_, p_sp) = timed(lambda: scipy.signal.welch(segs, fs=low, window="hann", nperseg=nper,
                                                               noverlap=0, detrend="constant"), repeats)
        else:
            t_sp, (_, p_sp) = timed(lambda: scipy.signal.welch(x1, fs=low, window="hann", nperseg=nper,
                                                               noverlap=nper - nstep, detrend="constant"), repeats)
        s2 = p_ip["psd"].values
        interior = slice(1, -1)
        diff = float(np.max(np.abs(s2[interior] / (0.5 * p_sp[interior]) - 1.0)))
        peer = {"imupipe": t_ip.to_dict(), "scipy": t_sp.to_dict(), "max_rel_diff": diff}
        out["_welch_peer"] = peer
        table += "\n\n" + md_table(
            ["PSD peer (1 axis, lowest rate, paper window)", "imupipe.spectra.psd (with xarray + confidence)",
             "scipy.signal.welch", "max rel. diff (interior bins)"],
            [["same input and settings", t_ip.cell(), t_sp.cell(), fmt(diff, 2)]],
        )
    except ImportError:
        pass
    return table, out


# ---------------------------------------------------------------------------------------------
# figure
# ---------------------------------------------------------------------------------------------
def plot(results: dict, path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(14, 10))
    ax = axes[0, 0]
    av = results.get("allan") or {}
    if av:
        labels = list(av)
        xpos = np.arange(len(labels))
        ip = [av[k]["imupipe_allan_variance"]["median_s"] for k in labels]
        core = [av[k]["imupipe_overlapping_avar"]["median_s"] for k in labels]
        at = [av[k].get("allantools", {}).get("median_s", np.nan) for k in labels]
        ax.bar(xpos - 0.27, ip, 0.27, label="imupipe allan_variance")
        ax.bar(xpos, core, 0.27, label="imupipe overlapping_avar")
        ax.bar(xpos + 0.27, at, 0.27, label="allantools oadev")
        ax.set_xticks(xpos, [f"{k}\n({av[k]['n_taus']} taus)" for k in labels])
        ax.set_yscale("log")
        ax.set_ylabel("wall time per axis (s), median")
        ax.legend(fontsize=8)
    ax.set_title("Allan variance: imupipe vs allantools, same taus")

    ax = axes[0, 1]
    ident = results.get("identify") or {}
    for key, v in ident.items():
        grid, method = key.split(" | ")
        t = v["t_av"]["median_s"] + v["t_fit"]["median_s"]
        e = v["errors_per_axis"]
        err = nanmedian(e.get("av_med", [])) if "av_med" in e else nanmedian(e["white"] + e["random_walk"])
        if not math.isfinite(err):
            continue
        marker = "s" if "slope" in method else ("o" if "1 GM" in method else "^")
        ax.scatter(t, err, marker=marker)
        ax.annotate(f"{grid}, {method.replace('fit_allan, ', '')}", (t, err), fontsize=7)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("AV + fit wall time per axis (s), median")
    ax.set_ylabel("relative error (fit: model AV median; slope line: median of N, K)")
    ax.set_title("identification: speed against error")

    ax = axes[1, 0]
    bd = {k: v for k, v in (results.get("bound") or {}).items() if not k.startswith("_")}
    for key, v in bd.items():
        rate, w, mode, gm = key.split(" | ")
        marker = {"raw": "o", "smoothed": "s", "confidence": "^"}[mode]
        color = "C0" if w.startswith("paper") else "C1"
        ax.scatter(v["total_median_s"], v["looseness_vs_true"], marker=marker, color=color,
                   edgecolor="k" if v["margin_vs_true"] < 1 else None)
        ax.annotate(f"{rate}, {mode}, {gm}", (v["total_median_s"], v["looseness_vs_true"]), fontsize=7)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("decimate + PSD + bound wall time (s), median")
    ax.set_ylabel("looseness: mean over log f of bound PSD / true PSD")
    ax.set_title("PSD bound: blue paper window, orange Welch 1 h; o raw, s smoothed, ^ confidence\n"
                 "(black edge: bound below the true PSD somewhere)", fontsize=9)

    ax = axes[1, 1]
    dag = results.get("dag") or {}
    per_rule = dag.get("per_rule") or {}
    if per_rule:
        names = list(per_rule)
        y = np.arange(len(names))
        ax.barh(y - 0.2, [per_rule[r]["sum_s"] for r in names], 0.4, label="sum of job wall times (s)")
        ax2 = ax.twiny()
        ax2.barh(y + 0.2, [per_rule[r].get("peak_rss_mb", np.nan) or np.nan for r in names], 0.4, color="C3",
                 label="peak RSS (MB)")
        ax.set_yticks(y, names, fontsize=8)
        ax.set_xlabel("sum of job wall times per rule (s), cold run")
        ax2.set_xlabel("peak RSS per rule (MB, red)")
        ax.legend(loc="lower right", fontsize=8)
    else:
        ax.text(0.5, 0.5, dag.get("skipped", "DAG not measured"), ha="center", va="center", wrap=True)
        ax.set_axis_off()
    ax.set_title("Snakemake DAG per rule (cold run)")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ---------------------------------------------------------------------------------------------
# targets
# ---------------------------------------------------------------------------------------------
def targets(results: dict, sizes: Sizes) -> list:
    """(name, measured value, PASS/FAIL/NOT MEASURED, how it was measured)."""
    out = []
    dag = results.get("dag") or {}
    if dag.get("cold"):
        floor = dag.get("floor") or {}
        cold = dag["cold"]["median_s"]
        fl = floor.get("total_s", math.nan)
        ok = cold <= 3.0 * fl
        out.append(("cold paper-scale run <= 3x floor", f"{fmt_s(cold)} = {fmt(cold / fl, 3)}x floor {fmt_s(fl)}",
                    "PASS" if ok else "FAIL", floor.get("formula", "")))
    else:
        out.append(("cold paper-scale run <= 3x floor", "n/a", "NOT MEASURED", dag.get("skipped", "")))
    if dag.get("spec_rerun"):
        t = dag["spec_rerun"]["median_s"]
        out.append(("spec-sheet rerun <= 5 s", fmt_s(t), "PASS" if t <= 5.0 else "FAIL",
                    f"{dag.get('spec_rerun_jobs', '?')} jobs re-run after editing {dag.get('spec_file', '?')}"))
    else:
        out.append(("spec-sheet rerun <= 5 s", "n/a", "NOT MEASURED", dag.get("skipped", "")))
    for label, v in (results.get("allan") or {}).items():
        if "speedup_api" in v:
            s = v["speedup_api"]
            out.append((f"AV >= 10x allantools ({label}, {v['n_taus']} taus)",
                        f"{fmt(s, 3)}x (estimator alone {fmt(v['speedup_core'], 3)}x)",
                        "PASS" if s >= 10.0 else "FAIL", "imupipe.allan.allan_variance vs allantools.oadev"))
    mem = dag.get("axis_memory")
    if mem:
        ratio = mem["peak_rss_mb"] / mem["raw_mb"]
        measured = (f"{fmt(mem['peak_rss_mb'], 3)} MB = {fmt(ratio, 3)}x {fmt(mem['raw_mb'], 3)} MB "
                    f"(rule {mem['rule']})")
        out.append(("peak RSS of an axis job <= 4x its raw data", measured, "PASS" if ratio <= 4.0 else "FAIL",
                    mem["source"]))
    else:
        out.append(("peak RSS of an axis job <= 4x its raw data", "n/a", "NOT MEASURED",
                    dag.get("skipped", "no per-job memory available")))
    return out


# ---------------------------------------------------------------------------------------------
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="small sizes (1 h at 25 Hz, 2 axes): the smoke test")
    ap.add_argument("--repeats", type=int, default=5, help="runs per timed setting (default 5)")
    ap.add_argument("--skip-dag", action="store_true", help="do not run the Snakemake DAG benchmark")
    ap.add_argument("--dag-repeats", type=int, default=3, help="cold runs and spec reruns of the DAG (default 3)")
    ap.add_argument("--cores", type=int, default=2, help="Snakemake --cores for the DAG benchmark (default 2)")
    ap.add_argument("--axes", type=int, default=None, help="simulated axes (default 3; quick 2)")
    ap.add_argument("--seed", type=int, default=20211101, help="seed of the simulated records")
    ap.add_argument("--out", type=Path, default=HERE / "results", help="output folder (default benchmarks/results)")
    ap.add_argument("--keep-scratch", action="store_true", help="keep the DAG's scratch copy of the workflow")
    args = ap.parse_args(argv)

    sizes = QUICK if args.quick else PAPER
    if args.axes:
        sizes = Sizes(sizes.name, sizes.duration_s, sizes.rate, sizes.rates, args.axes)
    args.out.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    command = "OPENBLAS_NUM_THREADS={} python benchmarks/run.py {}".format(
        os.environ.get("OPENBLAS_NUM_THREADS"), " ".join(shlex.quote(a) for a in (argv or sys.argv[1:])))
    results = {"command": command, "machine": machine_info(), "sizes": sizes.__dict__, "truth_SI": TRUTH}
    md = ["# imupipe benchmark: speed against error", "", f"Command: `{command}`", ""]
    md += ["Machine: " + "; ".join(f"{k} {v}" for k, v in results["machine"].items()), ""]
    md += [(f"Input: {sizes.name}; {sizes.n_axes} independent simulated axes of {sizes.n} samples "
            f"({sizes.n * 8 / 1e6:.3g} MB float64 each) from a STIM-300-like gyro model (paper Table 2 spec: "
            f"N {fmt(TRUTH['white'])} rad/s/sqrt(Hz), GM sigma {fmt(TRUTH['gm_sigma'])} rad/s and T "
            f"{fmt(TRUTH['gm_T'])} s, K {fmt(TRUTH['random_walk'])} rad/s/sqrt(s)), seed {args.seed}. "
            f"Times: median [min-max] of {args.repeats} runs. Errors: median over the axes of |estimate/true - 1| "
            "(one draw of the statistical scatter)."), ""]

    def section(title, note=""):
        md.extend([f"## {title}", ""] + ([note, ""] if note else []))

    record: dict = {}
    try:
        from imupipe.simulate import simulate
        from imupipe.spectra import decimate

        truth = truth_model(sizes.rate)
        rng = np.random.default_rng(args.seed)
        t_sim = time.perf_counter()
        raw_axes = [np.asarray(simulate(truth, sizes.n, sizes.rate, rng), dtype=np.float64)
                    for _ in range(sizes.n_axes)]
        t_sim = time.perf_counter() - t_sim
        results["simulate_s_all_axes"] = t_sim
        t_warm = warm_up(truth, sizes.rate)
        md += [(f"Simulation of the input (not compared with anything): {fmt_s(t_sim)} for {sizes.n_axes} axes; "
                f"warm-up of every timed function on a small record (lazy imports, first calls; untimed): "
                f"{fmt_s(t_warm)}."), ""]
        low = sizes.rates[-1]
        series = {"full": (raw_axes, sizes.rate),
                  "1Hz": ([decimate(x, sizes.rate, low)[0] for x in raw_axes], low)}
    except ImportError as exc:
        truth = None
        md += [f"**Library sections not measured**: {exc} (module not in the tree yet).", ""]

    if truth is not None:
        section("1. Allan variance: imupipe against allantools (same input, same taus)",
                "Time per axis. 'API' = imupipe.allan.allan_variance (sums + noise identification + EDF + "
                "xarray Dataset; '1st' = its first full-size call in this process, the one call a workflow job makes); "
                "'estimator' = imupipe.allan.overlapping_avar (the sums alone). allantools.oadev "
                "also returns its (simpler) error bars. AV error = |AV_hat/AV_exact - 1| over taus and axes "
                "(statistical scatter of the estimator, identical for both); last column: numerical agreement.")
        table, results["allan"] = bench_allan(series, sizes, truth, args.repeats, record)
        record["allan"] = results["allan"]
        md += [table, ""]
        print("\n".join(md), flush=True)
        md_start = len(md)

        section("2. Identification: fit_allan against the slope-line reading, per tau grid and GM terms",
                f"Components fitted: {', '.join(FIT_COMPONENTS)} (the paper's model; truth has 1 GM term); "
                "n_boot=0 (the bootstrap multiplies the fit time by about n_boot). Errors are relative to the "
                "truth; with 2 GM terms, sigma/T are those of the largest-sigma term. 'none' counts axes where the "
                "method returned no value (e.g. K fitted as 0, or no +1/2 slope found). Model AV error over "
                "60 log-spaced taus from 1/rate to a quarter of the record.")
        table, results["identify"] = bench_identify(series, sizes, truth, args.repeats, record)
        md += [table, ""]

        section("3. PSD and bound path: decimation, windows, bound mode, GM terms",
                f"Sample PSDs of the {sizes.n_axes} axes (two-sided, imupipe.spectra.psd, Hann, constant detrend) "
                "bounded together by imupipe.bound.bound_psd (white + GM + random walk, no spec sheet so that the "
                "bound is data-driven). Looseness = mean over 400 log-spaced frequencies of bound PSD / true PSD, "
                f"on the band common to every setting ({fmt(1 / sizes.windows['paper 7h/10h'][0], 3)} Hz to "
                f"{fmt(0.5 * sizes.rates[-1])} Hz); margin vs true PSD = min of that ratio (< 1: the bound "
                "is below the truth somewhere); margin vs raw periodograms = min of bound / sample PSD over every "
                "ordinate (>= 1 in raw mode; smoothed and confidence modes bound band averages or their upper "
                "limits, so < 1 by design), and whether the bound holds against its own mode's targets.")
        table, results["bound"] = bench_bound(series["full"][0], sizes, truth, args.repeats, record)
        md += [table, ""]
        print("\n".join(md[md_start:]), flush=True)
        md_start = len(md)
    else:
        md_start = len(md)

    section("4. Whole workflow (Snakemake DAG)")
    if args.skip_dag:
        results["dag"] = {"skipped": "skipped (--skip-dag)"}
        md += ["Not measured: --skip-dag.", ""]
    else:
        import dag as dagbench

        results["dag"] = dagbench.run(REPO, args.out, cores=args.cores, repeats=args.dag_repeats,
                                      keep_scratch=args.keep_scratch)
        md += [results["dag"]["markdown"], ""]

    section("Targets")
    rows = targets(results, sizes)
    results["targets"] = [dict(zip(("target", "measured", "verdict", "how"), r)) for r in rows]
    md += [md_table(["target", "measured", "verdict", "how"], rows), ""]
    results["total_benchmark_s"] = time.perf_counter() - t_start
    md += [f"Benchmark wall time: {fmt_s(results['total_benchmark_s'])}.", ""]
    print("\n".join(md[md_start:]), flush=True)

    (args.out / "benchmark.md").write_text("\n".join(md))
    results.pop("_avs", None)
    (args.out / "benchmark.json").write_text(json.dumps(results, indent=1, default=_json_default))
    plot(results, args.out / "benchmark.png", f"imupipe benchmark ({sizes.name}); {results['machine']['cpu']}")
    print(f"wrote {args.out / 'benchmark.md'}, benchmark.json, benchmark.png", flush=True)
    return 0


def _json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    return str(o)


if __name__ == "__main__":
    sys.exit(main())
