"""report.html beside every report.md, and outputs/index.html listing every report.

The report stage writes report.md; this renders the same text as HTML, figures by their relative
names (the folder stays movable), each heading an anchor, each figure's condition table an
anchor (`conditions-<figure>`) that the scorecard's cells link to. The Markdown is the report's
own small subset (headings, paragraphs, lists, pipe tables with <br> in cells, images, links,
emphasis, code spans, <details> blocks), so a converter of its own is a few dozen lines and the
report stage gains no dependency. `python -m pipeline.html_report [ROOT]` renders every report.md
under ROOT (default: outputs/) again and writes ROOT/index.html: each report with its first
figure, its date and the settings in which its command differs from the others'.
"""
from __future__ import annotations

import html
import re
import sys
from pathlib import Path

from . import io

STYLE = """body{font:15px/1.5 system-ui,sans-serif;max-width:1200px;margin:2em auto;padding:0 1em}
img{max-width:100%}table{border-collapse:collapse;font-size:13px;margin:1em 0}
td,th{border:1px solid #ccc;padding:2px 6px;vertical-align:top}th{background:#f3f3f3}
code{background:#f3f3f3;padding:0 2px}td a{color:inherit}.index img{max-width:320px}"""
INLINE = [(re.compile(r"!\[([^\]]*)\]\(([^)\s]+)\)"), r'<img src="\2" alt="\1">'),
          (re.compile(r"\[([^\]]+)\]\(([^)\s]+)\)"), r'<a href="\2">\1</a>'),
          (re.compile(r"\*\*(.+?)\*\*"), r"<strong>\1</strong>"),
          (re.compile(r"(?<![\w*])\*([^*\s][^*]*?)\*(?![\w*])"), r"<em>\1</em>")]
TAGS = re.compile(r"&lt;(/?(?:br|details|summary|sub|sup)\s*/?)&gt;")
CODE = re.compile(r"`([^`]+)`")


def inline(text: str) -> str:
    """One line of Markdown as HTML: code spans kept verbatim, the few tags the report writes
    passed through, the rest escaped."""
    parts = CODE.split(text)
    out = []
    for i, part in enumerate(parts):
        if i % 2:
            out.append(f"<code>{html.escape(part)}</code>")
            continue
        part = TAGS.sub(r"<\1>", html.escape(part, quote=False))
        for pattern, repl in INLINE:
            part = pattern.sub(repl, part)
        out.append(part)
    return "".join(out)


def slug(text: str) -> str:
    return re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-")


def _cells(line: str) -> list[str]:
    return [c.strip() for c in line.strip().strip("|").split("|")]


def _table(rows: list[str], links: dict) -> str:
    """A pipe table; a figure's condition table (first column `figure`, then `condition`) gets
    the anchor its figure's scorecard cells link to; the scorecard's cells (first column `claim
    of the paper`) link to the condition table of their column's figure."""
    head, body = _cells(rows[0]), [_cells(r) for r in rows[2:]]
    attr = ""
    if head[:2] == ["figure", "condition"] and body:
        anchor = f"conditions-{slug(body[0][0])}"
        if anchor not in links.setdefault("_seen", set()):
            links["_seen"].add(anchor)
            attr = f' id="{anchor}"'
    scorecard = head[0] == "claim of the paper"
    out = [f"<table{attr}><thead><tr>" + "".join(f"<th>{inline(c)}</th>" for c in head)
           + "</tr></thead><tbody>"]
    for row in body:
        cells = []
        for j, c in enumerate(row):
            text = inline(c)
            target = f"conditions-{slug(head[j])}" if scorecard and j < len(head) else ""
            if target in links.get("_tables", ()) and c not in ("", "—"):
                text = f'<a href="#{target}">{text}</a>'
            cells.append(f"<td>{text}</td>")
        out.append("<tr>" + "".join(cells) + "</tr>")
    return "\n".join(out + ["</tbody></table>"])


