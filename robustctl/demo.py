"""The main job: the whole modelling pipeline on an embedded example.

The default, the Caltech truss (``rc.examples.caltech_truss``), is "tested" by a simulated
experiment whose truth carries a physical effect the nominal model lacks, plus a few per cent
of error in some physical parameters and sensor noise (``rc.examples.caltech_truss_experiment``).
``example="mace"`` runs the same pipeline on the MACE-like bus (:mod:`robustctl.demo_mace`,
which also adds the 0-g prediction). Each example is a :class:`DemoExample`: the pipeline is
shared, the example says what differs. The demo does what a user would do and never peeks at
the truth until the reveal:

1. measure: three single-input white-noise experiments, H1 Welch estimates with coherence;
2. compare the physical model with the data: where it fails (channels, bands, modes);
3. identify a measurement model (the yardstick) and pair modes through it;
4. diagnose which physical effect is missing, add it, update the physical parameters and
   watch the cost fall;
5. reveal the truth and check what was recovered;
6. design (robustctl.demo_design): uncertainty weights, the seed's generalized plant, D-K
   iteration, mu over frequency, the measurement-model yardstick, exported controller files.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from .demo_design import DemoExample
from .report import Report
from .table import Table

__all__ = ["run_demo", "DEMO_BAND_HZ", "DemoExample", "EXAMPLES", "caltech_example"]

#: The Caltech design band (0.5-5.5 Hz) widened to hold the local longeron and diagonal modes
#: (32-43 Hz): below 30 Hz taut wires on the longerons and stiffer diagonals look alike.
DEMO_BAND_HZ = (0.5, 50.0)


def _caltech_measurement_model(data: Any) -> Any:
    from .identify import fit_measurement_model

    # White-noise excitation (as Caltech's): correct the Hamming window's damping bias.
    return fit_measurement_model(data, n_modes=6, band=(0.5, 5.5), correct_leakage=True)


def caltech_example() -> DemoExample:
    """The default demo: the Caltech truss with taut accelerometer wires (``--example caltech``)."""
    from . import examples

    return DemoExample(
        name="caltech",
        title="robustctl demo: the Caltech truss",
        experiment=lambda seed: examples.caltech_truss_experiment(seed=seed),
        model=examples.caltech_truss,
        band_hz=DEMO_BAND_HZ,
        sensors="accelerometers",
        actuators="voice-coil actuators",
        fit_measurement_model=_caltech_measurement_model,
        mm_caption="Six-mode measurement model against the data.",
        diagnose_options=lambda model: {},
    )


def _mace_example() -> DemoExample:
    from .demo_mace import mace_example

    return mace_example()


#: ``robustctl demo --example NAME``: the examples the demo runs, by name.
EXAMPLES: dict[str, Callable[[], DemoExample]] = {"caltech": caltech_example, "mace": _mace_example}


def _measure(report: Report, ex: DemoExample, seed: int) -> tuple[Any, Any]:
    from .plots import bode_grid

    data, truth = ex.experiment(seed)
    settings = data.meta["experiments"][0]
    report.heading("1. Measurements")
    report.text(
        f"{data.n_out} {ex.sensors} x {data.n_in} {ex.actuators}, one white-noise experiment "
        f"per actuator ({settings['n_samples']} samples at {settings['fs_hz']:g} Hz); H1 Welch estimates "
        f"with {settings['nperseg']}-point {settings['window']} windows ({settings['n_averages']} averages) "
        f"and coherence; {data.n_freq} points from {data.f_hz[0]:.3g} to {data.f_hz[-1]:.3g} Hz."
    )
    if data.coherence is not None:
        band = data.band(*ex.band_hz)
        report.record("median_coherence_in_band", float(np.median(band.coherence)))
    fig = bode_grid([data], ["measured"], phase=False, title="Measured FRFs")
    report.figure(fig, "measured", f"H1 estimates of the {data.n_out * data.n_in} transfer functions.")
    return data, truth


def _reveal(report: Report, data: Any, truth: Any, nominal: Any, upd: Any) -> None:
    """Section 7: the truth of the simulated experiment against what the pipeline found
    (the parameters the update could change, and those the truth changed)."""
    told = data.meta.get("truth", {})
    hidden = told.get("hidden_effect")
    report.heading("7. The truth, revealed")
    if hidden:
        report.text(f"Hidden effect: {hidden['name']} with {hidden['values']}. {hidden['description']}")
    rows = []
    free = {p.name for p in upd.model.free_params}
    for name, value in truth.values.items():
        changed = name not in nominal.param_names or nominal.param(name).value != value
        if name in upd.model.param_names and (name in free or changed):
            found = upd.model.param(name).value
            rows.append((name, value, found, 100 * (found - value) / value if value else float("nan")))
    report.table(Table(("parameter", "truth", "updated", "error (%)"), rows, title="Truth against update"))
    report.record("truth", told)


def _compare(report: Report, model: Any, data: Any, mm: Any, label: str, band_hz: tuple) -> Any:
    from .correlate import compare

    # a measurement model of fewer channels (MACE's: the design channels) cannot pair the
    # modes of every channel: then compare pairs them by peak picking
    channels = (tuple(data.outputs), tuple(data.inputs))
    same = mm is not None and (tuple(mm.outputs), tuple(mm.inputs)) == channels
    cmp = compare(model, data, band=band_hz, measurement_model=mm if same else None)
    report.heading(f"{label}: where the model fails")
    report.text(cmp.summary())
    report.table(cmp.table())
    report.table(cmp.mode_table())
    name = f"compare_{label.split()[0].strip('.')}"
    report.figure(cmp.plot(), name, "Data against model; failing bands shaded.")
    return cmp


def run_demo(out: str | Path = "out", seed: int = 0, design: bool = True, example: str = "caltech") -> Path:
    """Run the pipeline on an embedded example and write ``out/report.html``.

    Parameters
    ----------
    out : str or Path
        Report folder (created; an existing folder must be one robustctl wrote).
    seed : int
        Seed of the simulated experiment (noise and excitation).
    design : bool
        Also run the design half (sections 8-12: weights, generalized plant, D-K, mu,
        yardstick, exported controller files in ``out``); False stops after the update.
    example : {"caltech", "mace"}
        The Caltech truss (default) or the MACE-like bus (:mod:`robustctl.demo_mace`).

    Returns
    -------
    Path
        The report's HTML file.

    Raises
    ------
    RobustctlError
        Unknown ``example``.
    """
    from .checks import choice

    ex = EXAMPLES[choice(example, "example", tuple(EXAMPLES))]()
    report = Report(Path(out), title=ex.title)
    report.record("example", ex.name)
    data, truth = _measure(report, ex, seed)
    model = ex.model()
    mm, upd = _model_half(report, ex, data, truth, model)
    if design:
        from .demo_design import design_sections

        design_sections(report, data, truth, model, upd, mm, ex.design)
    for section in ex.extra_sections:
        section(report, data, truth, model, upd)
    return report.write()


def _model_half(report: Report, ex: DemoExample, data: Any, truth: Any, model: Any) -> tuple[Any, Any]:
    """Sections 2-7: measurement model, compare, diagnose, update, compare again, reveal."""
    from .correlate import diagnose, update

    report.heading("2. Measurement model (the yardstick)")
    mm = ex.fit_measurement_model(data)
    report.table(mm.table())
    report.figure(mm.plot(), "measurement_model", ex.mm_caption)
    report.record("measurement_model_cost", float(mm.cost.total))

    band = ex.band_hz
    cmp0 = _compare(report, model, data, mm, "3. Nominal physical model", band)
    report.record("cost_nominal", float(cmp0.cost))

    report.heading("4. Which physical effect is missing?")
    diag = diagnose(model, data, band=band, **ex.diagnose_options(model))
    report.text(diag.summary())
    report.table(diag.table())
    report.figure(diag.plot(), "diagnose", "Candidate effects ranked by the share of the error they explain.")
    if diag.best is None:
        report.text("No candidate effect is significant; updating the existing parameters only.", note=True)
        candidate = model
    else:
        report.text(f"Adding: {diag.best.name}.", note=True)
        candidate = model.with_effect(diag.best)
        report.record("diagnosed_effect", diag.best.name)

    report.heading("5. Updating the physical parameters")
    upd = update(candidate, data, band=band, **ex.update_options(model, diag.best))
    report.text(
        f"Cost {upd.cost_before:.4g} -> {upd.cost_after:.4g} "
        f"({100 * (1 - upd.cost_after / cmp0.cost):.1f}% below the nominal model's {cmp0.cost:.4g})."
    )
    report.table(upd.table())
    report.figure(upd.plot(), "update", "Cost per iteration, alignment (MACE eq. 8), orthogonality (eq. 9).")
    report.record("cost_updated", float(upd.cost_after))
    report.record("cost_reduction_percent", float(100 * (1 - upd.cost_after / cmp0.cost)))
    _compare(report, upd.model, data, mm, "6. Updated physical model", band)

    _reveal(report, data, truth, model, upd)
    return mm, upd
