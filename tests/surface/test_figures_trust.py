"""Figures an engineer trusts: every channel or a stated selection, the band asked for, readable
log axes, layouts that fit a single input, heat maps grey within the noise, plain numbers.

Data: a 12-mass chain (one shaker at the tip, 12 accelerometers) written here with numpy/scipy,
measured by a long random-phase multisine computed exactly in the frequency domain, 1 % output
noise, H1 estimates (rc.estimate_frf).
"""

import matplotlib

matplotlib.use("Agg")

import numpy as np
import pytest
import scipy.linalg

import robustctl as rc

N = 12
K_UNIT = 2 * np.eye(N) - np.eye(N, k=1) - np.eye(N, k=-1)
K_UNIT[-1, -1] = 1.0
OUTPUTS = [f"a{k + 1}" for k in range(N)]
BAND = (1.5, 60.0)


def accelerance(f_hz, k=4e4, zeta=0.02):
    w2, phi = scipy.linalg.eigh(k * K_UNIT, np.eye(N))
    w = 2 * np.pi * np.asarray(f_hz)
    modal = 1.0 / (w2[None] - w[:, None] ** 2 + 2j * zeta * np.sqrt(w2)[None] * w[:, None])
    return -(w**2)[:, None] * np.einsum("ir,r,fr->fi", phi, phi[-1], modal)


