"""The README's readings table regenerated from the committed matrix.

    python -m pipeline.tools.readings [README.md [readings_matrix.csv]]

Between the README's readings-table markers (pipeline.studies.readings.BEGIN, END), the table
pipeline.studies.readings.readme_block makes from readings_matrix.csv (outputs/report/ by
default); a test checks that the README equals it.
"""
from __future__ import annotations

import sys
from pathlib import Path

from ..config import REPO_ROOT
from ..studies.readings import readme_updated


def main(argv=None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    readme = Path(args[0]) if args else REPO_ROOT / "README.md"
    csv = Path(args[1]) if len(args) > 1 else REPO_ROOT / "outputs" / "report" / "readings_matrix.csv"
    try:
        readme.write_text(readme_updated(readme.read_text(), csv))
    except (OSError, ValueError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
