"""engine=local (the default): `workers` processes on this machine, one BLAS/numba thread each,
longest trial first; short trials travel in batches. The pool is the stage's (pipeline.execute,
given as `pool`): naming the engine (the config group) imports no pool."""
from __future__ import annotations

from . import engine


@engine("local", warms_up=True, takes=("pool",))  # the pool's first worker, or this process
def run(todo: list[dict], workers: int, fn, settings, logs, pool):
    yield from pool(todo, workers, fn)
