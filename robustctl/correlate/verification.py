"""Model verification (MACE, "Model Verification"): does the updated model stay accurate
when the structure is changed?

A model can match one data set with wrong parameter values (a stiffness error absorbed by
a mass, say). MACE therefore perturbs the hardware -- an added mass, a stiffer strut, a
changed suspension -- applies the same change to the model, and checks that the model
predicts the perturbed behaviour "with similar accuracy". :func:`verify` does that: the
perturbation is applied to the updated model, the perturbed model is compared with the
perturbed data (MACE eq. 5 cost per point, mode-frequency errors), and, when the
unperturbed data are given, with the accuracy on those.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..checks import UNSET, renamed_keyword
from ..errors import DataError, ModelError
from ..frd import FrequencyData
from ..modes import pair_modes
from ..table import Table, result_html
from .comparison import Comparison, compare, statespace_modes

__all__ = ["Verification", "verify", "apply_perturbation"]


def apply_perturbation(model: Any, perturbation: Any) -> tuple[Any, str]:
    """``model`` with ``perturbation`` applied, and a description in words.

    Parameters
    ----------
    model : PhysicalModel
    perturbation : Effect-like (``.apply(model)``), mapping or callable
        An object with ``.apply(model)`` (e.g. ``rc.effects.AddedMass(...)`` with its
        value set), a mapping of parameter overrides ``{"m_offset": 0.8}``, or a callable
        ``model -> model`` (e.g. ``lambda m: m.without("suspension", "gravity")``).
    """
    if isinstance(perturbation, type):
        raise ModelError(
            f"perturbation is the class {perturbation.__name__}; create the effect with its value, "
            "e.g. rc.effects.AddedMass('dof 3', mass=0.2)."
        )
    if hasattr(perturbation, "apply") and callable(perturbation.apply):
        return perturbation.apply(model), str(getattr(perturbation, "name", type(perturbation).__name__))
    if isinstance(perturbation, Mapping):
        if not perturbation:
            raise ModelError("the perturbation dict is empty; give the parameter values that change.")
        perturbed = model.with_values(**perturbation)  # refuses unknown names and non-numbers
        desc = ", ".join(f"{k} = {float(v):g}" for k, v in perturbation.items())
        return perturbed, desc
    if callable(perturbation):
        return perturbation(model), getattr(perturbation, "__name__", "custom perturbation")
    raise ModelError(
        f"cannot apply a perturbation of type {type(perturbation).__name__}: give an Effect "
        "(an object with .apply(model), e.g. rc.effects.AddedMass), a dict of parameter overrides, "
        "or a callable model -> model."
    )


@dataclass(frozen=True)
class ModeCheck:
    """One mode of the verification table (frequencies in Hz, errors and shifts in %)."""

    f_model: float
    f_data: float
    error_pct: float
    error_nominal_pct: float
    shift_model_pct: float
    shift_data_pct: float


@dataclass(frozen=True, eq=False)
class Verification:
    """Result of :func:`verify`.

    Attributes
    ----------
    holds : bool
        Whether the model's accuracy holds on the perturbed structure.
    reasons : tuple of str
        The criteria checked, each in words with its numbers.
    perturbation : str
        What was changed.
    cost_per_point, cost_per_point_nominal : float
        MACE eq. 5 cost per data point on the perturbed and (if given) the reference data.
    cost_ratio : float
        ``cost_per_point / cost_per_point_nominal`` (NaN without reference data).
    max_freq_error_pct, max_freq_error_nominal_pct : float
        Largest paired mode-frequency error ``(data - model)/model`` in % (NaN if none).
    modes : tuple of ModeCheck
    comparison, nominal : Comparison
        The perturbed comparison and the reference one (or None).
    """

    holds: bool
    reasons: tuple[str, ...]
    perturbation: str
    cost_per_point: float
    cost_per_point_nominal: float
    cost_ratio: float
    max_freq_error_pct: float
    max_freq_error_nominal_pct: float
    modes: tuple[ModeCheck, ...]
    comparison: Comparison = field(repr=False)
    nominal: Comparison | None = field(default=None, repr=False)

    def table(self) -> Table:
        """Per mode: perturbed model vs data, the nominal error, predicted vs measured shift."""
        rows = [
            (
                k + 1,
                m.f_model,
                m.f_data,
                m.error_pct,
                m.error_nominal_pct,
                m.shift_model_pct,
                m.shift_data_pct,
            )
            for k, m in enumerate(self.modes)
        ]
        title = (
            f"verification ({self.perturbation}): cost/point {self.cost_per_point:.4g}"
            + (
                f" vs {self.cost_per_point_nominal:.4g} nominal"
                if np.isfinite(self.cost_per_point_nominal)
                else ""
            )
            + f" -> {'holds' if self.holds else 'does NOT hold'}"
        )
        return Table(
            (
                "mode",
                "f model (Hz)",
                "f data (Hz)",
                "error (%)",
                "error nominal (%)",
                "shift model (%)",
                "shift data (%)",
            ),
            rows,
            title=title,
        )

    def summary(self) -> str:
        head = (
            f"Perturbation: {self.perturbation}. The model's accuracy "
            f"{'holds' if self.holds else 'does NOT hold'} on the perturbed structure."
        )
        return "\n".join([head] + [f"  {r}" for r in self.reasons])

    def _repr_html_(self) -> str:
        return result_html(self.summary(), self.table())

    def plot(self, fig: Any = None) -> Any:
        """The perturbed comparison's plot (data vs perturbed model, failing bands)."""
        return self.comparison.plot(fig)

    def __repr__(self) -> str:
        return (
            f"Verification(holds={self.holds}, perturbation={self.perturbation!r}, "
            f"cost_ratio={self.cost_ratio:.3g}, max_freq_error_pct={self.max_freq_error_pct:.3g})"
        )


