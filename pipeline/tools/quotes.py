"""Numbers in the prose that come from the report's tables, each checked against its table.

    python -m pipeline.tools.quotes              # check every page; exit 1 on a drifted number
    python -m pipeline.tools.quotes --fix        # rewrite each quoted number to its table's value
    python -m pipeline.tools.quotes docs/x.md    # only these pages, scanned even if on a list

A quote marker is an HTML comment written right after the number (and its unit), invisible when
the markdown is rendered, naming the cell the number is read from:

    12.4 mm<!-- q: summary.csv figure=fig4 condition=const0.5 final_abs_error_mean*1e3 -->

The marker's words (split like a shell line, so a value with spaces is quoted "..."):
- the table: a file name alone is a file of outputs/report/; a path with a / is from the
  repository root (pipeline/studies/coverage.csv);
- filters `col=value` (the cell's text equals value) and `col~text` (the cell's text contains
  text); together they must select exactly one row;
- the column, with an optional `#k` (the k-th number written in a text cell, from 1:
  `measured#3` of "mean 4.9 mm, worst 16.5 mm" is 16.5) and an optional `*scale` (`*1e3`: metres
  to mm, `*100`: a fraction to %);
- optionally `/` and a second such cell: the number is the first over the second.

The quoted number is compared with the cell's value formatted to the quoted number's own
decimals (a "+" and thousands commas as the quoted one writes them). A number that is not from
the report (the paper's text, a setting, a timing) carries `<!-- q: not data: why -->` instead;
`<!-- q: not data on this line: why -->` anywhere on a line exempts every number of that line
(for a line that holds no number of the report).

Every number with an error-like unit (mm, cm, %, an x or × ratio), and every number of a range or
list ending in one ("17.1-17.9 mm", "12.4 / 12.9 mm"), must carry one of the two: `check`
names each one without (outside code, and outside tables generated between the BEGIN and END
lines of other checked mechanisms).

Exit status: 0 all agree; 1 one line per drifted or unmarked number (page:line: ...); 2 a bad
marker (one line, `error: ...`: a filter or scale it cannot read, a table outside the repository
or not a table, a value that is not finite, a number of more than MAX_DECIMALS decimals, a page
that is not UTF-8), and --fix then writes nothing. --fix replaces a page in one rename (a kill
leaves the old page or the new one). A page is read in time linear in its length.
"""
from __future__ import annotations

import argparse
from decimal import ROUND_HALF_UP, Decimal
import math
import re
import shlex
import sys
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from ..config import REPO_ROOT

REPORT = Path("outputs/report")
# pages the scanner leaves out (their markers are still checked); both empty when every page is
# marked
REWRITTEN_ELSEWHERE: dict[str, str] = {}  # pages another change is rewriting: page -> why
# pages whose error-like numbers are not all marked yet: page -> what is left
NOT_YET_MARKED: dict[str, str] = {}
UNSCANNED_PAGES = {**REWRITTEN_ELSEWHERE, **NOT_YET_MARKED}

MARKER = re.compile(r"<!--\s*q:(?P<body>.*?)-->")
NOT_DATA = re.compile(r"\s*not data(?P<line> on this line)?:\s*(?P<why>\S.*?)\s*$")
# a number: thousands commas, decimals, a sign only where it is not a range's dash ("2-6")
NUMBER = re.compile(r"(?P<sign>(?<![\w.)\]>\0])[-+−])?"
                    r"(?P<digits>\d{1,3}(?:,\d{3})+(?:\.\d+)?|\d+(?:\.\d+)?)")
