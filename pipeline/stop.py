"""Ctrl-C, SIGTERM (Slurm, `kill`) and SIGHUP all stop a stage the same way: while a stage runs
(`armed()`) they raise `Stopped`, a KeyboardInterrupt, so its `finally` blocks release claims
and stop the workers, and pipeline.cli prints one line and exits 128 + the signal; before it
runs (nothing written yet) they end the process at once with one line, no traceback. Standard
library only, so it is installed before anything slow."""
from __future__ import annotations

import os
import signal
import sys
from contextlib import contextmanager

SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
_state = {"armed": False, "stopping": None, "held": 0, "pending": None}


class Stopped(KeyboardInterrupt):
    """A stage was asked to stop by signal `signum`."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def exit_status(err: KeyboardInterrupt) -> int:
    """128 + the signal that stopped the stage (130 for a plain KeyboardInterrupt)."""
    return 128 + getattr(err, "signum", signal.SIGINT)


def _handler(signum, frame):
    if not _state["armed"]:  # no stage is running: no claims, no pool, nothing to clean up
        name = signal.Signals(signum).name
        print(f"stopped by {name} (no stage was writing)", file=sys.stderr, flush=True)
        os._exit(128 + signum)
    if _state["stopping"] is not None:
        return  # the first signal's clean-up is running: let it finish (kill -9 still works)
    if _state["held"]:
        _state["pending"] = _state["pending"] or signum
        return
    _state["stopping"] = signum
    raise Stopped(signum)


@contextmanager
def held():
    """A signal in the block raises Stopped after it, not in it (a pool starting its workers:
    one started while the driver stops would be unknown to the pool, and outlive it)."""
    _state["held"] += 1
    try:
        yield
    finally:
        _state["held"] -= 1
    signum = _state["pending"]
    if signum is not None and not _state["held"] and _state["stopping"] is None:
        _state.update(pending=None, stopping=signum)
        raise Stopped(signum)


def ignore() -> None:
    """SIGNALS ignored in this process (a pool's worker, or its fork server: the driver's)."""
    for s in SIGNALS:
        signal.signal(s, signal.SIG_IGN)


@contextmanager
def blocked():
    """The stage's signals blocked in this thread while the block runs, delivered after it: a
    process started in it begins with them blocked (as CPython starts its resource tracker), so
    that none reaches it before it chooses to ignore them (pipeline/preload.py)."""
    old = signal.pthread_sigmask(signal.SIG_BLOCK, SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def install() -> None:  # (the main thread only can)
    for s in SIGNALS:
        signal.signal(s, _handler)


@contextmanager
def armed():
    """While the block runs, a signal raises Stopped in it once (repeats are ignored during the
    clean-up); the previous handlers come back afterwards."""
    old = {s: signal.getsignal(s) for s in SIGNALS}
    install()
    _state.update(armed=True, stopping=None, pending=None)
    try:
        yield
    finally:
        _state.update(armed=False, stopping=None, pending=None)
        for s, h in old.items():
            signal.signal(s, h)
