"""Watch it learn (pipeline/studies/animation.py): snapshots for the frames, the GIF per condition."""
import numpy as np
import pytest
from PIL import Image

import gbmodel
from conftest import run_cli, tiny_overrides
from pipeline.plan import frame_epochs
from pipeline.studies import animation, figures

MAX_BYTES = 2 * 1024 * 1024


def test_frame_epochs_are_log_spaced_and_end_at_the_last_epoch():
    e = frame_epochs(1000, 4)
    assert e == [1, 10, 100, 1000]
    assert frame_epochs(5, 12) == [1, 2, 3, 4, 5]  # fewer where epochs round together
    assert frame_epochs(70, 1) == [70] and frame_epochs(70, 0) == []


@pytest.mark.parametrize("growth", [dict(pattern="proportional", period=40),
                                    dict(pattern="per_segment", period=40, rates=[2, 2, 1, 1, 1])])
def test_snapshots_change_no_curve_byte(growth):
    base = gbmodel.TrialSpec(growth=growth, epochs=60)
    plain = gbmodel.run_trial(base, np.random.default_rng(7))
    snapped = gbmodel.run_trial(gbmodel.TrialSpec(growth=growth, epochs=60,
                                                  snapshots=tuple(frame_epochs(60, 12))),
                                np.random.default_rng(7))
    for col in ("epoch", "size", "abs_error", "rel_error"):
        assert getattr(plain, col).tobytes() == getattr(snapped, col).tobytes()
    assert plain.M.tobytes() == snapped.M.tobytes()
    assert sorted(snapped.snapshots) == frame_epochs(60, 12)


def _stored(spec):
    res = gbmodel.run_trial(spec, np.random.default_rng(1))
    return [(e, res.snapshots[e]) for e in sorted(res.snapshots)], res


@pytest.mark.parametrize("body, epochs", [("arm5", 40), ("icub", 20), ("arm2", 20)])
def test_gif_has_a_frame_per_stage_and_is_small(tmp_path, body, epochs):
    spec = gbmodel.TrialSpec(body={"name": body}, epochs=epochs,
                             growth=dict(pattern="proportional", period=epochs // 2),
                             snapshots=tuple(frame_epochs(epochs, 6)))
    stored, res = _stored(spec)
    d = spec.to_dict()
    path = animation.animate(d, stored, f"{body} test", tmp_path / "a.gif")
    data = path.read_bytes()
    assert len(data) < MAX_BYTES
    with Image.open(path) as im:
        assert im.format == "GIF" and im.n_frames == len(stored)
        # the frames differ: the body grows
        im.seek(0)
        first = np.asarray(im.convert("RGB"))
        im.seek(im.n_frames - 1)
        assert (np.asarray(im.convert("RGB")) != first).any()
    # the same stages give the same bytes
    assert animation.animate(d, stored, f"{body} test", tmp_path / "b.gif").read_bytes() == data
    # each frame's body is at its epoch's size, and the last frame's error is the model's
    f = figures.reach(d, stored[0][1], stored[0][0])
    assert f["size"] == pytest.approx(0.5)
    last = figures.reach(d, res.M, epochs)
    assert last["size"] == 1.0 and np.isfinite(last["error"])


def test_report_writes_a_gif_per_condition_with_frames(tmp_path):
    args = tiny_overrides(tmp_path, "conditions.frames=5", "growth.period=20", "figure=anim")
    for stage in ("pipeline.simulate", "pipeline.aggregate", "pipeline.report"):
        r = run_cli(stage, *args)
        assert r.returncode == 0, r.stderr[-2000:]
    out = tmp_path / "outputs" / "smoke" / "latest" / "anim"  # a named figure's own folder
    gifs = sorted(out.glob("*.gif"))
    assert [g.name for g in gifs] == ["anim_TG20.gif"]
    with Image.open(gifs[0]) as im:
        assert im.n_frames == 5
    assert "![anim_TG20](anim_TG20.gif)" in (out / "report.md").read_text()
    r = run_cli("pipeline.simulate", *tiny_overrides(tmp_path, "conditions.frames=-1"))
    assert r.returncode == 2 and "conditions.frames=-1" in r.stderr
