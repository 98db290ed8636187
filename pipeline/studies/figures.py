"""The report's drawings, each a function from aggregated data to a matplotlib Figure, saved by
`save` with reproducible bytes (rcParams, no timestamps or versions, a fixed SVG hash salt)."""
from __future__ import annotations

import functools
import re
import textwrap
from contextlib import contextmanager
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.artist as martist  # noqa: E402
import matplotlib.axis as maxis  # noqa: E402
import matplotlib.mathtext as mathtext  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.layout_engine import PlaceHolderLayoutEngine  # noqa: E402
from mpl_toolkits.mplot3d.axis3d import Axis as Axis3D  # noqa: E402
import numpy as np  # noqa: E402

import gbmodel  # noqa: E402
from gbmodel.growth import factors  # noqa: E402

RC = {"font.family": "DejaVu Sans", "font.size": 9, "axes.titlesize": 9, "legend.fontsize": 8,
      "axes.grid": True, "grid.alpha": 0.3, "savefig.bbox": "standard",
      "svg.hashsalt": "gbgrowth", "pdf.compression": 6, "path.simplify": False}
METADATA = {"png": {"Software": None},
            "pdf": {"Creator": None, "Producer": None, "CreationDate": None, "ModDate": None}}


def save(fig, stem: Path, dpi: int) -> list[Path]:
    """Write stem.png and stem.pdf with reproducible bytes; return the paths."""
    from ..io import atomic_path

    paths = []
    if isinstance(fig.get_layout_engine(), PlaceHolderLayoutEngine):
        fig.set_layout_engine(None)  # tight_layout's leftover: savefig would draw once more first
    for ext in ("png", "pdf"):
        path = stem.with_suffix(f".{ext}")
        with atomic_path(path) as tmp, drawn_once():
            fig.savefig(tmp, format=ext, dpi=dpi, metadata=METADATA[ext])
        paths.append(path)
    plt.close(fig)
    return paths


# A mathtext string (a log axis's tick label) is parsed once per font, dpi and output: matplotlib
# keeps the last 50 parses, fewer than a report's labels at its three dpis (layout, PNG, PDF),
# so a quarter of them were parsed again (272 parses in a cold smoke report, 204 kept longer).
mathtext.MathTextParser._parse_cached = functools.lru_cache(4096)(
    getattr(mathtext.MathTextParser._parse_cached, "__wrapped__",
            mathtext.MathTextParser._parse_cached))


@contextmanager
def _kept(patched: tuple, key):
    """Within the context each method (owner, name) of `patched` is computed once per key(fn,
    obj, args, kwargs) (None: not kept); the objects a key names by id are kept with the result."""
    real, seen = [(o, n, getattr(o, n)) for o, n in patched], {}

    def once(fn):
        def kept(obj, *args, **kwargs):
            k = key(fn, obj, args, kwargs)
            if k is None:
                return fn(obj, *args, **kwargs)
            if k not in seen:
                seen[k] = (obj, args, fn(obj, *args, **kwargs))
            return seen[k][2]
        return kept
    for o, n, fn in real:
        setattr(o, n, once(fn))
    try:
        yield
    finally:
        for o, n, fn in real:
            setattr(o, n, fn)


def drawn_once():
    """While a figure is drawn (a save), each 2-D axis lays out its ticks and measures their
    labels once per view interval and Axes box (matplotlib does it four to ten times per draw);
    3-D axes, which move their labels while drawing, are left alone. The same bytes
    (tests/studies/test_figure_layout.py)."""
    return _kept(((maxis.Axis, "_update_ticks"), (maxis.Axis, "_get_ticklabel_bboxes")),
                 lambda fn, axis, args, kw: None if isinstance(axis, Axis3D) else (
                     fn, id(axis), *map(id, args), *kw.items(), tuple(axis.get_view_interval()),
                     axis.axes.bbox.bounds))


def measured_once():
    """While a layout is computed nothing it measures moves: each axis lays out its ticks once
    and each Axes' layout box is measured once (tight_layout(rect=...) measures every Axes twice,
    an axis its ticks for each spine and label): the same layout and bytes, a third less CPU."""
    return _kept(((maxis.Axis, "_update_ticks"), (martist, "_get_tightbbox_for_layout_only")),
                 lambda fn, obj, args, kw: (fn, id(obj), *map(id, args), *kw.items()))


