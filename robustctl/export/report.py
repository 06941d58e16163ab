"""The result of :func:`robustctl.export_controller`."""

from __future__ import annotations

import html
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..table import Table

__all__ = ["ExportReport"]


@dataclass(frozen=True, eq=False)
class ExportReport:
    """What :func:`export_controller` wrote and what it checked.

    Attributes
    ----------
    path : pathlib.Path
        The file written.
    format : str
        ``"json"``, ``"csv"``, ``"h"``, ``"mat"`` or ``"sos"``.
    fs_hz : float
        Sample rate, Hz.
    method, prewarp_hz : str or None, float or None
        Discretisation used (None when K was already discrete).
    n_states, n_inputs, n_outputs : int
        Sizes of the exported realisation.
    spectral_radius : float
        Largest ``|z|`` of the discrete poles.
    stable : bool
        ``spectral_radius < 1``.
    crossover_hz : float or None
        Frequency where the discretisation error was evaluated (the given crossover or the
        frequency of the largest controller gain).
    discretization_error : float or None
        ``||K_d(e^{j w T}) - K(j w)||_2 / ||K(j w)||_2`` there (None when K was discrete).
    dynamic_range, dynamic_range_balanced : float, float or None
        ``max|coef| / min nonzero |coef|`` of A, B, C, D before and after balancing.
    balance : str or None
        ``"diagonal"``, ``"balanced"`` or None.
    sos_error : float or None
        SOS only: max relative deviation of the sections' response from the channel's, over
        frequency.
    channel : tuple of str or None
        SOS only: (output, input) exported.
    gamma, mu : float or None
        The design's figures when K came from a synthesis result.
    controller : control.StateSpace
        The discrete realisation written (the SOS channel for ``.sos``).
    """

    path: Path
    format: str
    fs_hz: float
    method: str | None
    prewarp_hz: float | None
    n_states: int
    n_inputs: int
    n_outputs: int
    spectral_radius: float
    stable: bool
    crossover_hz: float | None
    discretization_error: float | None
    dynamic_range: float
    dynamic_range_balanced: float | None
    balance: str | None
    sos_error: float | None
    channel: tuple[str, str] | None
    gamma: float | None
    mu: float | None
    controller: Any

    def table(self) -> Table:
        """The checks as a two-column table."""
        rows = [
            ("file", str(self.path)),
            ("format", self.format),
            ("fs (Hz)", self.fs_hz),
            ("method", self.method or "already discrete"),
            ("prewarp (Hz)", self.prewarp_hz),
            ("states / inputs / outputs", f"{self.n_states} / {self.n_inputs} / {self.n_outputs}"),
            ("max |pole| (z)", self.spectral_radius),
            ("stable", self.stable),
            ("error evaluated at (Hz)", self.crossover_hz),
            ("relative discretisation error", self.discretization_error),
            ("coefficient dynamic range", self.dynamic_range),
            (f"dynamic range {self._balance_phrase()}", self.dynamic_range_balanced),
            ("SOS channel (output <- input)", None if self.channel is None else " <- ".join(self.channel)),
            ("SOS max relative error", self.sos_error),
            ("gamma", self.gamma),
            ("mu peak", self.mu),
        ]
        return Table(("check", "value"), [r for r in rows if r[1] is not None], title="controller export")

    def _balance_phrase(self) -> str:
        return {"diagonal": "after diagonal balancing", "balanced": "in the balanced realisation"}.get(
            self.balance or "", "without balancing")

    def summary(self) -> str:
        """One paragraph: what was written and whether it is safe to run."""
        err = (
            f"; discretisation error {100 * self.discretization_error:.3g} % at {self.crossover_hz:.4g} Hz"
            if self.discretization_error is not None
            else ""
        )
        dr = f"; coefficient dynamic range {self.dynamic_range:.3g}"
        if self.dynamic_range_balanced is not None:
            dr += f" -> {self.dynamic_range_balanced:.3g} {self._balance_phrase()}"
        state = "stable" if self.stable else "UNSTABLE"
        return (
            f"{self.path.name}: {self.n_states}-state {self.n_outputs}x{self.n_inputs} controller at "
            f"{self.fs_hz:g} Hz, {state} (max |z| = {self.spectral_radius:.6f}){err}{dr}."
        )

    def _repr_html_(self) -> str:
        return f"<p>{html.escape(self.summary())}</p>" + self.table()._repr_html_()

    def __repr__(self) -> str:
        return f"ExportReport({self.summary()})"
