"""The main job: the whole modelling pipeline on the embedded default example.

The Caltech truss (``rc.examples.caltech_truss``) is "tested" by a simulated experiment
whose truth carries a physical effect the nominal model lacks, plus a few per cent of error
in some physical parameters and sensor noise (``rc.examples.caltech_truss_experiment``).
The demo does what a user would do and never peeks at the truth until the last section:

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

from pathlib import Path
from typing import Any

import numpy as np

from .report import Report
from .table import Table

__all__ = ["run_demo", "DEMO_BAND_HZ"]

#: The Caltech design band (0.5-5.5 Hz) widened to hold the local longeron and diagonal modes
#: (32-43 Hz): below 30 Hz taut wires on the longerons and stiffer diagonals look alike.
DEMO_BAND_HZ = (0.5, 50.0)


def _measure(report: Report, seed: int) -> tuple[Any, Any]:
    from . import examples
    from .plots import bode_grid

    data, truth = examples.caltech_truss_experiment(seed=seed)
    settings = data.meta["experiments"][0]
    report.heading("1. Measurements")
    report.text(
        f"{data.n_out} accelerometers x {data.n_in} voice-coil actuators, one white-noise experiment "
        f"per actuator ({settings['n_samples']} samples at {settings['fs_hz']:g} Hz); H1 Welch estimates "
        f"with {settings['nperseg']}-point {settings['window']} windows ({settings['n_averages']} averages) "
        f"and coherence; {data.n_freq} points from {data.f_hz[0]:.3g} to {data.f_hz[-1]:.3g} Hz."
    )
    if data.coherence is not None:
        band = data.band(*DEMO_BAND_HZ)
        report.record("median_coherence_in_band", float(np.median(band.coherence)))
    fig = bode_grid([data], ["measured"], phase=False, title="Measured FRFs")
    report.figure(fig, "measured", "H1 estimates of the nine transfer functions AiSj.")
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


def _compare(report: Report, model: Any, data: Any, mm: Any, label: str) -> Any:
    from .correlate import compare

    cmp = compare(model, data, band=DEMO_BAND_HZ, measurement_model=mm)
    report.heading(f"{label}: where the model fails")
    report.text(cmp.summary())
    report.table(cmp.table())
    report.table(cmp.mode_table())
    name = f"compare_{label.split()[0].strip('.')}"
    report.figure(cmp.plot(), name, "Data against model; failing bands shaded.")
    return cmp


def run_demo(out: str | Path = "out", seed: int = 0, design: bool = True) -> Path:
    """Run the pipeline on the embedded Caltech truss and write ``out/report.html``.

    Parameters
    ----------
    out : str or Path
        Report folder (created; an existing folder must be one robustctl wrote).
    seed : int
        Seed of the simulated experiment (noise and excitation).
    design : bool
        Also run the design half (sections 8-12: weights, generalized plant, D-K, mu,
        yardstick, exported controller files in ``out``); False stops after the update.

    Returns
    -------
    Path
        The report's HTML file.
    """
    from . import examples
    from .correlate import diagnose, update
    from .identify import fit_measurement_model

    report = Report(Path(out), title="robustctl demo: the Caltech truss")
    data, truth = _measure(report, seed)
    model = examples.caltech_truss()

    report.heading("2. Measurement model (the yardstick)")
    # White-noise excitation (as Caltech's): correct the Hamming window's damping bias.
    mm = fit_measurement_model(data, n_modes=6, band=(0.5, 5.5), correct_leakage=True)
    report.table(mm.table())
    report.figure(mm.plot(), "measurement_model", "Six-mode measurement model against the data.")
    report.record("measurement_model_cost", float(mm.cost.total))

    cmp0 = _compare(report, model, data, mm, "3. Nominal physical model")
    report.record("cost_nominal", float(cmp0.cost))

    report.heading("4. Which physical effect is missing?")
    # the local fits share a wall-clock budget: on a loaded machine the default (120 s) can cut
    # them short and rank a look-alike first; the budget is a cap, an idle machine needs ~1 min
    diag = diagnose(model, data, band=DEMO_BAND_HZ, time_budget_s=900.0)
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
    upd = update(candidate, data, band=DEMO_BAND_HZ)
    report.text(
        f"Cost {upd.cost_before:.4g} -> {upd.cost_after:.4g} "
        f"({100 * (1 - upd.cost_after / cmp0.cost):.1f}% below the nominal model's {cmp0.cost:.4g})."
    )
    report.table(upd.table())
    report.figure(upd.plot(), "update", "Cost per iteration, alignment (MACE eq. 8), orthogonality (eq. 9).")
    report.record("cost_updated", float(upd.cost_after))
    report.record("cost_reduction_percent", float(100 * (1 - upd.cost_after / cmp0.cost)))
    _compare(report, upd.model, data, mm, "6. Updated physical model")

    _reveal(report, data, truth, model, upd)
    if design:
        from .demo_design import design_sections

        design_sections(report, data, truth, model, upd, mm)
    return report.write()
