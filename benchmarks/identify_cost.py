"""Cost of the identify job's library calls on one sensor type: the full fit with its bootstrap, the component
selection and the selected refit (:func:`imupipe.identify.fit_allan`, :func:`~imupipe.identify.select_components`,
:func:`~imupipe.identify.refit_selected`), as workflow/scripts/identify.py makes them with the default
config (n_boot 100, confidence 0.95, one GM), on three simulated 10 h records at 10 Hz of a tactical gyro (white
+ GM + random walk) pooled. Median over `--repeats` runs of the calls' wall time and their CPU time (the process's
user + system time: the calls are single-threaded with OPENBLAS_NUM_THREADS=1, so on a shared machine the CPU time
is the steadier measure), OLD and NEW source trees alternating in fresh interpreters.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/identify_cost.py [--old SRC] [--repeats 5]

``--old SRC`` is the ``src`` folder of another checkout (e.g. ``git archive <commit> src | tar -x -C DIR``,
with its compiled kernel built or copied); without it only this checkout is timed.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

CALL = r"""
import time
import numpy as np
from imupipe.allan import allan_variance
from imupipe.identify import fit_allan, refit_selected, select_components
from imupipe.models import NoiseModel
from imupipe.simulate import simulate

rate, n = 10.0, 360000  # Hz, samples (10 h)
truth = NoiseModel(white=2.909e-5, gauss_markov=((4.848e-6, 200.0),), random_walk=1.454e-7)
rng = np.random.default_rng(12345)
avs = [allan_variance(simulate(truth, n, rate, rng), rate, taus="octave") for _ in range(3)]
t, y, e = [a.tau.values for a in avs], [a.avar.values for a in avs], [a.edf.values for a in avs]
kw = dict(n_boot=100, confidence=0.95, dt=1.0 / rate, record_rate_hz=[rate] * 3, n_samples=[n] * 3)
t0, c0 = time.perf_counter(), time.process_time()
fit = fit_allan(t, y, e, components=("white", "gauss_markov", "flicker", "random_walk", "quantization", "ramp"),
                n_gm=1, rng=20211, **kw)
sel = select_components(fit, t, y, e, filter_rate_hz=1.0, outage_s=3600.0)
rep = refit_selected(fit, sel, t, y, e, rng=20211, **kw)
print(time.perf_counter() - t0, time.process_time() - c0, sel["kept"], rep.intervals.get("gm_T_1"))
"""


def once(src: str) -> tuple[float, float, str]:
    env = dict(os.environ, PYTHONPATH=src, OPENBLAS_NUM_THREADS="1")
    out = subprocess.run([sys.executable, "-c", CALL], env=env, capture_output=True, text=True, check=True).stdout
    wall, cpu, rest = out.strip().split(" ", 2)
    return float(wall), float(cpu), rest


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--old", help="src folder of the tree to compare with")
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    trees = {"new": str(ROOT / "src")}
    if args.old:
        trees = {"old": args.old, **trees}
    wall, cpu = {k: [] for k in trees}, {k: [] for k in trees}
    last = {}
    for _ in range(args.repeats):
        for name, src in trees.items():
            w, c, last[name] = once(src)
            wall[name].append(w)
            cpu[name].append(c)
    for name in trees:
        print(f"{name}: median of {args.repeats}: wall {statistics.median(wall[name]):.2f} s "
              f"({', '.join(f'{s:.2f}' for s in wall[name])}), CPU {statistics.median(cpu[name]):.2f} s "
              f"({', '.join(f'{s:.2f}' for s in cpu[name])}); kept, T interval (s): {last[name]}")


if __name__ == "__main__":
    main()
