"""Compile every kernel once (numba caches the machine code beside the sources), so that no
stage is interrupted mid-compile and no worker compiles again: `make setup` runs this.

    python -m pipeline.warm

A damaged cache file (`__pycache__/*.nbi|*.nbc`, e.g. truncated by a full disk or a killed
compile) would make every trial on the fast path fail with EOFError or UnpicklingError, on every
rerun. `recovering` catches an error raised while numba loads its cache, removes that kernel's
cache files, says so in one line and runs the call once more (numba compiles it again).
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

import gbmodel


def damaged_cache(err: BaseException) -> list[Path]:
    """The cache files (index and data) of the kernel whose cache numba was loading when `err`
    was raised; [] if the error did not come from numba's cache."""
    tb, index = err.__traceback__, None
    while tb is not None:
        owner = tb.tb_frame.f_locals.get("self")
        owner = getattr(owner, "_cache_file", owner)  # numba's Cache or its IndexDataCacheFile
        if "numba" in tb.tb_frame.f_code.co_filename and hasattr(owner, "_index_path"):
            index = Path(owner._index_path)
        tb = tb.tb_next
    if index is None:
        return []
    base = index.name[:-len(".nbi")]
    return [index, *sorted(index.parent.glob(f"{base}.*.nbc"))]


def recovering(call):
    """call(), and if numba's cache of a kernel turns out damaged: remove that kernel's cache
    files, say so in one line (stderr) and call() again (once per damaged kernel). `call` must
    start afresh (make its random generator inside it), so that a retry draws the same numbers."""
    removed = set()
    while True:
        try:
            return call()
        except Exception as err:
            files = damaged_cache(err)
            if not files or files[0] in removed:  # not the cache, or removing it did not help
                raise
            removed.add(files[0])
            for f in files:
                f.unlink(missing_ok=True)
            print(f"numba's cache of a kernel was damaged ({type(err).__name__}: "
                  f"{str(err)[:60]}); removed {files[0]} and its data; compiling it again",
                  file=sys.stderr, flush=True)


def warm() -> float:
    """A two-epoch trial of every body on the fast path; returns the seconds it took."""
    start = time.perf_counter()
    for body in gbmodel.BODIES:
        if any(k in gbmodel.bodies.read_description(body) for k in gbmodel.bodies.READS):
            continue  # a body read from a file (whose package may be missing): the DH ones warm
        spec = gbmodel.TrialSpec(body={"name": body}, epochs=2)
        recovering(lambda: gbmodel.run_trial(spec, np.random.default_rng(0)))
    return time.perf_counter() - start


if __name__ == "__main__":
    print(f"kernels compiled or loaded from numba's cache in {warm():.1f} s")
