"""The real-sensor table of docs/results.md from finished runs: per run and sensor the white noise's bound/spec, the
exported model's effective in-band inflation (median and max of sqrt(S_model / S_spec) over the application band),
chi2/dof of the pooled Allan fit and per axis before/after the line terms, the components kept (flicker, random
walk), Kalibr's two densities (SI), the worst MSE/P in the outage against the identified upper envelope and the
replays that passed only within their sampling tolerance (model: worst MSE/P <= 1 + tolerance; the contract's
``within_tolerance``).

``python benchmarks/real_sensors_table.py results/adis_imu1 results/adis_imu2 results/adis16405``
(each a run folder ``results/<name>``; one spec sheet per run).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from imupipe.io import read_yaml


def _chi2(ident: dict) -> str:
    a = ident.get("adequacy_lines")
    if not a:
        return f"{ident['adequacy']['chi2_per_dof']:.3g} (no lines)"
    axes = a["per_axis"]
    before = "/".join(f"{axes[x]['before']['chi2_per_dof']:.3g}" for x in sorted(axes))
    after = "/".join(f"{axes[x]['after']['chi2_per_dof']:.3g}" for x in sorted(axes))
    return f"{a['pooled']['before']['chi2_per_dof']:.3g} -> {a['pooled']['after']['chi2_per_dof']:.3g} ({before} -> {after})"


def _by_tolerance(c: dict) -> str:
    models = [("global", c.get("verification"))] + [(f"axis {ax}", pa.get("verification"))
                                                    for ax, pa in (c.get("per_axis_models") or {}).items()
                                                    if pa.get("exported_in_kf")]
    out = [f"{label} {ch['worst_ratio']:.3g} (<= {1 + ch['tolerance']:.3g})" for label, checks in models
           for ch in (checks or {}).values() if ch.get("within_tolerance")]
    return "; ".join(out) or "-"


def rows(run: Path):
    spec = next(p.name for p in (run / "contract").iterdir() if p.is_dir())
    kalibr = read_yaml(run / "kf" / spec / "kalibr_imu.yaml")
    for sensor, kal in (("gyro", "gyroscope"), ("accel", "accelerometer")):
        c = read_yaml(run / "contract" / spec / f"{sensor}.yaml")
        ident = read_yaml(run / "identify" / f"{sensor}.yaml")
        inb = c["inband_inflation"]["vs_spec_psd"]
        kept = ", ".join(k for k in ("flicker", "random_walk") if k in ident["selection"]["kept"]) or "-"
        env = (c.get("verification") or {}).get("upper_envelope") or {}
        yield (run.name, sensor, "bounded" if c["bounded"] else "NOT BOUNDED", f"{c['inflation'].get('N', float('nan')):.3g}",
               f"{inb['median']:.3g} / {inb['max']:.3g}", _chi2(ident), kept,
               f"{kalibr.get(kal + '_noise_density', float('nan')):.3g} / {kalibr.get(kal + '_random_walk', float('nan')):.3g}",
               f"{env.get('worst_outage_ratio', float('nan')):.3g}", _by_tolerance(c))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+", type=Path)
    args = ap.parse_args(argv)
    head = ("run", "sensor", "contract", "N bound/spec", "in band median / max", "chi2/dof pooled (per axis) before -> after lines",
            "kept", "Kalibr density / random walk (SI)", "worst MSE/P outage, envelope",
            "replay passed by tolerance: worst MSE/P (<= limit)")
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for run in args.runs:
        for r in rows(run):
            print("| " + " | ".join(r) + " |")


if __name__ == "__main__":
    main()
