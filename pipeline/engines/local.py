"""engine=local (the default): `workers` processes on this machine, one BLAS/numba thread each,
longest trial first; short trials travel in batches (pipeline.execute)."""
from __future__ import annotations

from . import engine


@engine("local", warms_up=True)  # execute.local: the pool's first worker, or this process
def run(todo: list[dict], workers: int, fn, settings, logs):
    from ..execute import local  # here: naming the engine (the config group) imports no pool

    yield from local(todo, workers, fn)
