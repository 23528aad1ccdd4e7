"""The quality report's blocks (`handeye.workflow.report_layout`) as one self-contained HTML page or as
markdown with its figures beside it.

Everything taken from the user's data (file names, the command line, warnings) is escaped: in
HTML by `html.escape`; in markdown so that it renders as the text it is (`md_text`): no tag,
entity, link, image or code span can form from ``<img src=x onerror=...>`` in a file name.
"""

from __future__ import annotations

import base64
import html
import re
import urllib.parse
from collections.abc import Mapping, Sequence
from typing import Any

from handeye.workflow.report_layout import Block, Figure, Heading, Pre, Table, Text

CSS = """body{font-family:system-ui,sans-serif;max-width:62em;margin:2em auto;padding:0 1em;color:#222}
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ccc;padding:.2em .6em;text-align:right}
th{background:#f3f3f3}td.l,th.l{text-align:left}tr.outlier td{background:#fde2e2;color:#a00}
pre{background:#f7f7f7;padding:.5em}.status{font-size:1.2em;font-weight:bold}.bad{color:#b00}.ok{color:#070}
img{max-width:100%}"""


def html_page(blocks: Sequence[Block], images: Mapping[str, bytes]) -> str:
    """One HTML page; figures whose name is in `images` (PNG bytes) embedded as base64 ``data:``
    URIs, the others left out."""
    e = html.escape
    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>handeye calibration report</title>"
             f"<style>{CSS}</style></head><body>"]
    for b in blocks:
        if isinstance(b, Heading):
            parts.append(f"<h{b.level}>{e(b.text)}</h{b.level}>")
        elif isinstance(b, Text):
            parts.append(f"<p class='{e(b.css)}'>{e(b.text)}</p>" if b.css else f"<p>{e(b.text)}</p>")
        elif isinstance(b, Pre):
            parts.append(f"<pre>{e(b.text)}</pre>")
        elif isinstance(b, Table):
            parts.append(_html_table(b))
        elif isinstance(b, Figure) and b.name in images:
            data = base64.b64encode(images[b.name]).decode("ascii")
            parts.append(f"<p><img alt='{e(b.alt)}' src='data:image/png;base64,{data}'></p>")
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"


def _html_table(t: Table) -> str:
    e = html.escape

    def cells(row: Sequence[str], tag: str) -> str:
        return "".join(f"<{tag} class='l'>{e(c)}</{tag}>" if k < t.left else f"<{tag}>{e(c)}</{tag}>"
                       for k, c in enumerate(row))

    head = "" if t.header is None else f"<tr>{cells(t.header, 'th')}</tr>"
    body = "".join(f"<tr class='outlier'>{cells(row, 'td')}</tr>" if k < len(t.marked) and t.marked[k]
                   else f"<tr>{cells(row, 'td')}</tr>" for k, row in enumerate(t.rows))
    return f"<table>{head}{body}</table>"


def markdown(blocks: Sequence[Block], image_names: Mapping[str, str]) -> str:
    """Markdown; figures named in `image_names` (figure name -> file name relative to the report)
    linked, the others left out. A table without header becomes a list of "name: value"."""
    out: list[str] = []
    for b in blocks:
        if isinstance(b, Heading):
            out += ["#" * b.level + " " + md_text(b.text), ""]
        elif isinstance(b, Text):
            out += [f"**{md_text(b.text)}**" if b.css else md_text(b.text), ""]
        elif isinstance(b, Pre):
            out += ["```", b.text, "```", ""]
        elif isinstance(b, Table):
            out += [_md_table(b), ""]
        elif isinstance(b, Figure) and b.name in image_names:
            out += [f"![{md_text(b.alt)}]({urllib.parse.quote(image_names[b.name])})", ""]
    return "\n".join(out)


def _md_table(t: Table) -> str:
    if t.header is None:
        return "\n".join(f"- {md_text(row[0])}: " + " ".join(md_text(c) for c in row[1:]) for row in t.rows)
    lines = ["| " + " | ".join(md_text(h) for h in t.header) + " |", "|" + "---|" * len(t.header)]
    for k, row in enumerate(t.rows):
        cells = [md_text(c) for c in row]
        if k < len(t.marked) and t.marked[k]:
            cells = [f"**{c}**" if c else c for c in cells]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def md_text(text: Any) -> str:
    """`text` (a file name, a warning, the command line: anything from the user's data) as
    markdown that renders as that text: no HTML tag, entity, link, image or code span can form
    (``<img src=x onerror=...>`` in a file name stays text), and on one line."""
    text = html.escape(" ".join(str(text).split()), quote=False)  # < > & as entities
    return re.sub(r"([\\`\[\]|*])", r"\\\1", text)
