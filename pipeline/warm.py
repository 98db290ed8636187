"""Compile every kernel once (numba caches the machine code beside the sources), so that no
stage is interrupted mid-compile and no worker compiles again: `make setup` runs this.

    python -m pipeline.warm
"""
from __future__ import annotations

import time

import numpy as np

import gbmodel


def warm() -> float:
    """A two-epoch trial of every body on the fast path; returns the seconds it took."""
    start = time.perf_counter()
    for body in gbmodel.BODIES:
        if gbmodel.make_body(body).general:
            continue  # a URDF body runs on the reference path (nothing to compile)
        spec = gbmodel.TrialSpec(body={"name": body}, epochs=2)
        gbmodel.run_trial(spec, np.random.default_rng(0))
    return time.perf_counter() - start


if __name__ == "__main__":
    print(f"kernels compiled or loaded from numba's cache in {warm():.1f} s")
