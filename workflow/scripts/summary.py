"""The run summary (rule summary): results/{name}/summary.md and summary.html (imupipe.summary).

One section per spec sheet. The bound, identify and stationarity files of each sensor give the verdict, the
inflation table, the states kept and the checks (imupipe.summary.render_summary). Files of the other kinds
(contract, verify, lines, outliers, ...: whatever the stage files list in SUMMARY_INPUTS) are matched to a sensor
by their `sensor` key or file name and to a spec sheet by a folder of that name; their check keys (verified,
failed_checks, lines, narrowband, excluded, outliers, gaps, stuck_spans) join the sensor's checks. A file matched to no sensor
is listed with its path. A refused Kalibr export is flagged under "Exports"."""

import logging
import re
from pathlib import Path

from imupipe.io import read_yaml, run_job, write_text_atomic

#: keys of a stage file that imupipe.summary.flags_of turns into FAIL / FLAG lines
CHECK_KEYS = ("verified", "failed_checks", "lines", "narrowband", "excluded", "outliers", "gaps", "stuck_spans",
              "events")


def _sensor_spec(path: str, data, sensors: list, specs: list):
    parts = Path(path).parts
    sensor = data.get("sensor") if isinstance(data, dict) and data.get("sensor") in sensors else None
    sensor = sensor or next((s for s in sensors if Path(path).stem == s or s in parts[:-1]), None)
    spec = next((s for s in specs if s in parts[:-1]), None)
    return sensor, spec


def _merge_checks(target: dict, data: dict) -> None:
    for key in CHECK_KEYS:
        if key not in data or data[key] in (None, [], {}):
            continue
        if key == "verified":
            target["verified"] = bool(target.get("verified", True)) and bool(data["verified"])
        elif key in ("lines", "stuck_spans") and isinstance(data[key], list):
            # a lines or outliers file holds one dataset/sensor/axis and the units of its keys: each line (stuck
            # span) carries them, so its FLAG names where it is and what unit its amplitude (value) has
            tag = {k: data[k] for k in ("dataset", "sensor", "axis") if data.get(k) is not None}
            units = data.get("units") if isinstance(data.get("units"), dict) else {}
            if key == "stuck_spans":
                units = units.get("stuck_spans") if isinstance(units.get("stuck_spans"), dict) else {}
            items = [{**tag, **it, "units": units} if isinstance(it, dict) else it for it in data[key]]
            target[key] = (target[key] if isinstance(target.get(key), list) else []) + items
        elif isinstance(data[key], list) and isinstance(target.get(key), list):
            target[key] = target[key] + data[key]
        else:
            target[key] = data[key]


def kalibr_flags(paths: list) -> list:
    """Lines of the "Exports" section: a refused Kalibr file (no Kalibr field, `refused: true`)."""
    out = []
    for path in paths:
        data = read_yaml(path) if Path(path).is_file() else None
        if isinstance(data, dict) and data.get("refused"):
            out.append(f"- FLAG kalibr export [{path}]: refused: {data.get('reason', '-')} (no Kalibr fields written; "
                       "use the Kalman-filter export)")
        elif isinstance(data, dict):
            out.append(f"- Kalibr imu.yaml [{path}]: update_rate {data.get('update_rate')} Hz, rostopic "
                       f"{data.get('rostopic')}; bounding values, do not inflate again")
    return out


def psd_usage(path: str) -> dict | None:
    """The PSD file's labels and sample counts (global attrs dataset, sensor, axis, n_samples, n_samples_used,
    window_s, step_s, rate_hz), or None for a missing or unreadable file."""
    import netCDF4

    if not Path(path).is_file():
        return None
    try:
        with netCDF4.Dataset(path) as ds:
            attrs = {k: ds.getncattr(k) for k in ds.ncattrs()}
    except OSError:
        return None
    keys = ("dataset", "sensor", "axis", "n_samples", "n_samples_used", "window_s", "step_s", "rate_hz")
    return {k: (attrs[k].item() if hasattr(attrs[k], "item") else attrs[k]) for k in keys if k in attrs}


