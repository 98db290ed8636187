"""Commands beside the stages: the benches (bench: the kernel; scale: sweeps, cold reports and
the cached stages, against another checkout), the 1 / W rate rule, a body's inspector, the
coverage table, rescoring and the pages rendered from the report's named values (render). Run
as `python -m pipeline.tools.<name>`."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]  # the checkout


def fail(why: str) -> int:
    """A tool's one-line error on stderr; its exit status, 2."""
    print(f"error: {why}", file=sys.stderr)
    return 2


def interleaved(names, rounds: int, run, before=None, flip: bool = True) -> dict:
    """name -> [run(name, r) per round r]: every name once a round, `before()` first, in reversed
    order every other round with `flip` (a shared machine's drifting speed falls on each alike)."""
    out = {name: [] for name in names}
    for r in range(rounds):
        if before is not None:
            before()
        for name in list(out)[::-1 if flip and r % 2 else 1]:
            out[name].append(run(name, r))
    return out


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


def child(code, script: str, *args: str, env: dict | None = None) -> dict:
    """The JSON that `python -c script args` prints last in checkout `code`."""
    proc = subprocess.run([sys.executable, "-c", script, *args], cwd=code, capture_output=True,
                          text=True, env=env or dict(os.environ, PYTHONPATH=str(code)))
    if proc.returncode:
        raise RuntimeError(f"a child in {code} exited {proc.returncode}: {proc.stderr[-2000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])
