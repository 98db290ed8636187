"""Trained models from Python: the final inverse estimates (and snapshots) of a figure's trials.

    >>> from pipeline import models
    >>> fig = models.load("fig4")                      # outputs/aggregate/fig4/models.json
    >>> fig.labels                                     # ['TG10', 'TG100', ..., 'const1.0']
    >>> m = fig["TG1000"]                              # one condition
    >>> q = m.posture([[0.1, 0.5]])                    # the commands its trial 0 chooses
    >>> m.reach([[0.1, 0.5]])                          # where the hand then is [m]

It reads what `python -m pipeline.aggregate` wrote (paths.aggregate/<figure>/models.json), or
the report's compact copy (models/<figure>.json: final models, no snapshots), and
builds bodies and growth from each condition's trial spec, so a model is evaluated on the body
it learned, at the size the body had at the end of its trial.
"""
from __future__ import annotations

import json
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
        chooses for targets x (N, n) [m]."""
        M = self.M[trial] if epoch is None else self.snapshots[trial][epoch]
        learner, params = self.spec.make_learner()
        return learner.predict_model(M, params, self.body,
                                     np.atleast_2d(np.asarray(x, dtype=np.float64)))

    def reach(self, x, trial: int = 0, epoch: int | None = None) -> np.ndarray:
        """Where the hand is (N, n) [m] after the posture for targets x."""
        return self.body.forward(self.posture(x, trial, epoch), self.scale)


@dataclass
class Figure:
    name: str
    models: dict[str, Model]

    @property
    def labels(self) -> list[str]:
        return list(self.models)

    def __getitem__(self, label: str) -> Model:
        if label not in self.models:
            raise KeyError(f"{self.name} has no condition {label!r}; it has {self.labels}")
        return self.models[label]


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