# the number a marker quotes: the last one before it, then at most a unit
QUOTED = re.compile(NUMBER.pattern + r"(?P<unit>\s?(?:[A-Za-z%×]{1,4})?[*\"'”]*)$")
# a number written in a text cell: not part of a word ("TG10", "fig4", "const0.5")
CELL_NUMBER = re.compile(r"(?<![A-Za-z_\d.])" + NUMBER.pattern)
_NUM = r"[-+−]?(?:\d{1,3}(?:,\d{3})+|\d+)(?:\.\d+)?"
_JOIN = r"\s*(?:-|–|/|->|→|to)\s*"
# numbers that must be quoted: a range or list ending in mm, cm or %; a ratio 1.24x or x1.5
# (a run of numbers joined by dashes, slashes, arrows or "to", then the unit or the x): the whole
# run is matched possessively (never given back) and what ends it is looked at where it ends, so
# a run without one is passed over whole and no start inside it is tried again (linear time;
# backtracking into the run is quadratic on "1 - 1 - 1 ...")
RUN = re.compile(rf"(?<![\w.])(?>{_NUM})(?:{_JOIN}{_NUM})*+")
RUN_ENDS = (re.compile(r"\s?(?:mm|cm|%)(?![A-Za-z])"), re.compile(r"[x×](?![A-Za-z0-9])"))
RATIO_BEFORE = re.compile(rf"(?<![A-Za-z])[x×]{_NUM}(?![\w-])")  # "x1.5", not "x86-64"
TERM_COLUMN = re.compile(r"^(?P<col>[^=~#*]+?)(?:#(?P<k>\d+))?(?:\*(?P<scale>[0-9.eE+-]+))?$")
FILTER = re.compile(r"^(?P<col>[^=~]+)(?P<op>[=~])(?P<want>.*)$")
MAX_DECIMALS = 15  # a float holds 15-17 significant digits: more decimals quote nothing
MAX_QUOTED = 64  # characters of a quoted number and its unit (the tail of the line searched)


class BadMarker(ValueError):
    """A marker that names no single cell, or a number it cannot quote."""


@dataclass
class Quote:
    page: str
    line: int          # 1-based
    start: int         # the quoted number's span in the line (sign included)
    end: int
    text: str          # the number as written
    body: str          # the marker's words
    exempt: str | None  # why it is not data, or None
    exempt_line: bool = False  # the exemption covers every number of its line


def pages(root: Path | None = None) -> list[Path]:
    """README.md, docs/*.md and the hand-written discussion of the report."""
    root = REPO_ROOT if root is None else root
    return [root / "README.md", *sorted((root / "docs").glob("*.md")),
            root / "pipeline" / "studies" / "findings.md"]


# BEGIN and END lines of tables written and checked by other mechanisms: the coverage table
# and the README's readings matrix (pipeline.studies.coverage / readings .BEGIN, .END; the
# machinery imports no study, a test compares them)
GENERATED_BLOCKS = [("<!-- coverage table: pipeline.studies.coverage -->",
                     "<!-- end of coverage table -->"),
                    ("<!-- readings-table:begin -->", "<!-- readings-table:end -->")]


def generated_blocks() -> list[tuple[str, str]]:
    """BEGIN and END lines of tables written and checked by other mechanisms."""
    return list(GENERATED_BLOCKS)


def prose_lines(text: str, blocks=None) -> list[tuple[int, str]]:
    """(line number, line) outside fenced code and generated blocks, inline code blanked."""
    blocks = generated_blocks() if blocks is None else blocks
    out, fence, inside = [], False, None
    for i, line in enumerate(text.splitlines(), 1):
        s = line.strip()
        if inside is not None:
            if s == inside:
                inside = None
            continue
        if s.startswith("```") or s.startswith("~~~"):
            fence = not fence
            continue
        if fence:
            continue
        ends = [end for begin, end in blocks if s == begin]
        if ends:
            inside = ends[0]
            continue
        out.append((i, re.sub(r"`[^`]*`", lambda m: " " * len(m.group()), line)))
    return out


