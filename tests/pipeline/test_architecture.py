"""The architecture's promises: a learner is a plug-in (registered, configured by a generated
schema, run by the unchanged pipeline), the cache key follows one learner's code, every value has
one source, variants share their random numbers, and every experiment file plans."""
import dataclasses
import json
import re
import shutil
import types
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hydra.core.config_store import ConfigStore
from hydra.errors import ConfigCompositionException

import gbmodel
import gbmodel.learners
import pipeline.config
from gbmodel.learners import goal_babbling
from pipeline import aggregate, fingerprint, report, simulate
from pipeline.config import CONF_DIR, REPO_ROOT, ConfigError, compose
from pipeline.fingerprint import code_fingerprint
from pipeline.plan import cost, plan
from conftest import StayParams, stay_home_module, tiny_overrides  # noqa: F401

EXPERIMENTS = sorted(p.stem for p in (CONF_DIR / "experiment").glob("*.yaml"))
GBMODEL = Path(gbmodel.__file__).resolve().parent


# ---- (a) a learner registered at run time -----------------------------------------------------
STAY_HOME_YAML = """\
defaults:
  - stay_home_schema
  - _self_
name: stay_home
epochs: 100
evals_per_decade: 10
"""


@pytest.fixture
def registry(monkeypatch):
    """gbmodel's learner registry and Hydra's learner schemas, restored after the test."""
    monkeypatch.setattr(gbmodel.learners, "_REGISTERED", dict(gbmodel.learners._REGISTERED))
    repo = ConfigStore.instance().repo["learner"]
    before = set(repo)
    code_fingerprint.cache_clear()
    yield
    for k in set(repo) - before:
        del repo[k]
    code_fingerprint.cache_clear()


@pytest.fixture
def stay_home(tmp_path, monkeypatch, registry):
    """The stay_home learner registered, its schema generated, its YAML in a config folder that
    `hydra.searchpath` adds; returns that override."""
    gbmodel.learners.register("stay_home", stay_home_module())
    pipeline.config.register_schemas()
    conf = tmp_path / "conf"
    (conf / "learner").mkdir(parents=True)
    (conf / "learner" / "stay_home.yaml").write_text(STAY_HOME_YAML)
    return f"hydra.searchpath=[file://{conf}]"


def test_a_learner_registered_at_run_time_runs_through_every_stage(tmp_path, stay_home):
    cfg = compose(tiny_overrides(tmp_path / "out", stay_home, "learner=stay_home", "body=arm5",
                                 "growth=none", "figure=stay_home", "trials.count=2",
                                 "report.explain=false"))
    assert cfg.learner.name == "stay_home" and cfg.learner.reach == 0.0
    assert cfg.learner.epochs == 30 and cfg.learner.evals_per_decade == 10
    trials = plan(cfg)
    assert {t["labels"]["learner"] for t in trials} == {"stay_home"}
    s = simulate.simulate(cfg)
    assert s.failed == {} and s.ran == 2
    assert aggregate.aggregate(cfg) == []
    written = {p.name for p in report.report(cfg)}
    assert {"stay_home_curves.png", "summary.csv", "report.md"} <= written
    curves = pd.read_parquet(Path(cfg.paths.aggregate) / "stay_home" / "trials.parquet")
    assert set(curves["learner"]) == {"stay_home"} and curves["epoch"].max() == 30
    body = gbmodel.make_body("arm5")
    home_error = np.linalg.norm(body.forward(body.home) - body.targets, axis=-1).mean()
    for _, c in curves.groupby("trial"):
        assert len(c) > 5 and np.ptp(c["abs_error"]) == 0.0  # it never learns
        assert c["abs_error"].iloc[0] == pytest.approx(home_error, rel=1e-12)
    summary = pd.read_csv(Path(cfg.paths.report) / "summary.csv")
    assert set(summary["learner"]) == {"stay_home"}


