"""Spec sheet vs bound parameters in the spec sheet's units (paper Table 2; rule ``tables``): the rows
(:func:`imupipe.specsheet.inflation_rows` of each sensor's bound) as markdown, CSV and HTML.

Plain values in (the spec sheet, the bound files' dicts by sensor), the three texts out (:func:`tables_stage`).
"""

from __future__ import annotations

import csv
import io

__all__ = ["tables_stage"]


def tables_stage(spec, bounds: dict) -> dict:
    """{"markdown", "csv", "html"}: the texts of the table of `spec` (:class:`imupipe.specsheet.SpecSheet`) against
    `bounds` ({sensor: the bound file's dict}, in the config's sensor order)."""
    from imupipe.models import NoiseModel
    from imupipe.specsheet import inflation_rows
    from imupipe.summary import markdown_to_html

    rows = []
    for sensor, bound in bounds.items():
        b = bound["bound"]
        model = NoiseModel(white=b["white"] or 0.0, random_walk=b["random_walk"] or 0.0,
                           gauss_markov=tuple((g["sigma"], g["T"]) for g in b["gauss_markov"]))
        for r in inflation_rows(spec, sensor, model):
            rows.append({"sensor": sensor, **r, "mode": bound["mode"],
                         "bounded": bound.get("psd_bounded", bound.get("bounded")), "margin": bound["margin"]})

    def fmt(v):
        return "-" if v is None else f"{v:.4g}" if isinstance(v, float) else str(v)

    md = [f"# {spec.name}: spec sheet vs bound ({rows[0]['mode']} mode)", "",
          "| sensor | parameter | unit | spec | bound | bound/spec |", "|---|---|---|---|---|---|"]
    md += [f"| {r['sensor']} | {r['parameter']} | {r['unit']} | {fmt(r['spec'])} | {fmt(r['bound'])} | "
           f"{fmt(r['ratio'])} |" for r in rows]
    md += ["", "Margins (min S_model/S_sample over all curves and frequencies): "
           + ", ".join(f"{s} {fmt(b['margin'])}" for s, b in bounds.items()), ""]
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(rows[0]))
    w.writeheader()
    w.writerows(rows)
    return {"markdown": "\n".join(md), "csv": buf.getvalue(),
            "html": markdown_to_html("\n".join(md), title=f"{spec.name}: spec sheet vs bound")}