def tight_layout(fig, **kwargs) -> None:
    """fig.tight_layout(**kwargs), each measurement made once (measured_once)."""
    with measured_once():
        fig.tight_layout(**kwargs)


TITLE_CHARS = 36  # a posture panel's title is wrapped at this width (fontsize 8, 3.6 in)
GROWTH_LABEL = re.compile(r"(TG\d+|const[\d.]+)")  # a condition named by its growth alone


def by_growth(summary) -> bool:
    """Whether the figure's conditions differ by their growth only (the paper's figures)."""
    return all(GROWTH_LABEL.fullmatch(c) for c in summary["condition"])


def condition_label(row) -> str:
    """The legend entry: the paper's wording for a growth label, else the condition's own."""
    if not GROWTH_LABEL.fullmatch(row["condition"]):
        return row["condition"]
    if row["growth"] == "none":
        return f"constant size {row['end_size']:g}"
    return f"T_G = {row['growth_period']}"


FACTOR = re.compile(r"([^=,|]+)=(.*)")
LINE_STYLES = ("-", "--", ":", "-.")
MARKERS = ("o", "s", "^", "D", "v", "P", "X")


def label_levels(labels) -> list[dict]:
    """Each condition label as {factor: level}: `R=0.1, L=5 | TG100` is {R: 0.1, L: 5,
    growth: TG100} (pipeline.labels.condition_labels); a part without `=` is a factor of its own,
    named by its position."""
    out = []
    for label in labels:
        levels = {}
        for i, part in enumerate(str(label).split(" | ")):
            for item in re.split(r", (?=[^=,|]+=)", part):
                m = FACTOR.fullmatch(item.strip())
                if m:
                    levels[m.group(1).strip()] = m.group(2).strip()
                else:
                    levels["growth" if GROWTH_LABEL.fullmatch(item) else f"part {i + 1}"] = item
        out.append(levels)
    return out


def sweep_channels(labels) -> dict:
    """factor -> (channel, {level: value}) for the factors varied between `labels`: colour, line
    style, marker in turn; more than three: every condition its own colour ("condition")."""
    levels = label_levels(labels)
    names = [k for k in dict.fromkeys(k for lv in levels for k in lv)
             if len({lv.get(k) for lv in levels}) > 1]
    if len(names) > 3 or any(set(lv) != set(levels[0]) for lv in levels):
        names, levels = ["condition"], [dict(condition=str(c)) for c in labels]
    out = {}
    for name, channel in zip(names, ("color", "ls", "marker")):
        vals = list(dict.fromkeys(lv[name] for lv in levels))
        if channel == "color":
            cmap = plt.get_cmap("tab10" if len(vals) <= 10 else "viridis")
            colors = (cmap(np.arange(len(vals))) if len(vals) <= 10
                      else cmap(np.linspace(0.0, 0.85, len(vals))))
            out[name] = (channel, dict(zip(vals, colors)))
        else:
            pool = LINE_STYLES if channel == "ls" else MARKERS
            out[name] = (channel, {v: pool[i % len(pool)] for i, v in enumerate(vals)})
    return out


def sweep_handles(labels) -> list:
    """Legend entries of sweep_channels: one per level of each factor, in its channel only."""
    handles = []
    for name, (channel, values) in sweep_channels(labels).items():
        for level, value in values.items():
            style = dict(color="0.35", ls="-", lw=1.3)
            style["marker" if channel == "marker" else channel] = value
            handles.append(plt.Line2D([], [], label=f"{name}={level}" if name != "condition"
                                      else level, **style))
    return handles


def condition_styles(summary) -> dict:
    """Colour per growing condition, grey/black dashes for the references; a sweep of one's own:
    each varied factor on its own channel (sweep_channels)."""
    if not by_growth(summary):
        channels = sweep_channels(summary["condition"])
        styles = {}
        for c, lv in zip(summary["condition"], label_levels(summary["condition"])):
            st = dict(color="0.35", ls="-")
            for name, (channel, values) in channels.items():
                level = c if name == "condition" else lv[name]
                st[channel] = values[level]
            if "marker" in st:
                st.update(markevery=0.1, ms=4)
            styles[c] = st
        return styles
    growing = summary[summary["growth"] != "none"]
    colors = plt.get_cmap("viridis")(np.linspace(0.0, 0.85, max(len(growing), 1)))
    styles = {c: dict(color=col, ls="-") for c, col in zip(growing["condition"], colors)}
    refs = summary[summary["growth"] == "none"].sort_values("end_size")
    for i, c in enumerate(refs["condition"]):
        styles[c] = dict(color="0.55" if i < len(refs) - 1 else "black",
                         ls="--" if i < len(refs) - 1 else ":")
    return styles


