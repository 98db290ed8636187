"""`python -m pipeline.warm` (make setup) compiles every kernel once into numba's cache and every
module of gbmodel and pipeline into its __pycache__, so no stage or worker compiles; `recovering`
removes a kernel's damaged cache files (truncated by a full disk or a killed compile, failing
every trial on every rerun), says so and calls again."""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

import gbmodel


def damaged_cache(err: BaseException) -> list[Path]:
    """The cache files of the kernel whose cache numba was loading at `err`, else []."""
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
    """call(), again once per damaged kernel cache removed; `call` must start afresh (make its
    random generator inside it), so that a retry draws the same numbers."""
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


def warm(bodies=gbmodel.BODIES) -> float:
    """A two-epoch trial of each body on the fast path; returns the seconds it took."""
    start = time.perf_counter()
    for body in bodies:
        if any(k in gbmodel.bodies.read_description(body) for k in gbmodel.bodies.READS):
            continue  # a body read from a file (whose package may be missing): the DH ones warm
        spec = gbmodel.TrialSpec(body={"name": body}, epochs=2)
        recovering(lambda: gbmodel.run_trial(spec, np.random.default_rng(0)))
    return time.perf_counter() - start


def byte_compile() -> None:
    """gbmodel's and pipeline's modules into __pycache__: Python reads them even where it writes
    none (PYTHONDONTWRITEBYTECODE, common in containers), where a stage's import would otherwise
    compile 45 modules each time (0.07-0.1 s CPU of its 0.45)."""
    import compileall

    for folder in (Path(gbmodel.__file__).parent, Path(__file__).resolve().parent):
        compileall.compile_dir(folder, quiet=1)


if __name__ == "__main__":
    byte_compile()
    print(f"kernels compiled or loaded from numba's cache in {warm():.1f} s")
