"""FrequencyData files: npz, mat, csv and UFF dataset 58 round trips; corrupt files; no pickles."""

from __future__ import annotations

import json
import os
import pickle
import tempfile
import zipfile
from pathlib import Path

import control
import numpy as np
import pytest
import pyuff
from hypothesis import given, settings
from hypothesis import strategies as st

import robustctl as rc
from robustctl.errors import DataError

ALPHABET = st.characters(codec="utf-8", exclude_categories=("Cc", "Cs", "Zl", "Zp"))
FINITE = st.floats(-1e300, 1e300, allow_nan=False, allow_infinity=False)


def _names(prefix_free: bool):
    text = st.text(ALPHABET, min_size=1, max_size=12)
    if prefix_free:  # UFF ID lines are stripped
        text = text.map(str.strip).filter(lambda s: bool(s) and s.isprintable())
    return text


@st.composite
def frequency_data(draw, uff: bool = False):
    n_f = draw(st.integers(2 if uff else 1, 6))
    n_o = draw(st.integers(1, 3))
    n_i = draw(st.integers(1, 3))
    f = np.sort(np.array(draw(st.lists(st.floats(1e-6, 1e6), min_size=n_f, max_size=n_f, unique=True))))
    if np.any(np.diff(f) <= 0):
        f = np.arange(1, n_f + 1, dtype=float)
    values = draw(st.lists(FINITE, min_size=2 * n_f * n_o * n_i, max_size=2 * n_f * n_o * n_i))
    g = np.array(values[::2]) + 1j * np.array(values[1::2])
    outs = draw(st.lists(_names(uff), min_size=n_o, max_size=n_o, unique=True))
    ins = draw(st.lists(_names(uff), min_size=n_i, max_size=n_i, unique=True))
    coh = None
    if draw(st.booleans()):
        coh = np.array(draw(st.lists(st.floats(0, 1), min_size=g.size, max_size=g.size)))
        coh = coh.reshape(n_f, n_o, n_i)
    units = {outs[0]: "m/s^2"} if draw(st.booleans()) else None
    experiment = None
    if draw(st.booleans()):
        experiment = rc.Experiment(
            input_kind=draw(st.sampled_from([None, "measured", "held"])),
            excitation=draw(st.sampled_from([None, "random", "periodic", "burst", "impact", "stepped_sine"])),
            fs_hz=draw(st.one_of(st.none(), st.floats(2.0 * float(f[-1]), 4.0e6))),  # Nyquist above the data
            window=draw(st.sampled_from([None, "hamming", ("tukey", 0.25)])),
            nperseg=draw(st.one_of(st.none(), st.integers(2, 2**20))),
            n_averages=draw(st.one_of(st.none(), st.integers(1, 1000))),
            hold_divided=draw(st.booleans()),
        )
    return rc.FrequencyData(f, g.reshape(n_f, n_o, n_i), inputs=ins, outputs=outs, coherence=coh,
                            units=units, meta={"source": "hypothesis", "n": n_f, "x": [1.5, None]},
                            experiment=experiment)


def _round_trip(data: rc.FrequencyData, suffix: str) -> rc.FrequencyData:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"data{suffix}"
        assert data.save(path) == path
        loaded = rc.load_frd(path)
        sidecar = [path.name + ".json"] if suffix in (".uff", ".unv") else []  # experiment and meta
        assert sorted(os.listdir(tmp)) == [path.name] + sidecar  # no temporary files left behind
    return loaded


def _check(loaded, data, exact: bool, keeps_meta: bool):
    assert loaded.inputs == data.inputs and loaded.outputs == data.outputs
    np.testing.assert_array_equal(loaded.f_hz, data.f_hz)
    if exact:
        np.testing.assert_array_equal(loaded.response, data.response)
    else:
        np.testing.assert_allclose(loaded.response, data.response, rtol=1e-12, atol=0)
    if data.coherence is None:
        assert loaded.coherence is None
    else:
        np.testing.assert_allclose(loaded.coherence, data.coherence, rtol=1e-12, atol=0)
    if keeps_meta:
        assert loaded.units == data.units and loaded.meta == data.meta
    assert loaded.experiment == data.experiment  # every format keeps how the data were made


