"""The driver's progress lines (pipeline/progress.py): per trial as locally, and a heartbeat
when nothing has finished for a while (cluster shards finish in bursts)."""
import io
import time
from types import SimpleNamespace

from pipeline.progress import Progress


def summary(total=3):
    return SimpleNamespace(figure="fig4", total=total, cached=0, ran=0, failed={},
                           labels={f"k{i}": f"TG10 trial {i}" for i in range(total)})


class Tty(io.StringIO):
    def isatty(self):
        return True


def test_a_heartbeat_line_when_nothing_finished_for_heartbeat_s_as_plain_lines():
    s, out = summary(), io.StringIO()  # not a terminal: a SLURM log
    todo = [dict(key=f"k{i}") for i in range(3)]
    p = Progress(s, todo, heartbeat_s=0.3, stream=out, cost=lambda t: 1.0)
    time.sleep(1.0)
    s.ran = 1
    p.update(todo[0], dict(status="ok", seconds=0.5))
    p.close()
    lines = out.getvalue().splitlines()
    beats = [ln for ln in lines if "waiting: nothing finished for" in ln]
    assert beats and beats[0].startswith("[fig4] 0/3 trials done") and "3 trial(s)" in beats[0]
    assert lines[-1].startswith("[fig4] 1/3 trials done") and "TG10 trial 0 ok in 0.5 s" in lines[-1]
    assert "\r" not in out.getvalue() and "\x1b" not in out.getvalue()
    assert not p.beat.is_alive()  # close() stops the heartbeat


def test_on_a_terminal_the_heartbeat_rewrites_itself():
    s, out = summary(), Tty()
    p = Progress(s, [dict(key="k0")], heartbeat_s=0.2, stream=out, cost=lambda t: 1.0)
    time.sleep(0.8)
    p.close()
    text = out.getvalue()
    assert text.count("\r\x1b[K") >= 1 and text.endswith("\n")


def test_no_heartbeat_without_heartbeat_s_and_eta_by_cost():
    s, out = summary(2), io.StringIO()
    todo = [dict(key="k0", c=3.0), dict(key="k1", c=1.0)]
    p = Progress(s, todo, heartbeat_s=0, stream=out, cost=lambda t: t["c"])
    assert p.beat is None
    s.ran = 1
    p.update(todo[1], dict(status="ok", seconds=1.0))  # a quarter of the cost done
    assert "| ETA " in out.getvalue() and out.getvalue().count("\n") == 1
