"""The run summary of the workflow (rule ``summary``): ``summary.md``, ``summary.html`` and the report's first page.

The stage files a run lists (kind -> paths: bound, identify, stationarity, contract, verify, lines, outliers, psd,
kalibr, ...) are grouped per spec sheet and sensor (:func:`group_run_files`): a file is matched to a sensor by its
``sensor`` key or file name and to a spec sheet by a folder of that name; the check keys of the other kinds
(:data:`CHECK_KEYS`) join the sensor's checks, the PSD files' sample counts its record usage. The text
(:func:`summary_text`) is every spec sheet's first screen (verdicts, values to paste, checks), then the details
(:func:`imupipe.summary.summary_sections`). The report's first page carries the first screen only
(:func:`front_page`). What a run prints at its end is :func:`end_of_run_text`: the same summary, or after a
failure the one of the files the run left.
"""

from __future__ import annotations

import logging
import re
from pathlib import Path

__all__ = ["CHECK_KEYS", "end_of_run_text", "front_page", "group_run_files", "merge_checks", "psd_usage", "run_files",
           "summarise_results", "summary_stage", "summary_text"]

#: keys of a stage file that imupipe.summary.flags_of turns into FAIL / FLAG lines
CHECK_KEYS = ("verified", "failed_checks", "lines", "narrowband", "excluded", "outliers", "gaps", "stuck_spans",
              "events")


def _sensor_spec(path: str, data, sensors: list, specs: list):
    parts = Path(path).parts
    sensor = data.get("sensor") if isinstance(data, dict) and data.get("sensor") in sensors else None
    sensor = sensor or next((s for s in sensors if Path(path).stem == s or s in parts[:-1]), None)
    spec = next((s for s in specs if s in parts[:-1]), None)
    return sensor, spec


def merge_checks(target: dict, data: dict) -> None:
    """Merge one run file's findings (`data`: a bound, identify, stationarity, outliers or lines file as read) into
    the sensor's summary entry `target` (in place): the lines files' lines tagged with their dataset, sensor, axis
    and units and their search's statement (``line_search``), the event scan's false-alarm rate, every key of
    :data:`CHECK_KEYS` (lists appended, ``verified`` and-ed)."""
    scan = data.get("events_scan")
    if isinstance(scan, dict) and scan.get("false_alarm_rate_per_record") is not None:  # an outliers file: one axis
        target.setdefault("events_scanned", []).append(float(scan["false_alarm_rate_per_record"]))
        step = scan.get("step_scan") if isinstance(scan.get("step_scan"), dict) else {}
        if step.get("smallest_step") is not None:  # the least step the scan reports on this axis
            target.setdefault("step_floor", []).append(
                {**{k: data.get(k) for k in ("dataset", "axis")},
                 **{k: step[k] for k in ("smallest_step", "smallest_step_tau_s", "smallest_step_display") if k in step}})
    if data.get("n_tested") is not None and data.get("f_min_hz") is not None:  # a lines file: the band it searched
        target.setdefault("line_search", []).append(
            {**{k: data.get(k) for k in ("dataset", "axis", "f_min_hz", "f_max_hz", "resolution_hz", "alpha",
                                         "n_tested", "n_segments", "effective_segments", "floor_window_bins")},
             **{k: data[k] for k in ("low_band", "low_band_finer", "scales", "bursts_filled")
                if isinstance(data.get(k), (dict, list))}})
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


def psd_usage(path: str) -> dict | None:
    """The PSD file's labels and sample counts (global attrs dataset, sensor, axis, n_samples, n_samples_used,
    window_s, step_s, rate_hz; n_filled and filled_rows: the samples ``gap_policy: fill`` inserted in the record and
    the file rows before its gaps), or None for a missing or unreadable file."""
    import netCDF4

    if not Path(path).is_file():
        return None
    try:
        with netCDF4.Dataset(path) as ds:
            attrs = {k: ds.getncattr(k) for k in ds.ncattrs()}
    except OSError:
        return None
    keys = ("dataset", "sensor", "axis", "n_samples", "n_samples_used", "window_s", "step_s", "rate_hz", "n_filled",
            "filled_rows")
    return {k: (attrs[k].item() if hasattr(attrs[k], "item") else attrs[k]) for k in keys if k in attrs}


