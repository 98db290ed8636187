"""Learning-curve options for a paper (report.title, report.error_unit, report.log_error_axis,
report.log_epoch_axis: pipeline.studies.paper.figure_options): a title of one's own, errors in
millimetres, linear or log axes; the defaults draw the same bytes as before the options."""
import hashlib

import numpy as np
import pytest
from omegaconf import OmegaConf

from pipeline.config import ConfigError
from pipeline.studies import figures, paper
from test_figure_layout import _sweep


def _curves():
    c, s = _sweep(["TG100", "const1.0"])
    s.loc[1, "growth"] = "none"
    return c, s


def _bytes(fig, tmp_path, name):
    return [hashlib.sha256(p.read_bytes()).hexdigest() for p in figures.save(fig, tmp_path / name, 60)]


def test_the_defaults_draw_the_same_bytes_as_no_options(tmp_path):
    c, s = _curves()
    plain = figures.learning_curves(c, s, "fig4", paper_abs=0.02)
    opts = paper.figure_options(OmegaConf.create({"report": {"log_error_axis": True}}))
    assert opts == dict(log_y=True, log_x=True, unit="m", suptitle=None)
    same = figures.learning_curves(c, s, "fig4", paper_abs=0.02, **opts)
    assert _bytes(plain, tmp_path, "a") == _bytes(same, tmp_path, "b")


def test_a_title_millimetres_and_linear_axes(tmp_path):
    c, s = _curves()
    cfg = OmegaConf.create({"report": {"title": "Growth on the 5-DOF arm", "error_unit": "mm",
                                       "log_error_axis": False, "log_epoch_axis": False}})
    fig = figures.learning_curves(c, s, "mygrid", paper_abs=0.02, **paper.figure_options(cfg))
    assert fig._suptitle.get_text() == "Growth on the 5-DOF arm"
    a, b = fig.axes[:2]
    assert a.get_ylabel() == "absolute error [mm]" and b.get_ylabel() == "relative error [mm / size factor]"
    assert a.get_xscale() == a.get_yscale() == "linear"
    first = c[c["condition"] == "TG100"].sort_values("epoch")["abs_error_mean"].to_numpy()
    assert np.allclose(a.get_lines()[0].get_ydata(), 1e3 * first)
    assert any(np.allclose(ln.get_ydata(), 20.0) for ln in a.get_lines())  # the paper's 2 cm


def test_log_axes_stay_the_default_and_a_bad_unit_is_one_line():
    opts = paper.figure_options(OmegaConf.create({"report": {}}))
    assert opts["log_x"] and opts["log_y"] and opts["unit"] == "m"
    with pytest.raises(ConfigError, match=r"^report.error_unit=cm: one of m, mm$"):
        paper.figure_options(OmegaConf.create({"report": {"error_unit": "cm"}}))


def _schema_has_the_keys() -> bool:
    import dataclasses

    from pipeline import config

    report = next(f for f in dataclasses.fields(config.Config) if f.name == "report")
    names = {f.name for f in dataclasses.fields(report.default_factory())}
    return {"title", "error_unit", "log_epoch_axis"} <= names


@pytest.mark.skipif(not _schema_has_the_keys(), reason="report.title, report.error_unit and "
                    "report.log_epoch_axis are not in the config schema's ReportConf yet")
def test_the_keys_compose_on_the_command_line():
    from pipeline.config import compose

    cfg = compose(["report.title=Radius x period", "report.error_unit=mm",
                   "report.log_error_axis=false", "report.log_epoch_axis=false"])
    assert paper.figure_options(cfg) == dict(log_y=False, log_x=False, unit="mm",
                                             suptitle="Radius x period")
    assert paper.figure_options(compose([])) == dict(log_y=True, log_x=True, unit="m",
                                                     suptitle=None)
