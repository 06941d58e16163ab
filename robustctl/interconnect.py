"""Named-signal interconnection: the partitioned plant (w, u -> z, y) over one StateSpace.

A :class:`PartitionedPlant` is one ``control.StateSpace`` ``P`` whose inputs are ordered
``[w..., u...]`` (exogenous inputs, then control inputs) and whose outputs are ordered
``[z..., y...]`` (regulated outputs, then measurements), with every signal named. It is
the standard LFT form ``z = P11 w + P12 u, y = P21 w + P22 u`` closed by ``u = K y``
(Zhou, Doyle & Glover, *Robust and Optimal Control*, 1996, sec. 10.1), and the idea of
RobustAndOptimalControl.jl's ``ExtendedStateSpace``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import ModelError

__all__ = ["PartitionedPlant"]


def _count(value: Any, what: str, upper: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 0 <= value <= upper:
        raise ModelError(f"{what} must be an integer in [0, {upper}]; got {value!r}.")
    return int(value)


@dataclass(frozen=True)
class PartitionedPlant:
    """A plant ``P: [w; u] -> [z; y]`` with named signal groups.

    Parameters
    ----------
    P : control.StateSpace
        Inputs ordered ``[w..., u...]``, outputs ``[z..., y...]``.
    nmeas : int
        Number of measurements ``y`` (the last ``nmeas`` outputs of ``P``).
    ncon : int
        Number of control inputs ``u`` (the last ``ncon`` inputs of ``P``).

    Notes
    -----
    ``nw = P.ninputs - ncon`` and ``nz = P.noutputs - nmeas``. The signal names of each
    group are ``w_names``, ``u_names``, ``z_names`` and ``y_names``; a controller designed
    for this plant has inputs ``y_names`` and outputs ``u_names``.
    """

    P: Any
    nmeas: int
    ncon: int

    def __post_init__(self) -> None:
        import control

        if not isinstance(self.P, control.StateSpace):
            raise ModelError(
                f"a partitioned plant holds a control.StateSpace; got {type(self.P).__name__}. "
                "Convert it with rc.as_statespace first."
            )
        _count(self.nmeas, "nmeas (number of measurements)", self.P.noutputs)
        _count(self.ncon, "ncon (number of control inputs)", self.P.ninputs)

    # ------------------------------------------------------------------ sizes and names
    @property
    def nw(self) -> int:
        """Number of exogenous inputs ``w``."""
        return self.P.ninputs - self.ncon

    @property
    def nz(self) -> int:
        """Number of regulated outputs ``z``."""
        return self.P.noutputs - self.nmeas

    @property
    def nu(self) -> int:
        """Number of control inputs (alias of ``ncon``)."""
        return self.ncon

    @property
    def ny(self) -> int:
        """Number of measurements (alias of ``nmeas``)."""
        return self.nmeas

    @property
    def w_names(self) -> list[str]:
        """Names of the exogenous inputs."""
        return list(self.P.input_labels[: self.nw])

    @property
    def u_names(self) -> list[str]:
        """Names of the control inputs."""
        return list(self.P.input_labels[self.nw:])

    @property
    def z_names(self) -> list[str]:
        """Names of the regulated outputs."""
        return list(self.P.output_labels[: self.nz])

    @property
    def y_names(self) -> list[str]:
        """Names of the measurements."""
        return list(self.P.output_labels[self.nz:])

    # ------------------------------------------------------------------ partitions
    def matrices(self) -> dict[str, np.ndarray]:
        """The partitioned realisation: A, B1, B2, C1, C2, D11, D12, D21, D22 as arrays."""
        A, B, C, D = (np.asarray(m, dtype=float) for m in (self.P.A, self.P.B, self.P.C, self.P.D))
        nw, nz = self.nw, self.nz
        return {
            "A": A,
            "B1": B[:, :nw],
            "B2": B[:, nw:],
            "C1": C[:nz, :],
            "C2": C[nz:, :],
            "D11": D[:nz, :nw],
            "D12": D[:nz, nw:],
            "D21": D[nz:, :nw],
            "D22": D[nz:, nw:],
        }

    def sub(self, rows: str, cols: str):
        """One partition as a named ``control.StateSpace``: ``sub("z", "w")`` is ``P11``.

        Parameters
        ----------
        rows : {"z", "y"}
        cols : {"w", "u"}
        """
        import control

        if rows not in ("z", "y") or cols not in ("w", "u"):
            raise ModelError(
                f"sub(rows, cols) takes rows in ('z', 'y') and cols in ('w', 'u'); got {rows!r}, {cols!r}."
            )
        out = slice(0, self.nz) if rows == "z" else slice(self.nz, None)
        inp = slice(0, self.nw) if cols == "w" else slice(self.nw, None)
        P = self.P
        return control.ss(
            P.A, P.B[:, inp], P.C[out, :], P.D[out, inp], P.dt,
            inputs=list(P.input_labels[inp]), outputs=list(P.output_labels[out]),
        )

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}(states={self.P.nstates}, w={self.nw}, u={self.nu}, "
            f"z={self.nz}, y={self.ny})"
        )
