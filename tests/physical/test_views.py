"""The modal engineer's figures, PhysicalModel.select/without/with_effect, units in files, short reprs."""

from __future__ import annotations

import numpy as np
import pytest

import robustctl as rc
from robustctl.correlate.comparison import statespace_modes
from robustctl.correlate.diagnosis import CandidateResult, Diagnosis
from robustctl.errors import DataError, ModelError
from robustctl.physical.effects import candidates


@pytest.fixture(scope="module")
def experiment():
    data, truth = rc.examples.caltech_truss_experiment(seed=0, n_samples=8192, nperseg=512)
    return data, truth, rc.examples.caltech_truss()


@pytest.fixture(scope="module")
def data22(experiment):
    data = experiment[0]
    return data.select(outputs=["S1", "S2"], inputs=["A1", "A2"]).replace(
        units={"S1": "m/s^2", "S2": "m/s^2", "A1": "V", "A2": "V"}
    )


def _stacks_ok(fig, f_hz):
    """Every axis log-x over the data's full range and y-labelled; returns the axes."""
    axes = [ax for ax in fig.axes if ax.get_label() != "<colorbar>"]
    for ax in axes:
        assert ax.get_xscale() == "log"
        assert ax.get_ylabel()
        lo, hi = ax.get_xlim()
        assert lo == pytest.approx(f_hz[0]) and hi == pytest.approx(f_hz[-1])
    return axes


# ---------------------------------------------------------------------------- FRF plot
def test_frf_plot_has_magnitude_phase_coherence_on_a_two_column_grid(data22):
    fig = data22.plot()
    axes = _stacks_ok(fig, data22.f_hz)
    assert len(axes) == 2 * 2 * 3  # 4 channels x (magnitude, phase, coherence)
    assert {ax.get_subplotspec().get_gridspec().ncols for ax in axes} == {2}
    titles = [ax.get_title() for ax in axes if ax.get_title()]
    assert titles == ["S1 <- A1", "S1 <- A2", "S2 <- A1", "S2 <- A2"]
    mag = next(ax for ax in axes if ax.get_title() == "S2 <- A1")
    assert mag.get_ylabel() == "|G| (m/s^2/V)"
    np.testing.assert_allclose(mag.lines[0].get_ydata(), np.abs(data22.response[:, 1, 0]))
    assert sorted({ax.get_ylabel() for ax in axes}) == ["coherence (-)", "phase (deg)", "|G| (m/s^2/V)"]
    assert sum(ax.get_xlabel() == "frequency (Hz)" for ax in axes) == 4  # bottom of every stack
    assert data22.f_hz[-1] == pytest.approx(100.0)  # the full range, not cut at 50 Hz


def test_frf_plot_of_a_3x3_system_without_coherence(experiment):
    data = experiment[0].replace(coherence=None)
    fig = data.plot()
    axes = _stacks_ok(fig, data.f_hz)
    assert len(axes) == 9 * 2
    assert {ax.get_subplotspec().get_gridspec().ncols for ax in axes} == {3}
    with pytest.raises(DataError, match="no coherence"):
        data.plot(coherence=True)


def test_bode_grid_without_units_says_so_and_three_siso_panels_use_one_row(experiment):
    data = experiment[0].select(inputs=["A3"])
    assert rc.plots.bode_grid([data]).axes[0].get_ylabel() == "|G| (V/V)"  # the example's volts
    fig = rc.plots.bode_grid([data.replace(units={})], ["d"])
    assert len(fig.axes) == 3
    assert {ax.get_subplotspec().get_gridspec().ncols for ax in fig.axes} == {3}  # a row, not a column
    assert fig.axes[0].get_ylabel() == "|G| (data units)"


