"""A tiny document model rendered twice: self-contained HTML and Markdown.

Sections hold blocks (paragraphs, notes, tables, preformatted text, figures);
one builder produces the content, two renderers give the same sections in
both formats, so the HTML page and its Markdown twin cannot drift apart.
"""

from __future__ import annotations

import base64
import html
import re
from dataclasses import dataclass, field
from pathlib import Path


@dataclass
class Para:
    """A paragraph; ``note`` marks a visible remark (something missing, diverged, skipped)."""

    text: str
    note: bool = False


@dataclass
class Link:
    """A table cell that is a path or address: ``href`` relative to the report's folder."""

    text: str
    href: str


@dataclass
class Table:
    """Rows of cells: text, a ``Link`` or a list of links. Numeric cells are right-aligned,
    text left-aligned; ``collapsed`` folds the table (HTML ``<details>``) under its caption."""

    header: list[str]
    rows: list[list]
    caption: str = ""
    collapsed: bool = False


@dataclass
class Pre:
    """Preformatted text (equations, commands)."""

    text: str
    caption: str = ""


@dataclass
class Figure:
    """A PNG file on disk; the HTML embeds its bytes, the Markdown links ``files_dir/name``."""

    path: Path
    caption: str


@dataclass
class Section:
    id: str
    title: str
    blocks: list = field(default_factory=list)

    def add(self, *blocks) -> Section:
        self.blocks.extend(blocks)
        return self


CSS = """
body{font-family:-apple-system,'Segoe UI',Helvetica,Arial,sans-serif;max-width:1200px;margin:2em auto;
padding:0 1em;color:#222;line-height:1.45}
h1{font-size:1.6em;border-bottom:2px solid #444;padding-bottom:.2em}
h2{font-size:1.3em;margin-top:2em;border-bottom:1px solid #bbb}
h3{font-size:1.05em;margin-top:1.4em}
table{border-collapse:collapse;margin:.6em 0 1.2em;font-size:.82em}
th,td{border:1px solid #ccc;padding:.25em .45em;text-align:left;vertical-align:top}
td{max-width:36em;overflow-wrap:anywhere}
th{background:#eef1f5}.num{text-align:right}td.num{white-space:nowrap}
caption{caption-side:top;text-align:left;font-weight:600;padding:.3em 0}
.scroll{overflow-x:auto;max-width:100%}
details>summary{cursor:pointer;font-weight:600;margin:.6em 0}
pre{background:#f6f8fa;border:1px solid #ddd;padding:.6em;white-space:pre-wrap;font-size:.85em}
.note{background:#fff4e0;border-left:4px solid #e69500;padding:.4em .7em}
figure{margin:1em 0}figure img{max-width:100%;border:1px solid #ddd}
figcaption{font-size:.88em;color:#444}
nav a{margin-right:1em}
"""


def _h(text: str) -> str:
    return html.escape(str(text), quote=True)


# A number, a mean±std, a list of numbers, a ratio ("2.5×"), a count with a remark
# ("0 (12/12 ≤ paper)"), a count out of a total ("10 of 12"), or a mark.
_NUM = re.compile(r"^[-−+]?(\d[\d.,]*(e[-−+]?\d+)?[%×]?)(\s*[±,]\s*[-−+]?\d[\d.]*(e[-−+]?\d+)?)*"
                  r"(\s\(.*\))?$|^\d+ of \d+$|^[✓✗—★]$", re.I)


def is_numeric(cell) -> bool:
    """Whether a cell is a number (or a mark in a column of numbers): right-aligned."""
    return isinstance(cell, str) and bool(_NUM.match(cell.strip()))


def _cell_html(c) -> str:
    if isinstance(c, Link):
        return f'<a href="{_h(c.href)}">{_h(c.text)}</a>'
    if isinstance(c, list):
        return "<br>".join(_cell_html(x) for x in c)
    return _h(c)


