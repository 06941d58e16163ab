"""The demo's design half: uncertainty weights -> generalized plant -> D-K -> mu -> yardstick -> export.

It continues :func:`robustctl.demo.run_demo` after the model update, on the same data and
models, as a user would: cover the updated model's error, build the Caltech seed's design
plant (eq. 14 additive weight, 4 % input/output multiplicative uncertainty, performance on
the sensors), run D-K iteration, check mu over frequency, score controllers designed on the
nominal, updated and measurement models against the measured data (MACE's yardstick), and
export the controller as coefficient files.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .executors import available_cores, process_pool
from .report import Report
from .table import Table

__all__ = ["design_sections", "DESIGN_FS_HZ", "DesignSpec", "DemoExample"]

#: Sampling rate of the exported controller (the Caltech experiment's rate), Hz.
DESIGN_FS_HZ = 200.0
#: Band of the uncertainty cover, Hz: the design band with the local modes above it.
COVER_BAND_HZ = (0.3, 60.0)
#: D-K iterations per yardstick design (three designs; the demo's budget).
YARDSTICK_ITER = 4


@dataclass(frozen=True)
class DemoExample:
    """What the shared pipeline needs to know about one embedded example.

    Attributes
    ----------
    name : str
        ``robustctl demo --example NAME``.
    title : str
        The report's title.
    experiment : callable
        ``seed -> (data, truth)``: the simulated test (the truth is revealed in section 7).
    model : callable
        ``() -> PhysicalModel``: the nominal model.
    band_hz : (float, float)
        Band of compare, diagnose and update (Hz).
    sensors, actuators : str
        Plain words for the measurement section ("accelerometers", "voice-coil actuators").
    fit_measurement_model : callable
        ``data -> MeasurementModel`` (section 2).
    mm_caption : str
        Caption of the measurement-model figure.
    diagnose_options : callable
        ``model -> dict`` of keyword arguments of :func:`robustctl.diagnose` besides the band.
    update_options : callable
        ``(model, effect or None) -> dict`` of keyword arguments of :func:`robustctl.update`.
    design : object
        The design half's recipe (:class:`robustctl.demo_design.DesignSpec`); None: Caltech's.
    extra_sections : tuple of callables
        ``(report, data, truth, model, upd) -> None``, run after the design half
        (MACE: the 0-g prediction).
    """

    name: str
    title: str
    experiment: Callable[[int], tuple[Any, Any]]
    model: Callable[[], Any]
    band_hz: tuple[float, float]
    sensors: str
    actuators: str
    fit_measurement_model: Callable[[Any], Any]
    mm_caption: str
    diagnose_options: Callable[[Any], dict] = field(default=lambda model: {})
    update_options: Callable[[Any, Any], dict] = field(default=lambda model, effect: {})
    design: Any = None
    extra_sections: tuple[Callable[..., None], ...] = ()


@dataclass(frozen=True)
class DesignSpec:
    """What the design half needs to know about an example (defaults: the Caltech truss).

    Attributes
    ----------
    name : str
        Provenance of the exported controller files.
    plant : callable, optional
        ``nominal -> GeneralizedPlant``, the design recipe (also the yardstick's, when given); None: the
        Caltech seed's :func:`~robustctl.examples.caltech_design_plant`.
    reference_weight : callable, optional
        ``() -> system``, the weight drawn beside the cover; None: seed eq. 14.
    reference_label : str
        Its words in the report.
    outputs, inputs : tuple of str, optional
        The control channels the design uses (None: every channel).
    cover_order : int
        Order of the additive cover.
    cover_band_hz : (float, float)
        Band of the cover, Hz.
    fs_hz : float
        Sampling rate of the exported controller, Hz.
    yardstick_plant : callable, optional
        ``nominal -> GeneralizedPlant`` of the yardstick (None: see :meth:`yardstick_recipe`).
    """

    name: str = "caltech truss demo"
    plant: Callable[[Any], Any] | None = None
    reference_weight: Callable[[], Any] | None = None
    reference_label: str = "the Caltech seed's eq. 14 weight"
    outputs: tuple[str, ...] | None = None
    inputs: tuple[str, ...] | None = None
    cover_order: int = 4
    cover_band_hz: tuple[float, float] = COVER_BAND_HZ
    fs_hz: float = DESIGN_FS_HZ
    yardstick_plant: Callable[[Any], Any] | None = None

    def channels(self, sys: Any) -> Any:
        """``sys`` (data, model or truth) cut to the control channels."""
        if self.outputs is None and self.inputs is None:
            return sys
        return sys.select(outputs=self.outputs, inputs=self.inputs)

    def recipe(self) -> Callable[[Any], Any]:
        """The design plant recipe (Caltech's when ``plant`` is None)."""
        from .examples import caltech_design_plant

        return caltech_design_plant if self.plant is None else self.plant

    def yardstick_recipe(self, data: Any) -> Callable[[Any], Any]:
        """The yardstick's recipe: ``yardstick_plant``, else the design recipe when ``plant`` is
        given, else (Caltech) :class:`~robustctl.examples.ModelCoverRecipe` on ``data``, where
        each model's cover is its own error against the data."""
        from .examples import ModelCoverRecipe

        if self.yardstick_plant is not None:
            return self.yardstick_plant
        return ModelCoverRecipe(data) if self.plant is None else self.plant

    def reference(self) -> Any:
        """The weight drawn beside the cover."""
        from .robust import caltech_additive_weight

        return caltech_additive_weight() if self.reference_weight is None else self.reference_weight()


def _weights(report: Report, data: Any, nominal: Any, samples: list, design: DesignSpec) -> Any:
    from .robust import cover_additive

    report.heading("8. Uncertainty weights")
    cover = cover_additive(nominal, [data, *samples], order=design.cover_order, band=design.cover_band_hz)
    report.text(
        "An additive weight covering the updated model's error against the measured data (with 3 sigma "
        f"of the H1 estimate's random error) and against {len(samples)} models drawn from the update's "
        "parameter covariance (UpdateResult.sample_models). " + cover.summary()
    )
    report.table(cover.table())
    report.figure(
        cover.plot(reference=design.reference()),
        "weights",
        f"Error envelope, its cover, and {design.reference_label}.",
    )
    report.record("cover_margin", float(cover.margin))
    return cover


def _dk(report: Report, gp: Any) -> Any:
    from .robust import dksyn

    report.heading("9. Generalized plant and D-K iteration")
    report.text(gp.summary())
    dk = dksyn(gp, max_iter=4, reduce="auto")
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
        "experiment (the full-order model with the hidden effect).",
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


def _explain_model_cover_recipe(report: Report, recipe: Any, models: dict[str, Any]) -> None:
    """The text and cover table of a :class:`~robustctl.examples.ModelCoverRecipe` yardstick."""
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


def _design_pool() -> Any:
    """Two worker processes for the yardstick's three independent designs (the machine's second
    core; None, i.e. serial, on one core). They are :func:`robustctl.executors.process_pool`'s
    workers, which end with the demo however it ends (an exception, Ctrl-C, SIGTERM or SIGKILL)."""
    return process_pool(2 if available_cores() >= 2 else None, 3, 1)


def _yardstick(report: Report, data: Any, models: dict[str, Any], design: DesignSpec,
               truth: Any = None) -> Any:
    from .robust import yardstick

    report.heading("11. The yardstick: controllers scored on the measured data")
    recipe = design.yardstick_recipe(data)
    if hasattr(recipe, "cover"):  # a ModelCoverRecipe: each model pays for its own error
        _explain_model_cover_recipe(report, recipe, models)
    else:
        report.text(
            "One mu-controller per model by the design recipe above (the same weights and performance "
            "objectives for every model); each controller is then scored on the measured FRFs."
        )
    with _design_pool() as pool:
        yard = yardstick(
            data, models, recipe, reference="measurement", max_iter=YARDSTICK_ITER, executor=pool
        )
    report.text(yard.summary())
    report.table(yard.table())
    report.table(yard.mu_table())
    caption = "Measured closed loops of the controllers designed on each model."
    report.figure(yard.plot(), "yardstick", caption)
    report.record("yardstick_attenuation_db", {k: float(v) for k, v in yard.attenuation_db.items()})
    report.record("yardstick_gap_db", {k: float(yard.gap_db(k)) for k in yard.labels})
    report.record("yardstick_ratio", {k: float(yard.ratio(k)) for k in yard.labels})
    report.record("yardstick_stable_on_data", {k: yard.stability[k].label for k in yard.labels})
    if truth is not None:
        _yardstick_on_truth(report, yard, truth)
    return yard


def _yardstick_on_truth(report: Report, yard: Any, truth: Any) -> None:
    """Each yardstick controller closed on the simulated experiment's truth (u = K y): what the
    data's verdicts are checked against, revealed as in section 7."""
    from .interconnect import feedback
    from .lti import as_statespace

    rows, stable = [], {}
    for lab in yard.labels:
        p = np.linalg.eigvals(np.asarray(feedback(as_statespace(truth), yard.designs[lab].K, sign=+1).A))
        worst = p[int(np.argmax(p.real))]
        stable[lab] = bool(worst.real < 0)
        rows.append((lab, yard.stability[lab].label, "stable" if stable[lab] else "unstable",
                     float(worst.real), float(abs(worst.imag) / (2 * np.pi))))
    cols = ("controller designed on", "on the data", "on the truth", "max Re pole (1/s)", "at (Hz)")
    report.table(Table(cols, rows, title="The yardstick's controllers on the truth (revealed)"))
    report.record("yardstick_stable_on_truth", stable)


def _export(report: Report, dk: Any, folder: Path, design: DesignSpec) -> None:
    from .export import export_controller

    report.heading("12. Exported controller")
    rows = []
    # a reduced (balanced-truncated, hence minimal) controller can be written in its balanced
    # discrete realisation; otherwise the exact power-of-two diagonal scaling
    balance = "balanced" if dk.reduction is not None and dk.reduction.accepted else "diagonal"
    for suffix in (".h", ".json", ".mat", ".csv"):
        path = folder / f"controller{suffix}"
        rep = export_controller(
            dk, path, fs=design.fs_hz, method="tustin", overwrite=True, balance=balance,
            provenance={"example": design.name, "mu_peak": float(dk.mu_peak)},
        )
        rows.append((path.name, rep.summary()))
    title = f"Controller discretised at {design.fs_hz:g} Hz (Tustin)"
    report.table(Table(("file", "checks"), rows, title=title))
    report.record("exported_files", [r[0] for r in rows])


def design_sections(
    report: Report, data: Any, truth: Any, model: Any, upd: Any, mm: Any, design: DesignSpec | None = None
) -> None:
    """Sections 8-12 of the demo report (see the module docstring) on ``design``'s control channels."""
    design = DesignSpec() if design is None else design
    data, truth, model, updated = (design.channels(x) for x in (data, truth, model, upd.model))
    samples = [design.channels(m) for m in upd.sample_models(20, seed=0)]
    _weights(report, data, updated, samples, design)
    gp = design.recipe()(updated)
    dk = _dk(report, gp)
    _mu(report, gp, dk, truth)
    _yardstick(report, data, {"nominal": model, "updated": updated, "measurement": mm}, design, truth)
    _export(report, dk, Path(report.folder), design)