def group_run_files(files: dict, sensors: list, specs: list) -> tuple[dict, dict, list]:
    """The run's files grouped for :func:`imupipe.summary.summary_sections`.

    Returns ``(runs, kalibr, others)``: ``runs[spec][sensor]`` = {"bound", "identify", "stationarity"} dicts (the
    contract's verdict over the bound file's, the other kinds' check keys merged into "bound"); ``kalibr[spec]`` =
    (path, the Kalibr file as read); ``others``: lines naming the files matched to no sensor or unreadable."""
    from imupipe.io import read_yaml

    runs = {spec: {s: {} for s in sensors} for spec in specs}
    kalibr, others = {}, []
    for kind, paths in files.items():
        for path in paths:
            if kind == "psd":  # netCDF: the Welch segments' share of each record, per sensor
                usage = psd_usage(path)
                if usage and usage.get("sensor") in sensors:
                    for sp in specs:
                        runs[sp][usage["sensor"]].setdefault("bound", {}).setdefault("psd_usage", []).append(usage)
                continue
            data = read_yaml(path) if Path(path).is_file() else None
            if not isinstance(data, dict):
                others.append(f"- {kind} [{path}]: missing or not a YAML mapping")
                continue
            if kind == "kalibr":
                spec = next((s for s in specs if s in Path(path).parts[:-1]), specs[0] if specs else None)
                kalibr[spec] = (path, data)
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
                elif kind == "bound":
                    entry["bound"] = {**data, **entry.get("bound", {})}
                elif kind in ("identify", "stationarity"):
                    entry[kind] = data
                else:
                    merge_checks(entry.setdefault("bound", {}), data)
    return runs, kalibr, others


def summary_text(files: dict, sensors: list, specs: list, name: str) -> str:
    """The run summary (markdown): every spec sheet's first screen, then
    :data:`imupipe.summary.DETAILS_HEADING` and every spec sheet's details, then the files matched to no sensor."""
    from imupipe.summary import DETAILS_HEADING, summary_sections

    runs, kalibr, others = group_run_files(files, sensors, specs)
    heads, details = [], []
    for spec in specs:
        path, data = kalibr.get(spec, (None, None))
        head, detail = summary_sections(runs[spec], title=f"imupipe run summary: {name}, spec sheet {spec}",
                                        kalibr=data, kalibr_path=path)
        heads.append(head.rstrip())
        details.append((f"## spec sheet {spec}\n\n" if len(specs) > 1 else "") + detail.rstrip())
    text = "\n\n".join(heads) + "\n\n" + DETAILS_HEADING + "\n\n" + "\n\n".join(details)
    if others:
        text += "\n\n## Other run files\n\n" + "\n".join(others)
    return text + "\n"


def run_files(run_dir) -> tuple[dict, list, list]:
    """The files a finished run's summary reads, found under `run_dir` (``results/<name>``) as the workflow names
    them: ``(files, sensors, specs)`` with ``files`` kind -> paths (bound, contract, verify, identify, stationarity,
    lines, outliers, psd, kalibr), the sensors and spec sheets of the bound files (``bound/{spec}/{sensor}.yaml``)."""
    base = Path(run_dir)
    bounds = sorted(p for p in base.glob("bound/*/*.yaml"))
    specs = sorted({p.parent.name for p in bounds})
    order = ("gyro", "accel")  # the default config's order
    sensors = sorted({p.stem for p in bounds}, key=lambda s: (order.index(s) if s in order else len(order), s))
    files = {"bound": [str(p) for p in bounds]}
    for kind, pattern in (("contract", "contract/*/*.yaml"), ("verify", "verify/*/*.yaml"),
                          ("identify", "identify/*.yaml"), ("stationarity", "stationarity/*.yaml"),
                          ("lines", "lines/*/*/*.yaml"), ("outliers", "outliers/*/*/*.yaml"),
                          ("psd", "psd/*/*/*.nc"), ("kalibr", "kf/*/kalibr_imu.yaml")):
        found = sorted(str(p) for p in base.glob(pattern))  # (contract/verdict.yaml lies one level up: not matched)
        if found:
            files[kind] = found
    return files, sensors, specs


def summarise_results(results) -> str:
    """The summary of every finished run under `results` (``results/<name>/`` folders, or one such folder), as the
    workflow's summary job writes it (:func:`summary_text` on :func:`run_files`); "" when no bound file is found."""
    results = Path(results)
    # a run folder holds bound/{spec}/{sensor}.yaml; a bound/ folder inside a run (the report's copies under
    # report/bound/) is not one
    runs = sorted({p.parents[2] for p in results.rglob("bound/*/*.yaml")
                   if p.parent.name != "axes" and not (p.parents[3] / "bound").is_dir()})
    texts = []
    for run_dir in runs:
        files, sensors, specs = run_files(run_dir)
        if specs and sensors:
            texts.append(summary_text(files, sensors, specs, run_dir.name))
    return "\n\n".join(t.rstrip() for t in texts) + ("\n" if texts else "")


