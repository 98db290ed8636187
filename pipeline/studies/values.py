"""Named values: every number the prose quotes from the report, computed once under a name.

The registry (values.yaml beside this module) maps a name to the cell of a report table it is
read from; the report stage evaluates it over the tables it has just written and writes
values.csv (name, value) with them. The pages (README.md, docs/*.md: their templates under
docs/templates/, rendered by `python -m pipeline.tools.render`) and the report's discussion
(findings.md) reference a value by its name, `{{ fig4.const0.5.final_mm:.1f }}`, and never
write it by hand. Numbers that are not the report's (the paper's text, a setting, a timing) are
plain text.

A cell (the words of a registry entry, split like a shell line: a value with spaces is quoted):
- the table: a file name of the report folder (summary.csv);
- filters `col=value` (the cell's text equals value) and `col~text` (the cell's text contains
  text); together they must select exactly one row;
- the column, with an optional `#k` (the k-th number written in a text cell, from 1:
  `measured#3` of "mean 4.9 mm, worst 16.5 mm" is 16.5) and an optional `*scale` (`*1e3`: metres
  to mm, `*100`: a fraction to %);
- optionally `/` and a second such cell: the value is the first over the second.
Besides the cells, TABLES names the Markdown tables generated from a table (the README's
readings matrix, docs/scorecard.md's coverage table).

A reference is `{{ name }}` (a table, or a number as values.csv holds it) or `{{ name:FORMAT }}`,
FORMAT being `[+][,].Nf`: N decimals (rounded half away from zero, as a reader rounds 74.5 to
75), a sign always (+), thousands commas (,); `\\{{` is a literal `{{`. A reference to an
unknown name, a bad format or a `{{` that opens no reference is a BadValue naming the page and
line.
"""
from __future__ import annotations

import csv
import io as _io
import math
import re
import shlex
from decimal import ROUND_HALF_UP, Decimal
from pathlib import Path

REGISTRY = Path(__file__).parent / "values.yaml"
FILE = "values.csv"  # the report's named values, written beside its tables

NAME = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.+-]*$")
REFERENCE = re.compile(r"(?<!\\)\{\{\s*(?P<name>[^{}:\s]+)\s*(?::\s*(?P<format>[^{}\s]*)\s*)?\}\}")
ESCAPED = "\\{{"  # a literal "{{" in a template (a page that shows the syntax)
FORMAT = re.compile(r"^(?P<plus>\+)?(?P<comma>,)?\.(?P<decimals>\d{1,2})f$")
NUMBER = re.compile(r"(?P<sign>(?<![\w.)\]>])[-+−])?"
                    r"(?P<digits>\d{1,3}(?:,\d{3})+(?:\.\d+)?|\d+(?:\.\d+)?)")
# a number written in a text cell: not part of a word ("TG10", "fig4", "const0.5")
CELL_NUMBER = re.compile(r"(?<![A-Za-z_\d.])" + NUMBER.pattern)
TERM_COLUMN = re.compile(r"^(?P<col>[^=~#*]+?)(?:#(?P<k>\d+))?(?:\*(?P<scale>[0-9.eE+-]+))?$")
FILTER = re.compile(r"^(?P<col>[^=~]+)(?P<op>[=~])(?P<want>.*)$")
MAX_DECIMALS = 15  # a float holds 15-17 significant digits: more decimals quote nothing


class BadValue(ValueError):
    """A cell that names no single number, a reference that names no value, a bad format."""


def _readings_table(report: Path) -> str:
    from . import readings

    path = report / "readings_matrix.csv"
    if not path.is_file():
        raise BadValue("readings_matrix.csv: no such table")
    return readings.matrix_markdown(readings.read_matrix(path)).rstrip("\n")


def _coverage_table(report: Path) -> str:
    from . import coverage

    return coverage.markdown(coverage.read_table())


def _headline(report: Path, recommended: bool) -> str:
    """The headline of the default reading (the paper's claims on the counted figures, from
    claims.csv) or of the recommended one (its readings' cells, from readings.csv), as the
    report's scorecard words it: "10 reproduced, 4 not reproduced, 5 inconclusive"."""
    import pandas as pd

    from . import measures_table, scorecard

    t = pd.read_parquet(report / measures_table.NAME,
                        columns=["study", "figure", "reading", "counted", "recommended"])
    if recommended:
        pairs = set(zip(*t.loc[(t["study"] == "readings") & t["recommended"],
                               ["figure", "reading"]].to_numpy().T))
        cells = pd.read_csv(report / "readings.csv", keep_default_na=False)
        cells = cells[[(f, r) in pairs for f, r in zip(cells["figure"], cells["reading"])]]
        counted = None
    else:
        cells = pd.read_csv(report / "claims.csv", keep_default_na=False)
        counted = set(t.loc[(t["study"] == "figures") & t["counted"], "figure"])
    if not len(cells):
        raise BadValue(f"{report}: no cells for the {'recommended' if recommended else 'default'}"
                       " headline")
    cells = cells.assign(diagnostic=cells["diagnostic"].astype(str) == "True")
    return scorecard.headline_text(scorecard.headline(cells, counted))


