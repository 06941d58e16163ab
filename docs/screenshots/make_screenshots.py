"""Render the figures of issue 35 for a 12-channel case to PNG files beside this script.

Run from the repository root::

    python docs/screenshots/make_screenshots.py [FOLDER]

The case: a taut string of 12 masses (0.3 m apart, transverse motion), one shaker at the tip
and 12 accelerometers, written here with numpy/scipy; the "measured" structure is 5 % softer
than the model (every mode 2.5 % low), measured by a long random-phase multisine computed
exactly in the frequency domain, 1 % output noise, H1 estimates (``rc.estimate_frf``); a second
record of the model's own structure is the null (the model is the truth). Files written:

* ``compare.png`` -- ``rc.plot_compare`` over the band asked for (1.5-60 Hz), every channel;
* ``compare_selection.png`` -- the same with ``max_channels=9`` (the title states the selection);
* ``compare_result.png`` -- ``rc.compare(...).plot()``: panels and the error heat map;
* ``error_map_nominal.png`` / ``error_map_null.png`` -- the error heat map of the shifted data
  and of the null (cells within the noise grey);
* ``mode_shapes.png`` -- ``rc.plot_mode_shapes`` of the model's first four modes on its geometry.
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402
import scipy.linalg  # noqa: E402

import robustctl as rc  # noqa: E402

N = 12
K_UNIT = 2 * np.eye(N) - np.eye(N, k=1) - np.eye(N, k=-1)
K_UNIT[-1, -1] = 1.0
OUTPUTS = [f"a{k + 1}" for k in range(N)]
BAND = (1.5, 60.0)
K_MODEL = 4e4  # N/m


def accelerance(f_hz: np.ndarray, k: float, zeta: float = 0.02) -> np.ndarray:
    """Tip-driven accelerance (m/s^2/N) of the 12 masses by modal superposition, (n_f, 12)."""
    w2, phi = scipy.linalg.eigh(k * K_UNIT, np.eye(N))
    w = 2 * np.pi * np.asarray(f_hz)
    modal = 1.0 / (w2[None] - w[:, None] ** 2 + 2j * zeta * np.sqrt(w2)[None] * w[:, None])
    return -(w**2)[:, None] * np.einsum("ir,r,fr->fi", phi, phi[-1], modal)


def measure(k_true: float, seed: int, nperseg: int = 1024, n_seg: int = 16, fs: float = 256.0):
    """H1 estimate of the structure with stiffness ``k_true`` (N/m), 1 % output noise."""
    rng = np.random.default_rng(seed)
    n = nperseg * n_seg
    f = np.arange(n // 2 + 1) * fs / n
    force = np.exp(2j * np.pi * rng.random(f.size))
    force[0], force[-1] = 0.0, 1.0
    H = accelerance(np.where(f > 0, f, 1.0), k_true)
    H[0] = 0.0
    u = np.fft.irfft(force, n)
    y = np.fft.irfft(H * force[:, None], n, axis=0)
    y = y + 0.01 * y.std(axis=0) * rng.standard_normal(y.shape)
    return rc.estimate_frf(
        u,
        y,
        fs=fs,
        nperseg=nperseg,
        inputs=["F"],
        outputs=OUTPUTS,
        units={"F": "N", **{o: "m/s^2" for o in OUTPUTS}},
    )


def string_model():
    """The user's model: 12 unit masses, stiffness ``k`` (a free parameter), transverse DOFs."""
    labels = [f"{j + 1}:Y" for j in range(N)]
    return rc.structural_model(
        np.eye(N),
        lambda th: th["k"] * K_UNIT,
        inputs={"F": labels[-1]},
        outputs={o: (lab, "acceleration") for o, lab in zip(OUTPUTS, labels)},
        dof_labels=labels,
        damping=0.02,
        params=[rc.Parameter("k", K_MODEL, "N/m", bounds=(2e4, 8e4))],
        nodes={j + 1: (0.3 * (j + 1), 0.0, 0.0) for j in range(N)},
        lines=[(j + 1, j + 2) for j in range(N - 1)],
        name="12-mass string",
    )


def main(folder: Path) -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    model = string_model()
    shifted = measure(0.95 * K_MODEL, seed=0)
    null = measure(K_MODEL, seed=3)
    cmp = rc.compare(model, shifted, band=BAND)
    cmp_null = rc.compare(model, null, band=BAND)
    figures = {
        "compare": rc.plot_compare(shifted, {"model": model}, band=BAND),
        "compare_selection": rc.plot_compare(shifted, {"model": model}, band=BAND, max_channels=9),
        "compare_result": cmp.plot(),
        "error_map_nominal": cmp.plot_error_map(),
        "error_map_null": cmp_null.plot_error_map(),
        "mode_shapes": rc.plot_mode_shapes(model.mode_shapes(n_modes=4), model.geometry()),
    }
    paths = []
    for name, fig in figures.items():
        path = folder / f"{name}.png"
        fig.savefig(path, dpi=80, bbox_inches="tight")
        paths.append(path)
    print(cmp.summary())
    print(cmp_null.summary())
    return paths


if __name__ == "__main__":
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parent
    for p in main(out):
        print(f"wrote {p}")
