"""A self-contained HTML page of the small markdown subset the run summary and tables use (:func:`markdown_to_html`);
no imupipe imports, nothing printed."""

from __future__ import annotations

__all__ = ["markdown_to_html"]


def markdown_to_html(text: str, *, title: str = "imupipe") -> str:
    """A self-contained HTML page of the small markdown subset the run files use (for the HTML report).

    Handles ``#``/``##``/``###`` headings, ``|``-tables with a ``|---|`` separator line, ``-`` bullet lists
    (two-space indented items nested), ``**bold**``, inline ``code`` and paragraphs; everything else is
    escaped text. Lines starting with ``- FAIL`` / ``- FLAG`` get the classes ``fail`` / ``flag``.
    """
    import html
    import re

    def inline(s: str) -> str:
        s = html.escape(s)
        s = re.sub(r"\*\*(.+?)\*\*", r"<strong>\1</strong>", s)
        return re.sub(r"`([^`]+)`", r"<code>\1</code>", s)

    out, lines, i = [], text.splitlines(), 0
    para: list[str] = []

    def flush():
        if para:
            out.append(f"<p>{inline(' '.join(para))}</p>")
            para.clear()

    while i < len(lines):
        ln = lines[i]
        m = re.match(r"^(#{1,3}) (.*)$", ln)
        if m:
            flush()
            n = len(m.group(1))
            out.append(f"<h{n}>{inline(m.group(2))}</h{n}>")
            i += 1
        elif ln.startswith("|") and i + 1 < len(lines) and re.match(r"^\|(\s*:?-+:?\s*\|)+\s*$", lines[i + 1]):
            flush()
            cells = [c.strip() for c in ln.strip().strip("|").split("|")]
            rows = ["<tr>" + "".join(f"<th>{inline(c)}</th>" for c in cells) + "</tr>"]
            i += 2
            while i < len(lines) and lines[i].startswith("|"):
                cells = [c.strip() for c in lines[i].strip().strip("|").split("|")]
                rows.append("<tr>" + "".join(f"<td>{inline(c)}</td>" for c in cells) + "</tr>")
                i += 1
            out.append("<table>" + "".join(rows) + "</table>")
        elif re.match(r"^\s*- ", ln):
            flush()
            items = []
            while i < len(lines) and re.match(r"^\s*- ", lines[i]):
                item = lines[i]
                nested = item.startswith("  ")
                body = item.strip()[2:]
                cls = " class=\"fail\"" if body.startswith("FAIL") else " class=\"flag\"" if body.startswith("FLAG") else ""
                items.append((nested, f"<li{cls}>{inline(body)}</li>"))
                i += 1
            html_items, open_nested = [], False
            for nested, li in items:
                if nested and not open_nested:
                    html_items.append("<ul>")
                    open_nested = True
                if not nested and open_nested:
                    html_items.append("</ul>")
                    open_nested = False
                html_items.append(li)
            if open_nested:
                html_items.append("</ul>")
            out.append("<ul>" + "".join(html_items) + "</ul>")
        elif not ln.strip():
            flush()
            i += 1
        else:
            para.append(ln.strip())
            i += 1
    flush()
    style = ("body{font-family:sans-serif;max-width:60em;margin:1em auto}table{border-collapse:collapse}"
             "td,th{border:1px solid #999;padding:2px 8px;text-align:right}th{background:#eee}"
             "td:first-child,th:first-child{text-align:left}.fail{color:#b00;font-weight:bold}.flag{color:#a60}")
    return (f"<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>{html.escape(title)}</title>"
            f"<style>{style}</style></head><body>\n" + "\n".join(out) + "\n</body></html>\n")
