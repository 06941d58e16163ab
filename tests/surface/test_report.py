import json

import numpy as np
import pytest

import robustctl as rc
from robustctl.plots import bode_grid
from robustctl.report import Report
from robustctl.table import Table


def _frd(names=("y1",)):
    f = np.linspace(1, 10, 20)
    g = (1 / (1j * f))[:, None, None] * np.ones((1, len(names), 1))
    return rc.FrequencyData(f, g, outputs=names)


def test_report_writes_html_figures_and_summary(tmp_path):
    rep = Report(tmp_path / "out", title="T")
    rep.heading("H")
    rep.text("a < b")
    rep.table(Table(("x",), [(1.5,)]))
    png = rep.figure(bode_grid([_frd(), _frd()], ["a", "b"], shade_bands=[(2, 3)]), "bode")
    rep.record("cost", 1.25)
    path = rep.write()
    page = path.read_text()
    assert "a &lt; b" in page and png.name in page and "<td>1.5</td>" in page
    # self-contained: the figure is embedded byte for byte, nothing is linked
    import base64
    import re

    embedded = re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', page)
    assert [base64.b64decode(e) for e in embedded] == [png.read_bytes()]
    assert not re.search(r'src="(?!data:)', page)
    assert png.stat().st_size > 1000
    assert json.loads((tmp_path / "out" / "summary.json").read_text()) == {"cost": 1.25}
    Report(tmp_path / "out")  # a folder robustctl wrote may be reused


def test_report_never_takes_over_a_users_folder(tmp_path):
    (tmp_path / "mine.txt").write_text("precious")
    with pytest.raises(rc.RobustctlError, match="did not write"):
        Report(tmp_path)
    assert (tmp_path / "mine.txt").read_text() == "precious"


def test_bode_grid_refuses_mismatched_signals():
    with pytest.raises(rc.DataError, match="cannot overlay"):
        bode_grid([_frd(("y1",)), _frd(("z1",))])