def _max_freq_error(cmp: Comparison) -> float:
    errs = [abs(m.f_error_pct) for m in cmp.modes if np.isfinite(m.f_model) and np.isfinite(m.f_data)]
    return max(errs) if errs else float("nan")


def _pct(a: float, b: float) -> float:
    return 100.0 * (a - b) / b if np.isfinite(a) and np.isfinite(b) and b != 0 else float("nan")


def _mode_checks(
    model, perturbed_model, cmp: Comparison, nominal: Comparison | None
) -> tuple[ModeCheck, ...]:
    """Link each perturbed mode to the nominal one (pairing the models' modes by frequency and MAC)."""
    span = (float(cmp.f_hz[0]), float(cmp.f_hz[-1]))
    link: dict[float, float] = {}
    if nominal is not None:
        span = (min(span[0], float(nominal.f_hz[0])), max(span[1], float(nominal.f_hz[-1])))
        m0 = statespace_modes(model.statespace(), span)
        m1 = statespace_modes(perturbed_model.statespace(), span)
        for i, j in pair_modes(m1, m0, tol=0.3):
            if i is not None and j is not None:
                link[round(m1[i].f_hz, 9)] = m0[j].f_hz
    nominal_rows = {round(r.f_model, 9): r for r in (nominal.modes if nominal is not None else ())}
    out = []
    nan = float("nan")
    for r in cmp.modes:
        f0 = link.get(round(r.f_model, 9), nan) if np.isfinite(r.f_model) else nan
        r0 = nominal_rows.get(round(f0, 9)) if np.isfinite(f0) else None
        out.append(
            ModeCheck(
                r.f_model,
                r.f_data,
                r.f_error_pct if np.isfinite(r.f_model) and np.isfinite(r.f_data) else nan,
                r0.f_error_pct if r0 is not None else nan,
                _pct(r.f_model, f0),
                _pct(r.f_data, r0.f_data) if r0 is not None else nan,
            )
        )
    return tuple(out)


