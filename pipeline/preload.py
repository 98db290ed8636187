"""Imported once, by the local pool's fork server (execute.context), never by a stage: numpy,
numba's registries and Goal Babbling's fast kernels are loaded there, so that each worker, a fork
of the server, starts warm. Where this fails, each worker loads them itself (and reports)."""
from .warm import preload

preload()
