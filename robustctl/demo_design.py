"""The demo's design half: uncertainty weights -> generalized plant -> D-K -> mu -> yardstick -> export.

It continues :func:`robustctl.demo.run_demo` after the model update, on the same data and
models, as a user would: cover the updated model's error, build the Caltech seed's design
plant (eq. 14 additive weight, 4 % input/output multiplicative uncertainty, performance on
the sensors), run D-K iteration, check mu over frequency, score controllers designed on the
nominal, updated and measurement models against the measured data (MACE's yardstick), and
export the controller as coefficient files.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from .report import Report
from .table import Table

__all__ = ["design_sections", "DESIGN_FS_HZ"]

#: Sampling rate of the exported controller (the Caltech experiment's rate), Hz.
DESIGN_FS_HZ = 200.0
#: Band of the uncertainty cover, Hz: the design band with the local modes above it.
COVER_BAND_HZ = (0.3, 60.0)
#: D-K iterations per yardstick design (three designs; the demo's budget).
YARDSTICK_ITER = 4


def _weights(report: Report, data: Any, upd: Any) -> Any:
    from .robust import caltech_additive_weight, cover_additive

    report.heading("8. Uncertainty weights")
    samples = upd.sample_models(20, seed=0)
    cover = cover_additive(upd.model, [data, *samples], order=4, band=COVER_BAND_HZ)
    report.text(
        "An additive weight covering the updated model's error against the measured data (with 3 sigma "
        "of the H1 estimate's random error) and against 20 models drawn from the update's parameter "
        "covariance (UpdateResult.sample_models). " + cover.summary()
    )
    report.table(cover.table())
    report.figure(
        cover.plot(reference=caltech_additive_weight()),
        "weights",
        "Error envelope, its cover, and the Caltech seed's eq. 14 weight.",
    )
    report.record("cover_margin", float(cover.margin))
    return cover


def _dk(report: Report, gp: Any) -> Any:
    from .robust import dksyn

    report.heading("9. Generalized plant and D-K iteration")
    report.text(gp.summary())
    dk = dksyn(gp, max_iter=4, time_budget_s=120.0)
    report.text(dk.summary())
    report.table(dk.table())
    report.figure(dk.plot(), "dk", "mu upper bound per D-K iteration, and the iteration history.")
    report.record("dk_mu_peak", float(dk.mu_peak))
    report.record("dk_history_mu", [float(it.mu_peak) for it in dk.history])
    return dk


def _mu(report: Report, gp: Any, dk: Any, truth: Any) -> None:
    from .interconnect import feedback
    from .lti import as_statespace
    from .robust import robust_stability

    report.heading("10. mu over frequency")
    f_hz = dk.mu.f_hz
    rs = robust_stability(dk.closed_loop, gp, f_hz)
    report.text(
        f"Robust performance: peak mu {dk.mu.peak:.3g} at {dk.mu.f_peak_hz:.3g} Hz (upper bound; lower "
        f"bound {dk.mu.lower_peak:.3g}). Robust stability over the uncertainty blocks alone: peak mu "
        f"{rs.peak:.3g}, a stability margin of {rs.stability_margin:.3g} (the loop stays stable for every "
        f"perturbation up to {rs.stability_margin:.3g} times the weights)."
    )
    report.figure(dk.mu.plot(), "mu", "Robust performance mu of the D-K controller: upper and lower bounds.")
    # the design convention is u = K y (lower LFT): positive feedback of the truth's sensors
    loop = feedback(as_statespace(truth), dk.K, sign=+1)
    stable = bool(np.all(np.linalg.eigvals(np.asarray(loop.A)).real < 0))
    report.text(
        f"The controller {'stabilises' if stable else 'does NOT stabilise'} the truth model of the simulated "
        "experiment (the full-order truss with the hidden effect).",
        note=True,
    )
    report.record("robust_stability_peak_mu", float(rs.peak))
    report.record("robust_performance_peak_mu", float(dk.mu.peak))
    report.record("stabilises_truth", stable)


def _cover_table(recipe: Any, models: dict[str, Any]) -> Table:
    """Each model's own additive cover: what its controller must be robust to."""
    rows = []
    for label, model in models.items():
        cov = recipe.cover(model)
        design = (cov.f_hz >= recipe.band_hz[0]) & (cov.f_hz <= recipe.band_hz[1])
        rows.append((label, float(cov.envelope[design].max()), float(np.median(cov.envelope[design])),
                     cov.order, float(cov.margin)))
    cols = ("model", "peak error in band", "median error in band", "cover order", "cover margin")
    return Table(cols, rows, title="Each model's error against the data (as the H1 estimator sees it)")


def _yardstick(report: Report, data: Any, models: dict[str, Any]) -> Any:
    from .examples import ModelCoverRecipe
    from .robust import yardstick

    report.heading("11. The yardstick: controllers scored on the measured data")
    recipe = ModelCoverRecipe(data)
    report.text(
        "One mu-controller per model by the same recipe (robustctl.examples.ModelCoverRecipe): the model's "
        "six modes, an additive weight covering that model's own error against the data, 4 % input and "
        f"output multiplicative uncertainty, and a performance weight of {recipe.level:g} on the sensors "
        f"over {recipe.band_hz[0]:g}-{recipe.band_hz[1]:g} Hz, where the six lightly damped modes are. The "
        "nominal model's modes are 3-6 % low, one to two half-power bandwidths: at each resonance its error "
        "is as large as the response, so a controller that must be robust to it cannot act there. Each "
        "controller is then scored on the measured FRFs (the loop closed on the data), not on its model."
    )
    report.table(_cover_table(recipe, models))
    yard = yardstick(data, models, recipe, reference="measurement", max_iter=YARDSTICK_ITER)
    report.text(yard.summary())
    report.table(yard.table())
    report.table(yard.mu_table())
    caption = "Measured closed loops of the controllers designed on each model."
    report.figure(yard.plot(), "yardstick", caption)
    report.record("yardstick_attenuation_db", {k: float(v) for k, v in yard.attenuation_db.items()})
    report.record("yardstick_gap_db", {k: float(yard.gap_db(k)) for k in yard.labels})
    report.record("yardstick_ratio", {k: float(yard.ratio(k)) for k in yard.labels})
    report.record("yardstick_stable_on_data", {k: yard.stability[k].label for k in yard.labels})
    return yard


def _export(report: Report, dk: Any, folder: Path) -> None:
    from .export import export_controller

    report.heading("12. Exported controller")
    rows = []
    for suffix in (".h", ".json", ".mat", ".csv"):
        path = folder / f"controller{suffix}"
        rep = export_controller(
            dk, path, fs=DESIGN_FS_HZ, method="tustin", overwrite=True,
            provenance={"example": "caltech truss demo", "mu_peak": float(dk.mu_peak)},
        )
        rows.append((path.name, rep.summary()))
    title = f"Controller discretised at {DESIGN_FS_HZ:g} Hz (Tustin)"
    report.table(Table(("file", "checks"), rows, title=title))
    report.record("exported_files", [r[0] for r in rows])


def design_sections(report: Report, data: Any, truth: Any, model: Any, upd: Any, mm: Any) -> None:
    """Sections 8-12 of the demo report (see the module docstring)."""
    from .examples import caltech_design_plant

    _weights(report, data, upd)
    gp = caltech_design_plant(upd.model)
    dk = _dk(report, gp)
    _mu(report, gp, dk, truth)
    _yardstick(report, data, {"nominal": model, "updated": upd.model, "measurement": mm})
    _export(report, dk, Path(report.folder))
