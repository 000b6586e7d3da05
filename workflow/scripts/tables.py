"""Spec vs bound parameters in the spec sheet's units (paper Table 2), markdown, CSV and HTML (rule tables)."""

import csv
import io

from imupipe.io import read_yaml, run_job, write_text_atomic


def main(paths: list, sensors: list, path_spec: str, path_md: str, path_csv: str, path_html: str) -> None:
    from imupipe.models import NoiseModel
    from imupipe.summary import markdown_to_html
    from imupipe.specsheet import inflation_rows, load_spec

    spec = load_spec(path_spec)
    rows = []
    for sensor, path in zip(sensors, paths):
        bound = read_yaml(path)
        b = bound["bound"]
        model = NoiseModel(white=b["white"] or 0.0, random_walk=b["random_walk"] or 0.0,
                           gauss_markov=tuple((g["sigma"], g["T"]) for g in b["gauss_markov"]))
        for r in inflation_rows(spec, sensor, model):
            rows.append({"sensor": sensor, **r, "mode": bound["mode"], "bounded": bound.get("psd_bounded", bound.get("bounded")),
                         "margin": bound["margin"]})

    def fmt(v):
        return "-" if v is None else f"{v:.4g}" if isinstance(v, float) else str(v)

    md = [f"# {spec.name}: spec sheet vs bound ({rows[0]['mode']} mode)", "",
          "| sensor | parameter | unit | spec | bound | bound/spec |", "|---|---|---|---|---|---|"]
    md += [f"| {r['sensor']} | {r['parameter']} | {r['unit']} | {fmt(r['spec'])} | {fmt(r['bound'])} | "
           f"{fmt(r['ratio'])} |" for r in rows]
    md += ["", "Margins (min S_model/S_sample over all curves and frequencies): "
           + ", ".join(f"{s} {fmt(read_yaml(p)['margin'])}" for s, p in zip(sensors, paths)), ""]
    write_text_atomic("\n".join(md), path_md)
    write_text_atomic(markdown_to_html("\n".join(md), title=f"{spec.name}: spec sheet vs bound"), path_html)
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(rows[0]))
    w.writeheader()
    w.writerows(rows)
    write_text_atomic(buf.getvalue(), path_csv)


if __name__ == "__main__":
    run_job(main, snakemake.log[0], paths=[snakemake.input[s] for s in snakemake.params.sensors],
            sensors=list(snakemake.params.sensors),
            path_spec=snakemake.input.spec, path_md=snakemake.output.markdown, path_csv=snakemake.output.csv,
            path_html=snakemake.output.html)
