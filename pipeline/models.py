"""Trained models from Python: the final inverse estimates (and snapshots) of a figure's trials.

    >>> fig = models.load("fig4")                      # outputs/aggregate/fig4/models.json
    >>> m = fig["TG1000"]                              # a Figure maps label -> Model
    >>> m.posture([[0.1, 0.5]]), m.joint_angles([[0.1, 0.5]]), m.reach([[0.1, 0.5]])

Each model is evaluated on the body its trial spec builds, at its final size. Every file is
checked first (DamagedFile, one line naming the file and what makes it again): a report's copy
(models/<figure>.json) by its seal, an aggregate's models.json line by line against its
manifest.json; a spec must validate, every M be finite and of its shape, and the file's `figure`
its name. The seal and checksums detect damage, not a deliberate edit resealed; loading calls no
function a file names (a body in the loop's factory runs only if its author marked it:
docs/faults.md). `python -m pipeline.models seal FILE...` seals a report's file written before
seals, after re-deriving its final errors against curves.parquet (verify_against_curves).
"""
from __future__ import annotations

import json
import os
import sys
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import gbmodel

from . import io


@dataclass
class Model:
    """The trained inverse estimates of one condition: g(x) = M phi(x), one M per trial."""

    label: str
    spec: gbmodel.TrialSpec
    M: dict[int, np.ndarray]  # trial index -> final M (m, features)
    snapshots: dict[int, dict[int, np.ndarray]] = field(default_factory=dict)  # trial -> epoch -> M

    @property
    def body(self) -> gbmodel.Body:
        return self.spec.make_body()

    @property
    def size(self) -> float:  # the body's size factor at the end of the trial
        return float(self.spec.make_growth().sizes([self.spec.epochs], self.body)[-1])

    @property
    def scale(self) -> np.ndarray:  # per-joint length factors at the end of the trial
        return self.spec.make_growth().scales(self.body, np.array([self.size]))[0]

    def posture(self, x, trial: int = 0, epoch: int | None = None) -> np.ndarray:
        """Commands (N, m) the model of `trial` (after `epoch`, a snapshot; None: the final M)
        chooses for targets x (N, n) [m], in the body's units: radians (arm2, arm5) or, for a
        body with `normalise: true` (iCub, URDF), [-1, 1] onto the joint limits."""
        M = self.M[trial] if epoch is None else self.snapshots[trial][epoch]
        body = self.body
        x = np.atleast_2d(np.asarray(x, dtype=np.float64))
        if x.shape[-1] != body.n:
            raise ValueError(f"target of {x.shape[-1]} coordinates: {body.name} controls "
                             f"{body.n} ({', '.join('xyz'[o] for o in body.outputs)})")
        learner, params = self.spec.make_learner()
        return learner.predict_model(M, params, body, x)

    def joint_angles(self, x, trial: int = 0, epoch: int | None = None) -> np.ndarray:
        """The posture's joint angles (N, m) [rad] in the robot's own convention (its limits',
        without the DH offsets), saturated at the limits."""
        body = self.body
        return body.joint_angles(self.posture(x, trial, epoch)) - body.theta_offset

    def reach(self, x, trial: int = 0, epoch: int | None = None) -> np.ndarray:
        """Where the hand is (N, n) [m] after the posture for targets x."""
        return self.body.forward(self.posture(x, trial, epoch), self.scale)


@dataclass
class Figure(Mapping):
    """The models of a figure's conditions: a mapping label -> Model (keys, items, in, len)."""

    name: str
    models: dict[str, Model]

    @property
    def labels(self) -> list[str]:
        return list(self.models)

    def __getitem__(self, label: str) -> Model:
        if label not in self.models:
            raise KeyError(f"{self.name} has no condition {label!r}; it has {self.labels}")
        return self.models[label]

    def __iter__(self):
        return iter(self.models)

    def __len__(self) -> int:
        return len(self.models)


