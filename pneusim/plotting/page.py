"""A report page built once as a list of blocks and rendered twice: to Markdown (``report.md``) and to
one self-contained HTML file, its figures inlined as base64 PNG (open it anywhere, mail it, nothing to
keep beside it).

Blocks are ``(kind, payload)`` pairs:

* ``("h", (level, text))`` -- a heading;
* ``("p", text)`` -- a paragraph (``**bold**`` and ```code``` are kept in both renderings);
* ``("ul", [text, ...])`` -- a list;
* ``("table", (header, rows))`` -- a table;
* ``("fig", (file name, caption))`` -- a figure written beside the page;
* ``("code", text)`` -- a block of code or command lines.
"""

from __future__ import annotations

import base64
import html
import re
from pathlib import Path

from ..outputs import write_text_atomic

__all__ = ["render_markdown", "render_html", "write_page"]

_STYLE = ("body{font-family:sans-serif;max-width:60em;margin:2em auto;line-height:1.4}"
          "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #999;padding:2px 6px;"
          "font-size:90%}img{max-width:100%}figcaption{font-style:italic;font-size:90%}"
          "code{background:#eee;padding:0 3px}")


def render_markdown(blocks) -> str:
    """The blocks as Markdown."""
    out = []
    for kind, payload in blocks:
        if kind == "h":
            level, text = payload
            out.append("#" * level + " " + text)
        elif kind == "p":
            out.append(payload)
        elif kind == "ul":
            out.append("\n".join(f"* {item}" for item in payload))
        elif kind == "table":
            header, rows = payload
            cell = lambda c: str(c).replace("|", "\\|")  # noqa: E731 - a pipe would split the cell
            out.append("| " + " | ".join(map(cell, header)) + " |\n|" + "---|" * len(header) + "\n"
                       + "\n".join("| " + " | ".join(map(cell, row)) + " |" for row in rows))
        elif kind == "fig":
            name, caption = payload
            out.append(f"![{caption}]({name})\n\n*{caption}*")
        elif kind == "code":
            out.append(f"```\n{payload}\n```")
    return "\n\n".join(out) + "\n"


def _inline(text) -> str:
    text = html.escape(str(text))
    text = re.sub(r"\*\*(.+?)\*\*", r"<b>\1</b>", text)
    return re.sub(r"`([^`]+)`", r"<code>\1</code>", text)


def render_html(blocks, title: str, folder) -> str:
    """The blocks as one self-contained HTML page; figures are read from ``folder`` and inlined."""
    folder = Path(folder)
    body = []
    for kind, payload in blocks:
        if kind == "h":
            level, text = payload
            body.append(f"<h{level}>{_inline(text)}</h{level}>")
        elif kind == "p":
            body.append(f"<p>{_inline(payload)}</p>")
        elif kind == "ul":
            body.append("<ul>" + "".join(f"<li>{_inline(i)}</li>" for i in payload) + "</ul>")
        elif kind == "table":
            header, rows = payload
            body.append("<table><tr>" + "".join(f"<th>{_inline(h)}</th>" for h in header) + "</tr>"
                        + "".join("<tr>" + "".join(f"<td>{_inline(c)}</td>" for c in row) + "</tr>"
                                  for row in rows) + "</table>")
        elif kind == "fig":
            name, caption = payload
            data = base64.b64encode((folder / name).read_bytes()).decode("ascii")
            body.append(f'<figure><img alt="{html.escape(caption)}" src="data:image/png;base64,{data}">'
                        f"<figcaption>{html.escape(caption)}</figcaption></figure>")
        elif kind == "code":
            body.append(f"<pre>{html.escape(payload)}</pre>")
    return (f"<!DOCTYPE html>\n<html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
            f"<style>{_STYLE}</style></head><body>\n" + "\n".join(body) + "\n</body></html>\n")


def write_page(blocks, folder, title: str, markdown: str = "report.md", html_name: str = "report.html") -> Path:
    """Write ``folder/markdown`` and the self-contained ``folder/html_name`` (each atomically); returns the HTML
    file's path."""
    folder = Path(folder)
    write_text_atomic(folder / markdown, render_markdown(blocks))
    return write_text_atomic(folder / html_name, render_html(blocks, title, folder))
