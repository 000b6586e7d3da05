"""`imupipe plan` against simulation: predicted median half-widths of N, B and K vs the simulated ones.

For each truth (the STIM-300-like default truth and a MEMS-like one defined here) and record length, simulate
`--n` single-axis records (imupipe.simulate.simulate, fixed seeds), compute each record's Allan variance as the
workflow does (imupipe.allan.allan_variance, octave grid), run the same identification call the plan uses
(imupipe.plan.identify_intervals: fit_allan with the truth's components, 100 correlated-bootstrap replicates
(--n-boot), 95 %) and take the median half-width of each interval; the plan (imupipe.plan.predict, 1 record,
1 axis) predicts it from the expected Allan variance, and where that fit finds an interval one-sided or
confounded (column ~) from the median over --replicates replicate AV curves. Prints a markdown table (ratio = predicted / simulated median,
the goal 0.75-1.25; the expected-curve value beside it); with --figure it
draws imupipe.plot.plot_plan_check. One truth per process (two cores), then the table and figure of both:

    nice python benchmarks/plan_check.py --n 50 --truth stim300_like --json stim.json
    nice python benchmarks/plan_check.py --n 50 --truth mems_like --json mems.json
    python benchmarks/plan_check.py --load stim.json mems.json --figure docs/figures/plan_check_gyro.png
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from imupipe.allan import allan_variance
from imupipe.plan import N_BOOT, PARAMS, fit_components, half_widths, identify_intervals, predict
from imupipe.simulate import simulate
from imupipe.specsheet import load_spec, parse_spec

#: A MEMS-class gyro (consumer/industrial MEMS levels: N 0.4 deg/sqrt(h), a 10 deg/h bias wander over 100 s, a
#: random walk 0.2 (deg/h)/sqrt(s)); SI values come from imupipe.specsheet like any sheet.
MEMS_LIKE = {"name": "MEMS-like gyro (plan check)",
             "gyro": {"white": {"value": 0.4, "unit": "deg/sqrt(h)"},
                      "gauss_markov": [{"sigma": {"value": 10.0, "unit": "deg/h"}, "T": {"value": 100.0, "unit": "s"}}],
                      "random_walk": {"value": 0.2, "unit": "(deg/h)/sqrt(s)"}}}


def truths():
    return {"stim300_like": load_spec("config/truth/stim300_like.yaml").models["gyro"],
            "mems_like": parse_spec(MEMS_LIKE, "plan_check.MEMS_LIKE").models["gyro"],
            # the spec sheet's own model as a truth: its GM (T = 1500 s) confounded with K over 2-20 h
            "stim300_spec": load_spec("config/specs/stim300.yaml").models["gyro"]}


def simulated(model, hours, rate, n_rec, seed, records=1, n_boot=N_BOOT):
    """Half-widths (SI) of `n_rec` simulated sets of `records` pooled single-axis records, shape (n_rec, 3)."""
    n = int(round(hours * 3600 * rate))
    comps = fit_components(model)
    out = []
    for i in range(n_rec):
        curves = []
        for j in range(records):
            x = simulate(model, n, rate, rng=seed + i * records + j)
            av = allan_variance(x, rate)
            curves.append((av.tau.values, av.avar.values, av.edf.values))
        fit = identify_intervals(curves, n, rate, comps, n_boot=n_boot)
        out.append([half_widths(fit, model)[p] for p in PARAMS])
    return np.array(out)


def _print(rows):
    print("| truth | hours | records | param | ~ | expected curve (ratio) | predicted | simulated median (IQR) | "
          "ratio | sets |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        e = r.get("expected", r["predicted"])
        print(f"| {r['truth']} | {r['hours']:g} | {r['records']} | {r['param']} | "
              f"{'~' if r.get('confounded') else ''} | {e:.3g} ({e / r['simulated']:.2f}) | {r['predicted']:.3g} | "
              f"{r['simulated']:.3g} ({r['q25']:.3g}-{r['q75']:.3g}) | {r['ratio']:.2f} | {r['n']} |", flush=True)


def _predict_rows(models, rows, rate, replicates, n_boot=N_BOOT):
    """The plan's prediction for each (truth, hours, records) of `rows`: the expected-curve value (`expected`),
    the plan's value with `replicates` for ~ cells (`predicted`, `ratio`) and the ~ flag (`confounded`)."""
    for key in dict.fromkeys((r["truth"], r["hours"], r["records"]) for r in rows):
        p0 = predict(models[key[0]], key[1], key[2], rate, n_boot=n_boot)
        pr = (predict(models[key[0]], key[1], key[2], rate, replicates=replicates, n_boot=n_boot) if replicates
              else p0)
        for r in rows:
            if (r["truth"], r["hours"], r["records"]) == key:
                r["confounded"] = bool(p0["confounded"][r["param"]])
                r["expected"] = p0["half_width"][r["param"]]
                r["predicted"] = pr["half_width"][r["param"]]
                r["ratio"] = r["predicted"] / r["simulated"]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=50, help="simulated record sets per cell")
    ap.add_argument("--rate-hz", type=float, default=5.0)
    ap.add_argument("--hours", type=float, nargs="+", default=[2.0, 6.0, 20.0])
    ap.add_argument("--records", type=int, default=1, help="records pooled in each simulated set (and the plan)")
    ap.add_argument("--replicates", type=int, default=50,
                    help="the plan's replicates for one-sided or confounded cells (imupipe.plan.predict)")
    ap.add_argument("--n-boot", type=int, default=N_BOOT, help="bootstrap replicates of each identification, "
                    "simulated and predicted alike (default: the plan's, 100)")
    ap.add_argument("--truth", nargs="+", default=None, help="truth names (default: stim300_like mems_like)")
    ap.add_argument("--json", default=None, help="write the numbers here")
    ap.add_argument("--figure", default=None, help="write the figure here (PNG)")
    ap.add_argument("--load", nargs="+", default=None,
                    help="JSON files of earlier runs (--json): print their table (with the plan's ~ flag) and draw "
                    "--figure from them, no simulation")
    a = ap.parse_args(argv)
    models = truths()
    names = a.truth or ["stim300_like", "mems_like"]
    rows = []
    if a.load:
        for path in a.load:
            with open(path) as fh:
                doc = json.load(fh)
            a.rate_hz = doc["rate_hz"]
            rows += [{"records": 1, **r} for r in doc["rows"]]
        names = list(dict.fromkeys(r["truth"] for r in rows))
        a.hours = sorted({r["hours"] for r in rows})
        _predict_rows(models, rows, a.rate_hz, a.replicates, a.n_boot)
        print(f"records at {a.rate_hz:g} Hz; ~: the plan marks the interval one-sided or confounded")
        _print(rows)
    for name in [] if a.load else names:
        ti = list(models).index(name)
        model = models[name]
        for hi, h in enumerate(a.hours):
            t0 = time.process_time()
            sims = simulated(model, h, a.rate_hz, a.n, seed=1000 * (ti + 1) + 100 * hi, records=a.records,
                             n_boot=a.n_boot)
            med = np.nanmedian(sims, axis=0)
            new = []
            for j, p in enumerate(PARAMS):
                new.append({"truth": name, "hours": h, "records": a.records, "param": p, "simulated": float(med[j]),
                            "n": int(np.isfinite(sims[:, j]).sum()),
                            "q25": float(np.nanpercentile(sims[:, j], 25)),
                            "q75": float(np.nanpercentile(sims[:, j], 75))})
            _predict_rows(models, new, a.rate_hz, a.replicates, a.n_boot)
            _print(new)
            rows += new
            print(f"<!-- {name} {h:g} h: {time.process_time() - t0:.0f} s CPU -->", file=sys.stderr, flush=True)
    if a.json:
        with open(a.json, "w") as fh:
            json.dump({"rate_hz": a.rate_hz, "n": a.n, "rows": rows}, fh, indent=1)
    if a.figure:
        from imupipe.plot import plot_plan_check, save_figure

        curves = {}
        for name in names:
            hh = np.geomspace(min(a.hours), max(a.hours), 7)
            curves[name] = {"hours": hh, "half_width": [predict(models[name], h, 1, a.rate_hz,
                                                                replicates=a.replicates)["half_width"] for h in hh]}
        single = [r for r in rows if r.get("records", 1) == 1]  # the figure: one record per set
        save_figure(plot_plan_check(curves, single, sensor="gyro"), a.figure)
    for flag in (False, True):
        sel = [r for r in rows if bool(r.get("confounded")) == flag]
        ok = [r for r in sel if 0.75 <= r["ratio"] <= 1.25]
        print(f"{'~ (one-sided or confounded)' if flag else 'two-sided'}: {len(ok)} of {len(sel)} within 25 %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