# ---------------------------------------------------------------------------- singular values
def test_singular_values_match_the_matrix_two_norm(experiment):
    data, _, model = experiment
    fig = data.plot_sv()
    (ax,) = fig.axes
    assert ax.get_xscale() == "log" and ax.get_yscale() == "log" and ax.get_ylabel()
    assert len(ax.lines) == 3
    two_norm = np.array([np.linalg.norm(g, 2) for g in data.response])
    smallest = np.array([np.linalg.svd(g, compute_uv=False)[-1] for g in data.response])
    np.testing.assert_allclose(ax.lines[0].get_ydata(), two_norm, rtol=1e-12)
    np.testing.assert_allclose(ax.lines[2].get_ydata(), smallest, rtol=1e-10)
    fig2 = rc.plot_singular_values({"data": data, "model": model}, f_hz=data.f_hz)
    g_model = rc.freqresp(model, data.f_hz).response
    np.testing.assert_allclose(fig2.axes[0].lines[3].get_ydata(), np.linalg.norm(g_model, 2, axis=(1, 2)))
    with pytest.raises(DataError, match="needs f_hz"):
        rc.plot_singular_values(model)


# ---------------------------------------------------------------------------- compare with fit %
def test_fit_percent_analytic_values():
    f = np.array([1.0, 2.0, 3.0, 4.0])
    g = np.array([1.0, -1.0, 1.0, -1.0])  # mean 0, ||g - mean|| = 2
    data = rc.FrequencyData(f, g)
    assert rc.fit_percent(data, data)[0, 0] == pytest.approx(100.0)
    assert rc.fit_percent(data, data.replace(response=0.5 * g))[0, 0] == pytest.approx(50.0)
    assert rc.fit_percent(data, data.replace(response=np.zeros(4)))[0, 0] == pytest.approx(0.0)
    assert rc.fit_percent(data, data.replace(response=-g))[0, 0] == pytest.approx(-100.0)


def test_plot_compare_overlays_models_with_fit_and_phase(experiment, data22):
    _, truth, model = experiment
    # the plain FRF (estimator=False): fit % against rc.freqresp; the default view is tested in
    # tests/surface/test_figures_trust.py
    fig = rc.plot_compare(data22, {"nominal": model, "truth": truth}, phase=True, estimator=False)
    axes = _stacks_ok(fig, data22.f_hz)
    assert len(axes) == 4 * 2
    expected = rc.fit_percent(data22, rc.freqresp(model, data22.f_hz).select(["S1", "S2"], ["A1", "A2"]))
    np.testing.assert_allclose(fig.fit_percent["nominal"], expected)
    legend = [t.get_text() for t in axes[0].get_legend().get_texts()]
    assert legend[0] == "data"
    assert legend[1] == f"nominal (fit {expected[0, 0]:.0f}%)" and legend[2].startswith("truth (fit ")
    narrow = rc.plot_compare(data22, [model], band=(1.0, 10.0))
    assert narrow.axes[0].get_xlim() == pytest.approx(
        (data22.band(1.0, 10.0).f_hz[0], data22.band(1.0, 10.0).f_hz[-1])
    )


def test_comparison_plot_is_labelled_log_and_has_a_phase_option(experiment, data22):
    _, _, model = experiment
    cmp = rc.compare(model.select(inputs=["A1", "A2"], outputs=["S1", "S2"]), data22, band=(0.5, 50))
    fig = cmp.plot(phase=True)
    axes = [ax for ax in fig.axes if ax.get_label() != "<colorbar>"]
    assert len(axes) == 4 * 2 + 1 and len(fig.axes) == 4 * 2 + 2
    for ax in axes:
        assert ax.get_xscale() == "log" and ax.get_ylabel()
    assert axes[0].get_title() == "S1 <- A1"
    assert len(cmp.plot().axes) == 4 + 2