def load(figure, aggregate_dir=None) -> Figure:
    """The trained models of `figure`: a name (no separator, no .json) looked up under outputs/
    of the default paths.root, in outputs/aggregate, then any profile's (outputs/smoke/aggregate),
    then outputs/report/models/ (read on a fresh clone), or in `aggregate_dir` only; or a path:
    a models JSON file or a figure's aggregate folder."""
    path = locate(figure, aggregate_dir)
    data = read(path)
    out = {}
    for label, c in data["conditions"].items():
        trials = {int(i): t for i, t in c["trials"].items()}
        if any(t["M"] is None for t in trials.values()):
            continue  # a learner without a model (the example memory): nothing to load
        out[label] = Model(
            label=label, spec=gbmodel.TrialSpec.from_dict(c["spec"]),
            M={i: np.asarray(t["M"]) for i, t in trials.items()},
            snapshots={i: {int(e): np.asarray(m) for e, m in t.get("snapshots", {}).items()}
                       for i, t in trials.items()})
    return Figure(data.get("figure", str(figure)), out)


def locate(figure, aggregate_dir=None) -> Path:
    text = str(figure)
    if isinstance(figure, Path) or "/" in text or os.sep in text or text.endswith(".json"):
        path = Path(figure).expanduser()
        if path.is_dir():
            path = path / "models.json"
        if not path.is_file():
            raise FileNotFoundError(f"{path}: no models file (a models/<figure>.json of a "
                                    "report, or an aggregate's <figure>/models.json)")
        return path
    from .config import default_root

    root = Path(default_root()) / "outputs"
    folders = ([Path(aggregate_dir)] if aggregate_dir is not None else
               [root / "aggregate", *sorted(root.glob("*/aggregate")), root / "report"])
    tried = [p for d in folders
             for p in (d / figure / "models.json", d / "models" / f"{figure}.json")]
    path = next((p for p in tried if p.exists()), None)
    if path is None:
        held = sorted({p.parent.name for d in folders for p in d.glob("*/models.json")}
                      | {p.stem for d in folders for p in d.glob("models/*.json")})
        raise FileNotFoundError(f"{figure}: no models under {', '.join(map(str, folders))} "
                                f"(they hold: {', '.join(held) or 'none'}; run "
                                "pipeline.simulate and pipeline.aggregate for this figure)")
    return path


def _remedy(path: Path) -> str:
    if path.name == "models.json":
        return (f"run python -m pipeline.aggregate figure={path.parent.name} again (it rebuilds "
                "the file from the cache)")
    return (f"run python -m pipeline.report for {path.stem} again (make studies for the "
            "committed report), or restore the committed file")


def read(path, sealed: bool = True) -> dict:
    """The checked content of a models file, else DamagedFile (sealed=False: a report's file
    read without its seal, for `seal`)."""
    path = Path(path)
    try:
        raw = path.read_bytes()
        data = json.loads(raw)
        if not isinstance(data, dict) or not isinstance(data.get("conditions"), dict):
            raise ValueError("no conditions")
        if path.name == "models.json":
            _check_lines(path, raw)
        elif sealed:
            io.check_seal(data, path)
        if data.get("figure") != _named_for(path):
            raise io.DamagedFile(f"{path}: holds the models of figure {data.get('figure')!r}, "
                                 f"not of {_named_for(path)!r} (swapped or renamed)")
        for label, c in data["conditions"].items():
            _check_condition(label, c)
    except io.DamagedFile as err:
        raise io.DamagedFile(f"{err}; {_remedy(path)}") from None
    except (ValueError, TypeError, KeyError, AttributeError, IndexError, RecursionError) as err:
        why = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise io.DamagedFile(f"{path}: damaged ({why[:300]}); {_remedy(path)}") from None
    return data


def _named_for(path: Path) -> str:
    """The figure a models file's place names: <figure>.json, <figure>/models.json, or a set
    in .<figure>.sets/."""
    if path.name != "models.json":
        return path.stem
    sets = path.parent.parent.name
    if sets.startswith(".") and sets.endswith(".sets") and path.parent.name.startswith("set~"):
        return sets[1:-len(".sets")]
    return path.parent.name


def _check_lines(path: Path, raw: bytes) -> None:  # each condition's line against manifest.json
    from .aggregate_set import _checksum, model_lines

    manifest = io.read_json(path.parent / "manifest.json", need=("models",))
    seen = {name: _checksum(line) for name, line in model_lines(raw.decode()).items()}
    want = {k: v[1] for k, v in manifest["models"].items()}
    if seen != want:
        bad = sorted(k for k in set(seen) | set(want) if seen.get(k) != want.get(k))
        raise io.DamagedFile(f"{path}: damaged: condition {bad[0]!r} does not match the "
                             "checksum manifest.json holds")


