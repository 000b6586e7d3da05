"""Start cost of the workflow's per-axis and per-sensor jobs: a fresh interpreter that imports what the job's
script imports and makes the job's library calls once on a small input (so that every deferred import of the
call is paid), timed from the interpreter's start; best of `--repeats`, OLD and NEW source trees alternating
in the same run (relative numbers only on a loaded machine).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/job_start.py [--old SRC] [--repeats 5]

``--old SRC`` is the ``src`` folder of another checkout (e.g. ``git archive <commit> src | tar -x -C DIR``);
without it only this checkout is timed. Prints, per job, the wall time (s) and the heavy modules the call
loaded (scipy.optimize, scipy.stats, scipy.special, scipy.signal, scipy.linalg, xarray).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SPEC = ROOT / "config" / "specs" / "stim300.yaml"

SETUP = ("import numpy as np\nfrom imupipe.models import NoiseModel\nfrom imupipe.simulate import simulate\n"
         "x = simulate(NoiseModel(white=1e-4, gauss_markov=((2e-5, 300.0),)), 7200, 1.0, rng=1)\n")
JOBS = {
    "allan": "from imupipe.allan import allan_variance_labelled\nallan_variance_labelled(x, 1.0, units='rad/s')\n",
    "decimate": "from imupipe.spectra import decimate\ndecimate(x, 1.0, 0.5)\n",
    "psd": "from imupipe.spectra import psd_labelled\npsd_labelled(x, 1.0, window_s=1800.0, step_s=900.0, units='rad/s')\n",
    # the workflow's stationarity job: the calibrated test on the axis's own AV fit; the paper's asymptotic test
    # (scipy.stats) runs once per sensor type in stationarity_summary, not here (the calibrated function's
    # `paper=False`; a tree without that argument runs its own default, which included the paper's test)
    "stationarity": ("from imupipe.identify import fit_allan\nfrom imupipe.allan import allan_variance_labelled\n"
                     "from imupipe.stationarity import calibrated_stationarity\nimport inspect\n"
                     "av = allan_variance_labelled(x, 1.0, units='rad/s')\n"
                     "t, a, e = (np.asarray(av.coords['tau'][0]), *(np.asarray(av.data_vars[k][0]) for k in ('avar', 'edf')))\n"
                     "ok = np.isfinite(a) & np.isfinite(e)\n"
                     "fit = fit_allan([t[ok]], [a[ok]], [e[ok]], n_gm=1, n_boot=0, dt=1.0, record_rate_hz=1.0, n_samples=[x.size])\n"
                     "kw = {'paper': False} if 'paper' in inspect.signature(calibrated_stationarity).parameters else {}\n"
                     "calibrated_stationarity(x, 1.0, fit.model, n_sim=19, **kw)\n"),
    "identify": ("from imupipe.identify import fit_allan, select_components\nfrom imupipe.allan import allan_variance_labelled\n"
                 "av = allan_variance_labelled(x, 1.0, units='rad/s')\n"
                 "t, a, e = (np.asarray(av.coords['tau'][0]), *(np.asarray(av.data_vars[k][0]) for k in ('avar', 'edf')))\n"
                 "ok = np.isfinite(a) & np.isfinite(e)\n"
                 "fit = fit_allan([t[ok]], [a[ok]], [e[ok]], n_gm=1, n_boot=0, dt=1.0, record_rate_hz=1.0, n_samples=[x.size])\n"
                 "select_components(fit, [t[ok]], [a[ok]], [e[ok]], filter_rate_hz=1.0, outage_s=600.0)\n"),
    "bound_axis": ("from imupipe.bound import bound_psd\nfrom imupipe.specsheet import load_spec\n"
                   "f = np.arange(1, 901) / 1800.0  # a PSD as the job reads it from its file\n"
                   "e = np.full(f.size, 2.0)\n"
                   "s = NoiseModel(white=1e-4).psd_sampled(f, 1.0) * np.random.default_rng(2).chisquare(2, f.size) / 2\n"
                   f"spec = load_spec({str(SPEC)!r}).models['gyro']\n"
                   "bound_psd(f, {'a/x': s}, spec, dt=1.0, edf=e, keep=['white', 'gauss_markov', 'random_walk'],"
                   " T_grid=4, span_s=1200.0)\n"),
    "kf": "from imupipe.kf import export_kf\nexport_kf(NoiseModel(white=1e-4, gauss_markov=((2e-5, 300.0),)), 1.0, sensor='gyro')\n",
}
HEAVY = ("scipy.optimize", "scipy.stats", "scipy.special", "scipy.signal", "scipy.linalg", "xarray")
REPORT = "import sys\nprint(','.join(m for m in %r if m in sys.modules))\n" % (HEAVY,)


def once(src: str, job: str) -> tuple[float, str]:
    env = dict(os.environ, PYTHONPATH=src, OPENBLAS_NUM_THREADS="1")
    t0 = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", SETUP + JOBS[job] + REPORT], env=env, capture_output=True,
                         text=True, check=True).stdout
    return time.perf_counter() - t0, out.strip()


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--old", help="src folder of the checkout to compare with")
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args(argv)
    trees = {"new": str(ROOT / "src")} | ({"old": args.old} if args.old else {})
    print(f"{'job':<13}" + "".join(f"{k + ' [s]':>10}" for k in trees) + "  heavy modules loaded")
    for job in JOBS:
        best, mods = {k: float("inf") for k in trees}, {}
        for _ in range(args.repeats):
            for k, src in trees.items():  # alternating
                t, m = once(src, job)
                best[k] = min(best[k], t)
                mods[k] = m
        print(f"{job:<13}" + "".join(f"{best[k]:>10.3f}" for k in trees) + "  "
              + "; ".join(f"{k}: {mods[k] or '-'}" for k in trees))


if __name__ == "__main__":
    main()
