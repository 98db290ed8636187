"""Bad inputs are one line before any work: geometry, ranges, names, sweep sizes, Hydra's own
section (callbacks, targets, logging, launcher), experiment names, URDF files."""
import os
import time

import pytest

from gbmodel.bodies import body_from
from pipeline import cli

JP = "\u56f3" * 100  # 100 characters, 300 bytes: longer than a file name may be


@pytest.mark.parametrize("args, says", [
    (["body.dh.0.0=1e308"], "body.dh="),
    (["body.base.0.3=1e300"], "body.base="),
    (["body.grid.num=[1,1]"], "need num >= 2"),
    (["body.grid.num=[300,300]"], "at most 4,096"),
    (["growth.start_size=1e308"], "growth.start_size=1e+308: must be a number in (0, 100]"),
    (["aggregate.fail_factor=0"], "aggregate.fail_factor=0.0: must be a number in (1, 1000]"),
    (["conditions.budget_scale=-1"], "conditions.budget_scale=-1.0"),
    (["conditions.growth_share=1.5"], "conditions.growth_share=1.5"),
    (["report.dpi=0"], "report.dpi=0: must be a number in [10, 1200]"),
    (["report.dpi=100000"], "report.dpi=100000"),
    ([f'figure="{JP}"'], "at most 100 characters and 200 bytes"),
    (['figure="a\u202eb"'], "format (bidirectional)"),
    (["experiments=[fig2,nosuch]"], "'nosuch' is not an experiment"),
    (["+hydra.callbacks.x._target_=shutil.copyfile", "+hydra.callbacks.x.src=/etc/hostname",
      "+hydra.callbacks.x.dst=/tmp/x"], "hydra.callbacks.x: Hydra callbacks run code"),
    (["hydra/launcher=nosuch"], "hydra/launcher=nosuch: unknown option"),
    (["hydra/launcher=joblib", "hydra.launcher.n_jobs=0"], "hydra.launcher.n_jobs=0"),
    (["hydra/job_logging=default"], "hydra.job_logging.handlers.file: writes a log file"),
    (["+hydra.job_logging.handlers.f.filename=/tmp/x.log",
      "+hydra.job_logging.handlers.f.class=logging.FileHandler"], "writes a log file"),
    (["+report.postures._target_=os.system"], "report.postures._target_='os.system'"),
])
def test_bad_inputs_are_one_line(tmp_path, args, says):
    out = cli.check([*args, f"paths.root={tmp_path}"])
    assert out is not None and says in out and "\n" not in out, out
    assert not any(tmp_path.iterdir())


def test_a_huge_sweep_is_refused_before_it_is_built(tmp_path):
    import resource
    t = time.perf_counter()
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    out = cli.check(["-m", "growth.period=range(0,100000000)", f"paths.root={tmp_path}"])
    assert out is not None and "more than 10,000 jobs" in out, out
    assert time.perf_counter() - t < 30
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before < 200_000  # KiB


def test_a_sweep_within_the_bound_is_still_checked(tmp_path):
    assert cli.check(["-m", "growth.period=range(0,3)", "trials.count=1",
                      f"paths.root={tmp_path}"]) is None


def test_a_callback_in_a_body_yaml_on_the_searchpath_is_refused(tmp_path):
    body = tmp_path / "conf" / "body"
    body.mkdir(parents=True)
    (body / "evil.yaml").write_text(
        "# @package _global_\n"
        "defaults:\n  - /body/arm5@body\n"
        "hydra:\n  callbacks:\n    x:\n      _target_: shutil.copyfile\n"
        "      src: /etc/hostname\n      dst: " + str(tmp_path / "hit") + "\n")
    out = cli.check([f"hydra.searchpath=[file://{tmp_path / 'conf'}]", "body=evil",
                     f"paths.root={tmp_path / 'out'}"])
    assert out is not None and "hydra.callbacks.x" in out, out


ARM = """<?xml version="1.0"?>
<robot name="one">
  <link name="world"/><link name="l1"/><link name="tool"/>
  <joint name="j1" type="revolute"><parent link="world"/><child link="l1"/>
    <origin xyz="{xyz}"/><axis xyz="{axis}"/><limit lower="-2" upper="2"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="tool"/>
    <origin xyz="0.3 0 0"/><axis xyz="0 0 1"/><limit lower="-2" upper="2"/></joint>
</robot>
"""


def _desc(path, **urdf):
    return {"name": "one", "urdf": {"file": str(path), "root": "world", "tip": "tool", **urdf},
            "outputs": [0, 1], "home": [0.1, 0.2],
            "grid": {"lo": [0.1, 0.1], "hi": [0.2, 0.2], "num": [2, 2]}}


@pytest.mark.parametrize("xyz, axis, hold, says", [
    ("nan 0 0", "0 0 1", None, "finite numbers"),
    ("inf 0 0", "0 0 1", None, "finite numbers"),
    ("1e308 0 0", "0 0 1", None, "finite numbers"),
    ("0.3 0 0", "0 0 0", None, "is zero"),
    ("0.3 0 0", "0 0 1", {"j2": float("nan")}, "body.urdf.hold.j2=nan"),
])
def test_bad_urdf_geometry_is_refused(tmp_path, xyz, axis, hold, says):
    path = tmp_path / "one.urdf"
    path.write_text(ARM.format(xyz=xyz, axis=axis))
    desc = _desc(path) if hold is None else dict(_desc(path, joints=["j1"], hold=hold),
                                                 home=[0.1], outputs=[0],
                                                 grid={"lo": [0.1], "hi": [0.2], "num": [2]})
    with pytest.raises(ValueError, match=r"^body\.urdf\.") as err:
        body_from(desc)
    assert says in str(err.value)


def test_a_fifo_as_urdf_is_refused_at_once(tmp_path):
    fifo = tmp_path / "pipe.urdf"
    os.mkfifo(fifo)
    t = time.perf_counter()
    with pytest.raises(ValueError, match="not a regular file"):
        body_from(_desc(fifo))
    assert time.perf_counter() - t < 5


def test_an_oversized_urdf_is_refused_before_reading(tmp_path, monkeypatch):
    import gbmodel.urdf
    path = tmp_path / "big.urdf"
    path.write_text(ARM.format(xyz="0 0 0.1", axis="0 0 1") + " " * 2000)
    monkeypatch.setattr(gbmodel.urdf, "MAX_BYTES", 1000)
    with pytest.raises(ValueError, match="bytes; a URDF is at most 1,000"):
        body_from(_desc(path))