@settings(max_examples=12, deadline=None)
@given(data=frequency_data())
def test_npz_round_trip_exact(data):
    _check(_round_trip(data, ".npz"), data, exact=True, keeps_meta=True)


@settings(max_examples=12, deadline=None)
@given(data=frequency_data())
def test_mat_round_trip_exact(data):
    _check(_round_trip(data, ".mat"), data, exact=True, keeps_meta=True)


@settings(max_examples=12, deadline=None)
@given(data=frequency_data())
def test_csv_round_trip(data):
    _check(_round_trip(data, ".csv"), data, exact=False, keeps_meta=True)


@settings(max_examples=8, deadline=None)
@given(data=frequency_data(uff=True), suffix=st.sampled_from([".uff", ".unv"]))
def test_uff_round_trip(data, suffix):
    loaded = _round_trip(data, suffix)
    _check(loaded, data, exact=False, keeps_meta=True)
    assert loaded.units == data.units  # ordinate (output) and denominator (input) unit labels


def test_csv_layout_and_mat_matlab_layout(tmp_path):
    data = rc.FrequencyData([1.0, 2.5], np.arange(4.0).reshape(2, 2, 1) + 0.5j, outputs=["a", "b"],
                            inputs=["F"], coherence=np.full((2, 2, 1), 0.25))
    data.save(tmp_path / "d.csv")
    lines = (tmp_path / "d.csv").read_text().splitlines()
    assert lines[0] == "# robustctl.FrequencyData csv: 2 frequencies x 2 outputs x 1 inputs = 4 rows"
    assert lines[1] == "f_hz,output,input,re,im,coherence"
    assert lines[2:4] == ["1.0,a,F,0.0,0.5,0.25", "1.0,b,F,1.0,0.5,0.25"]
    assert lines[-1] == "# end, 4 rows" and len(lines) == 7
    from scipy.io import loadmat

    data.save(tmp_path / "d.mat")
    m = loadmat(tmp_path / "d.mat")
    assert m["ResponseData"].shape == (2, 1, 2)  # n_out x n_in x n_freq, as MATLAB's frd
    assert str(m["FrequencyUnit"][0]) == "Hz"
    np.testing.assert_array_equal(m["ResponseData"][1, 0, :], data.response[:, 1, 0])


def test_mat_from_matlab_style_file(tmp_path):
    from scipy.io import savemat

    g = np.array([1 + 1j, 2 - 1j, 3.0])
    savemat(tmp_path / "m.mat", {"Frequency": np.array([[1.0], [2.0], [3.0]]) * 2 * np.pi,
                                 "ResponseData": g.reshape(1, 1, 3)})
    data = rc.load_frd(tmp_path / "m.mat")  # no FrequencyUnit: MATLAB's default rad/s
    np.testing.assert_allclose(data.f_hz, [1.0, 2.0, 3.0], rtol=1e-15)
    np.testing.assert_array_equal(data.response[:, 0, 0], g)


def test_third_party_uff_names_from_nodes(tmp_path):
    path = tmp_path / "shaker.uff"
    f = np.linspace(1.0, 10.0, 10)
    sets = [
        pyuff.prepare_58(binary=0, id1="Point 12 response", func_type=4, rsp_node=node, rsp_dir=3,
                         ref_node=1, ref_dir=-3, data=(node + 1j) * np.ones(10), x=f, abscissa_spacing=0,
                         abscissa_spec_data_type=18, ordinate_spec_data_type=0, orddenom_spec_data_type=0,
                         z_axis_spec_data_type=0)
        for node in (12, 13)
    ]
    pyuff.UFF(str(path)).write_sets(sets, mode="add")
    data = rc.load_frd(path)
    assert data.outputs == ("12:3", "13:3") and data.inputs == ("1:-3",)
    np.testing.assert_allclose(data.response[:, 1, 0], 13 + 1j, rtol=1e-10)
    np.testing.assert_allclose(data.f_hz, f, rtol=1e-5)  # ASCII abscissa has 6 digits


