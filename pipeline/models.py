"""Trained models from Python: the final inverse estimates (and snapshots) of a figure's trials.

    >>> from pipeline import models
    >>> fig = models.load("fig4")                      # outputs/aggregate/fig4/models.json
    >>> fig.labels                                     # ['TG10', 'TG100', ..., 'const1.0']
    >>> m = fig["TG1000"]                              # one condition
    >>> q = m.posture([[0.1, 0.5]])                    # the commands its trial 0 chooses
    >>> m.joint_angles([[0.1, 0.5]])                   # the same as joint angles [rad]
    >>> m.reach([[0.1, 0.5]])                          # where the hand then is [m]
    >>> dict(fig.items())                              # a Figure is a mapping label -> Model

It reads what `python -m pipeline.aggregate` wrote (paths.aggregate/<figure>/models.json), or
the report's compact copy (models/<figure>.json: final models, no snapshots), and
builds bodies and growth from each condition's trial spec, so a model is evaluated on the body
it learned, at the size the body had at the end of its trial.
"""
from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import gbmodel


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
    def size(self) -> float:
        """The body's size factor at the end of the trial."""
        return float(self.spec.make_growth().sizes([self.spec.epochs], self.body)[-1])

    @property
    def scale(self) -> np.ndarray:
        """Per-joint length factors of the body at the end of the trial."""
        return self.spec.make_growth().scales(self.body, np.array([self.size]))[0]

    def posture(self, x, trial: int = 0, epoch: int | None = None) -> np.ndarray:
        """Commands (N, m) the model of `trial` (after `epoch`, a snapshot; None: the final M)
        chooses for targets x (N, n) [m], in the body's command units: joint angles [rad] for a
        body in radians (arm2, arm5), normalised commands in [-1, 1] onto the joint limits for a
        body with `normalise: true` (the iCub, URDF bodies); joint_angles() gives radians for
        both. A target whose number of coordinates is not the body's n is refused
        (ValueError)."""
        M = self.M[trial] if epoch is None else self.snapshots[trial][epoch]
        body = self.body
        x = np.atleast_2d(np.asarray(x, dtype=np.float64))
        if x.shape[-1] != body.n:
            raise ValueError(f"target of {x.shape[-1]} coordinates: {body.name} controls "
                             f"{body.n} ({', '.join('xyz'[o] for o in body.outputs)})")
        learner, params = self.spec.make_learner()
        return learner.predict_model(M, params, body, x)

    def joint_angles(self, x, trial: int = 0, epoch: int | None = None) -> np.ndarray:
        """The joints' angles (N, m) [rad] of the posture for targets x, in the robot's own
        convention (its limits', without the DH table's offsets), saturated at the limits as
        the body takes them."""
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


def load(figure: str, aggregate_dir=None) -> Figure:
    """The trained models of `figure` from paths.aggregate (default: outputs/aggregate of the
    repository; pass the folder for another root or profile, e.g. outputs/smoke/aggregate), or
    from a report folder's models/<figure>.json (the report stage writes them; without a local
    aggregate, the committed report's, outputs/report/models/, are read: a fresh clone)."""
    from .config import REPO_ROOT

    folders = ([Path(aggregate_dir)] if aggregate_dir is not None else
               [REPO_ROOT / "outputs" / "aggregate", REPO_ROOT / "outputs" / "report"])
    tried = [p for d in folders
             for p in (d / figure / "models.json", d / "models" / f"{figure}.json")]
    path = next((p for p in tried if p.exists()), None)
    if path is None:
        raise FileNotFoundError(f"{tried[0]}: not aggregated (run pipeline.simulate and "
                                "pipeline.aggregate for this figure, or pipeline.report for "
                                "its models/<figure>.json)")
    data = json.loads(path.read_text())
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
    return Figure(figure, out)