def measure(k_true, seed=0, nperseg=1024, n_seg=16, fs=256.0, noise=0.01):
    rng = np.random.default_rng(seed)
    n = nperseg * n_seg
    f = np.arange(n // 2 + 1) * fs / n
    force = np.exp(2j * np.pi * rng.random(f.size))
    force[0], force[-1] = 0.0, 1.0
    H = accelerance(np.where(f > 0, f, 1.0), k=k_true)
    H[0] = 0.0
    u = np.fft.irfft(force, n)
    y = np.fft.irfft(H * force[:, None], n, axis=0)
    y = y + noise * y.std(axis=0) * rng.standard_normal(y.shape)
    return rc.estimate_frf(u, y, fs=fs, nperseg=nperseg, inputs=["F"], outputs=OUTPUTS)


@pytest.fixture(scope="module")
def model():
    params = [rc.Parameter("k", 4e4, "N/m", bounds=(2e4, 8e4))]
    labels = [f"{j + 1}:X" for j in range(N)]
    return rc.structural_model(
        np.eye(N), lambda th: th["k"] * K_UNIT, inputs={"F": labels[-1]},
        outputs={o: (lab, "acceleration") for o, lab in zip(OUTPUTS, labels)}, dof_labels=labels,
        damping=0.02, params=params, nodes={j + 1: (0.3 * j, 0.0, 0.0) for j in range(N)},
        lines=[(j + 1, j + 2) for j in range(N - 1)], name="12-mass chain")


@pytest.fixture(scope="module")
def shifted():
    return measure(k_true=0.95 * 4e4)


def panels(fig):
    return [ax for ax in fig.axes if "<-" in ax.get_title()]


def tick_labels(ax):
    """The labelled ticks of the frequency axis inside its limits, as drawn (locator + formatter)."""
    ax.figure.canvas.draw()
    lo, hi = ax.get_xlim()
    axis = ax.xaxis
    ticks = [(x, axis.get_major_formatter()(x)) for x in axis.get_majorticklocs()]
    ticks += [(x, axis.get_minor_formatter()(x)) for x in axis.get_minorticklocs()]
    return sorted((x, s) for x, s in ticks if s and lo <= x <= hi)


def test_plot_compare_draws_every_channel_in_the_band_with_readable_ticks(model, shifted):
    fig = rc.plot_compare(shifted, {"model": model}, band=BAND)
    axes = panels(fig)
    assert len(axes) == 12
    inside = shifted.f_hz[(shifted.f_hz >= BAND[0]) & (shifted.f_hz <= BAND[1])]
    for ax in axes:
        assert ax.get_xlim() == pytest.approx((inside[0], inside[-1]))
    labels = [s for _, s in tick_labels(axes[-1])]
    assert labels == ["2", "5", "10", "20", "50"]  # decade and sub-decade ticks over 1.5-60 Hz
    # a stated selection says so in the title; channels= picks by name
    fig9 = rc.plot_compare(shifted, {"model": model}, band=BAND, max_channels=9)
    assert len(panels(fig9)) == 9
    assert "9 of 12 channels shown: pass channels= for others" in fig9._suptitle.get_text()
    data_fig = shifted.plot(max_channels=9)  # every bode grid states what it leaves out
    assert "9 of 12 channels shown: pass max_channels= for others" in data_fig._suptitle.get_text()
    assert "12 of" not in (shifted.plot(max_channels=12)._suptitle or matplotlib.text.Text()).get_text()
    picked = rc.plot_compare(shifted, {"model": model}, channels=[("a3", "F"), ("a12", "F")])
    assert [ax.get_title() for ax in panels(picked)] == ["a3 <- F", "a12 <- F"]
    with pytest.raises(rc.DataError, match="not in the data"):
        rc.plot_compare(shifted, {"model": model}, channels=[("a13", "F")])


def drawn_tick_sizes(ax):
    """Font sizes of the frequency axis's drawn labels inside its limits (major and minor)."""
    ax.figure.canvas.draw()
    lo, hi = ax.get_xlim()
    labels = ax.get_xticklabels(which="both")
    return {t.get_fontsize() for t in labels if t.get_text() and lo <= t.get_position()[0] <= hi}


def test_decade_and_sub_decade_labels_are_one_size(model, shifted):
    cmp = rc.compare(model, shifted, band=BAND)
    for fig in (cmp.plot(), rc.plot_compare(shifted, {"model": model}, band=BAND)):
        ax = panels(fig)[-1]
        assert [s for _, s in tick_labels(ax)] == ["2", "5", "10", "20", "50"]
        assert len(drawn_tick_sizes(ax)) == 1  # "10" (a major tick) as large as "20" (a minor one)


def test_plot_compare_draws_the_model_as_the_estimator_sees_it(model):
    """On a null (the model is the truth) the H1 estimate's leakage halves the 2 %-damped 4 Hz peak;
    the figure draws the model as rc.compare compares it, and says so."""
    null = measure(k_true=4e4, seed=3)
    cmp = rc.compare(model, null, band=BAND)
    fig = rc.plot_compare(null, {"model": model}, band=BAND)
    view = "models seen through the H1 estimator: window leakage of 1024-pt hamming"
    assert view in fig._suptitle.get_text()
    for k, ax in enumerate(panels(fig)):
        drawn = ax.get_lines()[1].get_ydata()
        assert np.allclose(drawn, np.abs(cmp.model_response[:, k, 0]), rtol=1e-12, atol=0)
    seen, plain = fig.fit_percent["model"], rc.plot_compare(null, {"model": model}, band=BAND,
                                                           estimator=False).fit_percent["model"]
    assert seen.min() > 97.5 and plain.min() < 90  # measured: 98.0-98.6 % against 86-97 %


def test_single_input_compare_is_a_grid_not_a_column(model, shifted):
    cmp = rc.compare(model, shifted, band=BAND)
    fig = cmp.plot()
    axes = panels(fig)
    assert len(axes) == 12
    columns = {round(ax.get_position().x0, 3) for ax in axes}
    rows = {round(ax.get_position().y0, 3) for ax in axes}
    assert (len(columns), len(rows)) == (4, 3)
    width, height = fig.get_size_inches()
    assert 0.6 < width / height < 2.0
    for ax in axes:
        assert ax.get_xlim() == pytest.approx((cmp.f_hz[0], cmp.f_hz[-1]))


def test_heat_map_greys_cells_within_the_noise():
    data = measure(k_true=4e4, seed=3)  # a null: the model is the truth
    params = [rc.Parameter("k", 4e4, "N/m", bounds=(2e4, 8e4))]
    null_model = rc.structural_model(
        np.eye(N), lambda th: th["k"] * K_UNIT, inputs={"F": "dof 12"},
        outputs={o: (f"dof {j + 1}", "acceleration") for j, o in enumerate(OUTPUTS)}, damping=0.02,
        params=params)
    cmp = rc.compare(null_model, data, band=BAND)
    assert cmp.noise_test.within
    fig = cmp.plot_error_map()
    mask = cmp.within_noise_mask()
    assert mask.mean() > 0.9  # every tested section of every channel
    ax = fig.axes[0]
    coloured = [m for m in ax.collections if m.get_cmap().name == "magma"][0]
    assert np.array_equal(np.ma.getmaskarray(coloured.get_array()).reshape(mask.shape), mask)
    assert "grey: within the noise" in ax.get_title()


def test_update_plot_numbers_are_plain(model, shifted):
    upd = rc.update(model, shifted, band=BAND, progress=False)
    fig = upd.plot()
    ax = fig.axes[0]
    fig.canvas.draw()
    texts = [t.get_text() for t in ax.get_yticklabels() + ax.get_yticklabels(minor=True) if t.get_text()]
    assert texts and not any("times" in t or "^" in t or "$" in t for t in texts)
    assert upd.model.param("k").value == pytest.approx(0.95 * 4e4, rel=2e-3)


def test_mode_shape_figure_of_a_matrix_model(model):
    shapes = model.mode_shapes(n_modes=4)
    fig = rc.plot_mode_shapes(shapes, model.geometry())
    axes3d = [ax for ax in fig.axes if ax.name == "3d"]
    assert len(axes3d) == 4
    assert [ax.get_title() for ax in axes3d][0].startswith("mode 1: ")
