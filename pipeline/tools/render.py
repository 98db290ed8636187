"""Every page that quotes the report, rendered from its template and the report's named values.

    python -m pipeline.tools.render            # write every page that differs (make docs)
    python -m pipeline.tools.render --check    # exit 1, one line per page that differs

A page with the report's numbers (README.md, docs/*.md) has its template at the same path under
docs/templates/: `{{ name:.1f }}` where a number stands, `{{ name }}` where a table does
(pipeline/studies/values.py), from the committed report's values.csv and first_hour.json
(firsthour.py). Edit the template, never the page. Exit 2 (one line, nothing written): a bad
reference, no values table, or a template or page reached through a link.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..studies import values as named
from . import REPO, fail, firsthour

TEMPLATES = "docs/templates"
VALUES = Path("outputs") / "report" / named.FILE


def rendered(root: Path, values_path: Path | None = None) -> dict[Path, str]:
    """page path (from the root) -> its rendering; BadValue on the first bad reference."""
    values_path = root / VALUES if values_path is None else values_path
    if not values_path.is_file():
        raise named.BadValue(f"{values_path}: no values table (the report stage writes it)")
    vals = {**named.read(values_path), **firsthour.values(root / firsthour.OUT)}
    out, base = {}, root / TEMPLATES
    for rel in sorted(p.relative_to(base) for p in base.rglob("*.md")) if base.is_dir() else []:
        src = unlinked(root, Path(TEMPLATES) / rel)
        unlinked(root, rel)  # the page: never written through a link
        try:
            text = src.read_bytes().decode("utf-8")
        except UnicodeDecodeError as e:
            raise named.BadValue(f"{TEMPLATES}/{rel}: not UTF-8 (byte {e.start})") from None
        out[rel] = named.render(text, vals, f"{TEMPLATES}/{rel}")
    return out


def unlinked(root: Path, rel: Path) -> Path:
    """root / rel; BadValue if it or a folder on its way is a link (a linked template would copy
    another file into a page, a linked folder put a page elsewhere)."""
    p = root
    for part in rel.parts:
        p = p / part
        if p.is_symlink():
            raise named.BadValue(f"{p.relative_to(root)}: a link; the renderer reads no template "
                                 "and writes no page through a link")
    return p


def differing(root: Path, pages: dict[Path, str]) -> list[Path]:
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
    root = REPO if root is None else root
    try:
        pages = rendered(root, args.values)
    except (named.BadValue, OSError) as e:
        return fail(e)
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
