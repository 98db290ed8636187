"""The fourth fault battery (issue 40): the solver's extremes, growth tables and frames refused
before planning; sealed models; a quote tool that cannot destroy a page; saved plans checked like
a cache; Hydra that cannot run code or write outside the root. Each test names its row of
docs/faults.md."""
import os
import time

import pytest

from pipeline.tools import quotes

SUMMARY = "figure,condition,v,tiny\nfig4,a,0.0123951,1e-320\nfig4,b,0.5,0\n"


@pytest.fixture
def qroot(tmp_path, monkeypatch):
    """A repository of one table (outputs/report/summary.csv) and a page, as quotes sees it."""
    (tmp_path / "outputs" / "report").mkdir(parents=True)
    (tmp_path / "outputs" / "report" / "summary.csv").write_text(SUMMARY)
    monkeypatch.setattr(quotes, "REPO_ROOT", tmp_path)
    return tmp_path


def _quote_main(root, text: bytes | str, capsys, *flags):
    page = root / "page.md"
    page.write_bytes(text if isinstance(text, bytes) else text.encode())
    rc = quotes.main([*flags, str(page)])
    return rc, capsys.readouterr().err.strip()


@pytest.mark.parametrize("marker, says", [
    ("summary.csv =x v", "'=x' is no filter"),
    ("summary.csv figure=fig4 condition=a v*1e999", "not a finite number"),
    ("summary.csv figure=fig4 condition=a v / summary.csv figure=fig4 condition=a tiny",
     "the ratio is inf"),
    ("summary.csv figure=fig4 condition=a v*1e-400 / summary.csv figure=fig4 condition=b v",
     None),  # a scale that underflows to 0: a number, 0.0 (no error)
    ("/etc/passwd.csv x", "without '..'"),
    ("../outside.csv x", "without '..'"),
    ("outputs/report/link.csv figure=fig4 condition=a v", "leads outside the repository"),
    ("outputs/report/garbage.csv x", "not a readable table"),
])
def test_r7_a_bad_marker_is_one_line_and_exit_2(qroot, capsys, marker, says):
    outside = qroot.parent / "outside.csv"
    outside.write_text(SUMMARY)
    os.symlink(outside, qroot / "outputs" / "report" / "link.csv")
    (qroot / "outputs" / "report" / "garbage.csv").write_bytes(b"\xff\xfe\x00\x00" * 10)
    rc, err = _quote_main(qroot, f"about 12.4 mm<!-- q: {marker} -->\n", capsys)
    if says is None:
        assert rc == 1 and err == "", err  # quoted 12.4, the table gives 0.0: drift, not an error
        return
    assert rc == 2 and err.startswith("error: page.md:1: ") and says in err, err
    assert "\n" not in err


@pytest.mark.parametrize("page, says", [
    ("a 0.012395100000000000000000000000 m<!-- q: summary.csv figure=fig4 condition=a v -->\n",
     "30 decimals"),
    (b"caf\xe9 12.4 mm<!-- q: summary.csv figure=fig4 condition=a v*1e3 -->\n", "not UTF-8"),
])
def test_r7_a_bad_number_or_page_is_one_line_and_exit_2(qroot, capsys, page, says):
    rc, err = _quote_main(qroot, page, capsys)
    assert rc == 2 and says in err and "\n" not in err, err


KILLED_WHILE_WRITING = """
import builtins, io, os, signal, sys
from pathlib import Path
from pipeline.tools import quotes
quotes.REPO_ROOT = Path(sys.argv[1])
real = io.open

class Dies:  # a file opened for writing: the process is killed (-9) at its first write
    def __init__(self, fh): self.fh = fh
    def write(self, data): os.kill(os.getpid(), signal.SIGKILL)
    def __enter__(self): return self
    def __exit__(self, *a): self.fh.close()
    def __getattr__(self, name): return getattr(self.fh, name)

def opened(file, mode="r", *a, **k):
    fh = real(file, mode, *a, **k)
    return Dies(fh) if "w" in mode else fh

io.open = opened
quotes.main(["--fix", sys.argv[2]])
"""


def test_r8_fix_killed_while_writing_leaves_the_page_whole(qroot):
    import signal
    import subprocess
    import sys

    from pipeline.config import REPO_ROOT
    page = qroot / "page.md"
    text = "about 10.0 mm<!-- q: summary.csv figure=fig4 condition=a v*1e3 -->\n"
    page.write_text(text)
    r = subprocess.run([sys.executable, "-c", KILLED_WHILE_WRITING, str(qroot), str(page)],
                       env=dict(os.environ, PYTHONPATH=str(REPO_ROOT)), capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == -signal.SIGKILL, r.stderr
    assert page.read_text() == text  # the old page, whole (Path.write_text left 0 bytes)
    assert quotes.main(["--fix", str(page)]) == 0
    assert page.read_text() == text.replace("10.0", "12.4")
    assert not [p.name for p in qroot.iterdir() if p.name.startswith(".")]  # the dead one's
    # temporary page is removed by the next --fix


def test_r7_a_long_line_is_read_in_linear_time(qroot):
    marker = "<!-- q: summary.csv figure=fig4 condition=a v*1e3 -->"
    lines = ["x 12.4 mm" + marker + " and" * 3,  # many markers on one line
             "1 - " * 4000 + "9",  # a range that never ends in a unit
             "7" * 16000 + marker]  # a number too long to be a quote
    for line in lines[:2]:
        page = qroot / "p.md"
        page.write_text(line * (16000 // len(line) + 1) + "\n")
        t = time.perf_counter()
        quotes.check([page], root=qroot, blocks=[], unscanned={})
        assert time.perf_counter() - t < 2
    page.write_text(lines[2] + "\n")
    t = time.perf_counter()
    with pytest.raises(quotes.BadMarker, match="longer than"):
        quotes.check([page], root=qroot, blocks=[], unscanned={})
    assert time.perf_counter() - t < 2