UNITS = {"m": 1.0, "mm": 1e3}  # report.error_unit: the errors' unit -> its factor from metres


def learning_curves(curves, summary, title: str, log_y: bool = True, paper_abs=None,
                    unit: str = "m", log_x: bool = True, suptitle: str | None = None):
    """Fig. 4/5/7: (a) absolute and (b) relative error against epochs, mean over trials and
    quartile band, a line per condition, the paper's final error (paper_abs) a horizontal line,
    the legend below; suptitle, unit, log_x, log_y: a paper's report.title, error_unit,
    log_epoch_axis and log_error_axis."""
    styles = condition_styles(summary)
    handles = (sweep_handles(summary["condition"]) if not by_growth(summary) else
               [plt.Line2D([], [], lw=1.3, label=condition_label(row),
                           **styles[row["condition"]]) for _, row in summary.iterrows()])
    if (summary["growth"] != "none").any():
        handles.append(growth_end_handle())
    if paper_abs is not None:
        handles.append(plt.Line2D([], [], color="tab:red", lw=0.9, ls="-.",
                                  label=f"paper: final error ≈ {1000 * paper_abs:g} mm"))
    if unit not in UNITS:
        raise ValueError(f"unit {unit!r}: one of {', '.join(UNITS)}")
    k = UNITS[unit]
    fig, axes = plt.subplots(1, 2, figsize=(9.0, 3.6))
    for ax, col, ylabel in ((axes[0], "abs_error", f"absolute error [{unit}]"),
                            (axes[1], "rel_error", f"relative error [{unit} / size factor]")):
        for _, row in summary.iterrows():
            cu = curves[curves["condition"] == row["condition"]].sort_values("epoch")
            if not len(cu):
                continue
            st = styles[row["condition"]]
            ax.fill_between(cu["epoch"], *(k * cu[f"{col}_{q}"] for q in ("q25", "q75")),
                            color=st["color"], alpha=0.15, lw=0)
            ax.plot(cu["epoch"], k * cu[f"{col}_mean"], label=condition_label(row), lw=1.3, **st)
        mark_growth_end(ax, summary, styles)
        if log_x:
            ax.set_xscale("log")
        if log_y:
            ax.set_yscale("log")
        ax.set_xlabel("epoch")
        ax.set_ylabel(ylabel)
    if paper_abs is not None:
        axes[0].axhline(k * paper_abs, color="tab:red", lw=0.9, ls="-.")
    axes[0].set_title("(a) absolute error")
    axes[1].set_title("(b) relative error")
    n = int(summary["n_trials"].max()) if len(summary) else 0
    fig.suptitle(suptitle or f"{title} (mean and quartiles over {n} trials)")
    legend_below(fig, handles, 3.6)
    return fig


def legend_below(fig, handles, height: float, max_cols: int = 4) -> None:
    """A legend under the panels in as many columns (<= max_cols) as fit; the figure grows by its
    height so the panels keep theirs (height: the panels' part [in])."""
    r = fig.canvas.get_renderer()
    for ncol in range(min(len(handles), max_cols) or 1, 0, -1):
        legend = fig.legend(handles=handles, loc="lower center", ncol=ncol, frameon=False)
        if legend.get_window_extent(r).width <= 0.98 * fig.bbox.width or ncol == 1:
            break
        legend.remove()
    below = legend.get_window_extent(r).height / fig.dpi + 0.1  # [in]
    fig.set_size_inches(fig.get_size_inches()[0], height + below)
    tight_layout(fig, rect=(0, below / (height + below), 1, 1))


def mark_growth_end(ax, summary, styles) -> None:
    """The end of growth (epoch T_G) of every growing condition: a thin line in its colour."""
    for _, row in summary[summary["growth"] != "none"].iterrows():
        if 0 < row["growth_period"] <= row.get("epochs", np.inf):  # growth that ends in the run
            ax.axvline(row["growth_period"], color=styles[row["condition"]]["color"], lw=0.7,
                       ls=(0, (1, 2)), alpha=0.8)


def growth_end_handle():
    return plt.Line2D([], [], color="0.3", lw=0.7, ls=(0, (1, 2)), label="end of growth (T_G)")