def end_of_run_text(results, logs, summary_md, failed: bool = False) -> str:
    """What a run prints at its end: the first screen of `summary_md` when the run wrote it; after a failure (or
    without it) the first screen of :func:`summarise_results` on the files the run left under `results`, marked
    partial, and where the failed job's log is. The same text as a finished run's summary job writes, so a partial
    summary never says something a finished one would not. "" when there is nothing to say."""
    from imupipe.summary import first_screen

    md, text = Path(summary_md), ""
    gate = Path(logs) / "contract" / "verdict.log"  # the integrity job's log (rule integrity)
    # a run whose only verdict is NOT BOUNDED fails in its integrity job, on purpose, after the summary job: that
    # summary is complete (a run starts by removing its stale outputs, so it is this run's), not partial
    not_bounded = (failed and md.is_file() and gate.is_file()
                   and "imupipe integrity: NOT BOUNDED" in gate.read_text(errors="replace"))
    if (not failed or not_bounded) and md.is_file():
        text = md.read_text()
    elif Path(results).is_dir():
        text = summarise_results(results)
        if text and failed:  # the counts cover the files written before the failure, not the failed job
            text = text.replace("**Verdict:**", "**Verdict (run FAILED; partial, not a verdict):**", 1)
        why = "; a job failed, so no check count below says the run passed" if failed else ""
        text = f"(partial: from the files this run has written so far{why})\n{text}" if text else ""
    # paths absolute: `imupipe run` runs in the checkout (or --directory), not where the user typed it; the
    # summary's own paths (`results/<name>/kf/...`) are relative to that working directory
    first = first_screen(text).rstrip() if text else ""
    if first and not Path(results).is_absolute():
        rel = Path(results).as_posix().rstrip("/")
        first = re.sub(rf"(?<![\w./-]){re.escape(rel)}/", Path(results).resolve().as_posix() + "/", first)
    parts = [first] if first else []  # the details stay in summary.md
    md_at, logs_at = md.resolve(), Path(logs).resolve()
    if not_bounded:
        parts.append(f"NOT BOUNDED: the integrity job failed the run on purpose (verify.on_failure: fail; warn makes "
                     f"it a warning); the verdict and its details: {md_at} (another job that failed is named above)")
    elif failed:  # a run starts by removing its stale outputs: a summary.md here was written by this run
        parts.append(f"RUN FAILED: the failed job's log is under {logs_at}/ (the error above names it); " +
                     (f"{md_at} was written before the failure and does not cover the failed job." if md.is_file()
                      else "summary.md is written only by a complete run."))
    elif md.is_file():
        parts.append(f"Summary with the details: {md_at}; the HTML report: imupipe run <this run's config> -- --report "
                     f"{Path(results).resolve()}/report.html (or make report CONFIG=<this run's config>)")
    return "".join(f"\n{p}\n" for p in parts).rstrip("\n")


def front_page(template: str, html_page: str) -> str:
    """The report's first page (reStructuredText): the workflow description, then the summary's first screen as
    raw HTML (its tables rendered), the HTML kept out of the report's Jinja rendering. The summary's style is
    scoped to its block, which spans the report's content panel (the panel is a narrow flex item beside the
    rule graph otherwise)."""
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
    # the report puts the description in a narrow prose column (max-w-lg, 32 rem) beside the rule graph: the page
    # holding the summary lets that column span the panel and the graph wrap below it (tests/test_report_browser.py
    # measures the widths at 1 400 px); the report's code style adds backticks around code, dropped here
    css += (".flex.gap-3:has(.imupipe-summary){flex-wrap:wrap}"
            ".py-2:has(.imupipe-summary){flex:1 1 100%;min-width:0}"
            ".prose:has(.imupipe-summary){max-width:none}"
            ".imupipe-summary table{width:auto}"
            ".imupipe-summary code::before,.imupipe-summary code::after{content:none}")
    inner = f'<style>{css}</style><div class="imupipe-summary">{body.group(1) if body else html_page}</div>'
    raw = "\n".join("   " + ln for ln in inner.splitlines())
    return (Path(template).read_text().rstrip() + "\n\n"
            "The run summary's first screen (the details, with the reasons for each state: the category "
            "\"0 Summary\" and ``summary.md`` of the run):\n\n"
            "{% raw %}\n.. raw:: html\n\n" + raw + "\n\n{% endraw %}\n")


def summary_stage(files: dict, sensors: list, specs: list, name: str, path_md: str, path_html: str, template: str,
                  path_front: str) -> None:
    """Write the summary (`path_md`), its HTML page (`path_html`) and the report's first page (`path_front`)."""
    from imupipe.io import write_text_atomic
    from imupipe.summary import first_screen, markdown_to_html

    text = summary_text(files, sensors, specs, name)
    write_text_atomic(text, path_md)
    write_text_atomic(markdown_to_html(text, title=f"imupipe run summary: {name}"), path_html)
    Path(path_front).parent.mkdir(parents=True, exist_ok=True)
    front = markdown_to_html(first_screen(text), title=f"imupipe run summary: {name}")
    write_text_atomic(front_page(template, front), path_front)
    logging.info("summary of %d file(s) written to %s", sum(len(v) for v in files.values()), path_md)
