"""Every page that quotes the report, rendered from its template and the report's named values.

    python -m pipeline.tools.render            # write every page that differs (make docs)
    python -m pipeline.tools.render --check    # exit 1, one line per page that differs

A page with numbers of the report (README.md, docs/*.md) has its template under docs/templates/ at
the same path (docs/templates/docs/results.md -> docs/results.md): its text with a reference
`{{ name:.1f }}` where each number of the report stands, `{{ name }}` where a generated table
does (pipeline/studies/values.py: the names, the formats). The values are the committed report's,
outputs/report/values.csv (written by the report stage: each section names the numbers it
computes). Edit the template, never the page; numbers that are not the report's are plain text,
except the first-hour times (set-up, make smoke, make test: `{{ first_hour.smoke.cpu_min:.1f }}`),
which are outputs/bench/first_hour.json's (`make first-hour`, pipeline/tools/firsthour.py); a page
that quotes none is plain Markdown with no template.

Exit status: 0 every page equals its rendering (or is written); 1 (--check) one line per page
that differs; 2 a bad reference, a missing values table, or a template or page reached through
a link (one line, `error: ...`), and nothing is written. A page is replaced in one rename (a
kill leaves the old page or the new one).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..studies import values as named
from . import firsthour

REPO_ROOT = Path(__file__).resolve().parents[2]  # the checkout (pipeline.config's, without Hydra)

TEMPLATES = "docs/templates"
VALUES = Path("outputs") / "report" / named.FILE


def templates(root: Path) -> list[Path]:
    """Every template, as its path under docs/templates/ (the page's path from the root)."""
    base = root / TEMPLATES
    return sorted(p.relative_to(base) for p in base.rglob("*.md")) if base.is_dir() else []


def rendered(root: Path, values_path: Path | None = None) -> dict[Path, str]:
    """page path (from the root) -> its rendering; BadValue on the first bad reference."""
    values_path = root / VALUES if values_path is None else values_path
    if not values_path.is_file():
        raise named.BadValue(f"{values_path}: no values table (the report stage writes it)")
    vals = {**named.read(values_path), **firsthour.values(root / firsthour.OUT)}
    out = {}
    for rel in templates(root):
        src = unlinked(root, Path(TEMPLATES) / rel)
        unlinked(root, rel)  # the page: never written through a link
        try:
            text = src.read_bytes().decode("utf-8")
        except UnicodeDecodeError as e:
            raise named.BadValue(f"{TEMPLATES}/{rel}: not UTF-8 (byte {e.start})") from None
        out[rel] = named.render(text, vals, f"{TEMPLATES}/{rel}")
    return out


def unlinked(root: Path, rel: Path) -> Path:
    """root / rel; BadValue if it or a folder on its way from root is a link (a template that
    is a link would copy another file into a page, a linked folder put a page elsewhere)."""
    p = root
    for part in rel.parts:
        p = p / part
        if p.is_symlink():
            raise named.BadValue(f"{p.relative_to(root)}: a link; the renderer reads no template "
                                 "and writes no page through a link")
    return p


def differing(root: Path, pages: dict[Path, str]) -> list[Path]:
    """The pages whose committed text is not their rendering."""
    return [rel for rel, text in pages.items()
            if not (root / rel).is_file() or (root / rel).read_bytes() != text.encode()]


def main(argv=None, root: Path | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pipeline.tools.render",
                                 description=__doc__.split("\n")[0])
    ap.add_argument("--check", action="store_true",
                    help="write nothing; exit 1 naming each page that differs from its rendering")
    ap.add_argument("--values", type=Path, default=None,
                    help=f"the named values (default: {VALUES})")
    args = ap.parse_args(argv)
    root = REPO_ROOT if root is None else root
    try:
        pages = rendered(root, args.values)
    except (named.BadValue, OSError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    stale = differing(root, pages)
    if args.check:
        for rel in stale:
            print(f"{rel}: differs from its rendering of {TEMPLATES}/{rel} "
                  "(python -m pipeline.tools.render)")
        return 1 if stale else 0
    from .. import io

    with io.confined(root):  # and nothing written outside the checkout
        for rel in stale:  # one rename each: the old page or the new one
            io.remove_stale_tmp((root / rel).parent)  # what a killed render of this host left
            io.write_text(root / rel, pages[rel])
            print(f"{rel}: rendered")
    return 0


if __name__ == "__main__":
    sys.exit(main())