def quotes(page: str, text: str, blocks=None) -> list[Quote]:
    """Every marker of a page with the number it quotes."""
    found = []
    for i, line in prose_lines(text, blocks):
        spans = [m.span() for m in MARKER.finditer(line)]
        for n, m in enumerate(MARKER.finditer(line)):
            nd = NOT_DATA.match(m.group("body"))
            if nd is None and m.group("body").strip().startswith("not data"):
                raise BadMarker(f"{page}:{i}: an exemption says why: <!-- q: not data: why -->")
            if nd and nd.group("line"):
                found.append(Quote(page, i, m.start(), m.start(), "", m.group("body").strip(),
                                   nd.group("why"), exempt_line=True))
                continue
            # the tail before the marker, earlier markers blanked: a number and its unit are short,
            # so the search is bounded however long the line is
            lo = max(0, m.start() - MAX_QUOTED)
            tail = list(line[lo:m.start()])
            for a, b in reversed(spans[:n]):  # only the markers that reach into the tail:
                if b <= lo:                       # the spans are sorted, so the rest end earlier
                    break
                for j in range(max(a, lo), min(b, m.start())):
                    tail[j - lo] = "\0"
            before = "".join(tail)
            q = QUOTED.search(before)
            if q is not None and q.start() == 0 and lo > 0 and line[lo - 1].isdigit():
                raise BadMarker(f"{page}:{i}: the number before a marker is longer than "
                                f"{MAX_QUOTED} characters")
            if q is None:
                raise BadMarker(f"{page}:{i}: a marker without a number right before it: "
                                f"<!-- q:{m.group('body')}-->")
            found.append(Quote(page, i, lo + q.start(), lo + q.end("digits"),
                               (q.group("sign") or "") + q.group("digits"),
                               m.group("body").strip(), nd.group("why") if nd else None))
    return found


def unmarked(page: str, text: str, blocks=None) -> list[tuple[int, str]]:
    """(line, number) of every number with an error-like unit that carries no marker."""
    found = quotes(page, text, blocks)
    exempt_lines = {q.line for q in found if q.exempt_line}
    marked = {(q.line, q.start) for q in found}
    marked |= {(q.line, q.start + len(q.text) - len(q.text.lstrip("+-−"))) for q in found}
    out = []
    for i, line in prose_lines(text, blocks):
        if i in exempt_lines:
            continue
        # positions in the line with markers removed map back to the line with them
        keep = _outside_markers(line)
        clean = "".join(line[j] for j in keep)
        for run in _runs(clean):
            for n in NUMBER.finditer(run.group()):
                for start in (run.start() + n.start(), run.start() + n.start("digits")):
                    if (i, keep[start]) in marked:
                        break
                else:
                    out.append((i, n.group()))
    return sorted(set(out))


def _runs(clean: str):
    """The matches of # (a run of numbers joined by dashes, slashes, arrows or "to", then the unit or the x): the whole
# run is matched possessively (never given back) and what ends it is looked at where it ends, so
# a run without one is passed over whole and no start inside it is tried again (linear time;
# backtracking into the run is quadratic on "1 - 1 - 1 ...")
RUN, RATIO_AFTER and RATIO_BEFORE in `clean`, in linear time."""
    for run in RUN.finditer(clean):
        if any(end.match(clean, run.end()) for end in RUN_ENDS):
            yield run
    yield from RATIO_BEFORE.finditer(clean)


def _outside_markers(line: str) -> list[int]:
    """The positions of `line` outside its markers, in one pass."""
    keep, at = [], 0
    for m in MARKER.finditer(line):
        keep.extend(range(at, m.start()))
        at = m.end()
    keep.extend(range(at, len(line)))
    return keep


def _numbers_in(cell: str) -> list[float]:
    return [(-1 if n.group("sign") in ("-", "−") else 1) * float(n.group("digits").replace(",", ""))
            for n in CELL_NUMBER.finditer(cell)]


