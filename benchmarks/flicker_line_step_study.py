"""Study: simulated records with a known flicker floor, a 0.5 Hz line with sidebands and a mean step (issue 28).

Each record: white noise N + flicker B (+ a random walk K, none by default) drawn by :func:`imupipe.simulate.simulate`,
plus, added here, a 0.5 Hz sinusoid amplitude-modulated at 0.1 Hz (carrier A, sidebands A m / 2 at 0.4 and 0.6 Hz,
random phases) and a mean step of size +-delta at a random time in the middle half of the record. The library
stages run as the workflow runs them:

1. events (:func:`imupipe.events.detect_events`) on the record as read: the step's time against the truth;
2. the record split at the step found (the ``split`` policy: each side analysed as a record; sides shorter than
   :data:`MIN_SIDE_S` are left out);
3. per side the lines (:func:`imupipe.lines.find_lines` at the workflow's resolution) and the overlapping Allan
   variance (octave taus), the lines' Allan variance a known term of the fit (:func:`imupipe.lines.line_avar`);
4. the identification (:func:`imupipe.stages.identify.identify_sensor`, the workflow's components and settings).

The same record without the step (lines kept) goes through 3-4 unsplit: the reference for K (the step must not
move K outside the interval of the same record without it).

Per record the table gives the flicker estimate and interval of the split record, the carrier's amplitude error
(lines stage on the record as read), the step time error, K of the split record and the K interval of the record
without the step. The summary gives, over all records, the coverage of the flicker and white-noise intervals (split
records, and records without the step) against the binomial range of the nominal level: the central 95 % of
Binomial(n, confidence).

Usage::

    OPENBLAS_NUM_THREADS=1 nice python benchmarks/flicker_line_step_study.py --records 50 --seed 101

Units: u (any rate unit), N u/sqrt(Hz), B u, K u/sqrt(s), times s.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from imupipe.allan import allan_variance
from imupipe.events import detect_events
from imupipe.lines import find_lines
from imupipe.models import NoiseModel
from imupipe.simulate import simulate
from imupipe.stages.identify import Curve, identify_sensor

RATE_HZ = 10.0
HOURS = 4.0
WHITE = 1e-3  # N, u/sqrt(Hz)
FLICKER = 2e-4  # B, u: floor 0.664 B = 1.33e-4 u above the white noise's ADEV from tau ~ 60 s
CARRIER_HZ, SIDEBAND_HZ = 0.5, 0.1
CARRIER_AMP = 1e-3  # A, u
MODULATION = 0.6  # m: sidebands of amplitude A m / 2
STEP_FACTOR = 5.0  # delta = 5 N sqrt(Hz): the least-squares change point then has sd sqrt(26) N^2 / delta^2 = 0.2 s
MIN_SIDE_S = 1800.0  # a side of the split shorter than this is left out
COMPONENTS = ["white", "gauss_markov", "flicker", "random_walk", "quantization", "ramp"]  # the workflow's default
LINES_RESOLUTION_HZ = 0.002  # the workflow's lines.resolution_hz


def identify(segments, truth, n_boot, seed):
    """identify_sensor on the segments (each a record: its lines known), as the workflow's identify rule runs."""
    curves, known = [], {}
    for i, x in enumerate(segments):
        label = f"sim/s{i}"
        av = allan_variance(x, RATE_HZ, taus="octave")
        curves.append(Curve(label, av.tau.values, av.avar.values, av.edf.values, x.size, RATE_HZ, "x"))
        known[label] = find_lines(x, RATE_HZ, resolution_hz=LINES_RESOLUTION_HZ).lines
    return identify_sensor(curves, sensor="gyro", components=COMPONENTS, n_gm=1, n_boot=n_boot, confidence=0.95,
                           significance=0.05, relevance=0.05, filter_rate_hz=1.0, outage_s=3600.0,
                           pooling_n_boot=19, truth=truth, seed=seed, lines=known, envelope_lines=True)


def interval(idn, name):
    est = float(idn.selected.params.get(name, 0.0) or 0.0)
    lo, hi = idn.selected.intervals.get(name, (math.nan, math.nan))
    return est, float(lo), float(hi)