# ---------------------------------------------------------------------------- MAC
def test_mac_matrix_against_hand_values():
    np.testing.assert_allclose(rc.mac_matrix(np.eye(3)), np.eye(3))
    shapes = np.array([[1.0, 1.0], [0.0, 1.0]])  # columns (1, 0) and (1, 1)
    np.testing.assert_allclose(rc.mac_matrix(shapes), [[1.0, 0.5], [0.5, 1.0]])
    np.testing.assert_allclose(rc.mac_matrix(shapes, np.array([[0.0], [2j]])), [[0.0], [0.5]])
    with pytest.raises(DataError, match="different lengths"):
        rc.mac_matrix(np.eye(2), np.eye(3))


def test_automac_and_mac_plots_of_the_truss(experiment):
    _, truth, model = experiment
    modes = statespace_modes(model.statespace(), (0.1, 60.0))
    true_modes = statespace_modes(truth.statespace(), (0.1, 60.0))
    fig = rc.plot_mac(modes)
    ax, bar = fig.axes
    values = np.asarray(ax.images[0].get_array())
    np.testing.assert_allclose(np.diag(values), 1.0)
    np.testing.assert_allclose(values, values.T, atol=1e-12)
    assert ax.get_title() == "AutoMAC" and ax.get_xlabel() and ax.get_ylabel()
    assert type(bar.yaxis.get_minor_locator()).__name__ == "NullLocator"  # no overlapping minor labels
    cross = rc.plot_mac(modes, true_modes, labels=("nominal", "truth"))
    values = np.asarray(cross.axes[0].images[0].get_array())
    assert values.shape == (len(modes), len(true_modes))
    assert np.max(values, axis=1)[0] > 0.9  # the first mode is the same mode in both


def test_mode_shape_bars_at_the_sensors(experiment):
    _, _, model = experiment
    modes = statespace_modes(model.statespace(), (0.1, 10.0))
    fig = rc.plot_mode_shapes(model, band=(0.1, 10.0))
    assert len(fig.axes) == len(modes) > 0
    for ax, mode in zip(fig.axes, modes):
        heights = np.array([p.get_height() for p in ax.patches])
        assert np.max(np.abs(heights)) == pytest.approx(1.0)
        col = mode.residue[:, np.argmax(np.linalg.norm(mode.residue, axis=0))]
        assert np.argmax(np.abs(heights)) == np.argmax(np.abs(col))
        assert [t.get_text() for t in ax.get_xticklabels()] == ["S1", "S2", "S3"]
        assert ax.get_ylabel() and ax.get_xlabel() and "Hz" in ax.get_title()


def test_cost_table_and_chart_use_the_one_channel_label_style():
    from robustctl.cost import cost_report

    cost = cost_report(np.full((4, 2, 1), 0.1 + 0j), outputs=("S1", "S2"), inputs=("A1",))
    assert [row[0] for row in cost.table().rows] == ["S1 <- A1", "S2 <- A1", "total"]
    ax = cost.plot().axes[0]
    assert [t.get_text() for t in ax.get_xticklabels()] == ["S1 <- A1", "S2 <- A1"] and ax.get_xlabel()


def test_alignment_legend_names_only_the_colours_drawn():
    from robustctl.correlate.updating import _alignment_legend
    from robustctl.plots import new_figure

    ax = new_figure().subplots()
    _alignment_legend(ax, [True, True])
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["updated"]
    _alignment_legend(ax, [True, False])
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["updated", "not updated"]


# ---------------------------------------------------------------------------- PhysicalModel
def test_select_gives_the_columns_of_a_single_shaker_test(experiment):
    _, _, model = experiment
    f = np.array([0.7, 2.0, 13.0])
    full = model.freqresp(f).response
    one = model.select(inputs="A2")
    assert one.inputs == ("A2",) and one.outputs == ("S1", "S2", "S3")
    np.testing.assert_allclose(one.freqresp(f).response, full[:, :, [1]], rtol=1e-12)
    sub = model.select(inputs=["A3", "A1"], outputs=["S2"])
    np.testing.assert_allclose(sub.freqresp(f).response, full[:, [1]][:, :, [2, 0]], rtol=1e-12)
    with pytest.raises(ModelError, match=r"no inputs \['A9'\]; its inputs are \['A1', 'A2', 'A3'\]"):
        model.select(inputs=["A9"])
    with pytest.raises(ModelError, match="twice"):
        model.select(outputs=["S1", "S1"])