def test_postures_are_drawn_for_any_learner_whose_stored_model_predicts(tmp_path, stay_home):
    """The report draws postures for a learner with predict_model, whatever its parameters (not
    only for one with a polynomial `degree`); without predict_model, none and no error."""
    m = gbmodel.learners.get("stay_home")
    m.init = lambda params, body, size, rng: np.array(body.home, dtype=float)
    m.model = lambda state: np.array(state, copy=True)  # it stores its home posture
    m.predict_model = lambda model, params, body, x: np.tile(model, (len(x), 1))
    over = tiny_overrides(tmp_path / "out", stay_home, "learner=stay_home", "body=arm5",
                          "growth=none", "figure=stay_home", "report.explain=false")
    cfg = compose(over)
    simulate.simulate(cfg)
    aggregate.aggregate(cfg)
    out = Path(cfg.paths.report)
    assert "stay_home_postures.png" in {p.name for p in report.report(cfg)}
    assert "## stay_home: targets, reached positions and postures" in \
        (out / "report.md").read_text()
    del m.predict_model
    written = report.report(compose([*over, "report.dpi=50"]))  # a setting: not "up to date"
    assert written and "stay_home_postures.png" not in {p.name for p in written}
    assert "postures" not in (out / "report.md").read_text()


def test_a_learners_schema_is_generated_from_its_params(tmp_path, stay_home):
    base = tiny_overrides(tmp_path, stay_home, "learner=stay_home", "growth=none")
    with pytest.raises(ConfigError, match=r"^learner\.reach=-1\.0: must be >= 0$"):
        plan(compose([*base, "learner.reach=-1"]))
    with pytest.raises(ConfigCompositionException):
        compose([*base, "learner.reech=1"])  # a typo: not a field of StayParams
    with pytest.raises(ConfigCompositionException):
        compose([*base, "learner.learning_rate=1"])  # goal_babbling's field, not this learner's


def test_a_learner_lacking_a_function_is_refused(registry):
    m = stay_home_module()
    del m.predict
    with pytest.raises(TypeError, match="predict"):
        gbmodel.learners.register("half", m)


@pytest.mark.parametrize("where", ["no file", "a file outside gbmodel"])
def test_a_learner_without_a_file_under_gbmodel_plans(tmp_path, registry, where):
    if where == "no file":
        module = stay_home_module()
    else:
        path = tmp_path / "stay_home_plugin.py"
        path.write_text("x = 1\n")
        module = stay_home_module()
        module.__file__ = str(path)
    gbmodel.learners.register("stay_home", module)
    pipeline.config.register_schemas()
    conf = tmp_path / "conf" / "learner"
    conf.mkdir(parents=True)
    (conf / "stay_home.yaml").write_text(STAY_HOME_YAML)
    cfg = compose(tiny_overrides(tmp_path, f"hydra.searchpath=[file://{conf.parent}]",
                                 "learner=stay_home", "growth=none"))
    assert plan(cfg)[0]["code"]


# ---- (b) the code fingerprint of one learner ---------------------------------------------------
def test_the_fingerprint_hashes_the_shared_core_and_the_learners_own_files(monkeypatch):
    seen = {}
    real = fingerprint.source_fingerprint

    def spy(sources):
        seen["sources"] = list(sources)
        return real(sources)

    monkeypatch.setattr(fingerprint, "source_fingerprint", spy)
    code_fingerprint.cache_clear()
    try:
        fp = code_fingerprint("goal_babbling")
    finally:
        code_fingerprint.cache_clear()
    assert fp == real(seen["sources"])
    for label, text in seen["sources"]:  # what is hashed is the file's current text
        assert (GBMODEL.parent / label).read_text() == text
    files = {label.split("/", 1)[1] for label, _ in seen["sources"]}
    shared = {p.relative_to(GBMODEL).as_posix() for p in GBMODEL.rglob("*.py")
              if p.relative_to(GBMODEL).parts[0] != "learners"}
    own = {p.relative_to(GBMODEL).as_posix()
           for p in (GBMODEL / "learners" / "goal_babbling").rglob("*.py")}
    assert {"trial.py", "bodies.py", "growth.py", "evaluation.py", "__init__.py"} <= shared
    assert files == shared | own | {"learners/__init__.py"}


