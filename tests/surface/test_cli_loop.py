"""The whole loop from the shell: load -> compare -> diagnose -> update -> design (-> report) on UFF files.

The truth is a three-mass chain written here with numpy/scipy (5 % stiffer springs and 0.15 kg on
the middle mass than the user's model); the measurement is a long random-phase multisine on the
third mass (one input: an impact-style one-input file against the two-input model), responses
computed exactly in the frequency domain, 1 % output noise, and an H1 estimate written as UFF.
"""

import json
import re

import numpy as np
import pytest
import scipy.linalg
import scipy.signal

import robustctl as rc
from robustctl.cli import main

K_UNIT = np.array([[2.0, -1.0, 0.0], [-1.0, 2.0, -1.0], [0.0, -1.0, 1.0]])
K_TRUE, ADDED_TRUE, ZETA = 4.2e4, 0.15, 0.02

MODEL_FILE = '''
import numpy as np
import robustctl as rc

K_UNIT = np.array([[2.0, -1.0, 0.0], [-1.0, 2.0, -1.0], [0.0, -1.0, 1.0]])


def model():
    params = [rc.Parameter("k", 4e4, "N/m", bounds=(2e4, 8e4), meaning="spring stiffness")]
    return rc.structural_model(
        np.eye(3), lambda th: th["k"] * K_UNIT, inputs={"F1": "x1", "F3": "x3"},
        outputs={"a1": ("x1", "acceleration"), "a2": ("x2", "acceleration"), "a3": ("x3", "acceleration")},
        dof_labels=["x1", "x2", "x3"], damping=0.02, params=params, name="chain")
'''


def truth_accelerance(f_hz):
    """Accelerance (m/s^2/N) of the true chain by modal superposition, (n_f, 3, 3)."""
    M, K = np.diag([1.0, 1.0 + ADDED_TRUE, 1.0]), K_TRUE * K_UNIT
    w2, phi = scipy.linalg.eigh(K, M)
    w = 2 * np.pi * np.asarray(f_hz)
    modal = 1.0 / (w2[None] - w[:, None] ** 2 + 2j * ZETA * np.sqrt(w2)[None] * w[:, None])
    return -(w**2)[:, None, None] * np.einsum("ir,jr,fr->fij", phi, phi, modal)


