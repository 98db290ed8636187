"""report.html beside every report.md (its own Markdown subset, no dependency; the scorecard's
cells link to their figure's condition table), and outputs/index.html listing every report.

    python -m pipeline.html_report [ROOT]   # every report.md under ROOT (outputs/) and the index
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
ITEM, RULE = re.compile(r"\s*[-*] "), re.compile(r"\|[-:| ]+\|$")
DETAILS = re.compile(r"\s*</?(details|summary)")


def inline(text: str) -> str:
    """One line as HTML: code spans verbatim, the few tags the report writes passed through."""
    out = []
    for i, part in enumerate(CODE.split(text)):
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


def _table(rows: list[str], tables: set, seen: set) -> str:
    """A pipe table; a figure's first condition table is the anchor its scorecard cells link to."""
    head, body = _cells(rows[0]), [_cells(r) for r in rows[2:]]
    attr = ""
    if head[:2] == ["figure", "condition"] and body:
        anchor = f"conditions-{slug(body[0][0])}"
        attr = "" if anchor in seen else f' id="{anchor}"'
        seen.add(anchor)
    out = [f"<table{attr}><thead><tr>" + "".join(f"<th>{inline(c)}</th>" for c in head)
           + "</tr></thead><tbody>"]
    for row in body:
        cells = []
        for j, c in enumerate(row):
            target = (f"conditions-{slug(head[j])}"
                      if head[0] == "claim of the paper" and j < len(head) else "")
            link = target in tables and c not in ("", "—")
            cells.append(f'<td><a href="#{target}">{inline(c)}</a></td>' if link
                         else f"<td>{inline(c)}</td>")
        out.append("<tr>" + "".join(cells) + "</tr>")
    return "\n".join(out + ["</tbody></table>"])


def _page(title: str, body: str) -> str:
    return (f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
            f"<title>{html.escape(title)}</title><style>{STYLE}</style></head>"
            f"<body>\n{body}\n</body></html>\n")


def to_html(markdown: str, title: str | None = None) -> str:
    """The report's Markdown as a standalone HTML page."""
    lines = markdown.splitlines()
    tables = {f"conditions-{slug(_cells(lines[i + 2])[0])}" for i in range(len(lines) - 2)
              if lines[i].startswith("| figure | condition |") and lines[i + 2].startswith("|")}
    out, i, para, seen = [], 0, [], set()

    def flush():
        if para:
            out.append("<p>" + " ".join(inline(p) for p in para) + "</p>")
            para.clear()

    while i < len(lines):
        line, j = lines[i], i + 1
        heading = re.match(r"(#{1,6}) (.*)", line)
        table = line.startswith("|") and j < len(lines) and RULE.match(lines[j].strip())
        if not (line.startswith("```") or heading or table or ITEM.match(line)
                or DETAILS.match(line)):
            para.append(line) if line.strip() else flush()
            i = j
            continue
        flush()
        if line.startswith("```"):
            j = next((k for k in range(i + 1, len(lines)) if lines[k].startswith("```")),
                     len(lines)) + 1
            out.append("<pre><code>" + html.escape("\n".join(lines[i + 1:j - 1]))
                       + "</code></pre>")
        elif heading:
            level, text = len(heading.group(1)), heading.group(2)
            title = title or re.sub(r"[`*]", "", text)
            out.append(f'<h{level} id="{slug(text)}">{inline(text)}</h{level}>')
        elif table:
            j = i
            while j < len(lines) and lines[j].startswith("|"):
                j += 1
            out.append(_table(lines[i:j], tables, seen))
        elif ITEM.match(line):
            items, j = [], i
            while j < len(lines) and re.match(r"\s*[-*] |\s{2,}\S", lines[j]):
                if ITEM.match(lines[j]):
                    items.append(ITEM.sub("", lines[j], count=1))
                else:
                    items[-1] += " " + lines[j].strip()
                j += 1
            out.append("<ul>" + "".join(f"<li>{inline(t)}</li>" for t in items) + "</ul>")
        else:  # <details>, <summary>
            out.append(TAGS.sub(r"<\1>", inline(line)))
        i = j
    flush()
    return _page(title or "report", "\n".join(out))


def write_html(report_md: Path) -> Path:
    """report.html beside report_md, rendered from it."""
    target = Path(report_md).with_name("report.html")
    io.write_text(target, to_html(Path(report_md).read_text()))
    return target


MADE = re.compile(r"^- made (\d{4}-\d\d-\d\d \d\d:\d\d UTC)[^`]*`([^`]*)`", re.M)


def write_index(root: Path) -> Path:
    """root/index.html: every report.md under root, newest first, each with its first figure,
    date and the command-line settings not shared by every report."""
    root = Path(root)
    info = {p: _describe(p.read_text(), p.parent.name) for p in sorted(root.rglob("report.md"))
            if not any(part.startswith(".") for part in p.relative_to(root).parts)}
    common = (set.intersection(*(set(d["args"]) for d in info.values())) if len(info) > 1
              else set())  # one report: all its settings
    rows = []
    for p, d in sorted(info.items(), key=lambda kv: kv[1]["date"], reverse=True):
        folder, e = p.parent.relative_to(root).as_posix(), html.escape
        page = f"{folder}/report.{'html' if p.with_name('report.html').exists() else 'md'}"
        img = (f'<img src="{e(folder + "/" + d["figure"])}" alt="{e(d["title"])}">'
               if d["figure"] else "")
        settings = " ".join(a for a in d["args"] if a not in common) or "(the same as all)"
        rows.append(f'<tr><td><a href="{e(page)}">{e(folder)}</a><br>{e(d["title"])}</td><td>'
                    f"{img}</td><td>{e(d['date'])}</td><td><code>{e(settings)}</code></td></tr>")
    target = root / "index.html"
    io.write_text(target, _page("Reports", (
        '<h1>Reports</h1><table class="index"><thead><tr><th>report</th><th>figure</th>'
        "<th>made</th><th>settings that differ</th></tr></thead><tbody>\n"
        + "\n".join(rows) + "\n</tbody></table>")))
    return target


def _describe(text: str, folder: str) -> dict:
    """A report's title, first figure, date and command line (its Provenance section)."""
    title = next((ln[2:] for ln in text.splitlines() if ln.startswith("# ")), folder)
    figure, made = re.search(r"!\[[^\]]*\]\(([^)\s]+)\)", text), MADE.search(text)
    return dict(title=title, figure=figure.group(1) if figure else None,
                date=made.group(1) if made else "",  # the command's settings: its overrides
                args=[a for a in made.group(2).split() if "=" in a] if made else [])


def main(argv: list[str] | None = None) -> int:
    """python -m pipeline.html_report [ROOT]: render every report.md under ROOT, write the index."""
    root = Path((sys.argv[1:] if argv is None else argv or [None])[0] or "outputs")
    if not root.is_dir():
        print(f"error: {root} is not a folder", file=sys.stderr)
        return 2
    for p in sorted(root.rglob("report.md")):
        print(write_html(p))
    print(write_index(root))
    return 0


if __name__ == "__main__":
    sys.exit(main())
