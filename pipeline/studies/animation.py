"""Watch it learn: an animation (GIF) of a body growing and reaching for its target grid.

One frame per stored model of trial 0 of a condition (its snapshots, then the final model): the
body at the size of that epoch (gbmodel.Growth.sizes / scales: every pattern and schedule), its
target grid (grey) and the grid its inverse estimate reaches (black), and a few postures. The
axes are fixed over the frames, at the extent of every frame, so the growth is seen as growth.
2-D bodies are drawn in their plane, 3-D bodies in perspective, bodies with one target
coordinate (arm2: a height) in the plane of their motion. The snapshots come from the trials
(`conditions.frames`, or `conditions.snapshots`); taking them changes no curve's bytes
(gbmodel.trial draws its random numbers regardless of where it stops to copy the model).

Written as matplotlib's Pillow writer does (Pillow comes with matplotlib): no system dependency.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

import gbmodel

from . import figures

FPS = 3  # frames per second: a stage is long enough to be read
MIN_FRAMES = 2  # fewer stored models: nothing moves, no animation
DPI = 80  # a frame of 4.2 x 4.2 in is 336 x 336 pixels: a GIF of tens of kB
N_POSTURES = 5


def stages(cond: dict) -> list[tuple[int, np.ndarray]]:
    """(epoch, M) of trial 0 of an aggregated condition (models.json): its snapshots, then the
    final model unless a snapshot is already of the last epoch."""
    trial = cond["trials"].get("0")
    if trial is None or not figures.draws_model(cond["spec"]):
        return []  # a learner without predict_model has nothing to draw
    out = [(int(e), np.asarray(M, float)) for e, M in trial["snapshots"].items()]
    epochs = int(cond["spec"]["epochs"])
    if epochs not in {e for e, _ in out} and trial.get("M") is not None:
        out.append((epochs, np.asarray(trial["M"], float)))
    return sorted(out, key=lambda em: em[0])


def frame_data(spec: dict, epoch: int, M: np.ndarray) -> dict:
    """What one frame draws: the body's size at `epoch`, targets, reached points, postures."""
    body, growth = gbmodel.make_body(spec["body"]), gbmodel.Growth(**spec["growth"])
    size = float(growth.sizes(np.array([epoch]), body)[0])
    learner, params = gbmodel.TrialSpec.from_dict(spec).make_learner()
    targets = body.target_set(size)
    q = learner.predict_model(M, params, body, targets)
    k = gbmodel.growth.factors(body, size, growth)
    reached = body.forward(q, k)
    picks = np.linspace(0, len(targets) - 1, N_POSTURES).round().astype(int)
    links = np.stack([body.frame_points(q[i], k) for i in
                      (range(len(q)) if body.n == 1 else picks)])
    return dict(epoch=epoch, size=size, targets=targets, reached=reached, links=links,
                picks=picks, body=body,
                error=float(np.linalg.norm(reached - targets, axis=-1).mean()))


def _plane(frames: list[dict]) -> tuple[int, int]:
    """(horizontal, vertical) root axes of a body with one target coordinate: the output axis
    and the axis along which the arm extends most over all frames."""
    body = frames[0]["body"]
    out = body.outputs[0]
    pts = np.concatenate([f["links"] for f in frames])
    return max((j for j in range(3) if j != out), key=lambda j: np.ptp(pts[..., j])), out


def _limits(frames: list[dict], axes) -> list[tuple[float, float]]:
    pts = np.concatenate([np.concatenate([f["links"].reshape(-1, 3)[:, axes]]
                                         + ([f["targets"], f["reached"]]
                                            if len(axes) == f["targets"].shape[1] else []))
                          for f in frames])
    lo, hi = np.nanmin(pts, axis=0), np.nanmax(pts, axis=0)
    pad = 0.05 * float(np.max(hi - lo) or 1.0)
    return [(float(a) - pad, float(b) + pad) for a, b in zip(lo, hi)]


