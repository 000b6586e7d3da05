"""Citations in the code name what a user's clone has: every `docs/method.md, section "<title>"` names a heading
of docs/method.md, and no file cites the method by a section number or a folder outside the project."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CITE = re.compile(r"""docs/method\.md, ["']?\s*(?:["']\s*)?section ["']([^"']+)["']""")
WHERE = [ROOT / "src" / "imupipe", ROOT / "tests", ROOT / "config"]
SUFFIXES = {".py", ".yaml", ".c", ".md"}


def _files():
    for base in WHERE:
        for p in sorted(base.rglob("*")):
            if p.suffix in SUFFIXES and p.is_file() and p.name != "test_citations.py":
                yield p


def _headings():
    return {m.group(1).strip() for m in re.finditer(r"^#+ (.+)$", (ROOT / "docs" / "method.md").read_text(), re.M)}


def test_cited_sections_exist():
    headings = _headings()
    cited = [(p.relative_to(ROOT), t) for p in _files() for t in CITE.findall(p.read_text(errors="replace"))]
    assert len(cited) > 10  # the scan reads the files (guards against a test that passes on nothing)
    missing = [f"{p}: {t!r}" for p, t in cited if t not in headings]
    assert not missing, "citations of docs/method.md sections that do not exist:\n" + "\n".join(missing)


def test_no_numbered_or_outside_citation():
    bad = re.compile(r"method notes|method\.md (section )?\d|\.\./shared/docs")
    hits = [f"{p.relative_to(ROOT)}:{i}" for p in _files()
            for i, line in enumerate(p.read_text(errors="replace").splitlines(), 1) if bad.search(line)]
    assert not hits, "citations a user's clone cannot follow:\n" + "\n".join(hits)
