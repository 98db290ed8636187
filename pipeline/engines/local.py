"""engine=local (the default): `workers` processes on this machine, one BLAS/numba thread each,
longest trial first; short trials travel in batches (pipeline.execute)."""
from __future__ import annotations

from ..execute import local
from . import engine


@engine("local")
def run(todo: list[dict], workers: int, fn, settings, logs):
    yield from local(todo, workers, fn)
