"""The robustctl command on a user's own files: a model in a .py file, data in UFF and CSV."""

import json
import textwrap

import numpy as np
import pytest

import robustctl as rc
from robustctl.cli import main

MODEL_PY = textwrap.dedent(
    """
    import numpy as np
    import robustctl as rc

    M = np.diag([2.0, 1.0, 1.0, 0.5])
    K = 1e3 * np.array([[3.0, -1, 0, 0], [-1, 2, -1, 0], [0, -1, 2, -1], [0, 0, -1, 1]])

    def build():
        k = rc.Parameter("k_scale", 1.0, "", (0.5, 2.0), meaning="stiffness scale")
        return rc.structural_model(
            M, lambda th: th["k_scale"] * K, inputs={"F1": "dof 1"},
            outputs={"a3": ("dof 3", "acceleration"), "a4": ("dof 4", "acceleration")},
            damping=0.02, params=[k], name="4-mass chain",
        )

    model = build()
    """
)
F_HZ = np.linspace(1.0, 20.0, 300)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("user")
    (folder / "chain.py").write_text(MODEL_PY)
    namespace: dict = {}
    exec(MODEL_PY, namespace)
    truth = namespace["model"].with_values(k_scale=1.1)
    rng = np.random.default_rng(3)
    g = truth.freqresp(F_HZ).response
    g = g * np.exp(0.01 * (rng.standard_normal(g.shape) + 1j * rng.standard_normal(g.shape)))
    data = rc.FrequencyData(F_HZ, g, inputs=truth.inputs, outputs=truth.outputs)
    data.save(folder / "chain.uff")
    data.save(folder / "chain.csv")
    return folder


def _summary(folder):
    page = (folder / "report.html").read_text()
    return page, json.loads((folder / "summary.json").read_text())


@pytest.mark.parametrize("fmt", ["uff", "csv"])
def test_compare_from_files_writes_its_report_section(files, tmp_path, fmt, capsys):
    out = tmp_path / "rep"
    code = main(["compare", str(files / "chain.py"), str(files / f"chain.{fmt}"), "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    page, summary = _summary(out)
    assert "Where the model fails" in page and "data:image/png;base64," in page
    namespace: dict = {}
    exec(MODEL_PY, namespace)
    expected = rc.compare(namespace["model"], rc.load_frd(files / f"chain.{fmt}")).cost
    assert summary["cost"] == pytest.approx(expected, rel=1e-9)


def test_diagnose_and_identify_from_files(files, tmp_path, capsys):
    code = main(["diagnose", f"{files / 'chain.py'}:build", str(files / "chain.uff"),
                 "--out", str(tmp_path / "d"), "--time-budget", "60"])
    assert code == 0, capsys.readouterr().err
    page, summary = _summary(tmp_path / "d")
    assert "Which physical effect is missing?" in page and isinstance(summary["ranking"], list)
    assert summary["verdict_word"] in ("within the noise", "answer", "incomplete", "unexplained",
                                       "no noise model")
    assert isinstance(summary["chain"], list) and isinstance(summary["misfit_left"], list)

    code = main(["identify", str(files / "chain.csv"), "--modes", "4", "--band", "1", "20",
                 "--out", str(tmp_path / "i")])
    assert code == 0, capsys.readouterr().err
    page, summary = _summary(tmp_path / "i")
    assert summary["n_modes"] == 4
    k = 1.1e3 * np.array([[3.0, -1, 0, 0], [-1, 2, -1, 0], [0, -1, 2, -1], [0, 0, -1, 1]])
    m = np.diag([2.0, 1.0, 1.0, 0.5])
    f_true = np.sqrt(np.sort(np.linalg.eigvals(np.linalg.solve(m, k)).real)) / (2 * np.pi)
    f_found = np.sort([mode["f_hz"] for mode in summary["modes"]])
    np.testing.assert_allclose(f_found, f_true, rtol=5e-3)


@pytest.mark.parametrize(
    "argv, words",
    [
        (["compare", "nope.py", "{data}"], "does not exist"),
        (["compare", "{model}:missing", "{data}"], "has no 'missing'"),
        (["compare", "{model}", "{folder}/absent.uff"], "no such file"),
        (["compare", "no_such_module_xyz", "{data}"], "neither a .py file nor an importable module"),
        (["compare", "numpy:pi", "{data}"], "not a model"),
        (["identify", "{data}", "--band", "30", "2"], "band"),
    ],
)
def test_bad_arguments_give_one_line_and_exit_2(files, tmp_path, capsys, argv, words):
    fill = {"data": str(files / "chain.uff"), "model": str(files / "chain.py"), "folder": str(files)}
    argv = [a.format(**fill) for a in argv] + ["--out", str(tmp_path / "o")]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and words in err, err