def _check_condition(label: str, c: dict) -> None:
    spec = gbmodel.TrialSpec.from_dict(c["spec"])
    try:
        body = spec.make_body()
        spec.validate(body)
    except ValueError as err:
        raise ValueError(f"condition {label!r}: {err}") from None
    if "degree" not in spec.learner:  # a learner without a polynomial M
        return
    shape = (body.m, len(gbmodel.exponents(body.n, spec.make_learner()[1].degree)))
    for i, t in c["trials"].items():
        for where, M in [("M", t.get("M")), *((f"snapshot {e}", m) for e, m in
                                               (t.get("snapshots") or {}).items())]:
            if M is None:
                continue
            M = np.asarray(M, dtype=np.float64)
            if M.shape != shape or not np.isfinite(M).all():
                raise ValueError(f"condition {label!r}, trial {i}: {where} is not a finite "
                                 f"{shape[0]} x {shape[1]} matrix")


def final_errors(data: dict) -> dict[str, np.ndarray]:
    """Condition -> each trial's final absolute error as its last evaluation measured it."""
    out = {}
    for label, c in data["conditions"].items():
        spec = gbmodel.TrialSpec.from_dict(c["spec"])
        model = Model(label, spec, {int(i): np.asarray(t["M"], np.float64)
                                    for i, t in c["trials"].items() if t.get("M") is not None})
        ev = {**gbmodel.evaluation.DEFAULTS, **spec.evaluation}
        xs = gbmodel.evaluation.eval_points(model.body, model.size, ev["points"],
                                            ev["path_steps"])
        out[label] = np.array([gbmodel.evaluation.error(
            np.linalg.norm(model.reach(xs, trial=i) - xs, axis=-1), ev["formula"])
            for i in sorted(model.M)])
    return out


def verify_against_curves(path, curves_file=None, rtol: float = 2e-5) -> list[str]:
    """What differs between a report's models file and its curves.parquet: per condition, the
    mean and quartiles of the final errors at the last epoch. [] when all agree within rtol (M
    is rounded to 9 digits: the committed files agree to 4.3e-6)."""
    import pandas as pd

    path = Path(path)
    data = read(path, sealed=False)
    curves = pd.read_parquet(curves_file or path.parent.parent / "curves.parquet")
    problems = []
    for label, errs in final_errors(data).items():
        rows = curves[(curves.figure == data["figure"]) & (curves.condition == label)]
        last = rows[rows.epoch == rows.epoch.max()]
        if len(last) != 1 or int(last.n_trials.iloc[0]) != len(errs):
            problems.append(f"{label}: {len(errs)} models, but the curves hold "
                            f"{last.n_trials.tolist()} trials at the last epoch")
            continue
        got = dict(abs_error_mean=errs.mean(), abs_error_q25=np.quantile(errs, 0.25),
                   abs_error_q75=np.quantile(errs, 0.75))
        for col, value in got.items():
            want = float(last[col].iloc[0])
            if not np.isclose(value, want, rtol=rtol, atol=0):
                problems.append(f"{label}: {col} {value:.6g} from the models, {want:.6g} in "
                                "the curves")
    return problems


def seal_file(path) -> None:
    data, problems = read(path, sealed=False), verify_against_curves(path)
    if problems:
        raise io.DamagedFile(f"{path}: its models do not give the report's final errors "
                             f"({problems[0]}); not sealed")
    io.write_json(path, io.seal({k: v for k, v in data.items() if k != io.SEAL}), compact=True)


def main(argv=None) -> int:
    """python -m pipeline.models seal FILE...: exit 2 and one line for a file not verified."""
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) < 2 or argv[0] != "seal":
        print("usage: python -m pipeline.models seal outputs/report/models/<figure>.json ...",
              file=sys.stderr)
        return 2
    for f in argv[1:]:
        try:
            seal_file(f)
        except (io.BadInput, OSError) as err:
            print(f"error: {err}", file=sys.stderr)
            return 2
        print(f"{f}: verified against the report's curves, sealed", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
