"""engine=ray: one Ray task per trial (one CPU, one thread), submitted longest first, collected
with ray.wait. No address: a local Ray of `workers` CPUs for this run; `auto` or `ray://host:10001`
joins a cluster (every node with this repository at the same code). A dead worker's task is not
retried (max_retries=0): it fails, and the next run computes it. No node with a CPU for RAY_LOST_S:
the trials left fail. Needs `pip install -e '.[ray]'`.
"""
from __future__ import annotations

import logging
import time
import traceback
from dataclasses import dataclass
from typing import Optional

from . import THREAD_VARS, call, engine, failed

RAY_OBJECT_STORE_BYTES = 100 * 1000**2  # a result is a few hundred kB at most
RAY_POLL_S = 5.0  # how often the driver looks at the cluster while no trial finishes
RAY_LOST_S = 60.0  # no node with a CPU for this long: the trials left fail (a node may rejoin)


@dataclass
class RaySettings:
    address: Optional[str] = None  # a Ray cluster's address (`auto`, `ray://host:10001`); null: a local Ray


@engine("ray", RaySettings, package="ray", extra="ray")
def run(todo: list[dict], workers: int, fn, settings: RaySettings, logs=None):
    address = settings.address
    import ray
    from ray.exceptions import RayError

    own = not ray.is_initialized()
    if own:
        kw = dict(address=address or None, include_dashboard=False, log_to_driver=False,
                  logging_level=logging.WARNING, configure_logging=True)
        if not address:  # a local instance for this run only
            kw.update(num_cpus=workers, object_store_memory=RAY_OBJECT_STORE_BYTES)
        ray.init(**kw)
    task = ray.remote(call).options(
        num_cpus=1, max_retries=0, name="gbgrowth-trial",
        runtime_env={"env_vars": {k: "1" for k in THREAD_VARS}})
    pending = {}
    try:
        fn_ref = ray.put(fn)
        pending = {task.remote(fn_ref, t): t for t in todo}
        no_cpu_since = None
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1, timeout=RAY_POLL_S)
            if not ready:
                if ray.cluster_resources().get("CPU", 0) >= 1:
                    no_cpu_since = None
                    continue
                # every node that could run a trial is gone: the tasks left can never be
                # scheduled, and ray.wait would wait for them forever
                no_cpu_since = no_cpu_since or time.monotonic()
                if time.monotonic() - no_cpu_since < RAY_LOST_S:
                    continue
                for ref, trial in list(pending.items()):
                    del pending[ref]
                    ray.cancel(ref, force=True)
                    yield trial, failed(trial, f"no Ray node with a CPU left for "
                                        f"{RAY_LOST_S:.0f} s: the trial cannot be scheduled")
                break
            (ref,) = ready
            trial = pending.pop(ref)
            try:
                result = ray.get(ref)
            except RayError as err:  # the worker died, the node was lost, the task was cancelled
                result = failed(trial, f"{type(err).__name__}: {err}", tb=traceback.format_exc())
            yield trial, result
    finally:
        for ref in pending:  # Ctrl-C, an error or a dropped generator: stop the rest now
            try:
                ray.cancel(ref, force=True)
            except Exception:  # noqa: BLE001 - already finished or gone
                pass
        if own:
            ray.shutdown()