# ------------------------------------------------------------------ refusals
@pytest.fixture
def small():
    return rc.FrequencyData([1.0, 2.0, 3.0], np.ones((3, 1, 2)), inputs=["a", "b"], outputs=["y"])


def test_unknown_extension_and_missing_files(small, tmp_path):
    supported = r"unknown file extension '.txt'.*supported: .npz, .mat, .csv, .uff, .unv"
    with pytest.raises(DataError, match=supported):
        small.save(tmp_path / "d.txt")
    with pytest.raises(DataError, match="unknown file extension ''"):
        rc.load_frd(tmp_path / "noext")
    with pytest.raises(DataError, match="no such file"):
        rc.load_frd(tmp_path / "missing.npz")
    with pytest.raises(DataError, match="directory .* does not exist"):
        small.save(tmp_path / "nodir" / "d.npz")
    with pytest.raises(DataError, match="path must be a file name"):
        rc.load_frd(3.5)


@pytest.mark.parametrize("suffix", [".npz", ".mat", ".csv", ".uff"])
def test_never_overwrites_unless_asked(small, tmp_path, suffix):
    path = tmp_path / f"precious{suffix}"
    path.write_bytes(b"the user's own file")
    with pytest.raises(DataError, match="already exists; pass overwrite=True"):
        small.save(path)
    assert path.read_bytes() == b"the user's own file"
    small.save(path, overwrite=True)
    np.testing.assert_array_equal(rc.load_frd(path).response, small.response)
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]  # no sidecar: nothing to keep


class _Marker:
    """Unpickling this creates a file: proof that pickled content was executed."""

    def __init__(self, path):
        self.path = path

    def __reduce__(self):
        return (open, (self.path, "w"))


def test_npz_with_pickled_objects_is_refused_not_executed(tmp_path):
    marker = tmp_path / "executed"
    evil = np.empty(1, dtype=object)
    evil[0] = _Marker(str(marker))
    path = tmp_path / "evil.npz"
    np.savez(path, format=np.array("robustctl.FrequencyData"), f_hz=evil, response=np.ones(1))
    with pytest.raises(DataError, match="pickled Python objects.*never loads"):
        rc.load_frd(path)
    assert not marker.exists()
    pickle.dumps(evil)  # the payload is a real pickle (sanity)


def _npz(path, **arrays):
    base = {"format": np.array("robustctl.FrequencyData"), "f_hz": np.array([1.0, 2.0]),
            "response": np.ones((2, 1, 1), complex), "inputs": np.array(["u"]), "outputs": np.array(["y"]),
            "units_json": np.array("{}"), "meta_json": np.array("{}")}
    base.update(arrays)
    np.savez(path, **{k: v for k, v in base.items() if v is not None})
    return path


