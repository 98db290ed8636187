"""Figures for a paper (pipeline/studies/figures.py): a 2 x 2 sweep gives each factor its own
channel, the legend covers no data, and no title or tick label is cut or overlaps another
(checked on the rendered extents); the layout measured once per object is matplotlib's own."""
import contextlib
import io
import itertools

import numpy as np
import pandas as pd
import pytest

import matplotlib.axis as maxis
from matplotlib.figure import Figure

import gbmodel
from pipeline.studies import figures

LABELS = [f"learner={a}, goal_selection={b}" for a, b in
          itertools.product(["goal_babbling", "online_goal_babbling"], ["random", "progress"])]


def _sweep(labels):
    epochs = np.unique(np.rint(np.geomspace(1, 1000, 30)))
    curves, rows = [], []
    for k, c in enumerate(labels):
        y = 0.3 * epochs ** -0.3 * (1 + 0.1 * k)
        curves.append(pd.DataFrame(dict(condition=c, epoch=epochs, **{
            f"{col}_{s}": y * f for col in ("abs_error", "rel_error")
            for s, f in (("mean", 1), ("q25", 0.9), ("q75", 1.1))})))
        rows.append(dict(condition=c, growth="proportional", growth_period=100, end_size=1.0,
                         epochs=1000, n_trials=3))
    return pd.concat(curves, ignore_index=True), pd.DataFrame(rows)


def test_factors_are_read_from_the_labels():
    assert figures.label_levels(["R=0.1, L=5 | TG100", "learner=a, goal_selection=b"]) == [
        dict(R="0.1", L="5", growth="TG100"), dict(learner="a", goal_selection="b")]


def test_each_varied_factor_has_its_own_channel():
    ch = figures.sweep_channels(LABELS)
    assert [c for c, _ in ch.values()] == ["color", "ls"]
    styles = figures.condition_styles(_sweep(LABELS)[1])
    colors = {c: tuple(s["color"]) for c, s in styles.items()}
    lines = {c: s["ls"] for c, s in styles.items()}
    # colour follows the learner alone, line style the goal selection alone
    assert colors[LABELS[0]] == colors[LABELS[1]] != colors[LABELS[2]] == colors[LABELS[3]]
    assert lines[LABELS[0]] == lines[LABELS[2]] != lines[LABELS[1]] == lines[LABELS[3]]
    three = [f"V={v}, R={r}, L={l}" for v, r, l in itertools.product([1, 2], [3, 4], [5, 6])]
    assert [c for c, _ in figures.sweep_channels(three).values()] == ["color", "ls", "marker"]
    assert len({(str(s["color"]), s["ls"], s["marker"]) for s in
                figures.condition_styles(pd.DataFrame(dict(condition=three))).values()}) == 8
    handles = figures.sweep_handles(LABELS)
    assert [h.get_label() for h in handles] == [
        "learner=goal_babbling", "learner=online_goal_babbling", "goal_selection=random",
        "goal_selection=progress"]


def _extents(fig):
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    return r, fig.bbox


def _drawn_ticklabels(axis, r):
    """Extents of the tick labels `axis` drew: the first len(locations) ticks (as the last draw
    placed them, 3-D included), those inside the view."""
    lo, hi = sorted(axis.get_view_interval())
    span = 1e-9 * (hi - lo)
    out = []
    for ticks, locs in ((axis.get_major_ticks(), axis.get_majorticklocs()),
                        (axis.get_minor_ticks(), axis.get_minorticklocs())):
        for t, loc in zip(ticks[:len(locs)], locs):
            if lo - span <= loc <= hi + span and t.label1.get_visible() and t.label1.get_text():
                out.append((t.label1, t.label1.get_window_extent(r)))
    return out


def _axes_of(ax):
    return [a for a in (getattr(ax, n, None) for n in ("xaxis", "yaxis", "zaxis")) if a]


def _texts(fig, r):
    """Every drawn text with its extent: titles, axis labels, drawn tick labels, legends."""
    out = [(t, t.get_window_extent(r)) for t in [fig._suptitle] if t is not None]
    for leg in fig.legends:
        out += [(leg, leg.get_window_extent(r))]
    for ax in fig.axes:
        for t in (ax.title, *(a.label for a in _axes_of(ax))):
            if t.get_visible() and t.get_text():
                out.append((t, t.get_window_extent(r)))
        for axis in _axes_of(ax):
            out += _drawn_ticklabels(axis, r)
    return out


