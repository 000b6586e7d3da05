"""The workflow's HTML report rendered by a real browser (headless Chromium): the page loads, shows the
workflow's description and result categories, and carries every figure the run wrote, with its caption.

Installs nothing: skipped with a reason where /usr/bin/chromium is absent (Debian package ``chromium``).
Runs the tiny test configuration (about 30 s on 2 cores): marked ``browser`` and ``slow``
(``pytest -m browser``)."""

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

pytest.importorskip("snakemake", reason="the report test runs the workflow (pip install -e '.[test]')")

pytestmark = [pytest.mark.browser, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[1]
TINY = ROOT / "tests" / "configs" / "tiny.yaml"
CHROMIUM = Path("/usr/bin/chromium")
ENV = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "MPLBACKEND": "Agg"}
FIGURE_SUFFIXES = (".png", ".svg", ".pdf")


def _chromium(tmp_path, url, *args, timeout=120):
    flags = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             f"--user-data-dir={tmp_path / 'chromium-profile'}", "--virtual-time-budget=15000"]
    return subprocess.run([str(CHROMIUM), *flags, *args, url], capture_output=True, timeout=timeout)


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    if not CHROMIUM.is_file():
        pytest.skip(f"{CHROMIUM} not found: install Debian's chromium package to render the report")
    work = tmp_path_factory.mktemp("report")
    shutil.copytree(ROOT / "config" / "specs", work / "specs")
    cfg = yaml.safe_load(TINY.read_text())
    cfg["spec_dir"] = str(work / "specs")
    config = work / "config.yaml"
    config.write_text(yaml.safe_dump(cfg))
    base = [sys.executable, "-m", "snakemake", "--snakefile", str(ROOT / "Snakefile"), "--cores", "2",
            "--directory", str(work), "--configfile", str(config)]
    for extra in ([], ["--report", str(work / "report.html")]):
        proc = subprocess.run(base + extra, capture_output=True, text=True, env=ENV, timeout=900)
        assert proc.returncode == 0, proc.stderr[-4000:]
    dom = _chromium(work, (work / "report.html").as_uri(), "--dump-dom")
    assert dom.returncode == 0, dom.stderr.decode(errors="replace")[-2000:]
    html = dom.stdout.decode(errors="replace")
    text = re.sub(r"<script.*?</script>|<style.*?</style>", " ", html, flags=re.S)
    text = re.sub(r"\s+", " ", re.sub(r"<[^>]+>", " ", text))
    return {"work": work, "html": html, "text": text}


def test_page_renders_description_and_categories(report):
    text = report["text"]
    assert "Results" in text  # the report's script ran: its menu is in the DOM
    assert "imupipe" in text and "bounds every sample PSD" in text
    assert "Bound" in text  # the category of the bound's figures


def test_every_figure_of_the_run_is_on_the_page_with_its_caption(report):
    figures = sorted(p for p in (report["work"] / "results").rglob("*") if p.suffix in FIGURE_SUFFIXES
                     and "benchmarks" not in p.parts)
    assert figures, "the run wrote no figure"
    html = report["html"]
    for fig in figures:
        rel = fig.relative_to(report["work"]).as_posix()
        m = re.search(re.escape(json.dumps(rel)) + r': \{"name": "[^"]+", "filename": "([^"]+)"(.*?)"mime_type": '
                      r'"([^"]+)"', html, flags=re.S)
        assert m, f"{rel} is not in the report"
        assert m.group(1) == fig.name
        assert m.group(3).startswith("image/") or m.group(3) == "application/pdf", (rel, m.group(3))
        caption = re.search(r'"caption": "(.*?)"', m.group(2), flags=re.S)
        assert caption and len(caption.group(1)) > 20, f"{rel} has no caption"


def test_screenshot_is_not_blank(report, tmp_path):
    shot = tmp_path / "report.png"
    proc = _chromium(tmp_path, (report["work"] / "report.html").as_uri(), f"--screenshot={shot}",
                     "--window-size=1280,900")
    assert proc.returncode == 0 and shot.is_file()
    from matplotlib.image import imread

    img = imread(shot)
    assert img.shape[0] == 900 and img.shape[1] == 1280
    assert img[..., :3].std() > 0.01  # something is drawn, not a uniform page


def test_first_page_shows_the_verdict(report):
    verdicts = []
    for path in sorted((report["work"] / "results").rglob("bound/*/*.yaml")):
        b = yaml.safe_load(path.read_text())
        if isinstance(b, dict) and "bounded" in b and "sensor" in b:
            verdicts.append(f"{b['sensor']}: {'BOUNDED' if b['bounded'] else 'NOT BOUNDED'}")
    assert verdicts
    # the first page (the workflow description, shown when the report opens) holds the verdicts and the
    # inflation table as a rendered table
    first = _first_page(report)
    for v in verdicts:
        assert v in first, v
    assert "bound/spec" in first and "white noise N" in first


def _first_page(report):
    """Text of the run summary block of the report's first page (the workflow description, rendered in the DOM
    when the report opens; the page's scripts left out)."""
    dom = re.sub(r"<script.*?</script>", " ", report["html"], flags=re.S)
    start = dom.find('class="imupipe-summary"')
    assert start >= 0, "the run summary is not on the report's first page"
    text = re.sub(r"<style.*?</style>", " ", dom[start:], flags=re.S)
    return re.sub(r"\s+", " ", re.sub(r"<[^>]+>", " ", text))