def test_without_refuses_a_typo_and_lists_the_known_tags():
    model = rc.examples.mace_beam()
    assert "suspension" in model.known_tags() and "gravity" in model.known_tags()
    with pytest.raises(ModelError, match=r"nothing tagged \['suspenion'\]; known tags: .*'suspension'"):
        model.without("suspenion")
    zero_g = model.without("suspension", "gravity")
    assert "suspension" in zero_g.excluded_tags
    assert zero_g.without("suspension").excluded_tags == zero_g.excluded_tags  # removing twice is fine


def test_with_effect_by_name_as_diagnose_prints_it(experiment):
    _, _, model = experiment
    cands = candidates(model, calibrate=False)
    effect = next(c for c in cands if c.kind == "added_mass")
    by_name = model.with_effect(effect.name)
    by_object = model.with_effect(effect)
    assert by_name.param_names == by_object.param_names != model.param_names
    f = np.array([1.0, 3.0])
    np.testing.assert_allclose(by_name.freqresp(f).response, by_object.freqresp(f).response)
    assert model.with_effect("  " + effect.name.upper() + " ").param_names == by_name.param_names
    row = CandidateResult(effect, 0.5, 45.0, False, 1.0, 0.0, 0.0)
    assert model.with_effect(row).param_names == by_name.param_names
    with pytest.raises(ModelError, match="close matches: .*'added mass at node platform_1'"):
        model.with_effect("added mas at node platform_1")
    with pytest.raises(ModelError, match="not the class AddedMass"):
        model.with_effect(rc.effects.AddedMass)
    with pytest.raises(ModelError, match="got int"):
        model.with_effect(3)


# ---------------------------------------------------------------------------- units
def _units_data():
    f = np.linspace(1.0, 20.0, 7)
    g = np.arange(14).reshape(7, 2, 1) * (1 + 0.5j) + 1
    return rc.FrequencyData(
        f,
        g,
        inputs=["F"],
        outputs=["acc", "volt"],
        coherence=np.full((7, 2, 1), 0.8),
        units={"F": "N", "acc": "m/s^2", "volt": "V"},
    )


@pytest.mark.parametrize("suffix", [".uff", ".npz"])
def test_units_round_trip_through_files(tmp_path, suffix):
    data = _units_data()
    back = rc.load_frd(data.save(tmp_path / f"d{suffix}"))
    assert back.units == {"F": "N", "acc": "m/s^2", "volt": "V"}
    np.testing.assert_allclose(back.response, data.response)
    bare = rc.load_frd(data.replace(units={}).save(tmp_path / f"bare{suffix}"))
    assert bare.units == {}


def test_uff_writes_ordinate_types_and_reads_a_foreign_type_code(tmp_path):
    import pyuff

    path = _units_data().save(tmp_path / "d.uff")
    rec = pyuff.UFF(str(path)).read_sets(0)
    assert (rec["ordinate_spec_data_type"], rec["orddenom_spec_data_type"]) == (12, 13)
    assert (
        rec["ordinate_axis_units_lab"],
        rec["orddenom_axis_units_lab"],
        rec["abscissa_axis_units_lab"],
    ) == ("m/s^2", "N", "Hz")
    foreign = tmp_path / "foreign.uff"
    f = np.linspace(1.0, 5.0, 5)
    record = pyuff.prepare_58(
        binary=0,
        id1="other tool",
        func_type=4,
        rsp_node=3,
        rsp_dir=1,
        ref_node=1,
        ref_dir=1,
        data=np.ones(5, complex),
        x=f,
        abscissa_spacing=0,
        abscissa_spec_data_type=18,
        ordinate_spec_data_type=8,
        orddenom_spec_data_type=13,
    )
    pyuff.UFF(str(foreign)).write_sets([record], mode="add")
    assert rc.load_frd(foreign).units == {"3:1": "m", "1:1": "N"}