def test_a_learner_that_imports_another_learners_code_hashes_its_files():
    """The shipped learners share code only through the core (gbmodel/inverse.py, goals.py):
    each one's fingerprint holds its own files alone; a learner importing another's code would
    have that code in its fingerprint too."""
    labels = lambda name: {label for label, _ in fingerprint.learner_sources(name)}  # noqa: E731
    own = lambda name: {p.relative_to(GBMODEL.parent).as_posix()  # noqa: E731
                        for p in (GBMODEL / "learners" / name).rglob("*.py")}
    for name in ("goal_babbling", "online_goal_babbling"):
        assert labels(name) == own(name) and f"gbmodel/learners/{name}/fast.py" in own(name)
    for name in ("motor_babbling", "example_memory"):
        assert labels(name) == {f"gbmodel/learners/{name}.py"}
    # relative and absolute imports, resolved from the importing file's package
    text = ("from .goal_babbling import goals\nfrom ..features import x\n"
            "import gbmodel.learners.example_memory\nfrom . import motor_babbling\n")
    assert fingerprint.imported_learners([("gbmodel/learners/new.py", text)], "new") == {
        "goal_babbling", "example_memory", "motor_babbling"}
    assert fingerprint.imported_learners([("gbmodel/learners/new/fast.py",
                                           "from .reference import f\n")], "new") == set()
    # a learner named from the package itself counts; the registry's own names do not
    text = ("from gbmodel.learners import goal_babbling\nfrom ..learners import motor_babbling\n"
            "from . import register, sources\n")
    assert fingerprint.imported_learners([("gbmodel/learners/new.py", text)], "new") == {
        "goal_babbling", "motor_babbling"}
    assert fingerprint.imported_learners([("gbmodel/learners/new/__init__.py",
                                           "from .. import example_memory, register\n")],
                                         "new") == {"example_memory"}


def test_the_fingerprint_of_one_learner_ignores_another_learners_files(tmp_path, monkeypatch):
    """On a copy of gbmodel: editing another learner changes its fingerprint only; editing a
    comment changes none; editing the shared core changes every learner's."""
    copy = tmp_path / "gbmodel"
    shutil.copytree(GBMODEL, copy, ignore=shutil.ignore_patterns("__pycache__", "*.nbi", "*.nbc"))
    other = copy / "learners" / "zz_other.py"
    other.write_text("def f(x):\n    return x\n")
    real = gbmodel.learners.sources

    def sources(name):  # the learner's files, read from the copy
        if name == "zz_other":
            return [("gbmodel/learners/zz_other.py", other.read_text())]
        return [(label, (copy.parent / label).read_text()) for label, _ in real(name)]

    monkeypatch.setattr(gbmodel, "__file__", str(copy / "__init__.py"))
    monkeypatch.setattr(gbmodel.learners, "sources", sources)

    def fp(name):
        code_fingerprint.cache_clear()
        return code_fingerprint(name)

    try:
        gb, zz = fp("goal_babbling"), fp("zz_other")
        other.write_text("def f(x):\n    return 2 * x\n")
        assert fp("goal_babbling") == gb and fp("zz_other") != zz
        zz = fp("zz_other")
        ref = copy / "learners" / "goal_babbling" / "reference.py"
        ref.write_text(ref.read_text() + "\n# a comment\n")
        assert fp("goal_babbling") == gb
        online = fp("online_goal_babbling")
        ref.write_text(ref.read_text() + "\nEXTRA = 1\n")
        assert fp("goal_babbling") != gb and fp("zz_other") == zz
        # online Goal Babbling shares no code with goal_babbling's folder: its trials stay
        assert fp("online_goal_babbling") == online
        gb = fp("goal_babbling")
        core = copy / "bodies.py"
        core.write_text(core.read_text() + "\nEXTRA = 1\n")
        assert fp("goal_babbling") != gb and fp("zz_other") != zz
    finally:
        code_fingerprint.cache_clear()


# ---- (c) one source per value ------------------------------------------------------------------
def test_goal_babblings_learning_rate_is_set_in_conf_only_by_bodies_and_variants():
    """Its default lives in gbmodel (Params: the 5-DOF arm's 1 / W); conf/ changes it only in a
    body's settings (conf/body_learner/<body>_goal_babbling.yaml: that body's 1 / W, one line) and
    in an experiment's variants."""
    hits, bodies = [], []
    for path in sorted(CONF_DIR.rglob("*.yaml")):
        where = path.relative_to(CONF_DIR).as_posix()
        for line in path.read_text().splitlines():
            code = line.split("#", 1)[0]
            if "learning_rate" not in code:
                continue
            body = max((b for b in gbmodel.BODIES if path.stem.startswith(b + "_")), key=len,
                       default="")  # the longest body name: icub_urdf before icub
            if path.parent.name == "body_learner" and path.stem[len(body) + 1:] == "goal_babbling":
                assert re.fullmatch(r"learning_rate: 0\.\d+\s*", code), (where, code)
                bodies.append(body)
            elif path.parent.name != "body_learner":  # another learner's body settings may
                hits.append((where, code))
    assert sorted(bodies) == ["arm2", "ergo_jr", "icub"]  # arm5 takes the default
    assert hits  # the variants of the choices and readings experiments
    for where, code in hits:
        assert where.startswith("experiment/"), where
        assert "set:" in code and not re.search(r"(^|[\s{,])learning_rate\s*:", code), code
        assert code.count("learning_rate") == code.count("learner.learning_rate=")


