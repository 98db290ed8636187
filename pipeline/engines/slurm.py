"""engine=slurm: the trials in SLURM array jobs through submitit (one CPU each), balanced by
estimated cost (submitit_jobs); run the driver on a login node (docs/engines.md). Needs the
repository on a shared file system and `pip install -e '.[slurm]'`.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any, Optional

from . import engine, submitit_jobs


@dataclass
class SlurmSettings:
    """engine.<field>: the SLURM options of every job (docs/engines.md: sizing timeout_min)."""

    partition: Optional[str] = None  # --partition; null: the cluster's default
    account: Optional[str] = None  # --account (the allocation charged); null: your default
    qos: Optional[str] = None  # --qos; null: the partition's default
    gres: Optional[str] = None  # --gres, e.g. "tmpdisk:10" (the trials need no GPU)
    constraint: Optional[str] = None  # --constraint, node features, e.g. "intel&avx2"
    # any other sbatch option, name without the dashes -> value, e.g. {reservation: lab,
    # exclude: "node[01-02]"}: `#SBATCH --reservation=lab` (submitit's additional_parameters)
    extra: dict[str, Any] = field(default_factory=dict)
    timeout_min: int = 1440  # --time of each job, minutes (a job runs a whole shard)
    mem_gb: float = 2.0  # --mem per job
    shards: Optional[int] = None  # array jobs; null: `workers`
    setup: list[str] = field(default_factory=list)  # shell lines before each job
    poll_s: float = 10.0  # how often the driver asks SLURM (sacct, squeue) about its jobs
    # SIGUSR2 this many seconds before --time (submitit's --signal=USR2@N). SLURM may send it up
    # to 60 s earlier; a shard that gets it is requeued, keeping its finished trials. null:
    # submitit's 90 s, but at most a tenth of timeout_min (so timeout_min=2 is not cut at ~30 s)
    signal_delay_s: Optional[int] = None
    # a job SLURM no longer lists (squeue) that left no result is lost after this many seconds:
    # its unfinished trials fail and the run goes on (with or without accounting, no hang)
    lost_s: float = 60.0


@engine("slurm", SlurmSettings, package="submitit", extra="slurm", takes=("cost",))
def run(todo: list[dict], workers: int, fn, settings: SlurmSettings, logs=None,
        cost=None):
    yield from submitit_jobs.results(todo, workers, fn, "slurm", asdict(settings), logs,
                                     cost)