def value(body: str, root: Path, tables: dict | None = None) -> float:
    """The number a marker's words name (BadMarker if they name none or several)."""
    tables = {} if tables is None else tables
    try:
        words = shlex.split(body)
    except ValueError as e:
        raise BadMarker(f"cannot split the marker's words ({e})") from None
    if words.count("/") > 1:
        raise BadMarker("at most one '/' (a ratio of two cells)")
    if "/" in words:
        k = words.index("/")
        num, den = _cell(words[:k], root, tables), _cell(words[k + 1:], root, tables)
        if den == 0:
            raise BadMarker("the ratio's second cell is 0")
        return _finite(num / den, "the ratio")
    return _cell(words, root, tables)


def _finite(x: float, what: str) -> float:
    if not math.isfinite(x):
        raise BadMarker(f"{what} is {x!r}, not a finite number")
    return x


def table_path(name: str, root: Path) -> Path:
    """The table a marker names: a file of outputs/report/, or a path from the repository root;
    a path that is absolute, climbs out ('..') or leads out of the repository (a link) is
    refused: a marker reads the repository's tables only."""
    rel = Path(name if "/" in name else REPORT / name)
    if rel.is_absolute() or ".." in rel.parts or "\0" in name:
        raise BadMarker(f"{name}: a table is named from the repository root, without '..'")
    path = root / rel
    real, base = path.resolve(), root.resolve()
    if base not in real.parents:
        raise BadMarker(f"{name}: leads outside the repository ({real})")
    return path


def _cell(words: list[str], root: Path, tables: dict) -> float:
    if not words or not words[0].endswith(".csv"):
        raise BadMarker("a marker starts with its table (a .csv file)")
    name, rest = words[0], words[1:]
    path = table_path(name, root)
    if path not in tables:
        if not path.is_file():
            raise BadMarker(f"{name}: no such table ({path.relative_to(root)})")
        try:
            tables[path] = pd.read_csv(path, dtype=str, keep_default_na=False)
        except (ValueError, UnicodeDecodeError, pd.errors.ParserError) as e:
            raise BadMarker(f"{name}: not a readable table ({type(e).__name__})") from None
    t = tables[path]
    filters = [w for w in rest if "=" in w or "~" in w]
    columns = [w for w in rest if w not in filters]
    if len(columns) != 1:
        raise BadMarker(f"{name}: name one column (got {columns or 'none'})")
    rows = pd.Series(True, index=t.index)
    for f in filters:
        m = FILTER.match(f)
        if m is None:
            raise BadMarker(f"{name}: {f!r} is no filter (col=value or col~text)")
        col, op, want = m.groups()
        if col not in t.columns:
            raise BadMarker(f"{name}: no column {col!r}")
        rows &= (t[col] == want) if op == "=" else t[col].str.contains(want, regex=False)
    spec = TERM_COLUMN.match(columns[0])
    if spec is None or spec["col"] not in t.columns:
        raise BadMarker(f"{name}: no column {columns[0]!r}")
    if rows.sum() != 1:
        raise BadMarker(f"{name}: {' '.join(filters) or 'no filter'} selects {rows.sum()} rows, "
                        "not one")
    cell = t.loc[rows, spec["col"]].iloc[0]
    if spec["k"]:
        nums, k = _numbers_in(cell), int(spec["k"])
        if not 1 <= k <= len(nums):
            raise BadMarker(f"{name}: {spec['col']} holds {len(nums)} numbers, not #{k}: {cell!r}")
        x = nums[k - 1]
    else:
        try:
            x = float(cell)
        except ValueError:
            raise BadMarker(f"{name}: {spec['col']} is not a number ({cell!r}); "
                            f"pick one of its numbers with {spec['col']}#k") from None
    if not math.isfinite(x):
        raise BadMarker(f"{name}: {spec['col']} is {cell!r}")
    try:
        scale = float(spec["scale"]) if spec["scale"] else 1.0
    except ValueError:
        raise BadMarker(f"{name}: bad scale {spec['scale']!r}") from None
    return _finite(x * _finite(scale, f"{name}: the scale {spec['scale']!r}"),
                   f"{name}: {spec['col']} x {spec['scale']}")


