"""Commands beside the stages: the benches (bench: the kernel; scale: sweeps, cold reports and
the cached stages, against another checkout), the 1 / W rate rule, a body's inspector, the
coverage table, rescoring and the pages rendered from the report's named values (render). Run
as `python -m pipeline.tools.<name>`."""
from __future__ import annotations

import os
import subprocess
import sys
import time


def fail(why: str) -> int:
    """A tool's one-line error on stderr; its exit status, 2."""
    print(f"error: {why}", file=sys.stderr)
    return 2


def turns(items, r: int) -> list:
    """`items` in order in round r, reversed every other round: a shared machine's drifting
    speed falls on each alike."""
    return list(items)[::1 if r % 2 == 0 else -1]


def timed(cmd: list, cwd, env: dict, merged: bool = False) -> tuple:
    """Run `cmd`: (wall s, CPU s of it and every process it waited for, peak MB of the largest,
    exit status, its stderr, or with `merged` its stdout and stderr)."""
    start = time.perf_counter()
    proc = subprocess.Popen(cmd, cwd=cwd, env=env, stderr=subprocess.STDOUT if merged else
                            subprocess.PIPE, stdout=subprocess.PIPE if merged else
                            subprocess.DEVNULL)
    text = (proc.stdout if merged else proc.stderr).read()
    _, status, usage = os.wait4(proc.pid, 0)
    return (time.perf_counter() - start, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024,
            os.waitstatus_to_exitcode(status), text)