def _overlap(a, b, tol=0.5):
    return (min(a.x1, b.x1) - max(a.x0, b.x0) > tol) and (min(a.y1, b.y1) - max(a.y0, b.y0) > tol)


def _check_layout(fig):
    r, box = _extents(fig)
    texts = _texts(fig, r)
    assert texts
    for t, e in texts:  # nothing cut at the figure's edge
        assert e.x0 >= box.x0 - 1 and e.x1 <= box.x1 + 1 and e.y0 >= box.y0 - 1 \
            and e.y1 <= box.y1 + 1, f"{t} is cut: {e} outside {box}"
    for ax in fig.axes:  # no two tick labels of one axis overlap, nor titles of two panels
        for axis in _axes_of(ax):
            labels = [e for _, e in _drawn_ticklabels(axis, r)]
            for a, b in itertools.combinations(labels, 2):
                assert not _overlap(a, b), f"tick labels overlap on {axis.axis_name}"
    titles = [ax.title.get_window_extent(r) for ax in fig.axes if ax.get_title()]
    for a, b in itertools.combinations(titles, 2):
        assert not _overlap(a, b), "panel titles overlap"
    return r


def test_sweep_figure_legend_covers_no_data_and_nothing_is_cut():
    fig = figures.learning_curves(*_sweep(LABELS), "2 x 2 sweep: learner x goal selection")
    r = _check_layout(fig)
    legend = fig.legends[0].get_window_extent(r)
    for ax in fig.axes:
        assert not _overlap(legend, ax.get_window_extent(r)), "the legend lies over a panel"
    assert len(fig.legends[0].get_texts()) == 5  # 2 + 2 levels, the end of growth
    figures.plt.close(fig)


@pytest.mark.parametrize("body", ["icub", "arm5"])
def test_posture_panels_titles_and_ticks_fit(body):
    spec = gbmodel.TrialSpec(body={"name": body}, epochs=5,
                             growth=dict(pattern="proportional", period=0, end_size=1.0))
    res = gbmodel.run_trial(spec, np.random.default_rng(0))
    d = spec.to_dict()
    d["learner"] = dict(d["learner"], degree=spec.make_learner()[1].degree)
    long = "my_sweep learner=online_goal_babbling, goal_selection=progress | TG1000, trial 0"
    for panels in ([("fig7 const0.5, trial 0", d, res.M), (long, d, res.M)],
                   [("fig7 const0.5, trial 0", d, res.M), ("fig7 TG1000, trial 0", d, res.M),
                    (long, d, res.M)]):
        fig = figures.postures(panels, "postures")  # a long label wraps, never cut
        _check_layout(fig)
        figures.plt.close(fig)


def test_figures_are_saved_as_png_and_pdf(tmp_path):
    fig = figures.learning_curves(*_sweep(LABELS), "sweep")
    paths = figures.save(fig, tmp_path / "s_curves", 60)
    assert [p.suffix for p in paths] == [".png", ".pdf"] and all(p.stat().st_size for p in paths)


def test_baselines_figure_legend_lies_below_the_panels():
    from pipeline.studies import baselines

    summary, curves = [], []
    for i, (learner, growth, schedule) in enumerate(itertools.product(
            baselines.LEARNERS, ("none", "proportional", "proportional"), ("linear",))):
        schedule = "infant" if i % 3 == 2 else schedule
        cond = f"c{i}"
        summary.append(dict(body="arm5", variant=f"{learner}, 1.06M, {schedule}", growth=growth,
                            condition=cond, final_samples=10 ** 6))
        samples = np.logspace(2, 6, 8)
        curves.append(pd.DataFrame(dict(condition=cond, samples=samples,
                                        heldout_abs_error_mean=0.3 / samples ** (0.1 + 0.02 * i))))
    aggs = {"baselines_arm5": dict(summary=pd.DataFrame(summary),
                                   curves=pd.concat(curves, ignore_index=True))}
    with figures.plt.rc_context(figures.RC):
        fig = baselines.figure(aggs, "Goal Babbling and its alternatives")
        r = _check_layout(fig)
    legend = fig.legends[0].get_window_extent(r)
    for ax in fig.axes:
        assert not _overlap(legend, ax.get_window_extent(r)), "the legend lies over a panel"
    assert len(fig.legends[0].get_texts()) == len(baselines.LEARNERS)
    figures.plt.close(fig)


