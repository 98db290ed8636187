"""The compiled kernel gives bit-identical results whatever x86-64 CPU it is compiled for.

Each case runs short trials in a fresh Python process whose numba compiles for one CPU target
(NUMBA_CPU_NAME / NUMBA_CPU_FEATURES, a fresh NUMBA_CACHE_DIR) and compares the learning curve
and the final M byte for byte (sha256). The targets differ in vector width (AVX2: 256 bits;
AVX-512: 512 bits, or 256 where LLVM prefers it; the x86-64 baseline: SSE2 and no FMA). All of
them run on this machine, so targets that need AVX-512 are skipped on a CPU without it. The child
reports whether its code uses zmm / ymm registers, so that a target LLVM did not take cannot
pass unnoticed.
"""
import json
import os
import subprocess
import sys

from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[2]

CHILD = r"""
import hashlib, json, sys
import numpy as np
import gbmodel
from gbmodel.learners.goal_babbling import core
from numba.core.registry import cpu_target


def digest(r):
    data = np.ascontiguousarray(r.abs_error).tobytes() + np.ascontiguousarray(r.M).tobytes()
    return hashlib.sha256(data).hexdigest()


out = {}
spec = gbmodel.TrialSpec(
    body={"name": "arm5"}, epochs=300, learner={"name": "goal_babbling"},
    growth={"pattern": "nonproportional", "period": 200, "start_size": 0.6})
out["arm5"] = digest(gbmodel.run_trial(spec, np.random.default_rng(1)))
if "icub" in sys.argv:
    spec = gbmodel.TrialSpec(
        body={"name": "icub"}, epochs=100,
        learner={"name": "goal_babbling", "radius": 0.1, "targets_per_epoch": 30, "steps": 10},
        growth={"pattern": "proportional", "period": 60, "start_size": 0.5})
    out["icub"] = digest(gbmodel.run_trial(spec, np.random.default_rng(2)))
if "urdf" in sys.argv:  # a general (URDF) chain: the iCub from icub-models' URDF
    spec = gbmodel.TrialSpec(
        body={"name": "icub_urdf"}, epochs=60,
        learner={"name": "goal_babbling", "radius": 0.1, "targets_per_epoch": 30, "steps": 10},
        growth={"pattern": "proximal_first", "period": 40, "start_size": 0.5})
    out["icub_urdf"] = digest(gbmodel.run_trial(spec, np.random.default_rng(3)))
if "lstsq" in sys.argv:  # learner.solver=lstsq: Gram sums in the kernel, the p x p solve
    spec = gbmodel.TrialSpec(
        body={"name": "arm5"}, epochs=60, learner={"name": "goal_babbling", "solver": "lstsq"},
        growth={"pattern": "nonproportional", "period": 40, "start_size": 0.6})
    out["arm5_lstsq"] = digest(gbmodel.run_trial(spec, np.random.default_rng(4)))
    spec = gbmodel.TrialSpec(
        body={"name": "icub_urdf"}, epochs=30,
        learner={"name": "goal_babbling", "solver": "lstsq", "radius": 0.1,
                 "targets_per_epoch": 30, "steps": 10})
    out["icub_urdf_lstsq"] = digest(gbmodel.run_trial(spec, np.random.default_rng(5)))
if "online" in sys.argv:  # learner.updates=online: the float64 per-sample kernel
    spec = gbmodel.TrialSpec(
        body={"name": "arm5"}, epochs=60, learner={"name": "goal_babbling", "updates": "online"},
        growth={"pattern": "nonproportional", "period": 40, "start_size": 0.6})
    out["arm5_online"] = digest(gbmodel.run_trial(spec, np.random.default_rng(6)))
    spec = gbmodel.TrialSpec(  # m = 10: two vectors of rows side by side
        body={"name": "icub_urdf"}, epochs=20,
        learner={"name": "goal_babbling", "updates": "online", "radius": 0.1,
                 "targets_per_epoch": 30, "steps": 10})
    out["icub_urdf_online"] = digest(gbmodel.run_trial(spec, np.random.default_rng(7)))
codegen = cpu_target.target_context.codegen()
out["cpu"] = codegen._get_host_cpu_name()
out["features"] = codegen._tm_features
asm = core._tile5x5.overloads[core._tile5x5.signatures[0]].library.get_asm_str()
out["zmm"], out["ymm"] = asm.count("%zmm"), asm.count("%ymm")
print(json.dumps(out))
"""

AVX512 = ("avx512f", "avx512bw", "avx512cd", "avx512dq", "avx512vl")


