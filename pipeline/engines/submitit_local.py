"""engine=submitit_local: the slurm engine's code path on this machine, its shards as `workers`
local submitit jobs (tests; a SLURM setup tried without a cluster). Needs the extra [slurm].
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Optional

from . import engine, submitit_jobs


@dataclass
class SubmititLocalSettings:
    timeout_min: int = 1440  # the time limit of each job, minutes (a job runs a whole shard)
    shards: Optional[int] = None  # jobs; null (and at most): `workers`, all started at once
    setup: list[str] = field(default_factory=list)  # shell lines before each job


@engine("submitit_local", SubmititLocalSettings, package="submitit", extra="slurm",
        takes=("cost",))
def run(todo: list[dict], workers: int, fn, settings: SubmititLocalSettings, logs=None,
        cost=None):
    yield from submitit_jobs.results(todo, workers, fn, "local", asdict(settings), logs,
                                     cost)