def one_record(truth, rng, n_boot):
    n = int(HOURS * 3600 * RATE_HZ)
    t = np.arange(n) / RATE_HZ
    x0 = simulate(truth, n, RATE_HZ, rng)
    ph_c, ph_m = rng.uniform(0, 2 * np.pi, 2)
    x0 += CARRIER_AMP * (1.0 + MODULATION * np.cos(2 * np.pi * SIDEBAND_HZ * t + ph_m)) * np.cos(
        2 * np.pi * CARRIER_HZ * t + ph_c)
    k0 = int(rng.integers(n // 4, 3 * n // 4))
    delta = float(rng.choice([-1.0, 1.0])) * STEP_FACTOR * truth.white  # u (N in u/sqrt(Hz) times 1 sqrt(Hz))
    x = x0.copy()
    x[k0:] += delta
    # 1. events on the record as read
    ev = detect_events(x, RATE_HZ, sensor="gyro")
    steps = [e for e in ev["events"] if e["kind"] == "step"]
    near = min(steps, key=lambda e: abs(e["index"] - k0)) if steps else None
    dt_step = (near["index"] - k0) / RATE_HZ if near else math.nan
    # 2. split at every step found
    cuts = [0] + sorted(e["index"] for e in steps) + [n]
    sides = [x[a:b] for a, b in zip(cuts[:-1], cuts[1:]) if (b - a) / RATE_HZ >= MIN_SIDE_S]
    # line amplitude: the lines stage on the record as read
    found = find_lines(x, RATE_HZ, resolution_hz=LINES_RESOLUTION_HZ).lines
    car = min(found, key=lambda ln: abs(ln.frequency_hz - CARRIER_HZ)) if found else None
    amp_err = (car.amplitude / CARRIER_AMP - 1.0) if car and abs(car.frequency_hz - CARRIER_HZ) < 0.01 else math.nan
    seed = int(rng.integers(1 << 30))
    split = identify(sides, truth, n_boot, seed)
    clean = identify([x0], truth, n_boot, seed)
    return {
        "k0_s": k0 / RATE_HZ, "delta": delta, "n_events": len(ev["events"]), "n_steps": len(steps),
        "dt_step_s": dt_step, "amp_err": amp_err, "n_sides": len(sides),
        "B": interval(split, "flicker"), "N": interval(split, "white"), "K": interval(split, "random_walk"),
        "B0": interval(clean, "flicker"), "N0": interval(clean, "white"), "K0": interval(clean, "random_walk"),
        "kept": split.record["selection"]["kept"], "kept0": clean.record["selection"]["kept"],
    }


def binomial_range(n, p, level=0.95):
    """Central `level` range of Binomial(n, p): (lo, hi) counts with P(X < lo) <= (1 - level)/2 >= P(X > hi)."""
    from scipy.stats import binom

    a = (1.0 - level) / 2.0
    return int(binom.ppf(a, n, p)), int(binom.isf(a, n, p))


def inside(triple, value):
    _, lo, hi = triple
    return bool(lo <= value <= hi)


HEAD = ("| seed | rec | step at s | dt step s | sides | B est [interval] | B in | N in | B in (no step) | "
        "N in (no step) | amp err % | K est | K interval (no step) | K in | kept |")


def yn(flag):
    return "y" if flag else "NO"


def row_text(seed, r, o):
    """One table row of record `r` (:func:`one_record`'s dict)."""
    b, k, k0 = o["B"], o["K"], o["K0"]
    return (f"| {seed} | {r} | {o['k0_s']:.0f} | {o['dt_step_s']:+.2f} | {o['n_sides']} | "
            f"{b[0]:.3g} [{b[1]:.3g}, {b[2]:.3g}] | {yn(inside(b, FLICKER))} | {yn(inside(o['N'], WHITE))} | "
            f"{yn(inside(o['B0'], FLICKER))} | {yn(inside(o['N0'], WHITE))} | {100 * o['amp_err']:+.1f} | "
            f"{k[0]:.3g} | [{k0[1]:.3g}, {k0[2]:.3g}] | {yn(inside(k0, k[0]))} | {','.join(o['kept'])} |")


def summary_text(rows) -> str:
    """The coverage table over the rows: parsed rows (dicts of column -> text, :func:`parse_rows`)."""
    n = len(rows)
    lo, hi = binomial_range(n, 0.95)
    out = [f"over {n} records (nominal 0.95; binomial 95 % range {lo}-{hi} of {n}):",
           "| quantity | split record | record without the step | within the binomial range |", "|---|---|---|---|"]
    for name, col in (("flicker B interval covers the truth", "B in"), ("white N interval covers the truth", "N in")):
        c1 = sum(r[col] == "y" for r in rows)
        c0 = sum(r[col + " (no step)"] == "y" for r in rows)
        out.append(f"| {name} | {c1}/{n} | {c0}/{n} | {yn(lo <= c1 <= hi)} / {yn(lo <= c0 <= hi)} |")
    dts = np.array([float(r["dt step s"]) for r in rows])
    amp = np.array([float(r["amp err %"]) for r in rows])
    out.append(f"| step found within 1 s | {int(np.sum(np.abs(dts) <= 1.0))}/{n} (largest error "
               f"{np.nanmax(np.abs(dts)):.2f} s; not found {int(np.sum(~np.isfinite(dts)))}) | | |")
    out.append(f"| carrier amplitude within 10 % | {int(np.sum(np.abs(amp) <= 10.0))}/{n} (largest error "
               f"{np.nanmax(np.abs(amp)):.1f} %) | | |")
    out.append(f"| K of the split record inside the K interval of the record without the step | "
               f"{sum(r['K in'] == 'y' for r in rows)}/{n} | | |")
    out.append(f"| flicker kept | {sum('flicker' in r['kept'] for r in rows)}/{n} | | |")
    out.append(f"| random walk kept | {sum('random_walk' in r['kept'] for r in rows)}/{n} | | |")
    return "\n".join(out)


def parse_rows(lines):
    """The rows of :data:`HEAD` in printed text (a log of one or several runs), as dicts column -> text."""
    cols = [c.strip() for c in HEAD.strip("|").split("|")]
    rows = []
    for line in lines:
        line = line[:line.rfind("|") + 1]  # without the record's time after the row
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if line.startswith("| ") and len(cells) == len(cols) and cells[0].isdigit():
            rows.append(dict(zip(cols, cells)))
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", type=int, default=50)
    ap.add_argument("--seed", type=int, default=101)
    ap.add_argument("--n-boot", type=int, default=100, help="bootstrap replicates (the workflow's identify.n_boot)")
    ap.add_argument("--random-walk", type=float, default=0.0, help="K of the truth, u/sqrt(s)")
    ap.add_argument("--summarise", nargs="+", metavar="LOG", help="only the coverage table of the rows in these "
                    "logs (runs of this script on other seeds)")
    a = ap.parse_args(argv)
    if a.summarise:
        rows = []
        for path in a.summarise:
            with open(path) as fh:
                rows += parse_rows(fh)
        print(summary_text(rows))
        return rows
    truth = NoiseModel(white=WHITE, flicker=FLICKER, random_walk=a.random_walk)
    rng = np.random.default_rng(a.seed)
    print(f"truth: N = {WHITE:g} u/sqrt(Hz), B = {FLICKER:g} u, K = {a.random_walk:g} u/sqrt(s); {HOURS:g} h at "
          f"{RATE_HZ:g} Hz; line {CARRIER_HZ} Hz A = {CARRIER_AMP:g} u, sidebands +-{SIDEBAND_HZ} Hz "
          f"A m/2 = {CARRIER_AMP * MODULATION / 2:g} u; step +-{STEP_FACTOR * WHITE:.3g} u "
          f"({STEP_FACTOR * WHITE / (0.664 * FLICKER):.3g} x the floor); seed {a.seed}; n_boot {a.n_boot}")
    print(HEAD)
    print("|" + "---|" * (HEAD.count("|") - 1))
    rows, text = [], []
    for r in range(a.records):
        t0 = time.perf_counter()
        o = one_record(truth, rng, a.n_boot)
        rows.append(o)
        text.append(row_text(a.seed, r, o))
        print(text[-1] + f"  ({time.perf_counter() - t0:.0f} s)", flush=True)
    print()
    print(summary_text(parse_rows(text)))
    return rows


if __name__ == "__main__":
    main()