def host_features() -> set[str]:
    import llvmlite.binding as ll

    return {f[1:] for f in ll.get_host_cpu_features().flatten().split(",") if f[0] == "+"}


def run_child(tmp_path, name: str, env: dict, *args: str) -> dict:
    """The child's report, compiled for the target that env (NUMBA_*) names."""
    clean = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    full = {**clean, **env, "NUMBA_CACHE_DIR": str(tmp_path / f"numba-{name}"),
            "PYTHONPATH": str(REPO_ROOT)}
    proc = subprocess.run([sys.executable, "-c", CHILD, *args], capture_output=True, text=True,
                          cwd=str(tmp_path), env=full, timeout=600)
    assert proc.returncode == 0, f"{name}:\n{proc.stderr[-3000:]}"
    return json.loads(proc.stdout.strip().splitlines()[-1])


# name -> (environment, the vector registers its code must use: "zmm", "ymm" or None)
TARGETS = {
    "host": ({}, None),  # this CPU as numba sees it
    "haswell": ({"NUMBA_CPU_NAME": "haswell", "NUMBA_CPU_FEATURES": ""}, "ymm"),
    "x86-64-v3": ({"NUMBA_CPU_NAME": "x86-64-v3", "NUMBA_CPU_FEATURES": ""}, "ymm"),
    "x86-64": ({"NUMBA_CPU_NAME": "x86-64", "NUMBA_CPU_FEATURES": ""}, None),  # SSE2, no FMA
    "skylake-avx512": ({"NUMBA_CPU_NAME": "skylake-avx512", "NUMBA_CPU_FEATURES": ""}, None),
    "skylake-avx512-zmm": ({"NUMBA_CPU_NAME": "skylake-avx512",
                            "NUMBA_CPU_FEATURES": "-prefer-256-bit"}, "zmm"),
    "x86-64-v4": ({"NUMBA_CPU_NAME": "x86-64-v4", "NUMBA_CPU_FEATURES": ""}, "zmm"),
}


def check_registers(name, report, expected):
    if expected is None:
        return
    if expected == "zmm":
        assert report["zmm"] > 0, f"{name}: no 512-bit code ({report['cpu']})"
    elif expected == "ymm":
        assert report["ymm"] > 0 and report["zmm"] == 0, f"{name}: not 256-bit code"


# slow (102 s of make test's CPU: two children that compile every kernel): the haswell and host
# targets, with the same six cases, are two of test_same_bits_on_every_target's (slow) targets.
@pytest.mark.slow
def test_arm5_same_bits_on_haswell_and_host(tmp_path):
    """AVX2 + FMA without AVX-512 (haswell) against whatever this CPU is: a DH and a URDF
    chain."""
    reports = {name: run_child(tmp_path, name, TARGETS[name][0], "urdf", "lstsq", "online")
               for name in ("host", "haswell")}
    check_registers("haswell", reports["haswell"], "ymm")
    for case in ("arm5", "icub_urdf", "arm5_lstsq", "icub_urdf_lstsq", "arm5_online",
                 "icub_urdf_online"):
        assert reports["haswell"][case] == reports["host"][case], reports


@pytest.mark.slow
def test_same_bits_on_every_target(tmp_path):
    """arm5, the iCub and the URDF iCub on every target this CPU can run, and on the host with its features given
    explicitly, as they are and with LLVM's preference for 256-bit vectors forced."""
    import llvmlite.binding as ll

    host = host_features()
    flat = ll.get_host_cpu_features().flatten()
    targets = dict(TARGETS)
    targets["host-features"] = ({"NUMBA_CPU_FEATURES": flat}, None)
    targets["host-256-bit"] = ({"NUMBA_CPU_FEATURES": flat + ",+prefer-256-bit"}, None)
    if not set(AVX512) <= host:
        for name in ("skylake-avx512", "skylake-avx512-zmm", "x86-64-v4"):
            targets.pop(name)
    if not {"avx2", "fma"} <= host:
        pytest.skip("this CPU has no AVX2 + FMA")
    reports = {}
    for name, (env, expected) in targets.items():
        reports[name] = run_child(tmp_path, name, env, "icub", "urdf", "lstsq", "online")
        check_registers(name, reports[name], expected)
    digests = {name: (r["arm5"], r["icub"], r["icub_urdf"], r["arm5_lstsq"],
                      r["icub_urdf_lstsq"], r["arm5_online"], r["icub_urdf_online"])
               for name, r in reports.items()}
    assert len(set(digests.values())) == 1, json.dumps(digests, indent=1)

