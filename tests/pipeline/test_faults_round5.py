"""The fifth fault battery (issue 54): data never runs code. A body or models file names no
function that its author did not mark; hostile registers, links and full disks are one line;
MJCF models read as MuJoCo reads them. Each test names its row of docs/faults.md (`test_r20_...`);
every row has a variant the issue did not list (the MJCF rows: tests/core/test_mjcf_faults.py).
Rows 38, 41 and 44 belong to the config's front door (its allow-list) and are tested there."""
import json
import os
import re
import resource
import shutil
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from gbmodel import body_loop
from gbmodel.bodies import body_from
from pipeline import io, models
from pipeline.config import REPO_ROOT
from pipeline.studies import claims
from pipeline.tools import render, rescore
from conftest import files_of

GRID = {"lo": [0.1, 0.15], "hi": [0.3, 0.35], "num": [3, 3]}


def _desc(factory, **callable_):
    return {"name": "loop_arm", "callable": {"factory": factory, **callable_},
            "outputs": [0, 1], "home": [1.0, 0.5], "grid": GRID}


def _one_line(err) -> str:
    assert "\n" not in str(err.value), str(err.value)
    return str(err.value)


@pytest.fixture
def mods(tmp_path, monkeypatch):
    """write(name, source): a module of the test's own, importable here and in children."""
    folder = tmp_path / "mods"
    folder.mkdir()
    monkeypatch.syspath_prepend(str(folder))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(folder), str(REPO_ROOT)]))
    tag = f"{os.getpid()}_{time.monotonic_ns()}"

    def write(name, source):
        (folder / f"m_{name}_{tag}.py").write_text(textwrap.dedent(source))
        return f"m_{name}_{tag}"
    return write


def _forward(desc):
    return body_from(desc).forward(np.zeros((1, 2)))


# ---- rows 20, 21: the standard library named as a factory --------------------------------------
@pytest.mark.parametrize("factory, args", [
    ("subprocess:run", {"args": ["touch", "{mark}"]}),
    ("os:system", {"command": "touch {mark}"}),
    ("shutil:rmtree", {"path": "{victim}"}),
    # variants: a built-in, a C module, a dotted stdlib path, an importer, ctypes
    ("builtins:exec", {"source": "open('{mark}', 'w')"}),
    ("posix:system", {"command": "touch {mark}"}),
    ("os.path:exists", {"path": "{mark}"}),
    ("importlib:import_module", {"name": "antigravity"}),
    ("ctypes:CDLL", {"name": "libc.so.6"}),
])
def test_r20_r21_the_standard_library_is_refused_before_anything_runs(tmp_path, factory, args):
    mark, victim = tmp_path / "MARK", tmp_path / "victim"
    victim.mkdir()
    (victim / "keep").write_text("x")
    args = json.loads(json.dumps(args).replace("{mark}", str(mark)).replace("{victim}",
                                                                             str(victim)))
    with pytest.raises(ValueError) as err:
        _forward(_desc(factory, args=args))
    assert "is the standard library" in _one_line(err)
    assert not mark.exists() and (victim / "keep").exists()


