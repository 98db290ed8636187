"""Progress lines: one per finished trial (done/total, elapsed, ETA), and a heartbeat when none
finished for `heartbeat_s` (a cluster's bursts); on a terminal the heartbeat overwrites itself.
"""
from __future__ import annotations

import sys
import threading
import time

HEARTBEAT_S = 60.0


def fmt_duration(seconds: float) -> str:
    seconds = int(round(seconds))
    h, rest = divmod(seconds, 3600)
    return f"{h}h{rest // 60:02d}m{rest % 60:02d}s" if h else f"{rest // 60}m{rest % 60:02d}s"


ESTIMATE_ABOVE_S = 60.0  # a run estimated to take longer than this says so before it starts


def estimate(trials: list[dict], workers: int, costs: dict | None = None,
             jobs: tuple[int, int] | None = None) -> str | None:
    """One line before a run above ESTIMATE_ABOVE_S of CPU (plan.cpu_seconds), else None.
    jobs=(planned, all): `trials` are those of `planned` jobs of a sweep, the rest at the mean."""
    from .plan import cost, cpu_seconds

    if not trials:
        return None
    planned, every = jobs or (1, 1)
    units = sum((costs or {}).get(t["key"]) or cost(t) for t in trials)
    cpu = cpu_seconds(units, len(trials)) * every / planned
    if cpu <= ESTIMATE_ABOVE_S:
        return None
    epochs = sorted({int(t["spec"]["epochs"]) for t in trials})
    span = f"{epochs[0]:,}" if len(epochs) == 1 else f"{epochs[0]:,} to {epochs[-1]:,}"
    n = round(len(trials) * every / planned)
    workers = max(1, min(workers, n))
    sweep = "" if jobs is None else f"the sweep's {every:,} jobs, "
    if every > planned:
        sweep = f"{sweep[:-2]} ({every - planned:,} counted at the mean of the {planned} planned), "
    return (f"estimate: {sweep}{n:,} trials of {span} epochs, about "
            f"{fmt_duration(cpu)} of CPU time (the cost model, pipeline.plan.cost), so about "
            f"{fmt_duration(cpu / workers)} on {workers} worker(s) with a core each; "
            "Ctrl-C stops it, and the same command resumes")


class Progress:
    """The lines of a run; `summary`: pipeline.simulate's Summary; close() stops the heartbeat."""

    def __init__(self, summary, todo: list[dict], heartbeat_s: float = HEARTBEAT_S,
                 stream=None, cost=None):
        if cost is None:
            from .plan import cost
        self.s, self.stream = summary, stream or sys.stderr
        self.start = self.last = time.perf_counter()
        self.costs = {t["key"]: cost(t) for t in todo}  # each estimated once (it builds the body)
        self.total_cost, self.done_cost = sum(self.costs.values()), 0.0
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.lock, self.stop = threading.Lock(), threading.Event()
        self.beat, self.open_line = None, False
        if heartbeat_s and todo:
            self.beat = threading.Thread(target=self._heartbeat, args=(heartbeat_s,),
                                         daemon=True, name="progress-heartbeat")
            self.beat.start()

    def head(self, elapsed: float) -> str:
        s = self.s
        eta = (elapsed * (self.total_cost - self.done_cost) / self.done_cost
               if self.done_cost else None)
        return (f"[{s.figure}] {s.cached + s.ran}/{s.total} trials done"
                f"{f', {len(s.failed)} failed' if s.failed else ''}"
                f" | elapsed {fmt_duration(elapsed)} | ETA "
                f"{fmt_duration(eta) if eta is not None else '?'}")

    def update(self, trial: dict, result: dict) -> None:
        with self.lock:
            self.done_cost += self.costs.get(trial["key"], 0.0)
            now = time.perf_counter()
            self.last = now
            self._write(f"{self.head(now - self.start)} | {self.s.labels[trial['key']]} "
                        f"{result['status']} in {result['seconds']:.1f} s")

    def _heartbeat(self, every: float) -> None:
        while not self.stop.wait(min(every, 5.0)):
            with self.lock:
                now = time.perf_counter()
                if now - self.last < every:
                    continue
                left = self.s.total - self.s.cached - self.s.ran
                self._write(f"{self.head(now - self.start)} | waiting: nothing finished for "
                            f"{fmt_duration(now - self.last)}, {left} trial(s) running or "
                            "queued", beat=True)
                if not self.tty:
                    self.last = now  # the next plain line after another `every` seconds

    def _write(self, line: str, beat: bool = False) -> None:
        if self.tty:  # a heartbeat rewrites itself; a trial's line replaces it
            line = f"\r\x1b[K{line}" + ("" if beat else "\n")
        else:
            line += "\n"
        self.open_line = self.tty and beat
        self.stream.write(line)
        self.stream.flush()

    def close(self) -> None:
        self.stop.set()
        if self.beat is not None:
            self.beat.join()
        if self.open_line:  # a heartbeat on a terminal ends without a newline
            self.stream.write("\n")
            self.stream.flush()


class Steps:
    """A line per step of a stage without trials: `[report] 3/9 readings | elapsed 0m41s`."""

    def __init__(self, stage: str, total: int, stream=None):
        self.stage, self.total, self.done = stage, total, 0
        self.stream = stream or sys.stderr
        self.start = time.perf_counter()

    def __call__(self, what: str) -> None:
        self.done += 1
        self.stream.write(f"[{self.stage}] {self.done}/{self.total} {what} | elapsed "
                          f"{fmt_duration(time.perf_counter() - self.start)}\n")
        self.stream.flush()