def test_learner_files_set_no_hyperparameter():
    """conf/learner/<name>.yaml names the schema and what a trial adds; every hyperparameter's
    default lives in gbmodel's Params, body-specific values in conf/body_learner/."""
    import yaml

    for path in sorted((CONF_DIR / "learner").glob("*.yaml")):
        keys = set(yaml.safe_load(path.read_text()))
        assert keys <= {"defaults", "name", "epochs", "evals_per_decade"}, (path.name, keys)
    for path in sorted((CONF_DIR / "body_learner").glob("*.yaml")):
        body = max((b for b in gbmodel.BODIES if path.stem.startswith(b + "_")), key=len)
        learner = path.stem[len(body) + 1:]  # the longest body name: icub_urdf before icub
        params = {f.name for f in dataclasses.fields(gbmodel.learners.get(learner).Params)}
        data = yaml.safe_load(path.read_text())
        for other in data.pop("defaults", []):  # another body's settings, shared
            assert other == "_self_" or (path.parent / f"{other}.yaml").is_file(), path.name
        assert set(data) <= params, path.name


def test_the_composed_learner_is_the_cores_params():
    """Every body composes the core's Params, except its own settings: the 2-DOF arm and the
    iCub their plain-step rate 1 / W (W = 1931, 1791; arm5's 1142 is the default), the iCub also
    its R, K, L (sec. 3.3)."""
    defaults = dataclasses.asdict(goal_babbling.Params())
    assert defaults["learning_rate"] == pytest.approx(1 / 1142, rel=1e-3)
    own = {"arm2": {"learning_rate": 1 / 1931}, "arm5": {},
           "icub": {"learning_rate": 1 / 1791, "radius": 0.1, "targets_per_epoch": 30, "steps": 10,
                    "rate_samples": 6020}}
    for body, settings in own.items():
        learner = compose([f"body={body}"]).learner
        assert {k: learner[k] for k in defaults if k not in settings} \
            == {k: v for k, v in defaults.items() if k not in settings}, body
        for k, v in settings.items():
            assert learner[k] == pytest.approx(v, rel=1e-3), (body, k)


# ---- (d) common random numbers across variants -------------------------------------------------
CHOICES = [e for e in EXPERIMENTS if e.startswith("choices_")]


@pytest.mark.parametrize("name", CHOICES)
def test_choice_variants_share_their_random_numbers(name):
    cfg = compose([f"experiment={name}"])
    trials = plan(cfg)
    # variants of the same settings share their trials (computed once); others never do
    content = {t["key"]: json.dumps([t["spec"], t["seed"]], sort_keys=True) for t in trials}
    assert len(set(content.values())) == len(content)
    # a root-seed variant is the one that draws other numbers, on purpose
    reseeded = [t for t in trials if t["seed"]["entropy"] != cfg.trials.root_seed]
    trials = [t for t in trials if t not in reseeded]
    assert not {json.dumps(t["seed"]) for t in reseeded} & {json.dumps(t["seed"]) for t in trials}
    streams = {}  # (body, growth) -> trial index -> seeds of every variant
    for t in trials:
        where = (t["spec"]["body"]["name"], json.dumps(t["spec"]["growth"], sort_keys=True))
        streams.setdefault(where, {}).setdefault(t["labels"]["trial"], set()).add(
            json.dumps(t["seed"], sort_keys=True))
    for per_trial in streams.values():
        assert all(len(seeds) == 1 for seeds in per_trial.values())
    # the variants at the experiment's own body and growth: one stream for all of them
    first = trials[0]
    same = [t for t in trials if t["spec"]["growth"] == first["spec"]["growth"]]
    assert len({t["variant"]["label"] for t in same}) >= 2