@pytest.mark.parametrize("source, factory, says", [
    (None, "subprocess:run", "subprocess is the standard library"),
    ("import sys\nsys.exit(0)\n", "{m}:make", "SystemExit: 0"),  # row 24: exit 2, not success
])
def test_r20_r24_planning_such_a_body_file_is_one_line_exit_2(mods, tmp_path, source, factory,
                                                              says):
    conf, mark = tmp_path / "conf" / "body", tmp_path / "MARK"
    conf.mkdir(parents=True)
    factory = factory.format(m=mods("exits", source) if source else "")
    (conf / "evil.yaml").write_text(json.dumps(
        _desc(factory, args={"args": ["touch", str(mark)]}) | {"name": "evil"}))
    r = subprocess.run([sys.executable, "-m", "pipeline.simulate",
                        f"hydra.searchpath=[file://{conf.parent}]", "body=evil",
                        "learner.fast=false", "trials.count=1", f"paths.root={tmp_path / 'o'}"],
                       cwd=REPO_ROOT, capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and says in r.stderr, r.stderr
    assert not mark.exists()


def test_r20_an_unmarked_function_is_never_called(mods, tmp_path):
    called = tmp_path / "CALLED"
    name = mods("unmarked", f"""
        def make(**kw):
            open({str(called)!r}, "w").write("x")
        class Maker:
            make = staticmethod(make)
        """)
    for factory in (f"{name}:make", f"{name}:Maker.make", "pipeline.io:write_text",
                    "gbmodel.body_loop:body_factory"):
        with pytest.raises(ValueError) as err:
            _forward(_desc(factory))
        assert "not marked as a body factory" in _one_line(err), factory
    assert not called.exists()


def test_r20_a_marked_factory_runs_and_the_mark_is_the_authors(mods):
    name = mods("marked", """
        import numpy as np
        import gbmodel

        @gbmodel.body_factory
        def make():
            return lambda angles, factors: np.column_stack([np.cos(angles[:, 0]),
                                                            np.sin(angles[:, 0]),
                                                            np.zeros(len(angles))])
        """)
    np.testing.assert_allclose(_forward(_desc(f"{name}:make")), [[1.0, 0.0]])
    with pytest.raises(TypeError):
        body_loop.body_factory(3)


# ---- row 22: loading a model builds no callable body --------------------------------------------
def _models_with_callable(tmp_path, factory, args=None):
    """The committed fig2 models file with its body replaced by a callable, resealed."""
    report = tmp_path / "report"
    (report / "models").mkdir(parents=True)
    path = report / "models" / "fig2.json"
    data = json.loads((REPO_ROOT / "outputs/report/models/fig2.json").read_text())
    for cond in data["conditions"].values():
        cond["spec"]["body"].update(dh=None, callable={"factory": factory, "args": args or {}})
        cond["spec"]["learner"]["fast"] = False  # a body in the loop: the reference path
    path.write_text(json.dumps(io.seal({k: v for k, v in data.items() if k != "seal"})))
    return report


def test_r22_a_resealed_models_file_naming_the_standard_library_runs_nothing(tmp_path):
    mark = tmp_path / "MARK"
    report = _models_with_callable(tmp_path, "os:system", {"command": f"touch {mark}"})
    with pytest.raises(io.DamagedFile) as err:
        models.load("fig2", report)
    assert "os is the standard library" in _one_line(err) and not mark.exists()


def test_r22_loading_imports_nothing_and_evaluating_calls_no_unmarked_function(mods, tmp_path):
    imported, called = tmp_path / "IMPORTED", tmp_path / "CALLED"
    name = mods("payload", f"""
        open({str(imported)!r}, "w").write("x")
        def make(**kw):
            open({str(called)!r}, "w").write("x")
        """)
    fig = models.load("fig2", _models_with_callable(tmp_path, f"{name}:make"))
    assert fig.labels == ["const1.0"] and not imported.exists()  # described, never built
    with pytest.raises(ValueError) as err:
        fig["const1.0"].reach([[0.1]])
    assert "not marked" in _one_line(err) and not called.exists()


# ---- rows 24, 25: a module that exits, hangs, interrupts or ends its process ---------------------
@pytest.mark.parametrize("source, where, says", [
    ("import sys\nsys.exit(0)", "import", "SystemExit: 0"),
    ("raise KeyboardInterrupt", "import", "KeyboardInterrupt"),
    ("import os\nos._exit(3)", "import", "ended the process (exit status 3)"),
    ("import time\ntime.sleep(600)", "import", "did not finish in 3 s"),
    # variants: the same in the factory's first call, a thread that never ends, a text exit
    ("import sys\nsys.exit('bye')", "call", "SystemExit: bye"),
    ("import os\nos._exit(0)", "call", "ended the process (exit status 0)"),
    ("import time\ntime.sleep(600)", "call", "did not finish in 3 s"),
    ("import threading, time\nthreading.Thread(target=time.sleep, args=(600,)).start()",
     "import", "must return the forward function"),
])
def test_r24_r25_exits_hangs_and_interrupts_are_one_line(mods, monkeypatch, source, where, says):
    monkeypatch.setattr(body_loop, "TIME_LIMIT", 3.0)
    body = f"    {source.replace(chr(10), chr(10) + '    ')}\n    return None" \
        if where == "call" else "    return None"
    name = mods("hostile", (source + "\n" if where == "import" else "")
                + f"import gbmodel\n@gbmodel.body_factory\ndef make():\n{body}\n")
    t = time.perf_counter()
    with pytest.raises(ValueError) as err:
        _forward(_desc(f"{name}:make"))
    assert says in _one_line(err) and time.perf_counter() - t < 30


def test_r25_what_the_import_started_is_stopped_with_it(mods, tmp_path):
    """Variant: the import starts a process that outlives it (holding its output open): the
    probe does not wait for it, and it is killed with the probe's session."""
    pid = tmp_path / "pid"
    name = mods("spawns", f"""
        import subprocess
        p = subprocess.Popen(["sleep", "600"])
        open({str(pid)!r}, "w").write(str(p.pid))
        import gbmodel
        @gbmodel.body_factory
        def make():
            return None
        """)
    t = time.perf_counter()
    with pytest.raises(ValueError, match="must return the forward function"):
        _forward(_desc(f"{name}:make"))
    assert time.perf_counter() - t < 30
    stat = Path(f"/proc/{pid.read_text()}/stat")
    for _ in range(50):  # killed, then reaped by whoever adopted it
        if not stat.exists() or stat.read_text().split()[2] == "Z":
            break
        time.sleep(0.1)
    assert not stat.exists() or stat.read_text().split()[2] == "Z"


# ---- row 26: positions held to +-1000 m ----------------------------------------------------------
@pytest.mark.parametrize("value", ["1e300", "-1e4", "float('nan')", "1000.5"])
def test_r26_positions_beyond_1000_m_are_one_line(mods, value):
    name = mods("huge", f"""
        import numpy as np
        import gbmodel
        @gbmodel.body_factory
        def make():
            return lambda angles, factors: np.full((len(angles), 3), {value})
        """)
    with pytest.raises(ValueError) as err:
        _forward(_desc(f"{name}:make"))
    assert "within +-1000" in _one_line(err)


# ---- row 31: a models file is the figure it is named for -----------------------------------------
def test_r31_swapped_models_files_are_refused(tmp_path):
    report = tmp_path / "report"
    (report / "models").mkdir(parents=True)
    src = REPO_ROOT / "outputs/report/models"
    shutil.copy(src / "fig7.json", report / "models" / "fig7_20trials.json")
    shutil.copy(src / "fig7_20trials.json", report / "models" / "fig7.json")
    for name in ("fig7", "fig7_20trials"):
        with pytest.raises(io.DamagedFile) as err:
            models.load(name, report)
        assert "swapped or renamed" in _one_line(err)
    # variant: a renamed copy loaded by its path
    shutil.copy(src / "fig2.json", tmp_path / "mine.json")
    with pytest.raises(io.DamagedFile, match="figure 'fig2', not of 'mine'"):
        models.load(tmp_path / "mine.json")
    assert models.load(src / "fig2.json").labels == ["const1.0"]
    # an aggregate's models.json: its folder, or the set that folder links to, names it
    assert models._named_for(tmp_path / "agg" / ".f2.sets" / "set~h~1~0" / "models.json") == "f2"
    assert models._named_for(tmp_path / "agg" / "f3" / "models.json") == "f3"


# ---- rows 33-36, 46: registers -------------------------------------------------------------------
def _register(tmp_path, edit=None, text=None):
    path = tmp_path / "register.yaml"
    if text is not None:
        path.write_text(text)
        return path
    import yaml
    data = yaml.safe_load(claims.REGISTER.read_text())
    edit({e["id"]: e for e in data["claims"]})
    path.write_text(yaml.safe_dump(data))
    return path


def _rescored(tmp_path, register, capsys):
    (tmp_path / "measures.parquet").write_bytes(b"")  # the register is refused before it is read
    t = time.perf_counter()
    rc = rescore.main([str(tmp_path), "--register", str(register)])
    out = capsys.readouterr()
    assert time.perf_counter() - t < 20
    return rc, out.err, out.out


def _param(key, value):
    def edit(by):
        by["final"]["readings"][0]["params"][key] = value
    return edit


@pytest.mark.parametrize("edit, says", [
    (_param("factor", 0), "factor=0: must be a finite number in [1, 1000]"),
    (_param("factor", 10**400), "factor=1000000"),
    (_param("factor", float("nan")), "factor=nan"),
    (_param("factor", -1.5), "factor=-1.5"),
    (_param("factor", float("inf")), "factor=inf"),
    # variants: a number as text, a fraction for a period, an unknown or a missing param, a
    # choice that is not one, a flag that is a string
    (_param("factor", "1.5"), "factor='1.5': must be a finite number"),
    (_param("from", 1.5), "from=1.5: must be an integer"),
    (_param("facter", 1.5), "params.facter=1.5: not a param"),
    (lambda by: by["final"]["readings"][0]["params"].pop("factor"), "a reading of final needs"),
    (_param("smaller", "both"), "one of ['two-sided', 'at-most']"),
    (lambda by: by["rise"]["readings"][0].update(primary="yes"), "primary='yes'"),
    (lambda by: by["rise"]["readings"][0]["params"].update(above=float("nan")), "above=nan"),
])
def test_r34_r36_register_params_are_finite_and_in_range(tmp_path, capsys, edit, says):
    rc, err, out = _rescored(tmp_path, _register(tmp_path, edit), capsys)
    assert rc == 2 and err.count("\n") == 1 and says in err and "register.yaml" in err, err
    assert out == ""  # no verdict was printed


@pytest.mark.parametrize("text, says", [
    ("claims: [1, 2]\n", "a claim is a mapping"),
    ("claims: " + "[" * 100000 + "]" * 100000 + "\n", "not a register"),
    ("claims: !!python/object/apply:os.system ['touch MARK']\n", "ConstructorError"),
    # variants: no claims, a list at the top, an alias bomb, text that is not UTF-8, readings
    # that are not mappings
    ("other: 1\n", "a register is a mapping {claims: [...]}"),
    ("- 1\n", "top level='list'"),
    ("a: &a [x, x, x, x, x, x, x, x, x]\nb: &b [*a, *a, *a, *a, *a, *a, *a, *a, *a]\n"
     "c: &c [*b, *b, *b, *b, *b, *b, *b, *b, *b]\nclaims: [*c, *c, *c, *c, *c, *c, *c, *c]\n",
     "top level="),
    ("claims: [{id: x, words: w, figures: f, measure: m, readings: [1]}]\n",
     "readings=[1]: must be a list of mappings"),
])
def test_r33_hostile_registers_are_one_line(tmp_path, capsys, text, says):
    rc, err, _ = _rescored(tmp_path, _register(tmp_path, text=text), capsys)
    assert rc == 2 and err.count("\n") == 1 and says in err, err[:500]
    assert not (Path.cwd() / "MARK").exists()


def test_r33_the_register_is_not_utf8_or_a_fifo(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_bytes(b"claims: \xff\n")
    fifo = tmp_path / "fifo.yaml"
    os.mkfifo(fifo)
    for path, says in [(bad, "not UTF-8"), (fifo, "not a regular file")]:
        rc, err, _ = _rescored(tmp_path, path, capsys)
        assert rc == 2 and says in err and err.count("\n") == 1, err


@pytest.mark.parametrize("size", [300 * 2**20, claims.MAX_BYTES + 1])
def test_r46_a_huge_register_is_refused_before_it_is_parsed(tmp_path, capsys, size):
    path = tmp_path / "huge.yaml"
    with open(path, "wb") as fh:  # sparse: no disk taken
        fh.write(b"claims:\n")
        fh.truncate(size)
    rc, err, _ = _rescored(tmp_path, path, capsys)
    assert rc == 2 and f"{size:,} bytes" in err, err


def test_r33_the_committed_register_passes_its_schema(tmp_path):  # and with a date unquoted
    text = claims.REGISTER.read_text().replace("date: '2026-12-03'", "date: 2026-12-03")
    assert claims.read_register(_register(tmp_path, text=text))["claims"]


# ---- row 37: links refused by the renderer -------------------------------------------------------
@pytest.fixture
def page_root(tmp_path):
    from pipeline.studies import values
    root = tmp_path / "repo"
    (root / "outputs" / "report").mkdir(parents=True)
    (root / "outputs" / "report" / values.FILE).write_text(values.to_csv({"a.mm": 1.5}))
    (root / "docs" / "templates" / "docs" / "sub").mkdir(parents=True)
    (root / "docs" / "templates" / "docs" / "sub" / "page.md").write_text("{{ a.mm:.1f }}\n")
    return root


@pytest.mark.parametrize("how", ["linked docs folder", "template link", "linked templates",
                                 "page link"])
def test_r37_the_renderer_writes_and_reads_nothing_through_a_link(page_root, tmp_path, capsys,
                                                                  how):
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "secret").write_text("SECRET\n")
    if how == "linked docs folder":  # the page docs/sub/page.md would be written outside
        os.symlink(outside, page_root / "docs" / "sub")
    elif how == "template link":
        (page_root / "docs" / "templates" / "docs" / "sub" / "hostname.md").symlink_to(
            outside / "secret")
    elif how == "linked templates":  # variant: the templates folder itself
        shutil.move(page_root / "docs" / "templates", outside / "templates")
        os.symlink(outside / "templates", page_root / "docs" / "templates")
    else:  # variant: the page itself a link to a file outside
        (page_root / "docs" / "sub").mkdir()
        os.symlink(outside / "secret", page_root / "docs" / "sub" / "page.md")
    before = sorted(p.name for p in outside.rglob("*"))
    assert render.main([], root=page_root) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "a link" in err, err
    assert sorted(p.name for p in outside.rglob("*")) == before
    assert (outside / "secret").read_text() == "SECRET\n"
    assert not any(p.is_file() and "SECRET" in p.read_text()
                   for p in (page_root / "docs").rglob("*.md") if not p.is_symlink())


def test_r37_without_links_the_page_is_rendered(page_root):
    assert render.main([], root=page_root) == 0
    assert (page_root / "docs" / "sub" / "page.md").read_text() == "1.5\n"


# ---- rows 39, 40: a full disk and a file-size limit, matplotlib's writers included ---------------
SAVE = """
import resource, sys
from pathlib import Path
import numpy as np
from pipeline import io
from pipeline.studies import figures
resource.setrlimit(resource.RLIMIT_FSIZE, (int(sys.argv[2]),) * 2)
fig = figures.plt.figure()
fig.add_subplot().plot(np.random.default_rng(0).normal(size=30000))  # PNG 22 kB, PDF 90 kB
try:
    {write}
except (io.BadInput, OSError) as err:
    print(f"error: {{err}}", file=sys.stderr)
    sys.exit(2)
"""


@pytest.mark.parametrize("write, limit", [
    ("figures.save(fig, Path(sys.argv[1]) / 'x', 100)", 15_000),  # the PNG
    ("figures.save(fig, Path(sys.argv[1]) / 'x', 100)", 40_000),  # the PDF after the PNG
    ("io.write_text(Path(sys.argv[1]) / 'x.md', 'x' * 50_000)", 20_000),  # variant: a page
    ("with io.new_set(Path(sys.argv[1]) / 'set') as d: io.write_text(d / 'x', 'x' * 50_000)",
     20_000),  # variant: a file of an aggregate's set, named as it will be called
])
def test_r40_a_file_size_limit_is_one_line_exit_2_no_temporary(tmp_path, write, limit):
    r = subprocess.run([sys.executable, "-c", SAVE.format(write=write), str(tmp_path),
                        str(limit)], cwd=REPO_ROOT, capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr[-3000:]
    assert "file too large" in r.stderr and "ulimit -f" in r.stderr and "~" not in r.stderr
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    """f4 simulated and aggregated once, tiny."""
    from pipeline import aggregate, simulate
    from pipeline.config import compose
    root = tmp_path_factory.mktemp("made5")
    cfg = compose(["experiment=fig4", "figure=f4", "profile=smoke", "learner.epochs=30",
                   "trials.count=1", "workers=1", f"paths.root={root}"])
    simulate.simulate(cfg)
    assert aggregate.aggregate(cfg) == []
    io.confine(None)
    return root


def _one_error(stderr: str) -> str:
    """The one error line a stage ends with (after its progress lines), no traceback."""
    lines = stderr.strip().splitlines()
    assert "Traceback" not in stderr and lines and lines[-1].startswith("error: "), stderr[-3000:]
    assert all(line.startswith("[") for line in lines[:-1]), stderr[-3000:]
    return lines[-1]


def _report(root, report, preexec=None):
    return subprocess.run([sys.executable, "-m", "pipeline.report", "experiment=fig4",
                           "figure=f4", "profile=smoke", "learner.epochs=30", "trials.count=1",
                           f"paths.root={root}", f"paths.report={report}"], cwd="/",
                          capture_output=True, text=True, timeout=300, preexec_fn=preexec,
                          env=dict(os.environ, PYTHONPATH=str(REPO_ROOT)))


def test_r40_report_under_a_file_size_limit_then_a_rerun(made):
    report = made / "outputs" / "smoke" / "limited"

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (30_000, 30_000))
    r = _report(made, report, limit)
    assert r.returncode == 2 and "file too large" in _one_error(r.stderr)
    assert f"{report}/f4/" in r.stderr  # the file as it will be called
    assert not [p for p in made.rglob("*") if ".tmp" in p.name]
    assert _report(made, report).returncode == 0  # the rerun: the files of a clean run
    assert _report(made, made / "outputs" / "smoke" / "clean").returncode == 0
    def stripped(folder):  # the provenance line (report.md, report.html) names the command and time
        made_line = re.compile(rb"^- made |<li>made ")
        return {k: b"".join(l for l in v.splitlines(True) if not made_line.search(l))
                for k, v in files_of(folder).items()}
    assert stripped(report) == stripped(made / "outputs" / "smoke" / "clean")
    assert (report / "f4" / "report.md").is_file()


def test_r39_report_on_a_full_disk_then_a_rerun(made, tmp_path):
    full = made / "outputs" / "smoke" / "full"
    full.mkdir()
    try:
        subprocess.run(["mount", "-t", "tmpfs", "-o", "size=300k", "tmpfs", str(full)],
                       check=True, capture_output=True, timeout=30)
    except (OSError, subprocess.SubprocessError):
        pytest.skip("a small tmpfs needs root (mount)")
    try:
        r = _report(made, full / "report")
        assert r.returncode == 2 and "no space left on the device" in _one_error(r.stderr)
        assert not [p for p in full.rglob("*") if ".tmp" in p.name]
    finally:
        subprocess.run(["umount", str(full)], check=True, timeout=30)
    assert _report(made, full / "report").returncode == 0


def test_threat_model_rows_are_documented():
    text = (REPO_ROOT / "docs" / "faults.md").read_text()
    for row in ("7", "10", "12", "14", "16", "20", "21", "22", "24", "25", "26", "31", "33",
                "34-36", "37", "38", "39", "40", "41, 44", "46"):
        assert f"\n| {row} | " in text, row
    assert "test_faults_round5.py" in text and "test_mjcf_faults.py -q" in text
    assert "never execute code" in text
