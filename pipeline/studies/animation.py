"""Watch it learn: a GIF of trial 0 of a condition, a frame per stored model (its snapshots:
conditions.frames or conditions.snapshots, then the final model), the body at that epoch's size
reaching for its target grid, on axes fixed over the frames so that growth is seen as growth.
Written as matplotlib's Pillow writer does: no system dependency."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

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


def _limits(frames: list[dict], axes) -> list[tuple[float, float]]:
    pts = np.concatenate([np.concatenate([f["links"].reshape(-1, 3)[:, axes]]
                                         + ([f["targets"], f["reached"]]
                                            if len(axes) == f["targets"].shape[1] else []))
                          for f in frames])
    lo, hi = np.nanmin(pts, axis=0), np.nanmax(pts, axis=0)
    pad = 0.05 * float(np.max(hi - lo) or 1.0)
    return [(float(a) - pad, float(b) + pad) for a, b in zip(lo, hi)]


def _draw(ax, f: dict, lims, three_d: bool, plane) -> None:
    ax.cla()
    if plane is not None:
        figures.draw_reach(ax, f, plane, xlim=lims[0], ylim=lims[1])
    elif three_d:
        figures.draw_reach(ax, f)
        ax.set(xlim3d=lims[0], ylim3d=lims[1], zlim3d=lims[2])
        figures.view_3d(ax, [b - a for a, b in lims], 0.8)
    else:
        figures.draw_reach(ax, f)
        ax.set(xlim=lims[0], ylim=lims[1], aspect="equal", xlabel="x [m]", ylabel="y [m]")
    ax.set_title(f"epoch {f['epoch']}, size {f['size']:.3f}\nmean error "
                 f"{1000 * f['error']:.1f} mm", fontsize=8)


def animate(spec: dict, stored: list[tuple[int, np.ndarray]], title: str, path: Path) -> Path:
    """Write the GIF of the stages `stored` ((epoch, M), in order) of a trial of `spec`."""
    from PIL import Image

    from ..io import atomic_path

    frames = [figures.reach(spec, M, e, N_POSTURES) for e, M in stored]
    body = frames[0]["body"]
    three_d = body.n == 3
    plane = figures.height_plane(frames) if body.n == 1 else None
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