def draws_model(spec: dict) -> bool:
    """Whether a trial's stored model can be drawn: its learner (known here) has predict_model."""
    from gbmodel import learners

    try:
        return hasattr(learners.get(spec["learner"]["name"]), "predict_model")
    except ValueError:
        return False


def final_body(spec: dict) -> tuple:
    """(body, final size, gbmodel.Growth, predict(M, x): the commands stored model M chooses)."""
    spec = gbmodel.TrialSpec.from_dict(spec)
    body, growth = spec.make_body(), spec.make_growth()
    learner, params = spec.make_learner()
    if not hasattr(learner, "predict_model"):
        raise ValueError(f"learner {spec.learner.get('name')!r} has no predict_model: its "
                         "stored model cannot be drawn")
    return body, growth.end_size, growth, lambda M, x: learner.predict_model(M, params, body, x)


def joint_space_stages(spec: dict, stages: list[tuple[str, list]], title: str):
    """Fig. 2: the inverse estimate of the 2-DOF arm in joint space over contours of equal hand
    height, a panel per (label, M) of `stages`."""
    body, size, pattern, predict = final_body(spec)
    targets = body.target_set(size)[:, 0]
    xs = np.linspace(targets.min(), targets.max(), 401)[:, None]
    curves = [predict(M, xs) for _, M in stages]
    lim = max(np.pi, *(np.abs(c).max() for c in curves))
    grid = np.linspace(-lim, lim, 301)
    Q = np.stack(np.meshgrid(grid, grid, indexing="xy"), axis=-1)
    height = body.forward(Q, factors(body, size, pattern))[..., 0]
    cmap = plt.get_cmap("coolwarm")
    norm = matplotlib.colors.Normalize(targets.min(), targets.max())

    fig, axes = plt.subplots(1, len(stages), figsize=(2.6 * len(stages), 3.2), squeeze=False)
    for ax, (label, M), g in zip(axes[0], stages, curves):
        ax.contour(grid, grid, height, levels=np.sort(targets), cmap=cmap, norm=norm,
                   linewidths=0.7)
        ax.plot(g[:, 0], g[:, 1], color="black", lw=1.2)
        q_t = predict(M, targets[:, None])
        ax.scatter(q_t[:, 0], q_t[:, 1], c=targets, cmap=cmap, norm=norm, s=14,
                   edgecolors="black", linewidths=0.4, zorder=3)
        ax.plot(*body.home, marker="+", color="black", ms=8)
        ax.set(xlim=(-lim, lim), ylim=(-lim, lim), aspect="equal", title=label,
               xlabel="q1 [rad]")
        ax.grid(False)
    axes[0, 0].set_ylabel("q2 [rad]")
    fig.suptitle(title)
    tight_layout(fig)
    return fig


def _grid_shape(targets) -> tuple | None:
    shape = tuple(len(np.unique(np.round(targets[:, j], 9))) for j in range(targets.shape[1]))
    return shape if int(np.prod(shape)) == len(targets) else None


def _draw_grid(ax, points, shape, **style):
    """Lines through a regular grid of points (built by gbmodel.bodies._grid: C order)."""
    if shape is None:
        ax.scatter(*points.T, s=4, color=style.get("color"))
        return
    dim = points.shape[1]
    P = points.reshape(*shape, dim)
    gap = np.full((1, dim), np.nan)  # one polyline, broken by NaN rows: one artist, fast
    parts = []
    for axis in range(len(shape)):
        for line in np.moveaxis(P, axis, -2).reshape(-1, shape[axis], dim):
            parts += [line, gap]
    ax.plot(*np.concatenate(parts).T, **style)


def reach(spec: dict, M, epoch: int | None = None, n_postures: int = 5) -> dict:
    """What a panel draws of model M of a trial of `spec`: the body at `epoch`'s size (None: its
    final size), targets, reached points, links of n_postures postures (of every target for a
    body with one target coordinate) and the mean error."""
    body, size, growth, predict = final_body(spec)
    if epoch is not None:
        size = float(growth.sizes(np.array([epoch]), body)[0])
    targets = body.target_set(size)
    q = predict(np.asarray(M, float), targets)
    k = factors(body, size, growth)
    reached = body.forward(q, k)
    picks = np.linspace(0, len(targets) - 1, n_postures).round().astype(int)
    links = np.stack([body.frame_points(q[i], k) for i in
                      (range(len(q)) if body.n == 1 else picks)])
    return dict(epoch=epoch, size=size, targets=targets, reached=reached, links=links,
                picks=picks, body=body,
                error=float(np.linalg.norm(reached - targets, axis=-1).mean()))