def verify(
    updated_model: Any,
    perturbed_data: FrequencyData,
    perturbation: Any,
    reference_data: FrequencyData | None = None,
    *,
    band: Sequence[float] | None = None,
    point_weights: Any = "auto",
    weights: Any = UNSET,
    cost_ratio_tol: float = 2.0,
    freq_tol_pct: float = 4.0,
    cost_floor: float = 1e-6,
    measurement_model: Any = None,
) -> Verification:
    """Check an updated model against data of a perturbed structure (MACE model verification).

    Parameters
    ----------
    updated_model : PhysicalModel
        The model after updating.
    perturbed_data : FrequencyData
        Measured responses of the perturbed structure (Hz).
    perturbation : Effect-like, mapping or callable
        The same physical change applied to the model (see :func:`apply_perturbation`):
        e.g. ``rc.effects.AddedMass(node, mass=0.2)``, ``{"m_offset": 0.8}``, or
        ``lambda m: m.without("suspension", "gravity")``.
    reference_data : FrequencyData, optional
        Data of the unperturbed structure: the accuracy to hold.
    band : (lo_hz, hi_hz), optional
        Band of both comparisons (Hz).
    point_weights : "auto", None, "coherence" or array
        Data-point weights on the squared log error (:func:`robustctl.checks.point_weights`);
        ``weights=`` is the deprecated name.
    weights
        Deprecated name of ``point_weights``.
    cost_ratio_tol : float
        The accuracy holds if the cost per point on the perturbed data is at most this
        multiple of the nominal one (or below ``cost_floor``).
    freq_tol_pct : float
        ... and every paired mode-frequency error is below this (%; MACE's 0-g model was
        within 4 %).
    cost_floor : float
        Cost per point regarded as a perfect match (noise-free data).
    measurement_model : optional
        Measurement model of the perturbed data for mode pairing (else peak picking).

    Returns
    -------
    Verification

    Raises
    ------
    ModelError
        A perturbation that is not an Effect, a mapping or a callable, or unknown parameters.
    DataError
        Signal names or band that do not fit the data; a NaN or negative tolerance.
    """
    for what, value in (
        ("cost_ratio_tol", cost_ratio_tol),
        ("freq_tol_pct", freq_tol_pct),
        ("cost_floor", cost_floor),
    ):
        if not (np.isfinite(value) and value >= 0):
            raise DataError(f"{what} must be a finite tolerance >= 0; got {value!r}.")
    point_weights = renamed_keyword(point_weights, weights, "point_weights", "weights", default="auto")
    perturbed_model, desc = apply_perturbation(updated_model, perturbation)
    cmp = compare(
        perturbed_model, perturbed_data, band=band, point_weights=point_weights,
        measurement_model=measurement_model,
    )
    nominal = (
        compare(updated_model, reference_data, band=band, point_weights=point_weights)
        if reference_data is not None
        else None
    )
    cpp = cmp.cost_per_point
    cpp0 = nominal.cost_per_point if nominal is not None else float("nan")
    ratio = cpp / cpp0 if nominal is not None and cpp0 > 0 else float("nan")
    ferr = _max_freq_error(cmp)
    ferr0 = _max_freq_error(nominal) if nominal is not None else float("nan")
    reasons, holds = [], True
    if nominal is not None:
        ok = cpp <= max(cost_ratio_tol * cpp0, cost_floor)
        holds &= ok
        reasons.append(
            f"cost per point {cpp:.4g} on the perturbed data vs {cpp0:.4g} nominal (ratio {ratio:.3g}; "
            f"allowed {cost_ratio_tol:g}): {'ok' if ok else 'accuracy lost'}."
        )
    else:
        reasons.append(
            f"cost per point on the perturbed data: {cpp:.4g} (no reference data to compare with)."
        )
    if np.isfinite(ferr):
        ok = ferr <= freq_tol_pct
        holds &= ok
        extra = f" (nominal {ferr0:.2f}%)" if np.isfinite(ferr0) else ""
        reasons.append(
            f"largest mode-frequency error {ferr:.2f}%{extra}; allowed {freq_tol_pct:g}%: "
            f"{'ok' if ok else 'too large'}."
        )
    else:
        reasons.append("no mode of the perturbed model could be paired with a measured one.")
    return Verification(
        holds=bool(holds),
        reasons=tuple(reasons),
        perturbation=desc,
        cost_per_point=cpp,
        cost_per_point_nominal=cpp0,
        cost_ratio=ratio,
        max_freq_error_pct=ferr,
        max_freq_error_nominal_pct=ferr0,
        modes=_mode_checks(updated_model, perturbed_model, cmp, nominal),
        comparison=cmp,
        nominal=nominal,
    )