def render(files: dict, sensors: list, specs: list, name: str) -> str:
    from imupipe.summary import render_summary

    runs = {spec: {s: {} for s in sensors} for spec in specs}
    others = []
    for kind, paths in files.items():
        if kind == "kalibr":
            continue
        if kind == "psd":  # netCDF: the Welch segments' share of each record, per sensor
            for path in paths:
                usage = psd_usage(path)
                if usage and usage.get("sensor") in sensors:
                    for sp in specs:
                        runs[sp][usage["sensor"]].setdefault("bound", {}).setdefault("psd_usage", []).append(usage)
            continue
        for path in paths:
            data = read_yaml(path) if Path(path).is_file() else None
            if not isinstance(data, dict):
                others.append(f"- {kind} [{path}]: missing or not a YAML mapping")
                continue
            sensor, spec = _sensor_spec(path, data, sensors, specs)
            if sensor is None:
                flagged = [k for k in CHECK_KEYS if data.get(k) not in (None, [], {}, True)]
                others.append(f"- {kind} [{path}]" + (f": see {', '.join(flagged)}" if flagged else ""))
                continue
            for sp in [spec] if spec else specs:
                entry = runs[sp][sensor]
                if kind == "contract":  # the verdict (bounded, verified, failed_checks) wins over the bound file
                    entry["bound"] = {**entry.get("bound", {}), **data}
                elif kind in ("bound", "identify", "stationarity"):
                    entry[kind] = {**data, **entry.get(kind, {})} if kind == "bound" else data
                else:
                    _merge_checks(entry.setdefault("bound", {}), data)
    texts = []
    for spec in specs:
        texts.append(render_summary(runs[spec], title=f"imupipe run summary: {name}, spec sheet {spec}").rstrip())
    exports = kalibr_flags(files.get("kalibr", []))
    if exports:
        texts.append("## Exports\n\n" + "\n".join(exports))
    if others:
        texts.append("## Other run files\n\n" + "\n".join(others))
    return "\n\n".join(texts) + "\n"


def compact(text: str) -> str:
    """The summary without the states-kept reasons, for the report's first page (short, beside the rule graph;
    the full text is the "0 Summary" page and summary.md)."""
    out, skipping = [], False
    for line in text.splitlines():
        if line.startswith("- states kept"):
            out.append(line)
            skipping = True
            continue
        if skipping and line.startswith("  - "):
            continue
        skipping = False
        out.append(line)
    return "\n".join(out) + "\n"


def front_page(template: str, html_page: str) -> str:
    """The report's first page (reStructuredText): the workflow description, then the (compact) summary as raw
    HTML (its tables rendered), the HTML kept out of the report's Jinja rendering."""
    style = re.search(r"<style>(.*?)</style>", html_page, flags=re.S)
    body = re.search(r"<body>(.*?)</body>", html_page, flags=re.S)
    css = style.group(1) if style else ""
    # scoped to the summary block: the report page keeps its own fonts and layout
    css = re.sub(r"(^|\})\s*body\{[^}]*\}", r"\1", css)
    css = re.sub(r"(^|\})([^{}]+)\{", lambda m: m.group(1) + ",".join(f".imupipe-summary {sel.strip()}"
                                                                   for sel in m.group(2).split(",")) + "{", css)
    # the report centres its content panel vertically (flex, h-screen): a page taller than the window would lose
    # its top, out of scroll reach; "safe center" centres only what fits
    css += ".grow.flex.items-center.justify-center.h-screen{align-items:safe center}.imupipe-summary h1{font-size:1.4em}"
    inner = f'<style>{css}</style><div class="imupipe-summary">{body.group(1) if body else html_page}</div>'
    raw = "\n".join("   " + ln for ln in inner.splitlines())
    return (Path(template).read_text().rstrip() + "\n\n"
            "The run summary (in full with the reasons for each state: the category \"0 Summary\" and ``summary.md``"
            " of the run):\n\n"
            "{% raw %}\n.. raw:: html\n\n" + raw + "\n\n{% endraw %}\n")


def main(files: dict, sensors: list, specs: list, name: str, path_md: str, path_html: str, template: str,
         path_front: str) -> None:
    from imupipe.summary import markdown_to_html

    text = render(files, sensors, specs, name)
    write_text_atomic(text, path_md)
    page = markdown_to_html(text, title=f"imupipe run summary: {name}")
    write_text_atomic(page, path_html)
    Path(path_front).parent.mkdir(parents=True, exist_ok=True)
    front = markdown_to_html(compact(text), title=f"imupipe run summary: {name}")
    write_text_atomic(front_page(template, front), path_front)
    logging.info("summary of %d file(s) written to %s", sum(len(v) for v in files.values()), path_md)


if __name__ == "__main__":
    files = {kind: list(snakemake.input[kind]) if not isinstance(snakemake.input[kind], str)
             else [snakemake.input[kind]] for kind in snakemake.params.kinds if kind in snakemake.input.keys()}
    run_job(main, snakemake.log[0], files=files, sensors=list(snakemake.params.sensors),
            specs=list(snakemake.params.specs), name=snakemake.params.name, path_md=snakemake.output.markdown,
            path_html=snakemake.output.html, template=snakemake.input.template, path_front=snakemake.output.front)
