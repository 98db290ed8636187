"""The fourth fault battery (issue 40): the solver's extremes, growth tables and frames refused
before planning; sealed models; a page renderer that cannot destroy a page; saved plans checked like
a cache; Hydra that cannot run code or write outside the root. Each test names its row of
docs/faults.md."""
import os
import time

import pytest

from pipeline.studies import values
from pipeline.tools import render

SUMMARY = "figure,condition,v,tiny\nfig4,a,0.0123951,1e-320\nfig4,b,0.5,0\n"


@pytest.fixture
def qroot(tmp_path):
    """A repository of one report table (outputs/report/summary.csv), its values.csv and a
    template, as the renderer sees it."""
    report = tmp_path / "outputs" / "report"
    report.mkdir(parents=True)
    (report / "summary.csv").write_text(SUMMARY)
    (report / values.FILE).write_text(values.to_csv({"a.mm": 12.3951}))
    (tmp_path / "docs" / "templates").mkdir(parents=True)
    return tmp_path


def _render_main(root, template: bytes | str, capsys, *flags):
    (root / "docs" / "templates" / "page.md").write_bytes(
        template if isinstance(template, bytes) else template.encode())
    rc = render.main([*flags], root=root)
    return rc, capsys.readouterr().err.strip()


@pytest.mark.parametrize("template, says", [
    ("a {{ a.mm:.30f }} m\n", "at most 15 decimals"),
    ("a {{ a.mm:.1f }} m\n{{ nosuch:.1f }}\n", "docs/templates/page.md:2: no value named"),
    ("a {{ a.mm:1f }} m\n", "format '1f'"),
    (b"caf\xe9 {{ a.mm:.1f }} mm\n", "not UTF-8"),
])
def test_r7_a_bad_reference_or_template_is_one_line_exit_2_and_nothing_written(
        qroot, capsys, template, says):
    rc, err = _render_main(qroot, template, capsys)
    assert rc == 2 and err.startswith("error: ") and says in err and "\n" not in err, err
    assert not (qroot / "page.md").exists()


KILLED_WHILE_WRITING = """
import builtins, io, os, signal, sys
from pathlib import Path
from pipeline.tools import render
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
render.main([], root=Path(sys.argv[1]))
"""


