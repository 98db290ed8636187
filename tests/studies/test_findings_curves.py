"""The numbers findings.md reads from the committed report's mean curves (curves.parquet, which
no named value reads yet: a section names the numbers of its tables): the T_G = 10,000 paragraph, each
checked here."""
import pandas as pd
import pytest

from pipeline.config import REPO_ROOT
from pipeline.studies import discussion, paper

CURVES = REPO_ROOT / "outputs" / "report" / "curves.parquet"


def test_the_t_g_10000_paragraph_is_the_mean_curves():
    if not CURVES.exists():
        pytest.skip("no committed report")
    c = pd.read_parquet(CURVES)
    f = c[c["figure"] == "fig4"]

    def at(cond, epoch, col="abs_error_mean"):
        return float(f[(f["condition"] == cond) & (f["epoch"] == epoch)][col].iloc[0])
    grown = f[(f["condition"] == "TG10000") & (f["epoch"] <= 10001)]
    low = grown.loc[grown["abs_error_mean"].idxmin()]
    text = " ".join(discussion.FINDINGS.read_text().split())
    para = text[text.index("why T_G = 10,000 rises at 1 / W"):]
    para = para[:para.index("**The half-size reference")]
    assert (f"from {1e3 * at('const1.0', 10000):.1f} mm there to "
            f"{1e3 * at('const1.0', 100000):.1f} mm at") in para
    assert (f"from {1e3 * at('const0.5', 10000):.1f} to "
            f"{1e3 * at('const0.5', 100000):.1f} mm") in para
    # both references still falling at epoch 10,000: no floor
    assert at("const1.0", 100000) < at("const1.0", 10000)
    assert at("const0.5", 100000) < at("const0.5", 10000)
    assert (f"{1e3 * low['abs_error_mean']:.1f} mm at epoch {int(low['epoch']):,}, at "
            f"{low['size']:.2f} of its final size, and climbs to "
            f"{1e3 * at('TG10000', 10000):.1f} mm at epoch 10,000") in para
    assert (f"stays at {1e3 * low['rel_error_mean']:.1f} and "
            f"{1e3 * at('TG10000', 10000, 'rel_error_mean'):.1f} mm per unit size") in para
    gain = 1 - at("const1.0", 10000) / at("const1.0", 5012)
    growth = at("TG10000", 10000, "size") / at("TG10000", 5012, "size") - 1
    assert f"gains {100 * gain:.0f} % from epoch 5,012 to 10,000, the body grows {100 * growth:.0f} %" \
        in para