def _draw(ax, f: dict, lims, three_d: bool, plane) -> None:
    body = f["body"]
    ax.cla()
    cols = figures.plt.get_cmap("tab10")(np.arange(N_POSTURES))
    if plane is not None:  # one target coordinate: the arm in its plane, heights beside the hand
        h, v = plane
        hand = f["links"][:, -1, h]
        ax.scatter(hand, f["targets"][:, 0], s=10, color="0.7", zorder=2)
        ax.scatter(hand, f["reached"][:, 0], s=4, color="black", zorder=3)
        for c, i in zip(cols, f["picks"]):
            ax.plot(f["links"][i, :, h], f["links"][i, :, v], color=c, lw=1.6, marker="o",
                    ms=2.5)
        ax.set(xlim=lims[0], ylim=lims[1], aspect="equal", xlabel=f"{'xyz'[h]} [m]",
               ylabel=f"{'xyz'[v]} [m] (target)")
    else:
        shape = figures._grid_shape(f["targets"])
        figures._draw_grid(ax, f["targets"], shape, color="0.7", lw=0.8)
        figures._draw_grid(ax, f["reached"], shape, color="black", lw=0.8)
        for c, pts in zip(cols, f["links"]):
            ax.plot(*pts[:, list(body.outputs)].T, color=c, lw=1.6, marker="o", ms=2.5)
        if three_d:
            ax.set(xlim3d=lims[0], ylim3d=lims[1], zlim3d=lims[2], xlabel="x [m]",
                   ylabel="y [m]", zlabel="z [m]")
            ax.set_box_aspect([b - a for a, b in lims], zoom=0.8)
            ax.grid(False)
            ax.view_init(elev=20, azim=-60)
            figures.sparse_3d_ticks(ax)
        else:
            ax.set(xlim=lims[0], ylim=lims[1], aspect="equal", xlabel="x [m]", ylabel="y [m]")
    ax.set_title(f"epoch {f['epoch']}, size {f['size']:.3f}\nmean error "
                 f"{1000 * f['error']:.1f} mm", fontsize=8)


def animate(spec: dict, stored: list[tuple[int, np.ndarray]], title: str, path: Path) -> Path:
    """Write the GIF of the stages `stored` ((epoch, M), in order) of a trial of `spec`."""
    from PIL import Image

    from ..io import atomic_path

    frames = [frame_data(spec, e, M) for e, M in stored]
    body = frames[0]["body"]
    three_d = body.n == 3
    plane = _plane(frames) if body.n == 1 else None
    lims = _limits(frames, list(plane) if plane else list(body.outputs))
    fig = figures.plt.figure(figsize=(4.2, 4.2), dpi=DPI)
    ax = fig.add_subplot(projection="3d" if three_d else None)
    fig.suptitle(title, fontsize=8)
    _draw(ax, frames[-1], lims, three_d, plane)
    figures.tight_layout(fig)  # fixed on the last (largest) frame, the same for every frame
    images = []
    for f in frames:  # what matplotlib's PillowWriter does, with the format named, not guessed
        _draw(ax, f, lims, three_d, plane)
        fig.canvas.draw()
        rgb = Image.frombuffer("RGBA", fig.canvas.get_width_height(),
                               fig.canvas.buffer_rgba(), "raw", "RGBA", 0, 1).convert("RGB")
        images.append(rgb.quantize(colors=64, method=Image.Quantize.MEDIANCUT, dither=0))
    figures.plt.close(fig)
    with atomic_path(path) as tmp:
        images[0].save(tmp, format="GIF", save_all=True, append_images=images[1:],
                       duration=int(1000 / FPS), loop=0, optimize=True)
    return path


def write(aggs: dict, out: Path) -> list[tuple[str, Path]]:
    """(title, GIF path) per figure and condition whose trial 0 stored at least MIN_FRAMES
    models; the GIFs go into `out`."""
    written = []
    for name, agg in aggs.items():
        for cid, cond in agg["models"]["conditions"].items():
            stored = stages(cond)
            if len(stored) < MIN_FRAMES:
                continue
            title = f"{name} {cid}, trial 0"
            path = out / f"{name}_{re.sub(r'[^A-Za-z0-9.=_-]+', '_', cid)}.gif"
            written.append((title, animate(cond["spec"], stored, title, path)))
    return written