def height_plane(frames: list[dict]) -> tuple[int, int]:
    """(horizontal, vertical) root axes of a body with one target coordinate: the one along which
    the arm extends most over the frames, and the output axis."""
    out, pts = frames[0]["body"].outputs[0], np.concatenate([f["links"] for f in frames])
    return max((j for j in range(3) if j != out), key=lambda j: np.ptp(pts[..., j])), out


def draw_reach(ax, f: dict, plane=None, **limits) -> None:
    """Target grid (grey), reached grid (black) and postures of reach(); a body with one target
    coordinate in the plane of its motion, heights beside the hand (limits: its axes')."""
    body, cols = f["body"], plt.get_cmap("tab10")(np.arange(len(f["picks"])))
    if body.n == 1:
        h, v = plane or height_plane([f])
        hand = f["links"][:, -1, h]
        ax.scatter(hand, f["targets"][:, 0], s=10, color="0.7", zorder=2)
        ax.scatter(hand, f["reached"][:, 0], s=4, color="black", zorder=3)
        for c, i in zip(cols, f["picks"]):
            ax.plot(f["links"][i, :, h], f["links"][i, :, v], color=c, lw=1.6, marker="o",
                    ms=2.5)
        ax.set(**limits, aspect="equal", xlabel=f"{'xyz'[h]} [m]",
               ylabel=f"{'xyz'[v]} [m] (target)")
        return
    shape = _grid_shape(f["targets"])
    _draw_grid(ax, f["targets"], shape, color="0.7", lw=0.8)
    _draw_grid(ax, f["reached"], shape, color="black", lw=0.8)
    for c, pts in zip(cols, f["links"]):
        ax.plot(*pts[:, list(body.outputs)].T, color=c, lw=1.6, marker="o", ms=2.5)


def view_3d(ax, spans, zoom: float, n: int = 4) -> None:
    """A 3-D panel at the same scale on all axes (spans), no grid but the targets', at most n
    ticks per axis in a smaller font (the default crowds the foreshortened axes)."""
    ax.set_box_aspect(spans, zoom=zoom)
    ax.grid(False)
    ax.set(xlabel="x [m]", ylabel="y [m]", zlabel="z [m]")
    ax.view_init(elev=20, azim=-60)
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.set_major_locator(matplotlib.ticker.MaxNLocator(n))
    ax.tick_params(labelsize=7, pad=1)


def postures(panels: list[tuple[str, dict, list]], title: str, n_postures: int = 5):
    """Fig. 3/6: target grid (grey) against reached grid (black) and a few postures, each panel
    (label, spec, M) with the body at its final size."""
    three_d = any(final_body(spec)[0].n == 3 for _, spec, _ in panels)
    fig = plt.figure(figsize=(max(3.6 * len(panels), 6.0), 4.0))
    for k, (label, spec, M) in enumerate(panels):
        f = reach(spec, M, n_postures=n_postures)
        ax = fig.add_subplot(1, len(panels), k + 1, projection="3d" if three_d else None)
        draw_reach(ax, f)
        ax.set_title(f"{textwrap.fill(label, TITLE_CHARS)}\nsize {f['size']:g}, mean error "
                     f"{1000 * f['error']:.1f} mm", fontsize=8)
        if three_d:
            view_3d(ax, [np.ptp(lim) for lim in (ax.get_xlim3d(), ax.get_ylim3d(),
                                                 ax.get_zlim3d())], 0.85)
        elif f["body"].n != 1:
            ax.set(aspect="equal", xlabel="x [m]", ylabel="y [m]")
    fig.legend(handles=[plt.Line2D([], [], color="0.7", lw=0.8, label="targets"),
                        plt.Line2D([], [], color="black", lw=0.8, label="reached"),
                        plt.Line2D([], [], color="tab:blue", lw=1.6, marker="o", ms=2.5,
                                   label=f"{n_postures} postures (links, base to hand)")],
               loc="lower center", ncol=3, frameon=False)
    fig.suptitle(title)
    tight_layout(fig, rect=(0, 0.07, 1, 0.93))  # room for the legend below, the title above
    return fig
