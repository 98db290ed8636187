"""The cold report benchmark (`python -m pipeline.tools.scale report`): its input checks, the
command it times, and the files it says differ."""
import pytest

from pipeline.tools import scale as bench_report
from pipeline.tools.scale import REPO


@pytest.mark.parametrize("args", [["--baseline", "/nonexistent"],
                                  ["--baseline", str(REPO), "--rounds", "0"]])
def test_bad_input_is_exit_2(args, capsys):
    assert bench_report.main(["report", *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ")


def test_both_checkouts_report_this_ones_aggregates_into_a_new_folder(tmp_path):
    args = bench_report.report_args(["fig2", "fig4"], "smoke", tmp_path / "r")
    assert args == ["experiments=[fig2,fig4]", "profile=smoke", f"paths.root={REPO}",
                    f"paths.report={tmp_path / 'r'}"]


def test_the_files_that_differ_are_named(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    for d, files in ((a, {"same.csv": "1", "moved.csv": "1.0", "only_a.png": "x"}),
                     (b, {"same.csv": "1", "moved.csv": "1.1", "sub/only_b.csv": "y"})):
        for name, text in files.items():
            (d / name).parent.mkdir(parents=True, exist_ok=True)
            (d / name).write_text(text)
    assert bench_report.differing(a, b) == ["moved.csv", "only_a.png", "sub/only_b.csv"]


def test_each_checkout_can_report_its_own_aggregates(tmp_path):
    """--aggregates own: an older checkout reads its own outputs/ (it cannot read this one's)."""
    args = bench_report.report_args(["fig2"], "smoke", tmp_path / "out" / "r", tmp_path)
    assert args[2:] == [f"paths.root={tmp_path}", f"paths.report={tmp_path / 'out' / 'r'}"]


FAKE_REPORT = """import sys
print("error: body.callable=None: unknown key", file=sys.stderr)
sys.exit(int(sys.argv[1]))
"""


@pytest.mark.parametrize("status", [0, 1, 2])
def test_a_report_that_fails_or_writes_nothing_is_an_error_not_a_time(tmp_path, status):
    """Before: a baseline whose report stopped at once (an older commit reading this one's
    aggregates) was timed as 6 s against 41 s ('0.15x faster'), every file 'differing'."""
    fake = tmp_path / "old"
    (fake / "pipeline").mkdir(parents=True)
    (fake / "pipeline" / "__init__.py").write_text("")
    (fake / "pipeline" / "report.py").write_text(FAKE_REPORT)
    with pytest.raises(RuntimeError, match="without .*report.md: error: body.callable=None"):
        bench_report.cold_report(fake, [str(status)], tmp_path / "r")