def test_uff_refuses_a_unit_too_long_for_its_label(tmp_path):
    data = _units_data().replace(units={"F": "newton (calibrated 2024)"})
    with pytest.raises(DataError, match="do not fit a UFF axis label"):
        data.save(tmp_path / "long.uff")


def test_estimate_frf_carries_units():
    import control

    sys = control.ss([[0, 1], [-((2 * np.pi * 5) ** 2), -3.0]], [[0], [1]], [[1, 0]], [[0]])
    u, y = rc.simulate_experiment(sys, n_samples=4096)
    data = rc.estimate_frf(
        u, y, fs=200.0, nperseg=512, inputs=["F"], outputs=["x"], units={"F": "N", "x": "m"}
    )
    assert data.units == {"F": "N", "x": "m"}
    assert data.plot().axes[0].get_ylabel() == "|G| (m/N)"
    with pytest.raises(DataError, match=r"signals \['Q'\]"):
        rc.estimate_frf(u, y, fs=200.0, nperseg=512, units={"Q": "N"})


# ---------------------------------------------------------------------------- reprs
def test_short_reprs_and_html(experiment):
    data, _, model = experiment
    assert len(repr(data)) < 200 and "<table>" in data._repr_html_()
    html = data.replace(units={"S1": "m/s^2"})._repr_html_()
    assert "S1: m/s^2" in html and "A1, A2, A3" in html
    assert len(repr(model)) < 200
    html = model._repr_html_()
    assert "Caltech truss" in html and "outputs S1, S2, S3" in html and len(html) < 2000


def test_diagnosis_repr_is_a_few_lines(experiment):
    _, _, model = experiment
    ranking = tuple(
        CandidateResult(c, 0.1, 80.0, False, 1.0, 0.0, 0.0, where="everywhere" * 10, sentence="s" * 200)
        for c in candidates(model, calibrate=False)
    )
    assert len(ranking) > 100
    diag = Diagnosis(
        ranking=ranking,
        best=ranking[0].effect,
        cost_nominal=2.0,
        cost_update=1.0,
        update_params=("E",),
        update_values={"E": 1.0},
        n=100,
        n_eff=50.0,
        rho=0.1,
        alpha=0.01,
        unexplained="x",
        band=None,
        n_evals=1,
        time_s=0.1,
    )
    text = repr(diag)
    assert len(text) < 300 and text.count("\n") <= 2
    assert f"{len(ranking)} candidates" in text and ranking[0].effect.name in text
    legend = diag.plot().axes[0].get_legend()
    assert [t.get_text() for t in legend.get_texts()] == ["screening only"]  # every bar drawn is grey


def test_annotated_matrix_writes_each_value_in_a_contrasting_colour_up_to_its_cell_limit():
    from robustctl.plots import annotated_matrix, new_figure

    values = np.array([[1.0, 0.25, 0.0], [0.25, 1.0, 0.61]])
    ax = new_figure().subplots()
    im = annotated_matrix(ax, values, ["a", "b"], ["x", "y", "z"], fmt=".2f", max_cells=6)
    assert np.array_equal(im.get_array(), values) and im.get_clim() == (0.0, 1.0)
    texts = {(t.get_position(), t.get_text()): t.get_color() for t in ax.texts}
    assert texts[((1, 0), "0.25")] == "w" and texts[((2, 1), "0.61")] == "k" and len(texts) == 6
    assert [t.get_text() for t in ax.get_xticklabels()] == ["x", "y", "z"]
    ax2 = new_figure().subplots()
    annotated_matrix(ax2, values, ["a", "b"], ["x", "y", "z"], max_cells=5)
    assert not ax2.texts  # too many cells: colours only