# name -> the Markdown table or text it is (of the report folder); pipeline/studies/coverage.csv,
# which the scorecard reads, is the report's input, so its table is the report's value too
TABLES = {"readings.table": _readings_table, "coverage.table": _coverage_table,
          "headline.default": lambda report: _headline(report, False),
          "headline.recommended": lambda report: _headline(report, True)}


def registry(path: Path = REGISTRY) -> dict[str, str]:
    """name -> its cell, as values.yaml lists them (BadValue on a bad name or entry)."""
    import yaml

    entries = yaml.safe_load(path.read_text()) or {}
    if not isinstance(entries, dict):
        raise BadValue(f"{path.name}: a mapping of name: cell")
    for name, cell in entries.items():
        if not isinstance(name, str) or not NAME.match(name) or not isinstance(cell, str):
            raise BadValue(f"{path.name}: {name!r}: a name (letters, digits, _ . + -) and "
                           "its cell (a line of words)")
        if name in TABLES:
            raise BadValue(f"{path.name}: {name}: the name of a generated table")
    return entries


def evaluate(report: Path, entries: dict | None = None) -> tuple[dict, dict]:
    """(name -> value, name -> why not) over the tables of the folder `report`: every name whose
    table this report holds gets its value (a float, or a table's Markdown text); a report of
    fewer studies holds fewer names."""
    entries = registry() if entries is None else entries
    report, tables, got, missing = Path(report), {}, {}, {}
    for name, cell in entries.items():
        try:
            got[name] = value(cell, report, tables)
        except BadValue as e:
            missing[name] = str(e)
    for name, make in TABLES.items():
        try:
            got[name] = make(report)
        except (BadValue, OSError, ValueError, KeyError) as e:
            missing[name] = str(e)
    return dict(sorted(got.items())), missing


def to_csv(values: dict) -> str:
    """values.csv: name, value (a number as its shortest exact decimal, a table as its text)."""
    buf = _io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["name", "value"])
    for name, v in values.items():
        w.writerow([name, repr(float(v)) if isinstance(v, float) else v])
    return buf.getvalue()


def read(path: Path) -> dict:
    """name -> value of a values.csv (a number as a float, anything else as its text)."""
    with open(path, newline="", encoding="utf-8") as fh:
        rows = list(csv.reader(fh))
    if not rows or rows[0] != ["name", "value"] or any(len(r) != 2 for r in rows[1:]):
        raise BadValue(f"{path}: not a values table (name,value)")
    out = {}
    for name, text in rows[1:]:
        try:
            out[name] = float(text)
        except ValueError:
            out[name] = text
    return out


def formatted(x: float, fmt: str) -> str:
    """x written in FORMAT `[+][,].Nf`, rounded half away from zero on its shortest decimal."""
    m = FORMAT.match(fmt)
    if m is None:
        raise BadValue(f"format {fmt!r}: write [+][,].Nf (.1f, +.0f, ,.0f)")
    decimals = int(m["decimals"])
    if decimals > MAX_DECIMALS:
        raise BadValue(f"format {fmt!r}: a table's number holds at most {MAX_DECIMALS} decimals")
    r = Decimal(repr(x)).quantize(Decimal(1).scaleb(-decimals), rounding=ROUND_HALF_UP)
    s = f"{r:{m['plus'] or ''}{m['comma'] or ''}.{decimals}f}"
    if s.lstrip("+-") == f"{0:.{decimals}f}":  # no "-0.0"
        s = (m["plus"] or "") + s.lstrip("+-")
    return s


def render(text: str, values: dict, where: str) -> str:
    """`text` with every reference replaced by its value (BadValue `where:line: ...` on the first
    bad one)."""
    out = []
    for i, line in enumerate(text.split("\n"), 1):
        def one(m, i=i):
            name, fmt = m["name"], m["format"]
            if name not in values:
                raise BadValue(f"{where}:{i}: no value named {name!r}")
            v = values[name]
            if fmt is None:
                if isinstance(v, float):
                    raise BadValue(f"{where}:{i}: {name} is a number: give its format "
                                   f"({{{{ {name}:.1f }}}})")
                return v
            if not isinstance(v, float):
                raise BadValue(f"{where}:{i}: {name} is a table, not a number: no format")
            try:
                return formatted(v, fmt)
            except BadValue as e:
                raise BadValue(f"{where}:{i}: {name}: {e}") from None
        done = REFERENCE.sub(one, line)
        if "{{" in REFERENCE.sub("", line).replace(ESCAPED, ""):
            raise BadValue(f"{where}:{i}: a '{{{{' that opens no reference ({{{{ name:.1f }}}}; "
                           f"a literal one is {ESCAPED})")
        out.append(done.replace(ESCAPED, "{{"))
    return "\n".join(out)


LEFT_OUT = ("## Discussion\n\n`pipeline/studies/findings.md` quotes {name}, which this report "
            "does not hold (its study was not run), so it is left out.\n")


