"""engine=local (the default): the stage's pool of processes (pipeline.execute, given as `pool`)."""
from __future__ import annotations

from . import engine


@engine("local", warms_up=True, takes=("pool",))  # the pool's first worker, or this process
def run(todo: list[dict], workers: int, fn, settings, logs, pool):
    yield from pool(todo, workers, fn)
