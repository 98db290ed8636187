"""A study added as exactly two files, with no other edit: its module (gbgrowth_study_toy.py,
declared by its distribution as an entry point of gbgrowth.studies, as a toy engine is one of
gbgrowth.engines) and its experiment file (conf/experiment/toy.yaml of the working directory). simulate, aggregate and report run it
from that directory, and the report holds its section and its table."""
import os
import subprocess
import sys

from conftest import declare_plugin
from pipeline import report
from pipeline.config import REPO_ROOT

MODULE = '''
"""A toy study: each condition's final held-out error, as a table and a CSV."""
from pipeline.studies.sections import of_study, register


@register("toy", 99)
def section(ctx):
    figs = ctx.of("toy")
    if not figs:
        return []
    rows = [(name, r.condition, r.final_heldout_abs_error_mean)
            for name in of_study("toy") if name in figs  # the experiments declaring the study
            for r in figs[name]["summary"].itertuples()]
    ctx.text("toy_study.csv", "figure,condition,final_heldout_abs_error\\n"
             + "".join(f"{f},{c},{e!r}\\n" for f, c, e in rows))
    return ["## A toy study", "", "| figure | condition | final held-out error (m) |",
            "|---|---|---|",
            *[f"| {f} | {c} | {e:.4f} |" for f, c, e in rows], ""]
'''

EXPERIMENT = """# @package _global_
# A toy study of two conditions: without growth and with the paper's growth.
defaults:
  - override /body: arm2
figure: toy  # named as its file, as the studies read their figures (of_study)
learner:
  epochs: 30  # tiny: a test
trials:
  count: 1
conditions:
  periods: [0, 20]
paper:
  study: toy  # its report section: gbgrowth_study_toy.py
declares:
  group: studies
  order: 99
"""


def stage(module, work, env, *overrides):
    return subprocess.run([sys.executable, "-m", module, "experiment=toy", "workers=1",
                           f"paths.root={work}", *overrides], capture_output=True, text=True,
                          cwd=work, env=env, timeout=600)


def test_a_toy_study_in_two_files_is_run_and_reported_with_no_other_edit(tmp_path):
    plugins, work = tmp_path / "plugins", tmp_path / "work"
    (work / "conf" / "experiment").mkdir(parents=True)
    declare_plugin(plugins, "gbgrowth.studies", "toy", "gbgrowth_study_toy", MODULE)
    (work / "conf" / "experiment" / "toy.yaml").write_text(EXPERIMENT)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(REPO_ROOT), str(plugins)]))
    for module in ("pipeline.simulate", "pipeline.aggregate", "pipeline.report"):
        r = stage(module, work, env)
        assert r.returncode == 0, f"{module}: {r.stderr[-3000:]}"
    out = work / "outputs" / "latest" / "toy"  # a figure's own report
    text = (out / "report.md").read_text()
    assert "## A toy study" in text, text
    section = text.split("## A toy study", 1)[1].split("\n## ", 1)[0]
    rows = [ln.split(" | ")[1] for ln in section.splitlines() if ln.startswith("| toy |")]
    assert rows == ["TG0", "TG20"], text  # a row per condition of the experiment file
    assert "toy_study.csv" in report.listed_files(out / "report.md")
    csv = (out / "toy_study.csv").read_text().splitlines()
    assert csv[0] == "figure,condition,final_heldout_abs_error" and len(csv) == 3
    assert all(float(ln.rsplit(",", 1)[1]) > 0 for ln in csv[1:])  # errors the trials measured


def test_a_study_module_that_does_not_import_costs_only_its_own_experiments(tmp_path,
                                                                            monkeypatch):
    """A study's module (an entry point of gbgrowth.studies) that fails to import made every report
    a traceback (the registry imports each one); now a report without its study is made, and
    an experiment naming it is refused in one line naming the module's error."""
    import pytest

    from pipeline.config import ConfigError
    from pipeline.studies import sections

    declare_plugin(tmp_path, "gbgrowth.studies", "broken", "gbgrowth_study_broken",
                   "import a_package_not_installed_zz\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    mine = dict(models=dict(paper=dict(study="figures")))
    assert list(sections.group({"fig": mine})) == ["figures"]
    theirs = dict(models=dict(paper=dict(study="broken")))
    with pytest.raises(ConfigError) as err:
        sections.group({"exp": theirs})
    assert str(err.value) == ("exp: paper.study='broken': its module did not import "
                              "(gbgrowth_study_broken: ModuleNotFoundError: No module named "
                              "'a_package_not_installed_zz')")
