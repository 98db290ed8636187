"""Named values: every number the prose quotes from the report, named where it is computed
(sections.Context.value) and written to values.csv (name, value) as its table prints it
(`printed`: 6 significant digits). The pages rendered from docs/templates/ and the report's
discussion (findings.md) reference a value as `{{ name }}` (a table, or a number as values.csv
holds it) or `{{ name:FORMAT }}`, FORMAT `[+][,].Nf` (N decimals rounded half away from zero, a
sign always, thousands commas); `\\{{` is a literal `{{`. An unknown name, a bad format or a `{{`
that opens no reference is a BadValue naming the page and line.
"""
from __future__ import annotations

import csv
import io as _io
import re
from decimal import ROUND_HALF_UP, Decimal
from pathlib import Path

FILE = "values.csv"  # the report's named values, written beside its tables

NAME = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.+-]*$")
REFERENCE = re.compile(r"(?<!\\)\{\{\s*(?P<name>[^{}:\s]+)\s*(?::\s*(?P<format>[^{}\s]*)\s*)?\}\}")
ESCAPED = "\\{{"  # a literal "{{" in a template (a page that shows the syntax)
FORMAT = re.compile(r"^(?P<plus>\+)?(?P<comma>,)?\.(?P<decimals>\d{1,2})f$")
MAX_DECIMALS = 15  # a float holds 15-17 significant digits: more decimals quote nothing


class BadValue(ValueError):
    """A reference that names no value, a bad format, a page that is not UTF-8."""


def printed(x: float) -> float:
    """x as a table of the report prints it (float_format %.6g) and reads it back."""
    return float(f"{x:.6g}")


def name_ok(name: str) -> None:
    if not NAME.match(name):
        raise ValueError(f"value {name!r}: a name is letters, digits, _ . + -")


def to_csv(values: dict) -> str:
    """values.csv: a number as its shortest exact decimal, a table as its text."""
    buf = _io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["name", "value"])
    for name, v in values.items():
        w.writerow([name, repr(float(v)) if isinstance(v, float) else v])
    return buf.getvalue()


def read(path: Path) -> dict:
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
    """A part of report.md (the discussion, findings.md) rendered, or the note that it is left
    out where it references a value this report does not hold (a report of fewer studies)."""
    if "{{" not in part:
        return part
    lacking = sorted(references(part) - set(values))
    if lacking:
        return LEFT_OUT.format(name=lacking[0])
    return render(part, values, "pipeline/studies/findings.md")


def references(text: str) -> set[str]:
    return {m["name"] for m in REFERENCE.finditer(text)}