def test_corrupt_or_mismatched_npz(tmp_path):
    with pytest.raises(DataError, match="bad.npz: not a readable npz file"):
        (tmp_path / "bad.npz").write_bytes(b"PK\x03\x04 this is not a zip archive")
        rc.load_frd(tmp_path / "bad.npz")
    with pytest.raises(DataError, match="has no 'response' array"):
        rc.load_frd(_npz(tmp_path / "a.npz", response=None))
    with pytest.raises(DataError, match="response has 3 frequency points but f_hz has 2"):
        rc.load_frd(_npz(tmp_path / "b.npz", response=np.ones((3, 1, 1))))
    with pytest.raises(DataError, match="outputs has 2 names"):
        rc.load_frd(_npz(tmp_path / "c.npz", outputs=np.array(["y1", "y2"])))
    with pytest.raises(DataError, match="is a 'something else'"):
        rc.load_frd(_npz(tmp_path / "d.npz", format=np.array("something else")))
    with pytest.raises(DataError, match="NaN or inf"):
        rc.load_frd(_npz(tmp_path / "e.npz", response=np.full((2, 1, 1), np.nan)))
    with pytest.raises(DataError, match="strictly increasing"):
        rc.load_frd(_npz(tmp_path / "f.npz", f_hz=np.array([2.0, 1.0])))
    with pytest.raises(DataError, match="meta is not valid JSON"):
        rc.load_frd(_npz(tmp_path / "g.npz", meta_json=np.array("{oops")))
    np.save(tmp_path / "single.npy", np.ones(3))
    os.replace(tmp_path / "single.npy", tmp_path / "single.npz")
    with pytest.raises(DataError, match="single array"):
        rc.load_frd(tmp_path / "single.npz")
    good = tmp_path / "good.npz"
    rc.FrequencyData([1.0, 2.0], np.ones(2)).save(good)
    raw = good.read_bytes()
    (tmp_path / "cut.npz").write_bytes(raw[: len(raw) // 2])
    with pytest.raises(DataError, match="cut.npz"):
        rc.load_frd(tmp_path / "cut.npz")
    assert zipfile.is_zipfile(good)


def test_corrupt_or_mismatched_mat(tmp_path):
    from scipy.io import savemat

    (tmp_path / "bad.mat").write_bytes(b"MATLAB 5.0 MAT-file, garbage" + bytes(200))
    with pytest.raises(DataError, match="not a readable MAT file"):
        rc.load_frd(tmp_path / "bad.mat")
    savemat(tmp_path / "a.mat", {"Frequency": [1.0, 2.0]})
    with pytest.raises(DataError, match="no 'ResponseData' variable"):
        rc.load_frd(tmp_path / "a.mat")
    savemat(tmp_path / "b.mat", {"Frequency": [1.0, 2.0], "FrequencyUnit": "Hz",
                                 "ResponseData": np.ones((1, 1, 3))})
    with pytest.raises(DataError, match=r"ResponseData has shape \(1, 1, 3\) but .* need \(1, 1, 2\)"):
        rc.load_frd(tmp_path / "b.mat")
    savemat(tmp_path / "c.mat", {"Frequency": [1.0, 2.0], "FrequencyUnit": "kHz", "ResponseData": np.ones(2)})
    with pytest.raises(DataError, match="FrequencyUnit 'khz' is not supported"):
        rc.load_frd(tmp_path / "c.mat")


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "the CSV file is empty"),
        ("freq,out,in,re,im\n1,y,u,1,0\n", "the CSV header is"),
        ("f_hz,output,input,re,im\n", "no data rows"),
        ("f_hz,output,input,re,im\n1,y,u,1\n", "line 2 has 4 fields; the header has 5"),
        ("f_hz,output,input,re,im\n1,y,u,1,zero\n", "line 2: im 'zero' is not a number"),
        ("f_hz,output,input,re,im\n1,y,u,1,0\n1,y,u,2,0\n", "line 3 repeats f_hz=1"),
        ("f_hz,output,input,re,im\n1,y,u,1,0\n1,y,v,1,0\n2,y,u,1,0\n",
         r"1 entries are missing.*f_hz=2.0.*'v'"),
        ("f_hz,output,input,re,im\n2,y,u,1,0\n1,y,u,1,0\n", "strictly increasing"),
        ("f_hz,output,input,re,im,coherence\n1,y,u,1,0,1.5\n",
         r"coherence must be finite and lie in \[0, 1\]"),
    ],
)
def test_corrupt_csv(tmp_path, text, message):
    path = tmp_path / "d.csv"
    path.write_text(text)
    with pytest.raises(DataError, match=message):
        rc.load_frd(path)


def _small_csv(tmp_path):
    data = rc.FrequencyData([1.0, 2.0, 4.0], np.arange(12.0).reshape(3, 2, 2) - 1j, outputs=["a", "b"],
                            inputs=["F", "G"], coherence=np.full((3, 2, 2), 0.5))
    return data, data.save(tmp_path / "d.csv").read_text().splitlines(keepends=True)


