"""Spec sheet vs bound parameters in the spec sheet's units (paper Table 2; rule ``tables``): the rows
(:func:`imupipe.specsheet.inflation_rows` of each sensor's bound) as markdown, CSV and HTML.

Plain values in (the spec sheet, the bound files' dicts by sensor), the three texts out (:func:`tables_stage`).
"""

from __future__ import annotations

import csv
import io

__all__ = ["exported_bound", "tables_stage"]


def exported_bound(bound: dict, contract: dict | None) -> dict:
    """The bound file entry of the model a run exports: with ``bound.mode: auto`` the candidate the contract's
    ``auto_selection`` names (its ``mode`` "auto (<winner>)"), else `bound` itself (the bound file's top level of an
    auto run is its first candidate, never what the KF file holds)."""
    sel = (contract or {}).get("auto_selection")
    if not sel or not bound.get("candidates"):
        return bound
    return {**bound["candidates"][sel["winner"]], "mode": f"auto ({sel['winner']})"}


def tables_stage(spec, bounds: dict, contracts: dict | None = None) -> dict:
    """{"markdown", "csv", "html"}: the texts of the table of `spec` (:class:`imupipe.specsheet.SpecSheet`) against
    `bounds` ({sensor: the bound file's dict}, in the config's sensor order); `contracts` ({sensor: the contract's
    dict}, needed with ``bound.mode: auto``) select the exported candidate (:func:`exported_bound`)."""
    bounds = {s: exported_bound(b, (contracts or {}).get(s)) for s, b in bounds.items()}
    if any(b.get("candidates") and b.get("mode") == "auto" for b in bounds.values()):
        raise ValueError("bound.mode auto: the table needs the contract files (the exported candidate)")
    from imupipe.models import NoiseModel
    from imupipe.specsheet import inflation_rows
    from imupipe.summary import markdown_to_html

    rows = []
    for sensor, bound in bounds.items():
        b = bound["bound"]
        model = NoiseModel(white=b["white"] or 0.0, random_walk=b["random_walk"] or 0.0,
                           gauss_markov=tuple((g["sigma"], g["T"]) for g in b["gauss_markov"]),
                           narrowband=tuple((t["sigma"], t["f0_hz"], t["zeta"]) for t in b.get("narrowband") or ()))
        for r in inflation_rows(spec, sensor, model):
            rows.append({"sensor": sensor, **r, "mode": bound["mode"],
                         "bounded": bound.get("psd_bounded", bound.get("bounded")), "margin": bound["margin"]})

    def fmt(v):
        return "-" if v is None else f"{v:.4g}" if isinstance(v, float) else str(v)

    modes = (f"{rows[0]['mode']} mode" if len({r["mode"] for r in rows}) == 1  # else the mode of each sensor's bound
             else "mode: " + ", ".join(dict.fromkeys(f"{r['sensor']} {r['mode']}" for r in rows)))
    md = [f"# {spec.name}: spec sheet vs bound ({modes})", "",
          "| sensor | parameter | unit | spec | bound | bound/spec |", "|---|---|---|---|---|---|"]
    md += [f"| {r['sensor']} | {r['parameter']} | {r['unit']} | {fmt(r['spec'])} | {fmt(r['bound'])} | "
           f"{fmt(r['ratio'])} |" for r in rows]
    md += ["", "Margins (min S_model over its mode's target, the sample PSDs in raw mode, all curves and frequencies): "
           + ", ".join(f"{s} {fmt(b['margin'])}" for s, b in bounds.items()), ""]
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(rows[0]))
    w.writeheader()
    w.writerows(rows)
    return {"markdown": "\n".join(md), "csv": buf.getvalue(),
            "html": markdown_to_html("\n".join(md), title=f"{spec.name}: spec sheet vs bound")}