def test_r8_render_killed_while_writing_leaves_the_page_whole(qroot):
    import signal
    import subprocess
    import sys

    from pipeline.config import REPO_ROOT
    page = qroot / "page.md"
    text = "about 10.0 mm\n"
    page.write_text(text)
    (qroot / "docs" / "templates" / "page.md").write_text("about {{ a.mm:.1f }} mm\n")
    r = subprocess.run([sys.executable, "-c", KILLED_WHILE_WRITING, str(qroot)],
                       env=dict(os.environ, PYTHONPATH=str(REPO_ROOT)), capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == -signal.SIGKILL, r.stderr
    assert page.read_text() == text  # the old page, whole (Path.write_text left 0 bytes)
    assert render.main([], root=qroot) == 0
    assert page.read_text() == "about 12.4 mm\n"
    assert not [p.name for p in qroot.iterdir() if p.name.startswith(".")]  # the dead one's
    # temporary page is removed by the next render


def test_r7_a_long_line_is_rendered_in_linear_time():
    vals = {"a.mm": 12.3951}
    lines = ["x {{ a.mm:.1f }} mm and" * 3,  # many references on one line
             "{ {{ a" * 4000 + "}",  # openings that never close
             "{{ " + "7" * 16000]  # a name that never ends
    # Linear, not quadratic: the CPU time (not wall time: the machine may be loaded) at 4x the
    # length grows about 4x, where a quadratic scan grows 16x.
    def cpu(line, size):
        text = line * (size // len(line) + 1) + "\n"
        best = float("inf")
        for _ in range(3):
            t = time.process_time()
            try:
                values.render(text, vals, "p.md")
            except values.BadValue:
                pass
            best = min(best, time.process_time() - t)
        return best
    for line in lines:
        small, large = cpu(line, 8000), cpu(line, 32000)
        assert large < 8 * max(small, 1e-3), (small, large)


# ---- rows 1-5: every key has a range, and the two paths agree at its edges ----------------------
def _h(root, *more):
    """The issue's H: simulate figure=bi learner.epochs=200 trials.count=1 workers=1."""
    return ["figure=bi", "learner.epochs=200", "trials.count=1", "workers=1",
            f"paths.root={root}", *more]


@pytest.mark.parametrize("args, says", [
    (["learner.solver=lstsq", "learner.ridge=0"], "learner.ridge=0.0: must be >= 1e-05"),
    (["learner.solver=lstsq", "learner.ridge=1e-300"], "learner.ridge=1e-300: must be >= 1e-05"),
    (["learner.ridge=1e308"], "learner.ridge=1e+308: must be <= 1e+06"),
    (["learner.window=1000000000"], "learner.window=1000000000: at most 1,000 epochs"),
    (["learner.degree=1000000000"], "learner.degree=1000000000: at most 6"),
    (["learner.variations=1000", "learner.targets_per_epoch=10000"], "samples per epoch"),
    (["growth.schedule=table", "growth.period=100", "growth.table=[[0,0.5],[1,1e300],[2,1.0]]"],
     "sizes must be <= 100"),
    (["growth.schedule=table", "growth.period=100", "growth.table=[[-1e308,0.5],[1e308,1.0]]"],
     "times within +-1e+12"),
    (["conditions.frames=1000000000"], "conditions.frames=1000000000: must be an integer in "
                                       "[0, 100]"),
])
def test_r1_to_r5_values_the_compiled_path_cannot_compute_are_refused(tmp_path, args, says):
    import resource

    from pipeline import cli
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    out = cli.check(_h(tmp_path, *args))
    assert out is not None and says in out and "\n" not in out, out
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before < 200_000  # KiB
    assert not any(tmp_path.iterdir())  # refused before planning: nothing written


def test_r1_every_key_of_a_learner_of_growth_and_of_a_body_has_a_range():
    import dataclasses

    import gbmodel
    from gbmodel import bodies, growth, spec
    tables = {name: (gbmodel.learners.get(name).Params, gbmodel.learners.get(name).LIMITS)
              for name in gbmodel.learners.available()}
    tables["growth"] = (growth.Growth, growth.LIMITS)
    tables["body"] = (bodies.Description, bodies.LIMITS)
    for name, (cls, limits) in tables.items():
        fields = [f.name for f in dataclasses.fields(cls)]
        assert sorted(limits) == sorted(fields), name
        for key, c in limits.items():
            assert isinstance(c, spec.Constraint), (name, key)
            inner = c.inner if isinstance(c, spec.Maybe) else c
            if isinstance(inner, (spec.Int, spec.Number)):
                assert inner.hi is not None, (name, key)  # bounded above, not only below
        cls_default = cls() if name not in ("growth", "body") else None
        if cls_default is not None:
            cls_default.validate()  # the defaults are inside their ranges


@pytest.mark.parametrize("learner", [dict(ridge="MIN_RIDGE"), dict(ridge="MAX_RIDGE"),
                                     dict(window="MAX_WINDOW", ridge="MIN_RIDGE")])
def test_r1_the_compiled_and_the_reference_path_agree_at_the_edges(learner):
    import numpy as np

    import gbmodel
    from gbmodel.learners import goal_babbling as gb
    learner = {k: getattr(gb, v) for k, v in learner.items()}
    errors = []
    for fast in (True, False):
        spec = gbmodel.TrialSpec(
            body={"name": "arm5"}, epochs=100, growth={"pattern": "proportional", "period": 50},
            learner={"name": "goal_babbling", "solver": "lstsq", "fast": fast, **learner})
        errors.append(gbmodel.run_trial(spec, np.random.default_rng(1)).abs_error)
    assert np.isfinite(errors[0]).all()
    np.testing.assert_allclose(errors[0], errors[1], rtol=1e-3)


# ---- row 9: a saved plan is a cache, checked like one ---------------------------------------------
@pytest.mark.parametrize("edit", ["rate", "key", "condition", "damaged"])
def test_r9_a_tampered_saved_plan_is_discarded_and_planned_again(tmp_path, compose_tiny, edit,
                                                                 caplog):
    import json
    from pathlib import Path

    from pipeline import io, planned, simulate
    cfg = compose_tiny(tmp_path)
    first = simulate.jobs_of(cfg)
    (saved,) = (Path(cfg.paths.out) / planned.PLANNED).glob("*.json")
    packed = io.read_json(saved)
    if edit == "rate":  # the issue's: the learning rate edited, the keys left as they were
        packed["specs"][0]["learner"]["learning_rate"] *= 10
    elif edit == "key":
        packed["jobs"][0]["trials"][0]["key"] = "0" * 20
    elif edit == "condition":
        packed["jobs"][0]["trials"][0]["condition"] = "0" * 16
    if edit == "damaged":
        saved.write_text('{"jobs": 1, "specs": 2}')
    else:
        io.write_json(saved, packed, compact=True)
    caplog.clear()
    again = simulate.jobs_of(cfg)
    assert [vars(j) for j in again] == json.loads(io.dump_json([vars(j) for j in first]))
    warned = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert len(warned) == 1 and str(saved) in warned[0] and "planned again" in warned[0], warned
    assert planned.misplanned(*(io.read_json(saved)[k] for k in ("specs", "jobs"))) is None  # healed


def test_r9_the_fast_check_of_a_saved_plan_is_trial_key_and_condition_id(tmp_path, compose_tiny):
    from pipeline import keys, planned, simulate
    cfg = compose_tiny(tmp_path, "trials.count=3")
    packed = simulate.pack_jobs(simulate.jobs_of(cfg))
    assert planned.misplanned(packed["specs"], packed["jobs"]) is None
    for t in packed["jobs"][0]["trials"]:
        spec = packed["specs"][t["spec"]]
        assert t["key"] == keys.trial_key(spec, t["seed"], t["code"])
        assert t["condition"] == keys.condition_id(spec, t["seed"]["entropy"])


# ---- rows 10-13: Hydra cannot run code or write outside the root ---------------------------------
EVIL_BODY = """# @package _global_
defaults:
  - /body/arm5@body
hydra:
  job_logging:
    formatters:
      evil: {"()": shutil.copyfile, src: /etc/hostname, dst: HIT}
"""


@pytest.mark.parametrize("args, says", [
    (["+hydra.job_logging.formatters.evil.class=os.symlink",
      "+hydra.job_logging.formatters.evil.format=/etc", "+hydra.job_logging.formatters.evil.datefmt=HIT"],
     "hydra.job_logging.formatters.evil.class: a formatter is its format"),
    (["+hydra.hydra_logging.formatters.evil.class=os.makedirs",
      "+hydra.hydra_logging.formatters.evil.format=HIT"], "hydra.hydra_logging.formatters.evil"),
    (["+hydra.job_logging.filters.f._=x"], "a logging filter is built by a factory"),
    (["hydra.job_logging.handlers.console.stream=ext://os.system"], "builds or imports"),
    (["+hydra.job_logging.root.filters=[x]"], "hydra.job_logging.loggers.root.filters"),
    (["+hydra.job.env_set.PYTHONPATH=HIT", "workers=2"], "hydra.job.env_set.PYTHONPATH: sets an "
                                                         "environment variable"),
    (["hydra.job.env_copy=[PATH]"], "hydra.job.env_set.PATH: sets an environment"),  # Hydra
    # copies env_copy into env_set
    (["+hydra.env.x=1"], "hydra.env.x=1: not a setting"),
    (["hydra.output_subdir=HIT"], "hydra.output_subdir='HIT'"),
    (["hydra.output_subdir=.hydra"], "hydra.run.dir='.': outside paths.root"),
    (["hydra.run.dir=HIT"], "hydra.run.dir='HIT': outside paths.root"),
    (["hydra.sweep.dir=HIT"], "hydra.sweep.dir='HIT': outside paths.root"),
    (["hydra.sweep.subdir=../../x"], "hydra.sweep.subdir='../../x'"),
    (["hydra.job.name=../../x"], "hydra.job.name"),
    (["hydra/launcher=joblib", "hydra.launcher.temp_folder=HIT"], "hydra.launcher.temp_folder"),
    (["-cd", "HIT"], "-cd: the stages read the project's config"),
    (["--experimental-rerun", "HIT"], "--experimental-rerun"),
])
def test_r10_to_r12_hydra_settings_outside_the_allow_list_are_one_line(tmp_path, args, says):
    from pipeline import cli
    hit = tmp_path / "outside"
    args = [a.replace("HIT", str(hit)) for a in args]
    out = cli.check([*args, f"paths.root={tmp_path / 'root'}"])
    says = says.replace("HIT", str(hit))
    assert out is not None and says in out and "\n" not in out, out
    assert not (tmp_path / "root").exists() and not hit.exists()


def test_r10_a_logging_factory_in_a_body_yaml_on_the_searchpath_is_refused(tmp_path):
    from pipeline import cli
    (tmp_path / "conf" / "body").mkdir(parents=True)
    (tmp_path / "conf" / "body" / "evil.yaml").write_text(
        EVIL_BODY.replace("HIT", str(tmp_path / "hit")))
    out = cli.check([f"hydra.searchpath=[file://{tmp_path / 'conf'}]", "body=evil",
                     f"paths.root={tmp_path / 'out'}"])
    assert out is not None and "hydra.job_logging.formatters.evil.()" in out, out
    assert not (tmp_path / "hit").exists()


def test_r10_the_command_line_refuses_a_formatter_class_and_writes_nothing(tmp_path):
    from conftest import run_cli
    link = tmp_path / "link"
    r = run_cli("pipeline.simulate", "+hydra.job_logging.formatters.evil.class=os.symlink",
                "+hydra.job_logging.formatters.evil.format=/etc",
                f"+hydra.job_logging.formatters.evil.datefmt={link}", "figure=bi",
                "learner.epochs=20", "trials.count=1", "workers=1",
                f"paths.root={tmp_path / 'root'}")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert r.stderr.startswith("error: hydra.job_logging.formatters.evil.class")
    assert not link.is_symlink() and not (tmp_path / "root").exists()


@pytest.mark.parametrize("args", [
    [],  # the project's own settings
    ["hydra.run.dir=${paths.out}/runs/x", "hydra.output_subdir=.hydra"],  # a snapshot inside
    ["hydra.sweep.dir=${paths.out}/sweeps", "hydra.sweep.subdir=job${hydra.job.num}"],
    ["hydra/launcher=joblib", "hydra.launcher.n_jobs=2"], ["hydra.verbose=true"],
    ["hydra.job.chdir=false"], ["hydra/job_logging=stdout", "hydra/hydra_logging=disabled"],
    ["hydra.job_logging.handlers.console.stream=ext://sys.stderr"],
])
def test_r12_what_the_allow_list_permits_passes(tmp_path, args):
    from pipeline import cli
    assert cli.check([*args, "figure=bi", "learner.epochs=20", "trials.count=1", "workers=1",
                      f"paths.root={tmp_path}"]) is None


def test_r13_a_link_at_planned_checked_is_neither_written_nor_read(tmp_path):
    from pipeline import cli, planned
    from pipeline.config import compose
    root, elsewhere = tmp_path / "root", tmp_path / "elsewhere"
    elsewhere.mkdir()
    (root / "outputs" / "planned").mkdir(parents=True)
    os.symlink(elsewhere, root / "outputs" / "planned" / "checked")
    args = ["figure=bi", "learner.epochs=20", "trials.count=1", "workers=1", f"paths.root={root}"]
    assert cli.check(args) is None
    cli.finish(lambda cfg: 0, compose(args))  # the stage ran: the note would be written now
    assert not any(elsewhere.iterdir())  # never through the link
    marker = planned.checked_marker(compose(args), args)
    marker.write_text('{"trials": 1, "body_files": []}')  # planted there (through the link)
    assert (elsewhere / marker.name).exists()
    assert not planned.was_checked(marker, str(root))  # not a note of this root's
    os.unlink(root / "outputs" / "planned" / "checked")
    (root / "outputs" / "planned" / "checked").mkdir()
    marker.write_text('{"trials": 1, "body_files": []}')
    assert planned.was_checked(marker, str(root))  # a real one inside the root is


# ---- row 6: sealed models ------------------------------------------------------------------------
def _report_copy(tmp_path, figure="fig2"):
    """The committed report's models/<figure>.json and curves.parquet in a report folder."""
    import shutil

    from pipeline.config import REPO_ROOT
    report = tmp_path / "report"
    (report / "models").mkdir(parents=True)
    shutil.copy(REPO_ROOT / "outputs/report/models" / f"{figure}.json", report / "models")
    shutil.copy(REPO_ROOT / "outputs/report/curves.parquet", report)
    return report, report / "models" / f"{figure}.json"


def _edit(path, how, reseal=False):
    import json

    from pipeline import io
    data = json.loads(path.read_text())
    cond = next(iter(data["conditions"].values()))
    if how == "M":
        cond["trials"]["0"]["M"][0][0] += 5
    elif how == "nan":
        cond["trials"]["0"]["M"][0][0] = float("nan")
    elif how == "end_size":
        cond["spec"]["growth"]["end_size"] = 3.0
    elif how == "degree":
        cond["spec"]["learner"]["degree"] = 1e9
    elif how == "shape":
        cond["trials"]["0"]["M"] = cond["trials"]["0"]["M"][:1]
    if reseal:
        data = io.seal({k: v for k, v in data.items() if k != "seal"})
    path.write_text(json.dumps(data))


def test_r6_the_committed_models_are_sealed_and_load():
    from pipeline import models
    from pipeline.config import REPO_ROOT
    for f in sorted((REPO_ROOT / "outputs/report/models").glob("*.json")):
        assert "seal" in models.read(f), f
    assert models.load("fig2", REPO_ROOT / "outputs/report").labels == ["const1.0"]


@pytest.mark.parametrize("how", ["M", "nan", "end_size", "degree"])
def test_r6_an_edited_model_file_is_refused_in_one_line(tmp_path, how):
    from pipeline import io, models
    report, path = _report_copy(tmp_path)
    _edit(path, how)
    t = time.perf_counter()
    with pytest.raises(io.DamagedFile) as err:
        models.load("fig2", report)
    msg = str(err.value)
    assert msg.startswith(f"{path}: damaged") and "\n" not in msg
    assert "pipeline.report" in msg  # what makes it again
    assert time.perf_counter() - t < 10  # degree 1e9: refused, not built


@pytest.mark.parametrize("how, says", [("nan", "not a finite"), ("degree", "learner.degree"),
                                       ("shape", "not a finite 2 x 4 matrix")])
def test_r6_a_resealed_model_file_must_still_be_a_model(tmp_path, how, says):
    from pipeline import io, models
    report, path = _report_copy(tmp_path)
    _edit(path, how, reseal=True)
    with pytest.raises(io.DamagedFile, match=says):
        models.load("fig2", report)


@pytest.mark.parametrize("text", [b"{", b"\xff\xfe", b"[]", b'{"conditions": {"a": 1}}'])
def test_r6_damaged_json_names_the_file(tmp_path, text):
    from pipeline import io, models
    report, path = _report_copy(tmp_path)
    path.write_bytes(text)
    with pytest.raises(io.DamagedFile, match=f"^{path}: damaged"):
        models.load("fig2", report)


def test_r6_seal_verifies_an_unsealed_file_against_the_report_first(tmp_path, capsys):
    import json

    from pipeline import models
    report, path = _report_copy(tmp_path, "fig4")
    data = json.loads(path.read_text())
    data.pop("seal")
    path.write_text(json.dumps(data))
    with pytest.raises(models.io.DamagedFile, match="no seal"):
        models.load("fig4", report)  # unsealed: refused, not taken on trust
    _edit(path, "M")
    assert models.main(["seal", str(path)]) == 2  # its models do not give the report's errors
    assert "TG10: abs_error_mean" in capsys.readouterr().err
    path.write_text(json.dumps(data))
    assert models.main(["seal", str(path)]) == 0
    assert models.load("fig4", report).labels[0] == "TG10"


def test_r6_an_aggregate_models_json_is_checked_against_its_manifest(tmp_path):
    import shutil

    from pipeline import aggregate, io, models, simulate
    from pipeline.config import compose
    cfg = compose(["experiment=fig2", "figure=f2", "profile=smoke", "learner.epochs=30",
                   "trials.count=1", "workers=1", f"paths.root={tmp_path}"])
    simulate.simulate(cfg)
    assert aggregate.aggregate(cfg) == []
    agg = tmp_path / "outputs/smoke/aggregate"
    assert models.load("f2", agg).labels == ["const1.0"]
    d = io.set_of(agg / "f2")
    os.chmod(d, 0o755)
    text = (d / "models.json").read_text()
    (d / "models.json").unlink()
    (d / "models.json").write_text(text.replace('"M":[[', '"M":[[5', 1))
    with pytest.raises(io.DamagedFile, match="manifest.json") as err:
        models.load("f2", agg)
    assert "pipeline.aggregate figure=f2" in str(err.value)
    shutil.rmtree(tmp_path / "outputs")


# ---- large but allowed inputs ----------------------------------------------------------------------
def test_large_a_10000_job_sweep_is_checked_in_a_few_composes(tmp_path, monkeypatch):
    from pipeline import check, cli, config
    composed, real = [], config.compose

    def counting(overrides=(), hydra=False):
        composed.append(list(overrides))
        return real(overrides, hydra)

    monkeypatch.setattr(check, "compose", counting)
    args = ["-m", "growth.period=range(1,10001)", "figure=bi", "learner.epochs=20",
            "trials.count=1", "workers=1", f"paths.root={tmp_path}"]
    assert cli.check(args) is None
    assert len(composed) <= check._MAX_COMBINATIONS + 1  # (+1: Hydra's own section, once)
    # Hydra composes each batch before launching it: batches of a few jobs, not all 10,000
    assert real(["paths.root=/"], hydra=True).hydra.sweeper.max_batch_size <= 16


@pytest.mark.parametrize("sweep, says", [
    ("learner.ridge=1e-3,1e-2,0.1,1,10,100,1000,1e4,1e5,1e6,1e7",
     "learner.ridge=10000000.0 (a value of the sweep"),
    ("growth.period=range(0,10000000000000000000000,1000000000000000000)", "growth.period="),
])
def test_large_every_value_of_a_sweep_is_checked_against_its_range(tmp_path, sweep, says):
    from pipeline import cli
    out = cli.check(["-m", sweep, "figure=bi", "learner.epochs=20", "trials.count=1",
                     f"paths.root={tmp_path}"])
    assert out is not None and says in out and "\n" not in out, out


def test_large_the_aggregate_index_holds_signatures_and_the_rest_is_identical(tmp_path):
    """aggregate/<figure>/index.parquet records each trial file's signature (size, inode,
    modification and change time: what the next aggregate compares to read only what changed),
    so it differs between identical runs by design; every other file of the set, and the
    index's other columns, are the same bytes (docs/faults.md)."""
    import pyarrow.parquet as pq

    from pipeline import aggregate, io, simulate
    from pipeline.config import compose
    sets = []
    for run in ("a", "b"):
        cfg = compose(["experiment=fig2", "figure=f2", "profile=smoke", "learner.epochs=30",
                       "trials.count=2", "workers=1", f"paths.root={tmp_path / run}"])
        simulate.simulate(cfg)
        assert aggregate.aggregate(cfg) == []
        sets.append(io.set_of(tmp_path / run / "outputs/smoke/aggregate/f2"))
    names = sorted(p.name for p in sets[0].iterdir())
    assert names == sorted(p.name for p in sets[1].iterdir())
    for name in names:
        if name == aggregate.INDEX:
            a, b = (pq.read_table(s / name).drop(["signature"]) for s in sets)
            assert a.equals(b)
        else:
            assert (sets[0] / name).read_bytes() == (sets[1] / name).read_bytes(), name