def test_csv_cut_at_every_line_boundary_is_refused_as_truncated(tmp_path):
    """A CSV cut exactly between two frequency blocks loaded as fewer frequencies."""
    data, lines = _small_csv(tmp_path)
    assert len(lines) == 3 * 4 + 3  # preamble, column header, 12 rows, end marker
    loaded = rc.load_frd(tmp_path / "d.csv")
    np.testing.assert_array_equal(loaded.response, data.response)
    np.testing.assert_array_equal(loaded.coherence, data.coherence)
    for cut in range(len(lines)):
        (tmp_path / "t.csv").write_text("".join(lines[:cut]))
        expected = "empty" if cut == 0 else "truncated"
        with pytest.raises(DataError, match=expected):
            rc.load_frd(tmp_path / "t.csv")
    # between frequency blocks (rows 2-5 are frequency 1.0): whole rows, only the marker tells
    (tmp_path / "t.csv").write_text("".join(lines[:6]))
    with pytest.raises(DataError, match=r"announces 12 data rows \(3 frequencies\) but it ends after 4 rows"):
        rc.load_frd(tmp_path / "t.csv")


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda ls: ls[:6] + ls[-1:], r"says 12 data rows but it holds 4"),
        (lambda ls: ls[1:6] + ls[-1:], r"'# end' line says 12 data rows but it holds 4"),
        (lambda ls: [ls[0].replace("= 12", "= 13")] + ls[1:],
         r"first line says 13 data rows but it holds 12"),
        (lambda ls: [ls[0].replace("3 freq", "4 freq")] + ls[1:], r"holds 3 frequencies .* announces 4"),
        (lambda ls: [ls[0].replace("robustctl", "robustctI")] + ls[1:], "not robustctl's CSV preamble"),
        (lambda ls: ls[:-1] + ["# end, twelve rows\n"], "damaged '# end, N rows' marker"),
        (lambda ls: ls[1:9], r"1 entries are missing, e.g. f_hz=2.0, output 'b', input 'G'"),
    ],
)
def test_csv_markers_are_checked(tmp_path, edit, message):
    _, lines = _small_csv(tmp_path)
    (tmp_path / "m.csv").write_text("".join(edit(lines)))
    with pytest.raises(DataError, match=message):
        rc.load_frd(tmp_path / "m.csv")


def test_csv_without_markers_still_loads(tmp_path):
    """Older files and a user's own CSV (no preamble, no end line, CRLF line ends) are read,
    with the checks they had: increasing frequencies, every pair at every frequency."""
    data, lines = _small_csv(tmp_path)
    rows = lines[2:-1]
    body = lines[1] + "".join(rows[4:] + rows[:4])  # whole blocks; frequency 1.0 last
    (tmp_path / "u.csv").write_bytes(body.replace("\n", "\r\n").encode())
    with pytest.raises(DataError, match="strictly increasing"):  # as before the markers
        rc.load_frd(tmp_path / "u.csv")
    (tmp_path / "u.csv").write_bytes((lines[1] + "".join(rows)).replace("\n", "\r\n").encode())
    loaded = rc.load_frd(tmp_path / "u.csv")
    np.testing.assert_array_equal(loaded.response, data.response)
    np.testing.assert_array_equal(loaded.coherence, data.coherence)
    assert loaded.outputs == ("a", "b") and loaded.inputs == ("F", "G")


def _frf58(rsp_node, ref_node, f):
    return pyuff.prepare_58(
        binary=1, func_type=4, rsp_node=rsp_node, rsp_dir=1, ref_node=ref_node, ref_dir=1, id1="x",
        data=np.ones(f.size) + 0j, x=f, abscissa_spacing=0, abscissa_spec_data_type=18,
        ordinate_spec_data_type=0, orddenom_spec_data_type=0, z_axis_spec_data_type=0,
    )


