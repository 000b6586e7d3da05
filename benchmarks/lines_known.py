"""Spectral lines as known terms of the Allan fit, and the record-consistency test, on simulated records.

Part 1 (``--lines N``): N records of 6 h at 10 Hz, white noise 2e-3 u/sqrt(Hz) + a GM (1e-3 u, 30 s) + a 0.5 Hz line
of amplitude 3e-3 u amplitude-modulated at 0.1 Hz (depth 0.6: sidebands 0.9e-3 u at 0.4 and 0.6 Hz) + a 3rd harmonic
of 0.9e-3 u (as tests/test_identify_lines.py, seeds 1000..). Per record: the lines found (imupipe.lines.find_lines,
0.005 Hz), the largest relative amplitude error of the four, and the fit (white + GM, 100 correlated-bootstrap
replicates, 95 %) with the lines known and without: how many records' intervals cover the truth (N, GM sigma, GM T),
and how many fits are adequate (p > 0.01).

Part 2 (``--trios M``): M trios of 14.6 h white + random-walk records (N 1e-3, K 1e-4; as tests/test_consistency.py,
seeds 5000..): records named by imupipe.identify.consistency.record_consistency (alpha 0.01) among equal records
(false alarms; the bound is alpha per trio) and with the third record's K doubled (power).

    OPENBLAS_NUM_THREADS=1 nice python benchmarks/lines_known.py --lines 20 --trios 20
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from imupipe.allan import allan_variance
from imupipe.identify import fit_allan
from imupipe.identify.consistency import record_consistency
from imupipe.lines import find_lines, line_avar
from imupipe.models import NoiseModel
from imupipe.simulate import simulate

RATE = 10.0
TRUTH = NoiseModel(white=2e-3, gauss_markov=((1e-3, 30.0),), dt=1.0 / RATE)
A, F0, DEPTH, F_MOD, A3 = 3e-3, 0.5, 0.6, 0.1, 0.9e-3
TRUE_LINES = ((F0 - F_MOD, A * DEPTH / 2), (F0, A), (F0 + F_MOD, A * DEPTH / 2), (3 * F0, A3))


def _av(x):
    av = allan_variance(x, rate=RATE, taus="octave")
    ok = np.isfinite(av["avar"].values) & np.isfinite(av["edf"].values)
    return av["tau"].values[ok], av["avar"].values[ok], av["edf"].values[ok]


def lines_part(n_rec: int) -> None:
    n = int(6 * 3600 * RATE)
    t = np.arange(n) / RATE
    truth = {"white": TRUTH.white, "gm_sigma_1": 1e-3, "gm_T_1": 30.0}
    cover = {k: {"known": 0, "blind": 0} for k in truth}
    adequate = {"known": 0, "blind": 0}
    amp_err = []
    for i in range(n_rec):
        x = simulate(TRUTH, n, RATE, np.random.default_rng(1000 + i))
        x += A * (1 + DEPTH * np.cos(2 * np.pi * F_MOD * t)) * np.sin(2 * np.pi * F0 * t)
        x += A3 * np.sin(2 * np.pi * 3 * F0 * t + 1.0)
        found = find_lines(x, RATE, resolution_hz=0.005).lines
        errs = []
        for f, amp in TRUE_LINES:
            near = [ln for ln in found if abs(ln.frequency_hz - f) < 0.02]
            errs.append(abs(near[0].amplitude / amp - 1) if near else math.inf)
        amp_err.append(max(errs))
        tau, avar, edf = _av(x)
        for kind, known in (("known", line_avar(tau, found)), ("blind", None)):
            fit = fit_allan(tau, avar, edf, components=("white", "gauss_markov"), n_gm=1, n_boot=100, rng=i,
                            record_rate_hz=RATE, n_samples=n, dt=1.0 / RATE, known_avar=known)
            for k, v in truth.items():
                lo, hi = fit.intervals[k]
                cover[k][kind] += bool(lo <= v <= hi)
            adequate[kind] += bool(fit.adequacy["adequate"])
    print(f"lines: {n_rec} records; largest relative amplitude error of the 4 lines: median "
          f"{np.median(amp_err):.3f}, max {np.max(amp_err):.3f}")
    print("| interval (95 %) | covers the truth, lines known | without the lines |")
    print("|---|---|---|")
    for k in truth:
        print(f"| {k} | {cover[k]['known']}/{n_rec} | {cover[k]['blind']}/{n_rec} |")
    print(f"| fit adequate (p > 0.01) | {adequate['known']}/{n_rec} | {adequate['blind']}/{n_rec} |")


def _record(k, seed):
    n = 2**19
    x = simulate(NoiseModel(white=1e-3, random_walk=k, dt=1.0 / RATE), n, RATE, np.random.default_rng(seed))
    tau, avar, edf = _av(x)
    f = fit_allan(tau, avar, edf, components=("white", "random_walk"), n_gm=0, n_boot=100, rng=seed,
                  record_rate_hz=RATE, n_samples=n, dt=1.0 / RATE)
    return {p: (f.params[p], *f.intervals[p]) for p in ("white", "random_walk")}


def consistency_part(n_trios: int) -> None:
    false_alarm = power = 0
    for j in range(n_trios):
        recs = {f"r{i}": _record(1e-4, 5000 + 10 * j + i) for i in range(3)}
        false_alarm += bool(record_consistency(recs, 0.95, 0.01)["flagged"])
        recs["r2"] = _record(2e-4, 5000 + 10 * j + 2)
        named = [(r, p) for r, p, *_ in record_consistency(recs, 0.95, 0.01)["flagged"]]
        power += named == [("r2", "random_walk")]
    print(f"consistency: {n_trios} trios; equal truths, trios with any record named: {false_alarm} "
          f"(bound: alpha = 0.01 per trio); K doubled in r2, only r2's K named: {power}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--lines", type=int, default=20, help="records of part 1")
    ap.add_argument("--trios", type=int, default=20, help="trios of part 2")
    a = ap.parse_args()
    if a.lines:
        lines_part(a.lines)
    if a.trios:
        consistency_part(a.trios)


if __name__ == "__main__":
    main()
