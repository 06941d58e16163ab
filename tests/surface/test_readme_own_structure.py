"""The README's "Your own structure" section, run verbatim on a test file from a numpy truth.

The truth is the README's tower with 3 % stiffer tubes, a 10 % lighter payload and a 0.25 kg
mass nobody modelled at node n21 (a cable clamp); its accelerances come from scipy's eigen-
solution of those matrices by modal superposition, the measurement is a long random-phase
multisine on the shaker with 1 % output noise, estimated as H1 and written as ``tower.uff``.
"""

import json
import re
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import numpy as np
import pytest
import scipy.linalg

import robustctl as rc

README = Path(__file__).resolve().parents[2] / "README.md"
E_TRUE, M_TOP_TRUE, CLAMP = 72.1e9, 0.9, 0.25


def readme_block() -> str:
    text = README.read_text()
    section = text.split("## Your own structure, from the model to the report", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"```python\n(.*?)```", section, flags=re.S)
    assert len(blocks) == 1
    return blocks[0]


def write_measurement(tower, path, seed=0, fs=512.0, nperseg=2048, n_seg=16, zeta=0.01, noise=0.01):
    sm = tower({"E": E_TRUE, "m_top": M_TOP_TRUE}).matrices()
    M, K = np.array(sm.mass, dtype=float), np.array(sm.stiffness, dtype=float)
    labels = list(sm.dof_labels)
    for axis in ("ux", "uy", "uz"):
        k = labels.index(f"n21 {axis}")
        M[k, k] += CLAMP
    w2, phi = scipy.linalg.eigh(K, M)
    at_sensors, at_force = np.asarray(sm.output_matrix) @ phi, phi.T @ np.asarray(sm.input_matrix)[:, 0]
    rng = np.random.default_rng(seed)
    n = nperseg * n_seg
    f = np.arange(n // 2 + 1) * fs / n
    w = 2 * np.pi * np.where(f > 0, f, 1.0)
    modal = 1.0 / (w2[None] - w[:, None] ** 2 + 2j * zeta * np.sqrt(w2)[None] * w[:, None])
    H = -(w**2)[:, None] * np.einsum("or,r,fr->fo", at_sensors, at_force, modal)
    force = np.exp(2j * np.pi * rng.random(f.size))
    force[0], force[-1] = 0.0, 1.0
    H[0] = 0.0
    u = np.fft.irfft(force, n)
    y = np.fft.irfft(H * force[:, None], n, axis=0)
    y = y + noise * y.std(axis=0) * rng.standard_normal(y.shape)
    rc.estimate_frf(u, y, fs=fs, nperseg=nperseg, inputs=["F"], outputs=list(sm.outputs)).save(path)


@pytest.mark.slow
def test_the_readme_section_runs_verbatim_and_finds_the_clamp(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    code = readme_block()
    definitions = {}
    exec(compile(code.split("\nmodel = rc.frame_model")[0], "README.md", "exec"), definitions)
    write_measurement(definitions["tower"], tmp_path / "tower.uff")

    ns = {}
    exec(compile(code, "README.md", "exec"), ns)
    out = capsys.readouterr().out
    assert ns["model"].param_names == ("E", "m_top", "zeta_modal")
    assert ns["geometry"].n_nodes == 12
    assert set(ns["geometry"].sensors) == {"a0x", "a0y", "a1x", "a1y", "a2x", "a2y"}
    assert (tmp_path / "tower_mode1.gif").stat().st_size > 1000
    assert "Beyond the noise in" in out  # the nominal model fails
    assert ns["diag"].best.name == "added mass at node n21"
    assert "Proposed: 0.25 kg of added mass at node n21" in out
    upd = ns["upd"]
    values = upd.model.values
    assert values["added_mass__n21"] == pytest.approx(CLAMP, rel=0.01)
    assert values["E"] == pytest.approx(E_TRUE, rel=0.005)
    assert values["m_top"] == pytest.approx(M_TOP_TRUE, rel=0.01)
    assert upd.noise_after.within, upd.summary()
    html = (tmp_path / "tower-report" / "report.html").read_text()
    assert "added mass at node n21" in html and html.count("<img") == 3
    summary = json.loads((tmp_path / "tower-report" / "summary.json").read_text())
    assert summary["diagnose"]["verdict"] == "proposed: added mass at node n21"
    assert summary["update"]["noise_after"]["verdict"] == "within the noise"
