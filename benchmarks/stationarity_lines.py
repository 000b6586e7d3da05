"""The calibrated stationarity test on axes with a spectral line: how often it flags stationary records, and how
often it sees a change of the broadband noise under the line, with the axis's lines left out of the test (the old
null: the broadband Allan fit alone) and with them (the workflow's: notched out and carried by the null).

    OPENBLAS_NUM_THREADS=1 python benchmarks/stationarity_lines.py --case line --zeta 0.0002 0.001 0.01 --step 1 1.6

Each record: 1.5 h at 10 Hz of a truth (``line``: white 1e-3 u/sqrt(Hz), a GM of 2e-4 u at T 300 s and a line of
sigma 3e-3 u at 0.08 Hz, nine times the decimated white variance; ``two``: white 2e-3, a GM of 5e-4 at 60 s, lines
at 0.11 Hz and at 1.3 Hz, which folds to 0.3 Hz at 1 Hz, damping zeta and 2 zeta; ``strong``: white 1e-3, a GM
of 3e-4 at 200 s and lines of sigma 2e-2 and 3e-2 u at 0.3 and 2.45 Hz, 400 and 900 times the decimated white
variance; ``none``: the first without its line), the white noise's standard deviation times `step` over the second half (1: stationary); the lines found by
the workflow's search (0.002 Hz resolution), the Allan variance on the full-rate record, the block average to 1 Hz,
and the stage's verdict (alpha 0.05, n_sim 199 up to 1599). Prints a Markdown table of counts.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from imupipe.allan import allan_variance
from imupipe.lines import find_lines
from imupipe.models import NoiseModel
from imupipe.simulate import simulate
from imupipe.spectra import decimate
from imupipe.stages.stationarity import stationarity_stage

RATE_HZ, HOURS = 10.0, 1.5


def truth_of(case: str, zeta: float) -> NoiseModel:
    if case == "none":
        return NoiseModel(white=1e-3, gauss_markov=((2e-4, 300.0),))
    if case == "strong":
        return NoiseModel(white=1e-3, gauss_markov=((3e-4, 200.0),),
                          narrowband=((2e-2, 0.3, zeta), (3e-2, 2.45, zeta)))
    if case == "two":
        return NoiseModel(white=2e-3, gauss_markov=((5e-4, 60.0),),
                          narrowband=((2e-3, 0.11, zeta), (6e-3, 1.3, 2 * zeta)))
    return NoiseModel(white=1e-3, gauss_markov=((2e-4, 300.0),), narrowband=((3e-3, 0.08, zeta),))


def flagged(case: str, zeta: float, step: float, records: int, seed: int) -> tuple[int, int, int]:
    """(records with a line found, flagged without the lines, flagged with them)."""
    truth = truth_of(case, zeta)
    rng = np.random.default_rng(seed)
    n = int(HOURS * 3600 * RATE_HZ)
    found = without = with_lines = 0
    for _ in range(records):
        x = simulate(truth, n, RATE_HZ, rng)
        if step != 1.0:
            x[n // 2:] += np.sqrt(step**2 - 1.0) * truth.white * np.sqrt(RATE_HZ) * rng.standard_normal(n - n // 2)
        av = allan_variance(x, RATE_HZ)
        lines = find_lines(x, RATE_HZ, resolution_hz=0.002).lines
        found += bool(lines)
        y, rate = decimate(x, RATE_HZ, 1.0)
        allan = (av.tau, av.avar, av.edf)
        without += not stationarity_stage(y, rate, allan=allan)["stationary"]
        with_lines += not stationarity_stage(y, rate, allan=allan, lines=lines)["stationary"]
    return found, without, with_lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--case", nargs="+", default=["line"], choices=["line", "two", "strong", "none"])
    ap.add_argument("--zeta", nargs="+", type=float, default=[0.001])
    ap.add_argument("--step", nargs="+", type=float, default=[1.0, 1.6], help="white noise sd factor, second half")
    ap.add_argument("--records", type=int, default=20)
    ap.add_argument("--seed", type=int, default=101)
    a = ap.parse_args(argv)
    print("| case | zeta | step | records | line found | flagged, lines left out | flagged, lines notched (now) |")
    print("|---|---|---|---|---|---|---|")
    seed = a.seed
    for case in a.case:
        for zeta in a.zeta if case != "none" else [0.0]:
            for step in a.step:
                found, without, with_lines = flagged(case, zeta, step, a.records, seed)
                seed += 1
                print(f"| {case} | {zeta:g} | {step:g} | {a.records} | {found} | {without} | {with_lines} |",
                      flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