def rendered_part(part: str, values: dict) -> str:
    """A part of report.md rendered with the report's values: the discussion (findings.md, the
    only part that references names), or the note that it is left out when it references a
    value this report does not hold (a report of fewer studies). A reference this report could
    never render (a bad format) is a BadValue."""
    if "{{" not in part:
        return part
    lacking = sorted(references(part) - set(values))
    if lacking:
        return LEFT_OUT.format(name=lacking[0])
    return render(part, values, "pipeline/studies/findings.md")


def references(text: str) -> set[str]:
    """The names `text` references."""
    return {m["name"] for m in REFERENCE.finditer(text)}


# ---- the cells ---------------------------------------------------------------------------------
def _numbers_in(cell: str) -> list[float]:
    return [(-1 if n.group("sign") in ("-", "−") else 1) * float(n.group("digits").replace(",", ""))
            for n in CELL_NUMBER.finditer(cell)]


def value(cell: str, report: Path, tables: dict | None = None) -> float:
    """The number a cell's words name (BadValue if they name none or several)."""
    tables = {} if tables is None else tables
    try:
        words = shlex.split(cell)
    except ValueError as e:
        raise BadValue(f"cannot split the cell's words ({e})") from None
    if words.count("/") > 1:
        raise BadValue("at most one '/' (a ratio of two cells)")
    if "/" in words:
        k = words.index("/")
        num, den = _cell(words[:k], report, tables), _cell(words[k + 1:], report, tables)
        if den == 0:
            raise BadValue("the ratio's second cell is 0")
        return _finite(num / den, "the ratio")
    return _cell(words, report, tables)


def _finite(x: float, what: str) -> float:
    if not math.isfinite(x):
        raise BadValue(f"{what} is {x!r}, not a finite number")
    return x


def table_path(name: str, report: Path) -> Path:
    """A table of the report folder, named by its file name; a path, or a link leading out of
    the folder, is refused."""
    if "/" in name or "\\" in name or name in (".", "..") or "\0" in name:
        raise BadValue(f"{name}: a table is a file name of the report folder (no path)")
    path = report / name
    if path.resolve().parent != report.resolve():
        raise BadValue(f"{name}: leads outside the report folder ({path.resolve()})")
    return path


def _cell(words: list[str], report: Path, tables: dict) -> float:
    import pandas as pd  # only to evaluate (the report, --values-from-tables), not to render

    if not words or not words[0].endswith(".csv"):
        raise BadValue("a cell starts with its table (a .csv file)")
    name, rest = words[0], words[1:]
    path = table_path(name, report)
    if path not in tables:
        if not path.is_file():
            raise BadValue(f"{name}: no such table")
        try:
            tables[path] = pd.read_csv(path, dtype=str, keep_default_na=False)
        except (ValueError, UnicodeDecodeError, pd.errors.ParserError) as e:
            raise BadValue(f"{name}: not a readable table ({type(e).__name__})") from None
    t = tables[path]
    filters = [w for w in rest if "=" in w or "~" in w]
    columns = [w for w in rest if w not in filters]
    if len(columns) != 1:
        raise BadValue(f"{name}: name one column (got {columns or 'none'})")
    rows = pd.Series(True, index=t.index)
    for f in filters:
        m = FILTER.match(f)
        if m is None:
            raise BadValue(f"{name}: {f!r} is no filter (col=value or col~text)")
        col, op, want = m.groups()
        if col not in t.columns:
            raise BadValue(f"{name}: no column {col!r}")
        rows &= (t[col] == want) if op == "=" else t[col].str.contains(want, regex=False)
    spec = TERM_COLUMN.match(columns[0])
    if spec is None or spec["col"] not in t.columns:
        raise BadValue(f"{name}: no column {columns[0]!r}")
    if rows.sum() != 1:
        raise BadValue(f"{name}: {' '.join(filters) or 'no filter'} selects {rows.sum()} rows, "
                       "not one")
    cell = t.loc[rows, spec["col"]].iloc[0]
    if spec["k"]:
        nums, k = _numbers_in(cell), int(spec["k"])
        if not 1 <= k <= len(nums):
            raise BadValue(f"{name}: {spec['col']} holds {len(nums)} numbers, not #{k}: {cell!r}")
        x = nums[k - 1]
    else:
        try:
            x = float(cell)
        except ValueError:
            raise BadValue(f"{name}: {spec['col']} is not a number ({cell!r}); "
                           f"pick one of its numbers with {spec['col']}#k") from None
    if not math.isfinite(x):
        raise BadValue(f"{name}: {spec['col']} is {cell!r}")
    try:
        scale = float(spec["scale"]) if spec["scale"] else 1.0
    except ValueError:
        raise BadValue(f"{name}: bad scale {spec['scale']!r}") from None
    return _finite(x * _finite(scale, f"{name}: the scale {spec['scale']!r}"),
                   f"{name}: {spec['col']} x {spec['scale']}")
