"""Wall time of one verify job's computation at filter rates 1 / 100 / 1000 Hz, beside the step loop.

One job = :func:`imupipe.verify.verification_stage` of one sensor (what rule ``verify`` calls through
``imupipe.stages.verify.verify_sensor``): the exact covariance analysis of the bound's filter against the upper
envelope and the spec sheet, the replay of the records, the reduction by integrity (every candidate against every
truth) and the reduced model's own checks when a reduction is accepted. 600 s of fixes + 3600 s outage.
Not timed: reading the records and drawing the figure.

Models (SI): the spec sheet is config/specs/stim300.yaml (the default config's); the bound stands in for the
default run's bound as the spec with every component x1.5, the upper envelope the spec x1.2; the records are
two 2.5 h records simulated from the spec at the filter rate (imupipe.simulate, seed 1), so the replay runs on
3 + 3 windows.

The closed form is timed `--repeats` times (median printed): wall time and the process's CPU time (on a machine
shared with other jobs the wall time grows with the load; the CPU time is what the job costs). The step loop is
the same job with
verify.covariance_analysis, verify.covariance_analyses (one truth after the other) and verify.replay replaced by
their step-loop references (covariance_analysis_steps, replay_steps), timed once; at filter rates >= 100 Hz on a
scenario shortened by `--step-fraction` and scaled by the step count (both loops are linear in the number of
steps): "estimated".

The per-fix loops run compiled (imupipe._kernels) when the module is built; `--numpy` times the NumPy path
instead (the fallback where no compiler is available); the line says which ran.

Usage: OPENBLAS_NUM_THREADS=1 python benchmarks/verify_job.py [--rates 1 100 1000] [--fix-rate 1]
       [--repeats 3] [--sensors accel gyro] [--step-fraction 0.01] [--numpy]
"""

import argparse
import statistics
import time
from pathlib import Path

import imupipe.verify as V
from imupipe.models import NoiseModel
from imupipe.simulate import simulate
from imupipe.specsheet import load_spec

SPEC = Path(__file__).resolve().parents[1] / "config" / "specs" / "stim300.yaml"


def scaled(m, k):
    return NoiseModel(white=m.white * k, gauss_markov=tuple((s * k, T) for s, T in m.gauss_markov),
                      random_walk=m.random_walk * k, flicker=m.flicker * k)


#: the bound and the upper envelope of each sensor: the stand-ins above, or a run's bound file (--bound-dir)
MODELS: dict = {}


def models(sensor, spec, bound_dir):
    """(bound, upper envelope) of `sensor`: from ``bound_dir/{sensor}.yaml`` (a run's ``bound/{spec}/``, its
    ``bound`` and ``upper_envelope`` models, SI) or the spec sheet x1.5 and x1.2."""
    if bound_dir is None:
        return scaled(spec, 1.5), scaled(spec, 1.2)
    import yaml

    doc = yaml.safe_load((Path(bound_dir) / f"{sensor}.yaml").read_text())
    return NoiseModel.from_dict(doc["bound"]), NoiseModel.from_dict(doc["upper_envelope"])


def job(sensor, spec, rate, fix_rate, fix_s, outage_s, records):
    bound, upper = MODELS[sensor]
    return V.verification_stage(bound, sensor, spec=spec, upper=upper, records=records,
                                record_rate_hz=rate, fix_s=fix_s, outage_s=outage_s, filter_rate_hz=rate,
                                fix_rate_hz=fix_rate, reduce=True)


def step_loop_job(*args):
    ca, cas, rp = V.covariance_analysis, V.covariance_analyses, V.replay
    V.covariance_analysis, V.replay = V.covariance_analysis_steps, (
        lambda *a, noise_mse=None, **k: V.replay_steps(*a, **k))  # the step loop computes its own noise MSE
    V.covariance_analyses = lambda f, ts, sc=None, sensor="accel": [V.covariance_analysis_steps(f, t, sc, sensor)
                                                                      for t in ts]
    try:
        return job(*args)
    finally:
        V.covariance_analysis, V.covariance_analyses, V.replay = ca, cas, rp


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rates", type=float, nargs="+", default=[1.0, 100.0, 1000.0])
    ap.add_argument("--fix-rate", type=float, default=None, help="Hz (default: a fix at every filter step)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--sensors", nargs="+", default=["accel", "gyro"])
    ap.add_argument("--step-fraction", type=float, default=0.01)
    ap.add_argument("--no-step-loop", action="store_true")
    ap.add_argument("--bound-dir", default=None,
                    help="a run's bound/<spec>/ folder (e.g. results/paper/bound/stim300 after make run): its bound "
                         "and upper envelope instead of the spec sheet x1.5 / x1.2")
    ap.add_argument("--numpy", action="store_true", help="the NumPy per-fix loops, not the compiled ones")
    a = ap.parse_args()
    import imupipe.covariance as cov

    if a.numpy:
        cov._kernels = None
    backend = cov.pick_backend("auto")
    sheet = load_spec(SPEC)
    for sensor in a.sensors:
        MODELS[sensor] = models(sensor, sheet.models[sensor], a.bound_dir)
    print(f"{'sensor':6} {'rate_Hz':>8} {'fix_Hz':>7} {'steps':>9} {'wall_s (median)':>16} {'cpu_s (median)':>15} "
          f"{'wall runs':>20} {'step_loop_cpu_s':>16}  note")
    for sensor in a.sensors:
        spec = sheet.models[sensor]
        for r in a.rates:
            fr = a.fix_rate if a.fix_rate is not None and a.fix_rate <= r else None
            records = list(simulate(spec, int(2.5 * 3600 * r), r, rng=1, n_records=2))
            times, cpus = [], []
            for _ in range(a.repeats):
                V._FILTER_CACHE.clear()  # each run starts cold, as a job does
                t0, c0 = time.perf_counter(), time.process_time()
                rep, _ = job(sensor, spec, r, fr, 600.0, 3600.0, records)
                times.append(time.perf_counter() - t0)
                cpus.append(time.process_time() - c0)
            ts, note = float("nan"), "not run"
            if not a.no_step_loop:
                f = 1.0 if r < 100 else a.step_fraction
                short = [x[: int(2.5 * 3600 * r * f)] for x in records]
                V._FILTER_CACHE.clear()
                c0 = time.process_time()
                step_loop_job(sensor, spec, r, fr, 600.0 * f, 3600.0 * f, short)
                ts = (time.process_time() - c0) / f
                note = "measured" if f == 1.0 else f"estimated from {f:g} of the steps"
            ex = rep["exported"]["verification"]["checks"]
            worst = ", ".join(f"{k} {c['worst_outage_ratio']:.3f}" for k, c in ex.items())
            steps = int(round(4200 * r))
            print(f"{sensor:6} {r:8g} {'every' if fr is None else f'{fr:g}':>7} {steps:9d} "
                  f"{statistics.median(times):16.2f} {statistics.median(cpus):15.2f} "
                  f"{' '.join(f'{t:.1f}' for t in times):>20} {ts:16.1f}  "
                  f"{note}; {backend} loops; exported {'reduced' if rep['exported']['reduced'] else 'bound'}, outage MSE/P: {worst}",
                  flush=True)


if __name__ == "__main__":
    main()