def test_corrupt_or_mismatched_uff(tmp_path, small):
    (tmp_path / "bad.uff").write_text("    -1\n    58\ngarbage\n    -1\n")
    with pytest.raises(DataError, match="bad.uff: not a readable universal file"):
        rc.load_frd(tmp_path / "bad.uff")
    path = tmp_path / "two_grids.uff"
    sets = [_frf58(1 + (n == 5), 1, np.arange(1.0, n + 1)) for n in (4, 5)]
    pyuff.UFF(str(path)).write_sets(sets, mode="add")
    with pytest.raises(DataError, match="different frequency axis"):
        rc.load_frd(path)
    path = tmp_path / "missing_pair.uff"
    sets = [_frf58(o, i, np.arange(1.0, 4.0)) for o, i in ((1, 1), (2, 1), (1, 2))]
    pyuff.UFF(str(path)).write_sets(sets, mode="add")
    with pytest.raises(DataError, match="no FRF record for output '2:1', input '2:1'"):
        rc.load_frd(path)
    with pytest.raises(DataError, match="cannot be stored in UFF ID lines"):
        small.replace(outputs=[" padded"]).save(tmp_path / "names.uff")
    with pytest.raises(DataError, match="at least 2 frequencies"):
        small.band(1.0, 1.5).save(tmp_path / "one.uff")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.uff", "missing_pair.uff", "two_grids.uff"]


def test_files_written_before_the_experiment_description_load_as_not_described(tmp_path):
    """An npz archive and a MAT file without the experiment fields (as robustctl wrote them before)
    load with every field unknown, their meta kept; a described file keeps its description."""
    from scipy.io import savemat

    f = np.array([1.0, 2.0, 3.0])
    g = np.array([1.0 + 1j, 0.5 - 1j, 0.2 + 0.1j])[:, None, None]
    meta = {"fs_hz": 200.0, "nperseg": 1024, "window": "hamming"}  # settings alone do not describe
    np.savez(tmp_path / "old.npz", format=np.array("robustctl.FrequencyData"), version=np.array(1), f_hz=f,
             response=g, inputs=np.array(["u1"]), outputs=np.array(["y1"]), units_json=np.array("{}"),
             meta_json=np.array(json.dumps(meta)))
    savemat(tmp_path / "old.mat", {"Frequency": f[:, None], "FrequencyUnit": "Hz",
                                   "ResponseData": np.transpose(g, (1, 2, 0)),
                                   "robustctl_meta": json.dumps(meta)})
    for name in ("old.npz", "old.mat"):
        old = rc.load_frd(tmp_path / name)
        assert old.experiment == rc.Experiment() and old.meta == meta
        one_pole = control.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]])
        assert rc.compare(one_pole, old).estimator_note == rc.frd.PLAIN_NOTE
    described = rc.FrequencyData(f, g, experiment=rc.Experiment(input_kind="measured", excitation="impact",
                                                                 fs_hz=256.0, n_averages=5))
    for ext in ("npz", "mat", "csv", "uff"):
        assert rc.load_frd(described.save(tmp_path / f"new.{ext}")).experiment == described.experiment


def test_a_matlab_file_describes_its_experiment_in_plain_variables(tmp_path):
    """A MATLAB user writes InputKind, Excitation, SampleRate, Window, NPerSeg beside frd's
    Frequency and ResponseData; robustctl writes them too, beside its complete JSON record."""
    from scipy.io import loadmat, savemat

    f = np.array([1.0, 2.0, 3.0])
    g = np.array([1.0 + 1j, 0.5 - 1j, 0.2 + 0.1j])[:, None, None]
    savemat(tmp_path / "user.mat", {"Frequency": f[:, None], "FrequencyUnit": "Hz",
                                    "ResponseData": np.transpose(g, (1, 2, 0)), "InputKind": "measured",
                                    "Excitation": "random", "SampleRate": 200.0, "Window": "hamming",
                                    "NPerSeg": 512.0})
    assert rc.load_frd(tmp_path / "user.mat").experiment == rc.Experiment(
        "measured", "random", fs=200.0, window="hamming", nperseg=512)
    described = rc.Experiment("held", "periodic", fs=100.0, whole_periods=True)
    plain = loadmat(rc.FrequencyData(f, g, experiment=described).save(tmp_path / "ours.mat"))
    assert plain["InputKind"][0] == "held" and plain["SampleRate"][0, 0] == 100.0
    assert plain["WholePeriods"][0, 0] == 1
