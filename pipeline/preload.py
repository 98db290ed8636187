"""Imported once, by the local pool's fork server (execute.context), never by a stage: the server
dies with the driver that started it (and its forks, the workers, with it), and numpy, numba's
registries and Goal Babbling's fast kernels are loaded there, so that each worker starts warm.
Where loading fails, each worker loads them itself (and reports)."""
from .warm import preload
from .worker import die_with_parent

die_with_parent()
preload()
