"""Imported once, by the local pool's fork server (execute.context), never by a stage. First the
server ignores the signals the driver handles and dies with the driver (and its forks, the
workers, with it); then numpy, numba's registries and Goal Babbling's fast kernels are loaded,
so that each worker starts warm. Where loading fails, each worker loads them itself (and
reports)."""
import signal

from .stop import SIGNALS, ignore  # (imported with the package already: pipeline/__init__.py)

ignore()  # (a group's Ctrl-C is the driver's)
signal.pthread_sigmask(signal.SIG_UNBLOCK, SIGNALS)  # blocked from the start (stop.blocked)

from .worker import die_with_parent, driver  # noqa: E402 (after the signals: a light import)

die_with_parent(driver())

try:
    from .warm import warm  # noqa: E402

    warm(("arm5",))  # the kernels are the same for every body
except Exception:  # noqa: BLE001 (a broken gbmodel: each worker loads, and its trials report)
    pass
