"""A result's .plot() shows as a picture in a Jupyter kernel with no %matplotlib magic."""

import pytest

nbformat = pytest.importorskip("nbformat", reason="nbformat comes with the dev extra (nbmake)")
nbclient = pytest.importorskip("nbclient", reason="nbclient comes with the dev extra (nbmake)")

CELL = """
import numpy as np
import robustctl as rc
from robustctl.plots import bode_grid
f = np.linspace(1, 10, 50)
d = rc.FrequencyData(f, (1 / (1j * f))[:, None, None])
bode_grid([d], ["data"])
"""


@pytest.mark.slow
def test_a_returned_figure_displays_as_png_in_a_kernel():
    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(CELL)])
    nbclient.NotebookClient(nb, timeout=600, kernel_name="python3").execute()  # wall: a loaded CI
    outputs = nb.cells[0].outputs
    assert any("image/png" in o.get("data", {}) for o in outputs), outputs
    assert not any(o.get("name") == "stderr" and "IProgress" in o.get("text", "") for o in outputs)


def test_stored_notebooks_show_a_picture_for_every_plot_cell():
    """The notebooks are stored executed, so they read well on a code host."""
    from pathlib import Path

    notebooks = sorted((Path(__file__).resolve().parents[2] / "notebooks").glob("*.ipynb"))
    assert notebooks
    for path in notebooks:
        nb = nbformat.read(path, as_version=4)
        for cell in nb.cells:
            if cell.cell_type != "code":
                continue
            last = cell.source.strip().splitlines()[-1] if cell.source.strip() else ""
            if ".plot(" in last:
                assert any("image/png" in o.get("data", {}) for o in cell.outputs), (path.name, last)