def _grid():
    """Shared log axes in rows, an equal-aspect panel, a title over all, the legend below."""
    fig, axes = figures.plt.subplots(2, 3, figsize=(7.5, 4.6), sharex=True, sharey="row")
    x = np.geomspace(1, 1e4, 40)
    for k, ax in enumerate(axes.flat[:-1]):
        ax.plot(x, 0.2 * x ** (-0.1 * (k + 1)), label=f"line {k}")
        ax.set(xscale="log", yscale="log", title=f"panel {k}")
    axes[1, 2].remove()
    square = fig.add_subplot(2, 3, 6)
    square.plot([0, 1], [0, 2])
    square.set(aspect="equal", title="equal aspect")
    fig.suptitle("a grid")
    figures.legend_below(fig, axes[0, 0].get_lines() + axes[0, 1].get_lines(), 4.6)
    return fig


@pytest.mark.parametrize("draw", [lambda: figures.learning_curves(*_sweep(LABELS), "sweep"),
                                  _grid], ids=["curves", "grid"])
def test_the_layout_measured_once_is_matplotlibs(draw, monkeypatch):
    """figures.tight_layout (measured_once) places every panel where fig.tight_layout does, to
    the last bit (the same PNG bytes), with under half the tick layouts."""
    real, calls = maxis.Axis._update_ticks, []
    monkeypatch.setattr(maxis.Axis, "_update_ticks",
                        lambda self: calls.append(1) or real(self))

    def laid_out():
        calls.clear()
        with figures.plt.rc_context(figures.RC):
            fig = draw()
            n, png = len(calls), io.BytesIO()
            fig.savefig(png, format="png", dpi=40, metadata=figures.METADATA["png"])
        pars = fig.subplotpars
        figures.plt.close(fig)
        return n, (pars.left, pars.right, pars.bottom, pars.top, pars.wspace, pars.hspace,
                   tuple(fig.get_size_inches()), png.getvalue())

    once, layout = laid_out()
    monkeypatch.setattr(figures, "measured_once", contextlib.nullcontext)
    plain, plain_layout = laid_out()
    assert layout == plain_layout
    assert once < 0.5 * plain, (once, plain)


@pytest.mark.parametrize("draw", [lambda: figures.learning_curves(*_sweep(LABELS), "sweep"),
                                  _grid], ids=["curves", "grid"])
def test_a_save_draws_once_per_format_with_matplotlibs_bytes(draw, tmp_path, monkeypatch):
    """figures.save draws a figure once per format (tight_layout leaves a placeholder layout
    engine, for which savefig drew the whole figure once more first) and lays out each axis's
    ticks once per draw (drawn_once; the grid shares its axes and has an equal-aspect panel):
    the PNG and PDF bytes of a plain savefig, in half the draws."""
    real_draw, draws = Figure.draw, []
    monkeypatch.setattr(Figure, "draw", lambda self, r: draws.append(1) or real_draw(self, r))
    real_ticks, ticks = maxis.Axis._update_ticks, []
    monkeypatch.setattr(maxis.Axis, "_update_ticks",
                        lambda self: ticks.append(1) or real_ticks(self))

    def saved(plain):
        with figures.plt.rc_context(figures.RC):
            fig = draw()
            draws.clear(), ticks.clear()
            if not plain:
                out = [p.read_bytes() for p in figures.save(fig, tmp_path / "f", 40)]
                return len(draws), len(ticks), out
            out = []
            for ext in ("png", "pdf"):
                buf = io.BytesIO()
                fig.savefig(buf, format=ext, dpi=40, metadata=figures.METADATA[ext])
                out.append(buf.getvalue())
            figures.plt.close(fig)
            return len(draws), len(ticks), out

    n, n_ticks, files = saved(plain=False)
    n_plain, n_ticks_plain, files_plain = saved(plain=True)
    assert files == files_plain
    assert (n, n_plain) == (2, 4)
    assert n_ticks < 0.5 * n_ticks_plain, (n_ticks, n_ticks_plain)
