"""White-noise inflation against the shipped ADIS16405 spec sheet with the line policies ``keep`` and ``model``.

Run: ``python benchmarks/adis_lines.py [--data ../shared/data/adis16405/raw] [--n-boot 100]``. Needs the two
ADIS16405 records (imudata, CC BY-NC-SA 4.0, not part of this repository) and the ``rdata`` package.

Library calls in the order of the workflow with the shipped ``config/adis16405.yaml``: records in deg/s and g
converted to SI, mean removed; lines detected per axis at full rate (:func:`imupipe.lines.find_lines`, 0.002 Hz
resolution, family-wise level 1 %); block averages to 1 Hz, Welch PSD with 3600 s windows every 1800 s; Allan fit,
component selection for the application (100 Hz filter, 600 s horizon) and the identified upper envelope; the
global bound over the 6 curves of a sensor type (``raw`` mode, one GM) with the lines handled by
:func:`imupipe.lines.line_policy`; the verification of the bound in the reference filter against the upper
envelope, the spec sheet and a replay of the records (:func:`imupipe.verify.verify_model`).

Prints, per sensor and policy: the bound's N/N_spec, the number of line columns the LP used, margin, whether the bound holds,
the Allan-domain check and whether the verification passed.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import math
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def load(data_dir):
    import rdata

    out = []
    for i in (1, 2):
        p = Path(data_dir) / f"adis_16405_imu{i}.rda"
        if not p.exists():
            raise SystemExit(f"{p}: ADIS16405 record not found (give --data, the folder of adis_16405_imu1.rda)")
        out.append(np.asarray(rdata.read_rda(str(p))[f"adis_16405_imu{i}"]))
    return out


def main(argv=None):
    from imupipe import allan_variance
    from imupipe.bound import bound_psd, check_allan, upper_envelope
    from imupipe.identify import fit_allan, select_components
    from imupipe.lines import find_lines, line_policy
    from imupipe.specsheet import load_spec
    from imupipe.spectra import decimate, psd
    from imupipe.verify import reference_scenario, verify_model

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=str(ROOT.parent / "shared" / "data" / "adis16405" / "raw"))
    ap.add_argument("--n-boot", type=int, default=100)
    ap.add_argument("--resolution-hz", type=float, default=0.002, help="line detection resolution, Hz")
    ap.add_argument("--policies", default="keep,model,exclude")
    ap.add_argument("--band-hz", type=float, default=0.1,
                    help="upper end of the application band in the 1 Hz spectrum, Hz (policy exclude)")
    ap.add_argument("--no-verify", action="store_true", help="skip the verification (faster)")
    a = ap.parse_args(argv)
    recs = load(a.data)
    spec_all = load_spec(ROOT / "config" / "specs" / "adis16405.yaml")
    rows = []
    for sensor, cols, scale in (("gyro", (0, 1, 2), math.pi / 180.0), ("accel", (3, 4, 5), 9.80665)):
        spec = spec_all.models[sensor]
        series = [(r[:, c] * scale) for r in recs for c in cols]
        series = [x - x.mean() for x in series]
        lines, curves, taus, avs, edfs, ns = [], [], [], [], [], []
        n_lines = []
        for k, x in enumerate(series):
            res = find_lines(x, 100.0, resolution_hz=a.resolution_hz, alpha=0.01, label=f"imu{k // 3 + 1}/{'xyz'[k % 3]}")
            lines += res.lines
            n_lines.append(len(res.lines))
            av = allan_variance(x, 100.0)
            taus.append(av["tau"].values)
            avs.append(av["avar"].values)
            edfs.append(av["edf"].values)
            ns.append(x.size)
            y, _ = decimate(x, 100.0, 1.0)
            sp = psd(y, 1.0, window_s=3600.0, step_s=1800.0)
            f, edf = sp["frequency"].values, sp["edf"].values
            curves.append(sp["psd"].values)
        fit = fit_allan(taus, avs, edfs, n_gm=1, n_boot=a.n_boot, confidence=0.95, rng=20211, dt=0.01, record_rate_hz=100.0,
                        n_samples=ns)
        sel = select_components(fit, taus, avs, edfs, filter_rate_hz=100.0, outage_s=600.0)
        up = upper_envelope(fit, sel, span_s=1200.0)
        print(f"{sensor}: lines per curve {n_lines}: "
              + ", ".join(f"{ln.frequency_hz:.4f} Hz (amp {ln.amplitude:.3g}, zeta {ln.zeta:.3g})"
                          for ln in lines[:6]) + (" ..." if len(lines) > 6 else ""))
        for policy in a.policies.split(","):
            pol = line_policy(lines, 1.0, (0.0, a.band_hz), policy, frequency=f)
            b = bound_psd(f, np.array(curves), spec, dt=1.0, keep=sel, edf=edf, span_s=1200.0, upper_model=up,
                          **pol.bound_kwargs())
            ver = None
            if not a.no_verify:
                sc = reference_scenario(sensor, outage_s=600.0)
                ver = verify_model(b.model, sensor, upper=up, spec=spec, records=series, record_rate_hz=100.0, scenario=sc)
            al = check_allan(b.model, fit.model, taus[0], kept=sel, sample_avar=np.array(avs),
                             sample_edf=np.array(edfs), span_s=600.0)
            rows.append((sensor, policy, b.inflation["N"], sum(s > 0 for s, _, _ in b.model.narrowband), b.margin,
                         b.bounded, al["passed"],
                         None if ver is None else ver["passed"],
                         None if ver is None else max(c["worst_ratio"] for c in ver["checks"].values()), b.model))
    print()
    print("| sensor | policy | N / N_spec | lines with sigma > 0 | PSD margin | bounded | Allan check | verified | "
          "worst MSE/P |")
    print("|---|---|---|---|---|---|---|---|---|")
    for s, p, infl, nl, m, bd, alp, v, w, _ in rows:
        print(f"| {s} | {p} | {infl:.3g}x | {nl} | {m:.4g} | {bd} | {alp} | {v} | {'-' if w is None else f'{w:.3g}'} |")
    print()
    for s, p, *_, model in rows:
        print(f"{s} {p}: {model}")


if __name__ == "__main__":
    main()