def to_html(markdown: str, title: str | None = None) -> str:
    """The report's Markdown as a standalone HTML page."""
    lines = markdown.splitlines()
    tables = {f"conditions-{slug(_cells(lines[i + 2])[0])}" for i in range(len(lines) - 2)
              if lines[i].startswith("| figure | condition |") and lines[i + 2].startswith("|")}
    links: dict = {"_tables": tables}
    out, i, para = [], 0, []

    def flush():
        if para:
            out.append("<p>" + " ".join(inline(p) for p in para) + "</p>")
            para.clear()

    while i < len(lines):
        line = lines[i]
        heading = re.match(r"(#{1,6}) (.*)", line)
        if line.startswith("```"):
            flush()
            j = next((k for k in range(i + 1, len(lines)) if lines[k].startswith("```")),
                     len(lines))
            out.append("<pre><code>" + html.escape("\n".join(lines[i + 1:j])) + "</code></pre>")
            i = j + 1
            continue
        if heading:
            flush()
            level, text = len(heading.group(1)), heading.group(2)
            title = title or re.sub(r"[`*]", "", text)
            out.append(f'<h{level} id="{slug(text)}">{inline(text)}</h{level}>')
        elif line.startswith("|") and i + 1 < len(lines) and re.match(r"\|[-:| ]+\|$",
                                                                         lines[i + 1].strip()):
            flush()
            j = i
            while j < len(lines) and lines[j].startswith("|"):
                j += 1
            out.append(_table(lines[i:j], links))
            i = j
            continue
        elif re.match(r"\s*[-*] ", line):
            flush()
            items = []
            while i < len(lines) and re.match(r"\s*[-*] |\s{2,}\S", lines[i]):
                if re.match(r"\s*[-*] ", lines[i]):
                    items.append(re.sub(r"^\s*[-*] ", "", lines[i]))
                else:
                    items[-1] += " " + lines[i].strip()
                i += 1
            out.append("<ul>" + "".join(f"<li>{inline(t)}</li>" for t in items) + "</ul>")
            continue
        elif re.match(r"\s*</?(details|summary)", line):
            flush()
            out.append(TAGS.sub(r"<\1>", inline(line)))
        elif not line.strip():
            flush()
        else:
            para.append(line)
        i += 1
    flush()
    return (f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
            f"<title>{html.escape(title or 'report')}</title><style>{STYLE}</style></head>"
            "<body>\n" + "\n".join(out) + "\n</body></html>\n")


def write_html(report_md: Path) -> Path:
    """report.html beside report_md, rendered from it."""
    report_md = Path(report_md)
    target = report_md.with_name("report.html")
    io.write_text(target, to_html(report_md.read_text()))
    return target


# ---- outputs/index.html ---------------------------------------------------------------------------
MADE = re.compile(r"^- made (\d{4}-\d\d-\d\d \d\d:\d\d UTC)[^`]*`([^`]*)`", re.M)


def describe(report_md: Path) -> dict:
    """A report's title, first figure, date and command line (its Provenance section)."""
    text = report_md.read_text()
    title = next((ln[2:] for ln in text.splitlines() if ln.startswith("# ")), report_md.parent.name)
    figure = re.search(r"!\[[^\]]*\]\(([^)\s]+)\)", text)
    made = MADE.search(text)
    return dict(title=title, figure=figure.group(1) if figure else None,
                date=made.group(1) if made else "",  # the command's settings: its overrides
                args=[a for a in made.group(2).split() if "=" in a] if made else [])


def write_index(root: Path) -> Path:
    """root/index.html: every report.md under root, newest first, each with its first figure,
    date and the command-line settings not shared by every report."""
    root = Path(root)
    reports = sorted(p for p in root.rglob("report.md")
                     if not any(part.startswith(".") for part in p.relative_to(root).parts))
    info = {p: describe(p) for p in reports}
    common = (set.intersection(*(set(d["args"]) for d in info.values())) if len(info) > 1
              else set())  # one report: all its settings
    rows = []
    for p, d in sorted(info.items(), key=lambda kv: kv[1]["date"], reverse=True):
        folder = p.parent.relative_to(root).as_posix()
        page = f"{folder}/report.html" if p.with_name("report.html").exists() else f"{folder}/report.md"
        img = (f'<img src="{html.escape(folder + "/" + d["figure"])}" alt="{html.escape(d["title"])}">'
               if d["figure"] else "")
        settings = " ".join(a for a in d["args"] if a not in common) or "(the same as all)"
        rows.append(f'<tr><td><a href="{html.escape(page)}">{html.escape(folder)}</a><br>'
                    f"{html.escape(d['title'])}</td><td>{img}</td><td>{html.escape(d['date'])}</td>"
                    f"<td><code>{html.escape(settings)}</code></td></tr>")
    body = ("<h1>Reports</h1><table class=\"index\"><thead><tr><th>report</th><th>figure</th>"
            "<th>made</th><th>settings that differ</th></tr></thead><tbody>\n"
            + "\n".join(rows) + "\n</tbody></table>")
    target = root / "index.html"
    io.write_text(target, f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
                  f"<title>Reports</title><style>{STYLE}</style></head><body>\n{body}\n"
                  "</body></html>\n")
    return target


def main(argv: list[str] | None = None) -> int:
    """python -m pipeline.html_report [ROOT]: render every report.md under ROOT, write ROOT/index.html."""
    args = sys.argv[1:] if argv is None else argv
    root = Path(args[0] if args else "outputs")
    if not root.is_dir():
        print(f"error: {root} is not a folder", file=sys.stderr)
        return 2
    for p in sorted(root.rglob("report.md")):
        print(write_html(p))
    print(write_index(root))
    return 0


if __name__ == "__main__":
    sys.exit(main())