def formatted(x: float, like: str) -> str:
    """x written as `like` writes its number: its decimals, its sign style, its commas."""
    digits = like.lstrip("+-−")
    decimals = len(digits.split(".")[1]) if "." in digits else 0
    if decimals > MAX_DECIMALS:
        raise BadMarker(f"{like}: {decimals} decimals; a table's number holds at most "
                        f"{MAX_DECIMALS}")
    # half away from zero on the shortest decimal of x, as a reader rounds 74.5 to 75
    r = Decimal(repr(x)).quantize(Decimal(1).scaleb(-decimals), rounding=ROUND_HALF_UP)
    s = f"{r:{'+' if like.startswith('+') else ''}{',' if ',' in digits else ''}.{decimals}f}"
    if s.lstrip("+-") == f"{0:.{decimals}f}":  # no "-0.0"
        s = ("+" if like.startswith("+") else "") + s.lstrip("+-")
    return s.replace("-", "−") if like.startswith("−") else s


def check(files: list[Path], root: Path | None = None, fix: bool = False, blocks=None,
          unscanned=None, explicit: bool = False) -> list[str]:
    """One line per drifted or unmarked number; with fix, rewrite the drifted ones.
    Raises BadMarker before writing anything."""
    root = REPO_ROOT if root is None else root
    unscanned = UNSCANNED_PAGES if unscanned is None else unscanned
    tables, problems, rewrites = {}, [], {}
    for path in files:
        page = _name(path, root)
        try:
            text = path.read_bytes().decode("utf-8")
        except UnicodeDecodeError as e:
            raise BadMarker(f"{page}: not UTF-8 (byte {e.start})") from None
        lines = text.splitlines(keepends=True)
        for q in sorted(quotes(page, text, blocks), key=lambda q: (q.line, -q.start)):
            if q.exempt is not None:
                continue
            try:
                want = formatted(value(q.body, root, tables), q.text)
            except (BadMarker, ArithmeticError) as e:
                raise BadMarker(f"{page}:{q.line}: {e}") from None
            if want != q.text:
                problems.append(f"{page}:{q.line}: quoted {q.text}, "
                                f"{q.body.split()[0]} gives {want}")
                line = lines[q.line - 1]
                lines[q.line - 1] = line[:q.start] + want + line[q.end:]
        if fix and "".join(lines) != text:
            rewrites[path] = "".join(lines)
        if explicit or page not in unscanned:
            problems += [f"{page}:{i}: {n} has no quote marker (<!-- q: ... --> or "
                         "<!-- q: not data: why -->)" for i, n in unmarked(page, text, blocks)]
    from .. import io

    for path, text in rewrites.items():  # one rename each: the old page or the new one
        io.remove_stale_tmp(path.parent)  # what a killed --fix of this host left
        io.write_text(path, text)
    return problems


def _name(path: Path, root: Path) -> str:
    try:
        return str(path.resolve().relative_to(root.resolve()))
    except ValueError:
        return str(path)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pipeline.tools.quotes",
                                 description=__doc__.split("\n")[0])
    ap.add_argument("--fix", action="store_true",
                    help="rewrite each quoted number to its table's value")
    ap.add_argument("files", nargs="*", type=Path,
                    help="pages to check (default: README.md, docs/*.md, findings.md)")
    args = ap.parse_args(argv)
    files = args.files or pages()
    for f in files:
        if not f.is_file():
            print(f"error: {f}: no such page", file=sys.stderr)
            return 2
    try:
        problems = check(files, fix=args.fix, explicit=bool(args.files))
    except BadMarker as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    for p in problems:
        print(p)
    if args.fix:
        fixed = sum("quoted" in p for p in problems)
        left = [p for p in problems if "quoted" not in p]
        print(f"{fixed} numbers rewritten; reread their sentences", file=sys.stderr)
        return 1 if left else 0
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