def test_a_changed_variant_recomputes_only_itself():
    cfg = compose(["experiment=choices_arm5"])
    before = plan(cfg)
    changed = cfg.conditions.variants[0].label
    cfg.conditions.variants[0].set = ["learner.learning_rate=0.6"]
    after = plan(cfg)
    assert len(before) == len(after)
    for a, b in zip(before, after):
        assert a["labels"] == b["labels"] and a["seed"] == b["seed"]
        if a["variant"]["label"] == changed:
            assert a["key"] != b["key"] and b["spec"]["learner"]["learning_rate"] == 0.6
        else:
            assert a["key"] == b["key"]


def test_a_variant_may_choose_a_learner_for_its_body_but_not_another_group():
    cfg = compose(["experiment=choices_icub"])
    cfg.conditions.variants[0].set = ["learner=goal_babbling", "learner.learning_rate=0.5"]
    spec = plan(cfg)[0]["spec"]["learner"]
    assert spec["learning_rate"] == 0.5 and spec["radius"] == 0.1  # the iCub's settings
    cfg.conditions.variants[0].set = ["body=arm2"]
    with pytest.raises(ConfigError, match=r"^conditions\.variants="):
        plan(cfg)
    cfg.conditions.variants[0].set = ["learner.rat=1"]
    with pytest.raises(ConfigError, match=r"^conditions\.variants="):
        plan(cfg)


# ---- (e) every experiment file composes and plans ----------------------------------------------
@pytest.mark.parametrize("name", EXPERIMENTS)
@pytest.mark.parametrize("profile", ["full", "smoke"])
def test_every_experiment_composes_and_plans(name, profile):
    cfg = compose([f"experiment={name}", f"profile={profile}"])
    assert cfg.figure == name
    trials = plan(cfg)
    content = {t["key"]: json.dumps([t["spec"], t["seed"]], sort_keys=True) for t in trials}
    assert trials and len(set(content.values())) == len(content)  # one key per content
    assert {t["figure"] for t in trials} == {name}
    assert all(cost(t) > 0 for t in trials[:3])
    if cfg.conditions.variants:
        labels = [v.label for v in cfg.conditions.variants]
        assert list(dict.fromkeys(t["variant"]["label"] for t in trials)) == labels


def _imports(package: str = "pipeline") -> dict[str, set[str]]:
    """module -> the modules of `package` (pipeline or gbmodel) it imports, at the top or inside
    a function; a name imported from a package counts as its submodule where one exists."""
    import ast

    root = REPO_ROOT / package
    mods = {}
    for path in root.rglob("*.py"):
        mod = ".".join((package,) + path.relative_to(root).with_suffix("").parts)
        mods[mod.removesuffix(".__init__")] = path
    out = {}
    for mod, path in mods.items():
        pkg = mod if path.name == "__init__.py" else mod.rsplit(".", 1)[0]
        deps = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    base = pkg.split(".")[: len(pkg.split(".")) - node.level + 1]
                    target = ".".join(base + ([node.module] if node.module else []))
                else:
                    target = node.module or ""
                if not target.split(".")[0] == package:
                    continue
                subs = {f"{target}.{a.name}" for a in node.names} & set(mods)
                deps |= subs if subs else {target}
            elif isinstance(node, ast.Import):
                deps |= {a.name for a in node.names if a.name.split(".")[0] == package}
        out[mod] = {d for d in deps if d in mods and d != mod}
    return out


def _circle(graph: dict[str, set[str]]) -> list[str] | None:
    """An import circle of graph (module -> modules it imports), or None."""
    state = {}

    def visit(m, stack):
        state[m] = "open"
        for d in sorted(graph[m]):
            if state.get(d) == "open":
                return stack + [m, d]
            if d not in state:
                found = visit(d, stack + [m])
                if found:
                    return found
        state[m] = "done"
        return None

    for m in sorted(graph):
        if m not in state:
            found = visit(m, [])
            if found:
                return found
    return None


def test_the_circle_check_finds_a_circle():
    assert _circle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert _circle({"a": {"b"}, "b": set(), "c": {"a", "b"}}) is None


def test_gbmodel_has_no_import_circle_and_imports_no_pipeline():
    graph = _imports("gbmodel")
    assert "gbmodel.bodies" in graph and "gbmodel.learners.goal_babbling.fast" in graph
    # the package's __init__ gathers the public names: what it imports is not a circle
    inner = {m: deps - {"gbmodel"} for m, deps in graph.items() if m != "gbmodel"}
    assert _circle(inner) is None, f"import circle: {' -> '.join(_circle(inner))}"
    for path in (REPO_ROOT / "gbmodel").rglob("*.py"):
        text = path.read_text()
        assert not re.search(r"^\s*(from|import) pipeline", text, re.M), path