def _table_html(b: Table) -> str:
    # A column is numeric when every non-empty cell in it is: header and cells right-aligned.
    ncol = len(b.header)
    num = [all(is_numeric(r[i]) for r in b.rows if i < len(r) and r[i] not in ("", None)) and
           any(i < len(r) and r[i] not in ("", None) for r in b.rows) for i in range(ncol)]

    def td(i, c, tag="td"):
        cls = ' class="num"' if (i < ncol and num[i] and (tag == "th" or is_numeric(c))) else ""
        return f"<{tag}{cls}>{_cell_html(c) if tag == 'td' else _h(c)}</{tag}>"

    head = "".join(td(i, c, "th") for i, c in enumerate(b.header))
    body = "".join("<tr>" + "".join(td(i, c) for i, c in enumerate(r)) + "</tr>" for r in b.rows)
    if b.collapsed:
        return (f"<details><summary>{_h(b.caption or 'table')} ({len(b.rows)} rows)</summary>"
                f'<div class="scroll"><table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table></div>'
                "</details>")
    cap = f"<caption>{_h(b.caption)}</caption>" if b.caption else ""
    return f'<div class="scroll"><table>{cap}<thead><tr>{head}</tr></thead><tbody>{body}</tbody></table></div>'


def render_html(title: str, intro: list, sections: list[Section]) -> str:
    """One self-contained page: inline CSS, figures as base64 data URIs, no external resource."""
    out = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
           f"<title>{_h(title)}</title><style>{CSS}</style></head><body>", f"<h1>{_h(title)}</h1>"]
    out += [_block_html(b) for b in intro]
    out.append("<nav>" + "".join(f'<a href="#{_h(s.id)}">{_h(s.title)}</a>' for s in sections) + "</nav>")
    for s in sections:
        out.append(f'<section id="{_h(s.id)}"><h2>{_h(s.title)}</h2>')
        out += [_block_html(b) for b in s.blocks]
        out.append("</section>")
    out.append("</body></html>")
    return "\n".join(out) + "\n"


def _block_html(b) -> str:
    if isinstance(b, str):  # a sub-heading
        return f"<h3>{_h(b)}</h3>"
    if isinstance(b, Para):
        return f'<p class="note">{_h(b.text)}</p>' if b.note else f"<p>{_h(b.text)}</p>"
    if isinstance(b, Table):
        return _table_html(b)
    if isinstance(b, Pre):
        cap = f"<p><em>{_h(b.caption)}</em></p>" if b.caption else ""
        return f"{cap}<pre>{_h(b.text)}</pre>"
    if isinstance(b, Figure):
        data = base64.b64encode(Path(b.path).read_bytes()).decode("ascii")
        return (f'<figure><img alt="{_h(b.caption)}" src="data:image/png;base64,{data}">'
                f"<figcaption>{_h(b.caption)}</figcaption></figure>")
    raise TypeError(f"unknown block {type(b).__name__}")


def _md_cell(text) -> str:
    if isinstance(text, Link):
        return f"[{_md_cell(text.text)}]({text.href})"
    if isinstance(text, list):
        return "<br>".join(_md_cell(x) for x in text)
    return str(text).replace("|", "\\|").replace("\n", " ")


def render_markdown(title: str, intro: list, sections: list[Section], files_dir: str) -> str:
    """The Markdown twin; figures link ``files_dir/<png name>`` (relative to the .md file)."""
    out = [f"# {title}", ""]
    for b in intro:
        out += [_block_md(b, files_dir), ""]
    for s in sections:
        out += [f'<a id="{s.id}"></a>', "", f"## {s.title}", ""]
        for b in s.blocks:
            out += [_block_md(b, files_dir), ""]
    return "\n".join(out).rstrip() + "\n"


def _block_md(b, files_dir: str) -> str:
    if isinstance(b, str):
        return f"### {b}"
    if isinstance(b, Para):
        return f"> **Note:** {b.text}" if b.note else b.text
    if isinstance(b, Table):
        lines = [f"**{b.caption}**", ""] if b.caption else []
        lines.append("| " + " | ".join(_md_cell(c) for c in b.header) + " |")
        lines.append("|" + "---|" * len(b.header))
        lines += ["| " + " | ".join(_md_cell(c) for c in r) + " |" for r in b.rows]
        return "\n".join(lines)
    if isinstance(b, Pre):
        cap = f"*{b.caption}*\n\n" if b.caption else ""
        return f"{cap}```\n{b.text}\n```"
    if isinstance(b, Figure):
        return f"![{b.caption}]({files_dir}/{Path(b.path).name})\n\n*{b.caption}*"
    raise TypeError(f"unknown block {type(b).__name__}")