def measured_file(path, seed=0, nperseg=1024, n_seg=24, fs=128.0, noise=0.01):
    rng = np.random.default_rng(seed)
    n = nperseg * n_seg
    f = np.arange(n // 2 + 1) * fs / n
    force = np.exp(2j * np.pi * rng.random(f.size))
    force[0], force[-1] = 0.0, 1.0
    H = truth_accelerance(np.where(f > 0, f, 1.0))[:, :, 2]
    H[0] = 0.0
    u = np.fft.irfft(force, n)
    y = np.fft.irfft(H * force[:, None], n, axis=0)
    y = y + noise * y.std(axis=0) * rng.standard_normal(y.shape)
    data = rc.estimate_frf(u, y, fs=fs, nperseg=nperseg, inputs=["F3"], outputs=["a1", "a2", "a3"],
                           units={"F3": "N", "a1": "m/s^2", "a2": "m/s^2", "a3": "m/s^2"})
    data.save(path)
    return path


def run(capsys, *argv):
    assert main([str(a) for a in argv]) == 0
    return capsys.readouterr().out


def summary(folder):
    return json.loads((folder / "summary.json").read_text())


@pytest.mark.slow
def test_load_compare_diagnose_update_report_on_uff_files(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "chain.py").write_text(MODEL_FILE)
    uff = measured_file(tmp_path / "chain.uff")
    band = ("--band", 2, 40)

    out = run(capsys, "load", uff, "--out", tmp_path / "load")
    assert "3 outputs ['a1', 'a2', 'a3'] x 1 inputs ['F3']" in out and "with coherence" in out
    assert summary(tmp_path / "load")["inputs"] == ["F3"]

    out = run(capsys, "compare", "chain.py", uff, *band, "--modes", "auto", "--out", tmp_path / "cmp")
    assert "Model channels selected to match DATA: inputs ['F3']" in out  # model.select, not data.select
    assert "Beyond the noise in" in out
    cmp = summary(tmp_path / "cmp")
    assert cmp["noise"]["verdict"] == "beyond the noise" and cmp["noise"]["n_failing"] >= 1
    assert all(c["p_value"] < 0.01 / cmp["noise"]["n_cells"] for c in cmp["noise"]["failing"])
    assert sum(c["share_of_cost"] for c in cmp["channels"]) == pytest.approx(1.0, abs=1e-9)
    # the mode table takes the data's damping from the measurement model (truth: 2 %)
    measured = [m for m in cmp["modes"] if m["f_data_hz"] is not None]
    assert measured and all(m["zeta_data"] == pytest.approx(ZETA, rel=0.1) for m in measured)

    out = run(capsys, "diagnose", "chain.py", uff, *band, "--out", tmp_path / "diag")
    assert "Proposed: 0.15 kg of added mass at node x2" in out
    diag = summary(tmp_path / "diag")
    assert diag["verdict"] == "proposed: added mass at node x2"
    best = diag["best"]
    assert best["significant"] and best["p_value"] < 0.01
    assert best["values"]["added_mass__x2"] == pytest.approx(ADDED_TRUE, rel=0.03)
    # the error before and after the effect: the parameters alone leave the misfit, the effect removes it
    page = (tmp_path / "diag" / "report.html").read_text()
    before = re.search(r"Error with the parameters alone updated \(cost ([0-9.e+-]+)\)", page)
    after = re.search(r"Error with effect 1, added mass at node x2 = [^(]*\(cost ([0-9.e+-]+)\)", page)
    assert before and after, page[:2000]
    assert float(after.group(1)) < 0.05 * float(before.group(1))

    out = run(capsys, "update", "chain.py", uff, *band, "--diagnosis", tmp_path / "diag",
              "--out", tmp_path / "upd")
    assert "Effect added: added mass at node x2" in out
    assert "The misfit is within the noise in every channel and band" in out
    upd = summary(tmp_path / "upd")
    assert upd["effect"] == "added mass at node x2"
    params = {p["name"]: p for p in upd["parameters"]}
    for name, truth in (("k", K_TRUE), ("added_mass__x2", ADDED_TRUE), ("zeta_modal", ZETA)):
        p = params[name]
        assert p["std_error"] > 0
        assert abs(p["after"] - truth) < 5 * p["std_error"] + 1e-3 * truth, (name, p)
    assert params["k"]["change_pct"] == pytest.approx(5.0, abs=0.1)
    assert upd["noise_after"]["verdict"] == "within the noise"
    assert upd["compare_after"]["noise"]["verdict"] == "within the noise"
    assert upd["cost_after"] < 0.01 * upd["cost_before"]
    html = (tmp_path / "upd" / "report.html").read_text()
    assert "within the noise in every channel and band" in html

    # the design step on the model as the update left it (its effect and fitted values)
    out = run(capsys, "design", "chain.py", uff, "--update", tmp_path / "upd", "--inputs", "F3",
              "--outputs", "a3", "--band", 1, 40, "--perf-band", 2, 20, "--level", 0.05, "--fs", 256,
              "--max-iter", 1, "--d-order", 2, "--no-reduce", "--out", tmp_path / "des")
    after = {p["name"]: p["after"] for p in upd["parameters"]}
    assert "effect 'added mass at node x2' added" in out
    assert all(f"{name} = {value:.6g}" in out for name, value in after.items()), (after, out)
    des = summary(tmp_path / "des")
    assert f"mu: peak {des['mu_peak']:.4g}" in out and des["controller_states"] >= 1

    out = run(capsys, "report", tmp_path / "cmp", tmp_path / "diag", tmp_path / "upd",
              "--out", tmp_path / "all")
    assert "Joined 3 reports" in out
    page = (tmp_path / "all" / "report.html").read_text()
    order = [page.index(h) for h in ("Where the model fails", "Which physical effect", "updated model")]
    assert order == sorted(order)
    joined = summary(tmp_path / "all")
    assert joined["diag"]["best"]["name"] == "added mass at node x2" and joined["upd"] == upd


def test_channel_flags_and_bad_diagnosis(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "chain.py").write_text(MODEL_FILE)
    uff = measured_file(tmp_path / "chain.uff", n_seg=8)
    out = run(capsys, "compare", "chain.py", uff, "--outputs", "a3", "--band", 2, 40, "--out", tmp_path / "c")
    assert "outputs ['a3']" in out and "1x1 channels" in out
    assert [c["output"] for c in summary(tmp_path / "c")["channels"]] == ["a3"]
    assert main(["compare", "chain.py", str(uff), "--inputs", "F9"]) == 2
    assert "the data has no such inputs" in capsys.readouterr().err
    (tmp_path / "nothing").mkdir()
    (tmp_path / "nothing" / "summary.json").write_text(json.dumps({"verdict": "no candidate is significant",
                                                                     "best": None}))
    assert main(["update", "chain.py", str(uff), "--diagnosis", str(tmp_path / "nothing")]) == 2
    assert "proposed no effect (no candidate is significant)" in capsys.readouterr().err


def truth_statespace():
    """The true chain from F3 to a3 (accelerance): x = (q, dq), numpy, 2 % modal damping."""
    M, K = np.diag([1.0, 1.0 + ADDED_TRUE, 1.0]), K_TRUE * K_UNIT
    w2, phi = scipy.linalg.eigh(K, M)  # phi.T M phi = I
    Mp = M @ phi
    C_damp = Mp @ np.diag(2 * ZETA * np.sqrt(w2)) @ Mp.T
    Minv = np.linalg.inv(M)
    A = np.block([[np.zeros((3, 3)), np.eye(3)], [-Minv @ K, -Minv @ C_damp]])
    B = np.concatenate([np.zeros(3), Minv[:, 2]])[:, None]
    return A, B, A[5:6], B[5:6]


def test_design_from_an_update_to_an_exported_controller(tmp_path, capsys, monkeypatch):
    """robustctl design on the model as an update left it: mu printed and recorded, the written
    controller checked by numpy on the true chain (sampled loop stable, nominal performance <= mu)."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "chain.py").write_text(MODEL_FILE)
    uff = measured_file(tmp_path / "chain.uff", n_seg=8)
    (tmp_path / "upd").mkdir()
    params = [{"name": "k", "after": K_TRUE}, {"name": "added_mass__x2", "after": ADDED_TRUE}]
    (tmp_path / "upd" / "summary.json").write_text(
        json.dumps({"effect": "added mass at node x2", "parameters": params}))
    fs, perf_band, level = 256.0, (2.0, 20.0), 0.05
    out = run(capsys, "design", "chain.py", uff, "--update", tmp_path / "upd", "--inputs", "F3",
              "--outputs", "a3", "--band", 1, 40, "--perf-band", *perf_band, "--level", level, "--fs", fs,
              "--max-iter", 1, "--d-order", 2, "--no-reduce", "--out", tmp_path / "des")
    assert "effect 'added mass at node x2' added, k = 42000, added_mass__x2 = 0.15" in out
    rec = summary(tmp_path / "des")
    mu = rec["mu_peak"]
    assert f"mu: peak {mu:.4g}" in out and "D-K iteration: peak mu" in out
    certified = "robust performance certified (mu < 1)"
    assert rec["verdict"] == (certified if mu < 1 else "not certified (mu >= 1)")
    assert rec["mu_lower_peak"] <= mu * (1 + 1e-9) and rec["controller_inputs"] == ["a3"]
    assert rec["files"] == ["controller.json", "controller.h", "controller.mat"]
    K = json.loads((tmp_path / "des" / "controller.json").read_text())
    assert K["fs_hz"] == fs and K["inputs"] == ["a3"] and K["outputs"] == ["F3"]
    Ak, Bk, Ck, Dk = (np.atleast_2d(np.asarray(K[m], dtype=float)) for m in "ABCD")
    # the sampled loop: the truth held (ZOH) at fs with the file's controller, u = +K y
    A, B, C, D = truth_statespace()
    Ad, Bd, Cd, Dd, _ = scipy.signal.cont2discrete((A, B, C, D), 1 / fs, "zoh")
    g = 1.0 / (1.0 - (Dd @ Dk).item())
    top = np.hstack([Ad + g * Bd @ Dk @ Cd, g * Bd @ Ck])
    bottom = np.hstack([g * Bk @ Cd, Ak + g * Bk @ Dd @ Ck])
    assert np.abs(np.linalg.eigvals(np.vstack([top, bottom]))).max() < 1.0
    # Tustin maps s = jw to z = (2 fs + jw) / (2 fs - jw): the file gives the continuous K(jw) exactly
    f = np.geomspace(0.5, 100.0, 2000)
    s = 2j * np.pi * f
    z = (2 * fs + s) / (2 * fs - s)
    n = Ak.shape[0]
    k_c = np.array([(Ck @ np.linalg.solve(zz * np.eye(n) - Ak, Bk) + Dk).item() for zz in z])
    G = np.array([(C @ np.linalg.solve(ss * np.eye(6) - A, B) + D).item() for ss in s])
    w1, w2 = 2 * np.pi * np.asarray(perf_band)
    Wp = level * w2 * s / ((s + w1) * (s + w2))
    nominal = np.abs(Wp * G / (1.0 - G * k_c))  # input disturbance -> weighted sensor: a block of mu's matrix
    assert nominal.max() <= mu * (1 + 1e-3)
    assert nominal.max() > 0.5 * mu  # 0.62 mu measured: the performance block is most of mu


def test_design_refuses_bad_input_in_one_line(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "chain.py").write_text(MODEL_FILE)
    cases = [
        (["--perf-band", "5", "2"], "the performance band must be (low, high) in Hz with low < high"),
        (["--perf-band", "1", "5", "--level", "-1"], "level must be positive"),
        ([], "give --perf-band LO_HZ HI_HZ (or DATA, whose span is the default)"),
        (["--update", "nowhere"], "--update nowhere: cannot read nowhere"),
    ]
    for extra, message in cases:
        assert main(["design", "chain.py", "--fs", "200", *extra]) == 2
        err = capsys.readouterr().err
        assert err.startswith("robustctl design: ") and message in err and err.count("\n") == 1
    (tmp_path / "upd").mkdir()
    (tmp_path / "upd" / "summary.json").write_text(json.dumps({"parameters": [{"name": "q", "after": 1.0}]}))
    assert main(["design", "chain.py", "--fs", "200", "--perf-band", "1", "5", "--update", "upd"]) == 2
    assert "MODEL has no parameter q" in capsys.readouterr().err