def test_no_learner_imports_another_learners_code():
    """A learner's files import the shared core (gbmodel's modules outside learners/), never
    another learner's: a new learner is its own folder, and changing one learner touches no
    other."""
    learner_of = {}
    for mod in _imports("gbmodel"):
        parts = mod.split(".")
        if parts[:2] == ["gbmodel", "learners"] and len(parts) > 2:
            learner_of[mod] = parts[2]
    assert {"goal_babbling", "online_goal_babbling", "motor_babbling",
            "example_memory"} <= set(learner_of.values())
    for mod, deps in _imports("gbmodel").items():
        if mod in learner_of:
            others = {d for d in deps if learner_of.get(d, learner_of[mod]) != learner_of[mod]}
            assert not others, f"{mod} imports another learner's code: {sorted(others)}"


def test_pipeline_has_no_import_circle_and_the_machinery_knows_no_study():
    graph = _imports("pipeline")
    inner = {m: deps - {"pipeline"} for m, deps in graph.items() if m != "pipeline"}
    assert _circle(inner) is None, f"import circle: {' -> '.join(_circle(inner))}"
    # the report and the commands beside the stages (pipeline.tools: coverage, readings, quotes)
    # stand on the studies; everything else is machinery
    machinery = [m for m in graph if not m.startswith(("pipeline.studies", "pipeline.tools"))
                 and m != "pipeline.report"]
    for m in machinery:
        studies = {d for d in graph[m] if d.startswith("pipeline.studies")}
        assert not studies, f"{m} imports the studies {sorted(studies)}"


# The floors of pipeline/, from the ground up: a room (a module, or a folder of modules) imports
# only rooms on lower floors, at the top of a file or inside a function alike (the engines got
# their pool and cost model as arguments for this). A new module is put on a floor here.
FLOORS = [
    ("errors", "keys", "io", "stop", "searchpath", "plugins", "measures", "envs"),
    ("__init__", "experiments", "fingerprint", "warm", "engines", "cache",
     "html_report"),
    ("config", "planned", "checkpoint"),
    ("plan", "labels", "worker"),
    ("check", "progress", "studies", "execute", "aggregate_set", "preload"),
    ("cli", "aggregate_stats"),
    ("simulate", "aggregate", "tools"),
    ("report", "models"),
    ("__main__",),
]


def _room(module: str) -> str:
    """pipeline.config.schema -> config; pipeline.cli -> cli; pipeline -> __init__."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def _back_up(graph: dict[str, set[str]], floors) -> list[str]:
    floor = {room: n for n, rooms in enumerate(floors) for room in rooms}
    out = []
    for m, deps in sorted(graph.items()):
        for d in sorted(deps):
            a, b = _room(m), _room(d)
            if a != b and floor.get(b, len(floors)) >= floor.get(a, -1):
                out.append(f"{m} -> {d}")
    return out


def test_every_import_of_pipeline_runs_down_its_declared_floors():
    """Every module of pipeline/ stands on a declared floor (FLOORS), and imports only what
    stands lower: an import that runs back up (or across a floor) fails here, naming it."""
    graph = _imports("pipeline")
    undeclared = sorted({_room(m) for m in graph} - {r for rooms in FLOORS for r in rooms})
    assert undeclared == [], f"put these rooms of pipeline/ on a floor (FLOORS): {undeclared}"
    assert _back_up(graph, FLOORS) == []
    assert len(FLOORS) <= 9  # gbmodel on the ground floor beside the first (farm-studio look)
    # the check itself: an engine that imported the pool again would run back up
    assert _back_up({"pipeline.engines.local": {"pipeline.execute"}}, FLOORS) == [
        "pipeline.engines.local -> pipeline.execute"]


def _named(doc: str, paths, folders: bool = True) -> list[str]:
    """The paths whose file name (and, with folders, each folder above it, as `folder/`) the
    doc does not name."""
    text = (REPO_ROOT / "docs" / doc).read_text()
    missing = []
    for p in paths:
        rel = p.relative_to(REPO_ROOT)
        names = [rel.name] + ([f"{d}/" for d in rel.parts[:-1]] if folders else [])
        missing += [f"{rel} ({n})" for n in names if n not in text]
    return missing


def test_the_docs_name_every_module_and_test_file():
    """docs/core.md's layout names every module of gbmodel and pipeline (and its folders),
    docs/tests.md every file of tests/: a file added without its line fails here."""
    modules = [p for pkg in ("gbmodel", "pipeline") for p in (REPO_ROOT / pkg).rglob("*.py")]
    assert len(modules) > 40
    assert _named("core.md", modules) == []
    assert _named("tests.md", sorted((REPO_ROOT / "tests").rglob("*.py"))) == []
    assert _named("core.md", [REPO_ROOT / "gbmodel" / "not_a_module.py"]) == [
        "gbmodel/not_a_module.py (not_a_module.py)"]


def test_the_body_schema_is_generated_from_gbmodels_description():
    """BodyConf has gbmodel.bodies.Description's fields, types and defaults; a field without a
    default must be given (MISSING), and the grid's schema is generated the same way."""
    from omegaconf import MISSING

    from gbmodel.bodies import FIELDS, Description

    conf = {f.name: f for f in dataclasses.fields(pipeline.config.BodyConf)}
    assert tuple(conf) == FIELDS == tuple(f.name for f in dataclasses.fields(Description))
    assert conf["name"].default == MISSING and conf["units"].default == "rad"
    assert conf["base"].default_factory() == Description(
        name="x", outputs=[0], home=[0.0], grid=None).base
    grid = conf["grid"].default_factory()
    assert type(grid).__name__ == "GridConf" and grid.lo == MISSING


