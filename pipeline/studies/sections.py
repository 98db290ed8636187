"""The report's sections: a study (an experiment's `paper.study`, "figures" by default) is a
function registered here with its place, given a Context (settings, output folder, every study's
aggregates) and returning Markdown lines. A new study is one module (here, or an entry point of
`gbgrowth.studies`) and its experiment files (tests/studies/test_toy_study.py)."""
from __future__ import annotations

import functools
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

DEFAULT = "figures"
TEXT = Path(__file__).parent / "report_text.md"  # the report's constant prose


@functools.lru_cache(maxsize=None)
def _texts() -> dict:
    parts = re.split(r"^<!-- ([a-z_.]+) -->\n", TEXT.read_text(), flags=re.M)
    return {k: v.strip("\n") for k, v in zip(parts[1::2], parts[2::2])}


def prose(name: str, **fields) -> str:
    """The paragraph `name` of report_text.md, its {fields} filled in."""
    return _texts()[name].format(**fields)


SECTIONS: dict[str, tuple[int, object]] = {}  # study -> (place in the report, section)


def register(study: str, place: int):
    """Register `section(ctx) -> list[str]` as the section of `study`, at `place` (ascending)."""
    def deco(fn):
        SECTIONS[study] = (place, fn)
        return fn
    return deco


def declared() -> dict:
    """experiment -> what its file declares (pipeline.experiments), in order."""
    from ..config import config_folders
    from ..experiments import declared as read

    return read(config_folders())


def of_study(study: str) -> list[str]:
    """The experiments whose file names `study` as theirs, in declared order."""
    return [n for n, e in declared().items() if e.study == study]


def reads(study: str) -> dict[str, str]:
    """experiment -> the paper figure it reads (declares.reads), of `study`, in declared order."""
    return {n: e.declares.reads for n, e in declared().items()
            if e.study == study and e.declares.reads}


def _load() -> None:
    """Import every module of this package and every entry point `gbgrowth.studies`: each
    registers its section."""
    import importlib
    import pkgutil

    from ..plugins import STUDIES, load_plugins

    for m in pkgutil.iter_modules([str(Path(__file__).parent)]):
        if m.name != "__main__":
            importlib.import_module(f"{__package__}.{m.name}")
    load_plugins(STUDIES, _BROKEN)  # a failure is named where its study is asked for


_BROKEN: dict[str, str] = {}  # study -> why its entry point's module did not import


def group(aggs: dict) -> dict:
    """study -> {figure: aggregate}; a study without a section is a ConfigError."""
    from ..config import ConfigError

    _load()
    out = {}
    for name, agg in aggs.items():
        s = agg["models"].get("paper", {}).get("study") or DEFAULT
        if s not in SECTIONS and s in _BROKEN:
            raise ConfigError(f"{name}: paper.study={s!r}: its module did not import "
                              f"({_BROKEN[s]})")
        if s not in SECTIONS:
            raise ConfigError(f"{name}: paper.study={s!r} names no report section (known: "
                              f"{', '.join(sorted(SECTIONS))})")
        out.setdefault(s, {})[name] = agg
    return out


@dataclass
class Context:
    cfg: object
    out: Path
    title: str
    groups: dict  # study -> {figure: aggregate}
    written: list = field(default_factory=list)
    shared: dict = field(default_factory=dict)  # what several sections read, made once (once)
    values: dict = field(default_factory=dict)  # name -> value: values.csv (value, quote)

    def of(self, study: str) -> dict:
        return self.groups.get(study, {})

    def once(self, key, make):
        """make(), computed at the first call with `key` and the same object after (what two
        sections read, computed once; its readers must not change it)."""
        if key not in self.shared:
            self.shared[key] = make()
        return self.shared[key]

    def value(self, name: str, x) -> None:
        """Name a number (or a table's text) for the pages that quote it (values.py), once; a
        number that is not finite names nothing."""
        from .values import name_ok

        name_ok(name)
        x = x if isinstance(x, str) else float(x)
        if not isinstance(x, str) and not math.isfinite(x):
            return
        if name in self.values:
            raise ValueError(f"value {name}: named twice")
        self.values[name] = x

    def quote(self, frame, keys: tuple, quoted: dict) -> None:
        """Name the numbers of `frame` the pages quote: `quoted` maps a name to its row's values
        of `keys`, its column and optionally a scale, named as printed (values.printed) times
        the scale; a row the frame does not hold names nothing."""
        from .values import printed

        for name, (*want, column, scale) in ((n, q if len(q) > len(keys) + 1 else (*q, 1.0))
                                             for n, q in quoted.items()):
            rows = frame
            for k, w in zip(keys, want):
                rows = rows[rows[k] == w]
            if len(rows) > 1:
                raise ValueError(f"value {name}: {len(rows)} rows of its table, not one")
            if len(rows):
                self.value(name, printed(rows[column].iloc[0]) * scale)

    def text(self, name: str, text: str) -> Path:
        from .. import io

        io.write_text(self.out / name, text)
        self.written.append(self.out / name)
        return self.out / name

    def save(self, fig, stem: str) -> list[Path]:
        """A figure as PNG and PDF (figures.save), PNG first."""
        from . import figures

        paths = figures.save(fig, self.out / stem, self.cfg.report.dpi)
        self.written.extend(paths)
        return paths


def run(ctx: Context, step=None) -> list[str]:
    """Every registered section in its place; `step(name)` before each study the report holds."""
    _load()
    md = []
    for study, (_, section) in sorted(SECTIONS.items(), key=lambda s: s[1][0]):
        if step is not None and study in ctx.groups:
            step(f"{study}: {', '.join(ctx.groups[study])}")
        md += section(ctx)
    return md


def declares_claims(agg: dict) -> bool:
    """Whether the figure's experiment declares the paper's claims (paper.claims: true)."""
    return bool(agg["models"].get("paper", {}).get("claims", False))