def test_a_growth_pattern_becomes_factors_in_one_place():
    body = gbmodel.make_body("arm5")
    np.testing.assert_array_equal(gbmodel.growth.factors(body, 0.5), np.full(5, 0.5))
    g = gbmodel.Growth(pattern="proximal_first")
    np.testing.assert_array_equal(gbmodel.growth.factors(body, 0.7, g), g.scales(body, 0.7))
    with pytest.raises(gbmodel.SpecError, match="growth.pattern='spiral'"):
        gbmodel.growth.factors(body, 0.5, "spiral")


def test_every_hydra_command_finds_the_config_folder():
    """A stage or tool's @hydra.main takes config_path=CONFIG_PATH (pipeline.config): the
    checkout's conf/ here, pkg://gbgrowth_conf when installed (tests/e2e/test_wheel.py); a path
    of its own would fail from a wheel ('Primary config directory not found')."""
    import re

    from pipeline.config import CONFIG_PATH
    found = 0
    for path in (REPO_ROOT / "pipeline").rglob("*.py"):
        for arg in re.findall(r'hydra\.main\(config_path=([^,]+),', path.read_text()):
            found += 1
            assert arg == "CONFIG_PATH", path
    assert found >= 5
    assert Path(CONFIG_PATH) == REPO_ROOT / "conf"


def test_every_test_file_and_command_the_project_names_exists():
    """A path `tests/...py` or a command `python -m pipeline...` named in the README, the docs,
    the configs or the code is a file or module that exists (files move; their mentions must
    move with them)."""
    import importlib.util
    texts = [REPO_ROOT / "README.md", *(REPO_ROOT / "docs").glob("*.md"),
             *(REPO_ROOT / "conf").rglob("*.yaml"), *(REPO_ROOT / "examples").glob("*.py"),
             *(REPO_ROOT / "gbmodel").rglob("*.py"), *(REPO_ROOT / "pipeline").rglob("*.py"),
             REPO_ROOT / "Makefile"]
    files, modules = set(), set()
    for path in texts:
        text = path.read_text()
        files |= set(re.findall(r"\btests/[\w/]+\.py", text))
        modules |= set(re.findall(r"-m (pipeline(?:\.\w+)+)", text))
        modules |= set(re.findall(r"`(pipeline\.tools\.\w+)`", text))
    assert files and modules
    assert sorted(f for f in files if not (REPO_ROOT / f).exists()) == []
    assert sorted(m for m in modules if importlib.util.find_spec(m) is None) == []


def test_the_docs_name_no_path_outside_the_clone():
    """README and docs/ point only at what a clone has: no absolute path of one machine."""
    texts = [REPO_ROOT / "README.md", *(REPO_ROOT / "docs").glob("*.md")]
    bad = [f"{p.name}: {m}" for p in texts
           for m in re.findall(r"(?<![\w.])/(?:work|tmp|root|home)/[\w./-]+", p.read_text())
           if not m.startswith("/tmp/")]
    assert bad == []
