"""Named-signal interconnection: the partitioned plant (w, u -> z, y) over one StateSpace.

A :class:`PartitionedPlant` is one ``control.StateSpace`` ``P`` whose inputs are ordered
``[w..., u...]`` (exogenous inputs, then control inputs) and whose outputs are ordered
``[z..., y...]`` (regulated outputs, then measurements), with every signal named. It is
the standard LFT form ``z = P11 w + P12 u, y = P21 w + P22 u`` closed by ``u = K y``
(Zhou, Doyle & Glover, *Robust and Optimal Control*, 1996, sec. 10.1), and the idea of
RobustAndOptimalControl.jl's ``ExtendedStateSpace``.

The interconnections keep every signal name (python-control 0.10's ``StateSpace.lft``
names its result's inputs ``u[0]``...): :func:`lft` (lower LFT ``Fl(P, K)``),
:func:`upper_lft` (``Fu(P, Delta)``), :func:`star` (Redheffer star product), and
:func:`series`, :func:`parallel`, :func:`feedback`, which connect signals by name. All of
them work on the realisation matrices (numpy) and build one named ``control.StateSpace``
at the end; states are ordered first system first. Static channel maps (rename, scale,
select, combine) are in :mod:`robustctl.signals`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import control
import numpy as np
from control.iosys import common_timebase

from .checks import flag, integer, is_default_names
from .errors import ModelError, PlantError
from .lti import as_statespace, rebuild_statespace, series_matrices, statespace_state
from .signals import _arrays, select_signals
from .table import Table

__all__ = ["PartitionedPlant", "lft", "upper_lft", "star", "series", "parallel", "feedback", "block_diagonal"]


def _count(value: Any, what: str, upper: int) -> int:
    return integer(value, what, ModelError, lo=0, hi=upper)


def _pack(value: Any) -> Any:
    """A picklable stand-in for a ``control.StateSpace`` (python-control's holds a lambda)."""
    return _PackedStateSpace(statespace_state(value)) if isinstance(value, control.StateSpace) else value


@dataclass(frozen=True)
class _PackedStateSpace:
    """Marks a field that was a StateSpace: :func:`robustctl.lti.statespace_state` of it."""

    state: dict

    def unpack(self):
        return rebuild_statespace(self.state)


class PicklesStateSpaces:
    """Mixin for frozen dataclasses holding ``control.StateSpace`` fields: pickle by matrices and names."""

    def __getstate__(self) -> dict[str, Any]:
        return {k: _pack(v) for k, v in self.__dict__.items()}

    def __setstate__(self, state: dict[str, Any]) -> None:
        for k, v in state.items():
            object.__setattr__(self, k, v.unpack() if isinstance(v, _PackedStateSpace) else v)


@dataclass(frozen=True)
class PartitionedPlant(PicklesStateSpaces):
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
        if not isinstance(self.P, control.StateSpace):
            raise PlantError(
                f"a partitioned plant holds a control.StateSpace; got {type(self.P).__name__}. "
                "Convert it with rc.as_statespace first, or use rc.as_partitioned(P, nmeas, ncon)."
            )
        _count(self.nmeas, "nmeas (number of measurements)", self.P.noutputs)
        _count(self.ncon, "ncon (number of control inputs)", self.P.ninputs)

    # ------------------------------------------------------------------ the system
    @property
    def A(self) -> np.ndarray:
        """State matrix of ``P`` (so python-control's ``hinfsyn``/``h2syn`` take the plant)."""
        return self.P.A

    @property
    def B(self) -> np.ndarray:
        """Input matrix of ``P``, columns ``[w..., u...]``."""
        return self.P.B

    @property
    def C(self) -> np.ndarray:
        """Output matrix of ``P``, rows ``[z..., y...]``."""
        return self.P.C

    @property
    def D(self) -> np.ndarray:
        """Feedthrough matrix of ``P``."""
        return self.P.D

    @property
    def dt(self) -> Any:
        """Sampling time of ``P`` (0 for continuous time)."""
        return self.P.dt

    @property
    def ninputs(self) -> int:
        """Number of inputs of ``P`` (``nw + ncon``)."""
        return self.P.ninputs

    @property
    def noutputs(self) -> int:
        """Number of outputs of ``P`` (``nz + nmeas``)."""
        return self.P.noutputs

    @property
    def nstates(self) -> int:
        """Number of states of ``P``."""
        return self.P.nstates

    @property
    def input_labels(self) -> list[str]:
        """Input names of ``P``: ``w_names + u_names``."""
        return list(self.P.input_labels)

    @property
    def output_labels(self) -> list[str]:
        """Output names of ``P``: ``z_names + y_names``."""
        return list(self.P.output_labels)

    @property
    def state_labels(self) -> list[str]:
        """State names of ``P``."""
        return list(self.P.state_labels)

    def isctime(self, strict: bool = False) -> bool:
        """Whether ``P`` is continuous time (python-control's ``isctime``)."""
        return self.P.isctime(strict=strict)

    def isdtime(self, strict: bool = False) -> bool:
        """Whether ``P`` is discrete time (python-control's ``isdtime``)."""
        return self.P.isdtime(strict=strict)

    def statespace(self):
        """The plant as one ``control.StateSpace`` (``rc.as_statespace`` takes this object)."""
        return self.P

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

    def closed_loop(self, K: Any):
        """``Fl(P, K)``: the loop closed by the controller ``K`` (y -> u), ``w -> z`` with names."""
        return lft(self, K)

    # ------------------------------------------------------------------ reports
    def table(self):
        """One row per signal group: role, count and names."""
        rows = [
            ("w", "exogenous inputs", self.nw, ", ".join(self.w_names)),
            ("u", "control inputs", self.nu, ", ".join(self.u_names)),
            ("z", "regulated outputs", self.nz, ", ".join(self.z_names)),
            ("y", "measurements", self.ny, ", ".join(self.y_names)),
        ]
        return Table(("group", "role", "count", "names"), rows, title=f"{type(self).__name__} signals")

    def summary(self) -> str:
        """One sentence in plain words."""
        return (
            f"{type(self).__name__} with {self.P.nstates} states: w = {self.nw}, u = {self.nu} -> "
            f"z = {self.nz}, y = {self.ny}; a controller takes {self.y_names} to {self.u_names}."
        )

    def _repr_html_(self) -> str:
        import html

        return f"<p>{html.escape(self.summary())}</p>" + self.table()._repr_html_()

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}(states={self.P.nstates}, w={self.nw}, u={self.nu}, "
            f"z={self.nz}, y={self.ny})"
        )


# ============================================================================ coercion
def _system(sys: Any, what: str):
    """``sys`` as a named ``control.StateSpace``; a number or 2-D array is a static gain."""
    if isinstance(sys, PartitionedPlant):
        return sys.P
    if _is_static(sys):
        try:
            D = np.atleast_2d(np.asarray(sys, dtype=float))
        except (TypeError, ValueError):
            D = np.full((1, 1), np.nan)
        if D.ndim != 2 or not np.all(np.isfinite(D)):
            raise ModelError(f"{what} as a static gain must be a finite number or 2-D array; got {sys!r}.")
        p, m = D.shape
        return control.ss(np.zeros((0, 0)), np.zeros((0, m)), np.zeros((p, 0)), D)
    return as_statespace(sys, name=what)


def _is_static(sys: Any) -> bool:
    return isinstance(sys, (int, float, np.integer, np.floating, np.ndarray, list))


def _timebase(*systems) -> Any:
    """The common sampling time of the dynamic systems (static gains adapt)."""
    dt = 0
    dynamic = [s for s in systems if s.nstates > 0]
    if dynamic:
        dt = dynamic[0].dt
        for s in dynamic[1:]:
            try:
                dt = common_timebase(dt, s.dt)
            except ValueError as exc:
                raise ModelError(
                    f"cannot connect systems with different sampling times ({dt} and {s.dt}); "
                    "discretise or convert them to one time base first."
                ) from exc
    return dt


def named_statespace(A, B, C, D, dt, inputs: Sequence[str], outputs: Sequence[str], what: str):
    """The one named ``control.StateSpace`` built at the end of every interconnection.

    Parameters
    ----------
    A, B, C, D : ndarray
        The realisation (state units as the caller's).
    dt : float, True or 0
        Sampling time in s (0: continuous).
    inputs, outputs : sequence of str
        Signal names, one per input / output, all distinct.
    what : str
        What is being built, for the refusal.

    Returns
    -------
    control.StateSpace

    Raises
    ------
    ModelError
        Repeated input or output names.
    """
    for names, kind in ((inputs, "input"), (outputs, "output")):
        dup = sorted({n for n in names if list(names).count(n) > 1})
        if dup:
            raise ModelError(
                f"the {what} would have repeated {kind} names {dup}; rename the signals of one "
                "system first (rc.rename_signals)."
            )
    return control.ss(A, B, C, D, dt, inputs=list(inputs), outputs=list(outputs))


# ============================================================================ star product kernel
def _star_arrays(p1, p2, n_forward: int, n_back: int, what: str):
    """Redheffer star product of two realisations (Zhou, Doyle & Glover 1996, sec. 10.2).

    ``p1 = (A1, B1, C1, D1)`` has inputs ``[a1, v]`` and outputs ``[b1, e]``; ``p2`` has
    inputs ``[e, a2]`` and outputs ``[v, b2]`` with ``len(e) = n_forward`` and
    ``len(v) = n_back``. The loop equations ``[I, -D1ev; -D2ve, I] [e; v] = ...`` are solved
    once; the result has states ``[x1; x2]``, inputs ``[a1; a2]``, outputs ``[b1; b2]``.

    Raises
    ------
    ModelError
        The interconnection is not well posed (``I - D1ev D2ve`` singular).
    """
    A1, B1, C1, D1 = p1
    A2, B2, C2, D2 = p2
    n1, n2 = A1.shape[0], A2.shape[0]
    m1, q1 = B1.shape[1] - n_back, C1.shape[0] - n_forward
    m2, q2 = B2.shape[1] - n_forward, C2.shape[0] - n_back
    nf, nb, n = n_forward, n_back, n1 + n2
    # loop equations M [e; v] = N [x1; x2; a1; a2]
    M = np.eye(nf + nb)
    M[:nf, nf:] = -D1[q1:, m1:]
    M[nf:, :nf] = -D2[:nb, :nf]
    N = np.zeros((nf + nb, n + m1 + m2))
    N[:nf, :n1], N[:nf, n:n + m1] = C1[q1:], D1[q1:, :m1]
    N[nf:, n1:n], N[nf:, n + m1:] = C2[:nb], D2[:nb, nf:]
    if M.size:
        cond = np.linalg.cond(M)
        if not np.isfinite(cond) or cond > 1e12:
            raise ModelError(
                f"the {what} is not well posed: I - D22 Dk (the feedthrough around the loop) is singular "
                f"(condition number {cond:.3g}); make one of the two systems strictly proper in the loop "
                "(e.g. a controller with roll-off) or change the feedthrough."
            )
        sol = np.linalg.solve(M, N)
    else:
        sol = N
    # [x1'; x2'] and [b1; b2] before the loop signals, then the loop signals' share
    top = np.zeros((n, n + m1 + m2))
    top[:n1, :n1], top[:n1, n:n + m1] = A1, B1[:, :m1]
    top[n1:, n1:n], top[n1:, n + m1:] = A2, B2[:, nf:]
    top[:n1] += B1[:, m1:] @ sol[nf:]
    top[n1:] += B2[:, :nf] @ sol[:nf]
    bot = np.zeros((q1 + q2, n + m1 + m2))
    bot[:q1, :n1], bot[:q1, n:n + m1] = C1[:q1], D1[:q1, :m1]
    bot[q1:, n1:n], bot[q1:, n + m1:] = C2[nb:], D2[nb:, nf:]
    bot[:q1] += D1[:q1, m1:] @ sol[nf:]
    bot[q1:] += D2[nb:, :nf] @ sol[:nf]
    return top[:, :n], top[:, n:], bot[:, :n], bot[:, n:]


def _loop_sizes(P: Any, X: Any, who: str, into: tuple, back: tuple) -> tuple[int, int]:
    """Checked numbers of P outputs into X and of X outputs back into P (default: X's size)."""
    (key_in, text_in, n_in), (key_out, text_out, n_out) = into, back
    n_in = _count(X.ninputs if n_in is None else n_in, f"{key_in} ({text_in})", P.noutputs)
    n_out = _count(X.noutputs if n_out is None else n_out, f"{key_out} ({text_out})", P.ninputs)
    if (X.ninputs, X.noutputs) != (n_in, n_out):
        raise ModelError(
            f"{who} must have {key_in} = {n_in} inputs and {key_out} = {n_out} outputs; it has "
            f"{X.ninputs} inputs and {X.noutputs} outputs."
        )
    return n_in, n_out


def _match_by_name(K: Any, inputs: Sequence[str], outputs: Sequence[str]):
    """``K`` reordered to ``inputs``/``outputs`` when its names are exactly those (any order)."""
    k_in, k_out = list(K.input_labels), list(K.output_labels)
    same = (
        sorted(k_in) == sorted(inputs) and sorted(k_out) == sorted(outputs)
        and len(set(k_in)) == len(k_in) and len(set(k_out)) == len(k_out)
    )
    if same and (k_in != list(inputs) or k_out != list(outputs)):
        return select_signals(K, list(inputs), list(outputs))
    return K


# ============================================================================ LFTs
def lft(P: Any, K: Any, nmeas: int | None = None, ncon: int | None = None):
    """Lower linear fractional transformation ``Fl(P, K)``, keeping P's w and z names.

    ``Fl(P, K) = P11 + P12 K (I - P22 K)^{-1} P21`` (Zhou, Doyle & Glover 1996, eq. 10.1):
    ``P`` has inputs ``[w..., u...]`` and outputs ``[z..., y...]``; ``K`` closes the loop
    ``u = K y``.

    Parameters
    ----------
    P : PartitionedPlant, control.StateSpace or anything ``rc.as_statespace`` takes
        The plant. A :class:`PartitionedPlant` brings its own ``nmeas`` and ``ncon``.
    K : system, number or 2-D array
        The controller, ``ncon x nmeas``. When its input names are exactly P's measurement
        names and its output names P's control names (in any order), it is connected by
        name; otherwise by position.
    nmeas, ncon : int, optional
        Number of measurements (last outputs of P) and controls (last inputs of P);
        default: from a PartitionedPlant, else ``K.ninputs`` and ``K.noutputs``.

    Returns
    -------
    control.StateSpace
        ``w -> z`` with P's names; states ``[x_P; x_K]``.

    Raises
    ------
    ModelError
        Sizes that do not fit, or an ill-posed loop (``I - D22 Dk`` singular).
    """
    if isinstance(P, PartitionedPlant):
        nmeas = P.nmeas if nmeas is None else nmeas
        ncon = P.ncon if ncon is None else ncon
    Pss = _system(P, "the plant P")
    Kss = _system(K, "the controller K")
    nmeas, ncon = _loop_sizes(Pss, Kss, "K", ("nmeas", "number of measurements", nmeas),
                              ("ncon", "number of control inputs", ncon))
    nw, nz = Pss.ninputs - ncon, Pss.noutputs - nmeas
    y_names, u_names = list(Pss.output_labels[nz:]), list(Pss.input_labels[nw:])
    if not _is_static(K):
        Kss = _match_by_name(Kss, y_names, u_names)
    dt = _timebase(Pss, Kss)
    A, B, C, D = _star_arrays(_arrays(Pss), _arrays(Kss), nmeas, ncon, "lower LFT Fl(P, K)")
    return named_statespace(A, B, C, D, dt, Pss.input_labels[:nw], Pss.output_labels[:nz], "lower LFT")


def upper_lft(P: Any, Delta: Any, n_delta_in: int | None = None, n_delta_out: int | None = None):
    """Upper linear fractional transformation ``Fu(P, Delta)``, keeping P's other names.

    ``Fu(P, Delta) = P22 + P21 Delta (I - P11 Delta)^{-1} P12`` (Zhou, Doyle & Glover 1996,
    eq. 10.2): the first ``n_delta_in`` outputs of ``P`` drive ``Delta``, whose outputs are
    the first ``n_delta_out`` inputs of ``P``. With a generalized plant this closes the
    uncertainty channels (block order) and leaves ``[performance..., u] -> [performance..., y]``.

    Parameters
    ----------
    P : PartitionedPlant, control.StateSpace or anything ``rc.as_statespace`` takes
    Delta : system, number or 2-D array
        ``n_delta_out x n_delta_in``.
    n_delta_in, n_delta_out : int, optional
        Default ``Delta.ninputs`` and ``Delta.noutputs``.

    Returns
    -------
    control.StateSpace
        The remaining inputs to the remaining outputs, with P's names; states ``[x_P; x_Delta]``.
    """
    Pss = _system(P, "the plant P")
    Dss = _system(Delta, "the perturbation Delta")
    n_in, n_out = _loop_sizes(Pss, Dss, "Delta", ("n_delta_in", "outputs of P into Delta", n_delta_in),
                              ("n_delta_out", "inputs of P from Delta", n_delta_out))
    A, B, C, D = _arrays(Pss)
    ii = np.r_[n_out:Pss.ninputs, 0:n_out]  # uncertainty channels last: a lower LFT
    oo = np.r_[n_in:Pss.noutputs, 0:n_in]
    perm = (A, B[:, ii], C[oo], D[np.ix_(oo, ii)])
    if not _is_static(Delta):
        Dss = _match_by_name(Dss, list(Pss.output_labels[:n_in]), list(Pss.input_labels[:n_out]))
    dt = _timebase(Pss, Dss)
    A, B, C, D = _star_arrays(perm, _arrays(Dss), n_in, n_out, "upper LFT Fu(P, Delta)")
    return named_statespace(A, B, C, D, dt, Pss.input_labels[n_out:], Pss.output_labels[n_in:], "upper LFT")


def star(P1: Any, P2: Any, n_forward: int | None = None, n_back: int | None = None):
    """Redheffer star product ``P1 * P2``, keeping the names of the open channels.

    The last ``n_forward`` outputs of ``P1`` drive the first ``n_forward`` inputs of ``P2``,
    and the first ``n_back`` outputs of ``P2`` drive the last ``n_back`` inputs of ``P1``
    (MATLAB's ``lft(P1, P2, nu, ny)``; Zhou, Doyle & Glover 1996, sec. 10.2). With ``P2``
    having no other channels it is the lower LFT; with ``P1`` having none, the upper LFT.

    Parameters
    ----------
    P1, P2 : PartitionedPlant, control.StateSpace or anything ``rc.as_statespace`` takes
    n_forward, n_back : int, optional
        Default from a PartitionedPlant ``P1`` (its ``nmeas`` and ``ncon``).

    Returns
    -------
    control.StateSpace
        Inputs ``[P1's open inputs, P2's open inputs]``, outputs ``[P1's open outputs,
        P2's open outputs]``; states ``[x1; x2]``. Repeated names raise ModelError.
    """
    if isinstance(P1, PartitionedPlant):
        n_forward = P1.nmeas if n_forward is None else n_forward
        n_back = P1.ncon if n_back is None else n_back
    if n_forward is None or n_back is None:
        raise ModelError(
            "star(P1, P2, n_forward, n_back) needs the number of P1 outputs feeding P2 (n_forward) and "
            "of P2 outputs feeding P1 (n_back), unless P1 is a PartitionedPlant."
        )
    S1 = _system(P1, "P1")
    S2 = _system(P2, "P2")
    n_forward = _count(n_forward, "n_forward (outputs of P1 into P2)", min(S1.noutputs, S2.ninputs))
    n_back = _count(n_back, "n_back (outputs of P2 into P1)", min(S2.noutputs, S1.ninputs))
    dt = _timebase(S1, S2)
    A, B, C, D = _star_arrays(_arrays(S1), _arrays(S2), n_forward, n_back, "star product")
    m1, q1 = S1.ninputs - n_back, S1.noutputs - n_forward
    ins = list(S1.input_labels[:m1]) + list(S2.input_labels[n_forward:])
    outs = list(S1.output_labels[:q1]) + list(S2.output_labels[n_back:])
    return named_statespace(A, B, C, D, dt, ins, outs, "star product")


def block_diagonal(*systems: Any):
    """Systems side by side, ``diag(G1, G2, ...)`` (MATLAB ``append``), keeping all names.

    Parameters
    ----------
    *systems : systems
        One or more systems (anything :func:`robustctl.as_statespace` accepts), with a common
        time base.

    Returns
    -------
    control.StateSpace
        Inputs and outputs concatenated in order (repeated names raise ModelError);
        states first system first.
    """
    from scipy.linalg import block_diag

    if not systems:
        raise ModelError("block_diagonal needs at least one system.")
    parts = [_system(s, f"system {i} of the block diagonal") for i, s in enumerate(systems)]
    mats = [_arrays(s) for s in parts]
    A, B, C, D = (block_diag(*[m[k] for m in mats]) for k in range(4))
    ins = [n for s in parts for n in s.input_labels]
    outs = [n for s in parts for n in s.output_labels]
    return named_statespace(A, B, C, D, _timebase(*parts), ins, outs, "block diagonal")


# ============================================================================ series, parallel, feedback
def _selection(names: Sequence[str], known: Sequence[str], what: str, hint: str) -> np.ndarray:
    """Matrix ``S`` (len(names) x len(known)) picking each name out of ``known``."""
    known = list(known)
    missing = [n for n in names if n not in known]
    if missing:
        raise ModelError(f"unknown {what} {missing}; the known names are {known}. {hint}")
    S = np.zeros((len(names), len(known)))
    for i, n in enumerate(names):
        S[i, known.index(n)] = 1.0
    return S


def _static_like(value: Any, n_out: int, n_in: int, what: str) -> np.ndarray:
    """A number (times identity) or array as an ``n_out x n_in`` gain matrix."""
    try:
        D = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        D = np.full(1, np.nan)
    if not np.all(np.isfinite(D)):
        raise ModelError(f"{what} must be a finite real number or array; got {value!r}.")
    if D.ndim == 0:
        if n_out != n_in:
            raise ModelError(
                f"{what} is a number, which means a multiple of the identity; that needs a square "
                f"connection, here {n_out} x {n_in}. Give a {n_out} x {n_in} array."
            )
        return float(D) * np.eye(n_out)
    if D.shape != (n_out, n_in):
        raise ModelError(f"{what} must be a {n_out} x {n_in} gain matrix; got shape {D.shape}.")
    return D


def _as_gain_system(value: Any, n_out: int, n_in: int, inputs, outputs, what: str):
    D = _static_like(value, n_out, n_in, what)
    return control.ss(np.zeros((0, 0)), np.zeros((0, n_in)), np.zeros((n_out, 0)), D,
                      inputs=list(inputs), outputs=list(outputs))


_BY_POSITION = "Pass by_name=False to connect by position."


def _default_names(sys: Any) -> bool:
    """True when ``sys`` carries python-control's default names ``u[i]`` / ``y[i]``, which say nothing."""
    return is_default_names(sys.input_labels, "u") and is_default_names(sys.output_labels, "y")


def _series_pair(s1: Any, s2: Any, by_name: bool):
    if _is_static(s2):
        s2 = _as_gain_system(s2, s1.noutputs, s1.noutputs, s1.output_labels, s1.output_labels,
                             "a static gain in series")
    else:
        s2 = _system(s2, "a system in series")
    if by_name and not _default_names(s2):
        T = _selection(list(s2.input_labels), s1.output_labels, "input(s) of the later system",
                       "In series(a, b) every input of b must be an output of a. " + _BY_POSITION)
    elif s2.ninputs != s1.noutputs:
        raise ModelError(
            f"series by position needs as many inputs of the later system ({s2.ninputs}) as outputs "
            f"of the earlier one ({s1.noutputs})."
        )
    else:
        T = np.eye(s1.noutputs)
    A2, B2, C2, D2 = _arrays(s2)
    A, B, C, D = series_matrices(_arrays(s1), (A2, B2 @ T, C2, D2 @ T))
    return named_statespace(A, B, C, D, _timebase(s1, s2), s1.input_labels, s2.output_labels, "series")


def series(*systems: Any, by_name: bool = True):
    """Series connection ``systems[-1] * ... * systems[0]``, connecting signals by name.

    Each system after the first reads, by name, outputs of the one before it (outputs not
    read are dropped); with ``by_name=False``, or when the later system carries
    python-control's default names ``u[i]``/``y[i]`` (which say nothing), all outputs feed
    all inputs by position, as ``control.series``. A number or array after the first
    system is a static gain on its outputs (names kept).

    Parameters
    ----------
    *systems : systems, numbers or arrays
        The cascade, first acting first; at least one system.
    by_name : bool
        Connect by signal name (default) or, False, all outputs to all inputs by position.

    Returns
    -------
    control.StateSpace
        Inputs of ``systems[0]``, outputs of ``systems[-1]``; states first system first.
    """
    by_name = flag(by_name, "by_name", ModelError)
    if not systems:
        raise ModelError("series needs at least one system.")
    out = _system(systems[0], "the first system in series")
    for s in systems[1:]:
        out = _series_pair(out, s, by_name)
    return out


def _placement(names: Sequence[str], union: Sequence[str], by_name: bool) -> np.ndarray:
    """Selection of ``names`` out of ``union`` (by name) or the identity (by position)."""
    if not by_name:
        return np.eye(len(names))
    return _selection(list(names), union, "signal", "")


def _parallel_pair(s1: Any, s2: Any, by_name: bool):
    if _is_static(s2):
        s2 = _as_gain_system(s2, s1.noutputs, s1.ninputs, s1.input_labels, s1.output_labels,
                             "a static gain in parallel")
    else:
        s2 = _system(s2, "a system in parallel")
    if by_name:
        ins = list(s1.input_labels) + [n for n in s2.input_labels if n not in s1.input_labels]
        outs = list(s1.output_labels) + [n for n in s2.output_labels if n not in s1.output_labels]
    elif (s1.ninputs, s1.noutputs) != (s2.ninputs, s2.noutputs):
        raise ModelError(
            f"parallel by position needs systems of one size; got {s1.noutputs} x {s1.ninputs} and "
            f"{s2.noutputs} x {s2.ninputs}."
        )
    else:
        ins, outs = list(s1.input_labels), list(s1.output_labels)
    S1, S2 = _placement(s1.input_labels, ins, by_name), _placement(s2.input_labels, ins, by_name)
    R1 = _placement(s1.output_labels, outs, by_name).T  # y = R1 y1 + R2 y2, u_i = S_i u
    R2 = _placement(s2.output_labels, outs, by_name).T
    A1, B1, C1, D1 = _arrays(s1)
    A2, B2, C2, D2 = _arrays(s2)
    n1, n2 = A1.shape[0], A2.shape[0]
    A = np.block([[A1, np.zeros((n1, n2))], [np.zeros((n2, n1)), A2]])
    B = np.vstack([B1 @ S1, B2 @ S2])
    C = np.hstack([R1 @ C1, R2 @ C2])
    D = R1 @ D1 @ S1 + R2 @ D2 @ S2
    return named_statespace(A, B, C, D, _timebase(s1, s2), ins, outs, "parallel connection")


def parallel(*systems: Any, by_name: bool = True):
    """Parallel connection (sum) of systems, matching signals by name.

    Inputs of the same name are one shared input; outputs of the same name are summed.
    The result has the union of the names (first system's order, then new names). With
    ``by_name=False`` all systems must have one size and are summed by position, as
    ``control.parallel``. A number (times identity) or array is a static gain with the
    first system's names.

    Parameters
    ----------
    *systems : systems, numbers or arrays
        The branches; at least one system.
    by_name : bool
        Share inputs and sum outputs by signal name (default) or, False, by position.

    Returns
    -------
    control.StateSpace
        The union of the names; states first system first.
    """
    by_name = flag(by_name, "by_name", ModelError)
    if not systems:
        raise ModelError("parallel needs at least one system.")
    out = _system(systems[0], "the first system in parallel")
    for s in systems[1:]:
        out = _parallel_pair(out, s, by_name)
    return out


def feedback(sys1: Any, sys2: Any = 1.0, sign: float = -1, *, by_name: bool = True):
    """Feedback ``u1 = r + sign * sys2(y1)`` around ``sys1``, connecting signals by name.

    ``sys2`` reads the outputs of ``sys1`` named like its inputs and adds (with ``sign``) to
    the inputs of ``sys1`` named like its outputs; a controller whose inputs are the plant's
    measurement names and outputs its control names closes the loop on those channels only.
    With ``by_name=False``, a number / array ``sys2``, or a ``sys2`` with python-control's
    default names ``u[i]``/``y[i]``, all outputs feed all inputs by position, as
    ``control.feedback``.

    Parameters
    ----------
    sys1 : system
        Forward path; the result keeps its input and output names.
    sys2 : system, number or array
        Feedback path. A number means ``sys2 * I`` (square ``sys1``).
    sign : {-1, +1}
        Negative (default) or positive feedback.
    by_name : bool
        Connect by signal name (default) or, False, all outputs to all inputs by position.

    Returns
    -------
    control.StateSpace
        ``r -> y1``; states ``[x1; x2]``.
    """
    by_name = flag(by_name, "by_name", ModelError)
    G = _system(sys1, "sys1 (the forward system)")
    if isinstance(sign, (bool, np.bool_)) or sign not in (-1, 1):
        raise ModelError(f"sign must be -1 (negative feedback) or +1 (positive feedback); got {sign!r}.")
    p, m = G.noutputs, G.ninputs
    if _is_static(sys2):
        K = _as_gain_system(sys2, m, p, G.output_labels, G.input_labels, "sys2 (the feedback gain)")
        Sy, Su = np.eye(p), np.eye(m)
    else:
        K = _system(sys2, "sys2 (the feedback system)")
        if by_name and not _default_names(K):
            hint = "In feedback(G, K) K's inputs must be outputs of G and K's outputs inputs of G. "
            Sy = _selection(list(K.input_labels), G.output_labels, "input(s) of the feedback system",
                            hint + _BY_POSITION)
            Su = _selection(list(K.output_labels), G.input_labels, "output(s) of the feedback system",
                            hint + _BY_POSITION).T
        elif (K.ninputs, K.noutputs) != (p, m):
            raise ModelError(f"feedback by position needs a {m} x {p} feedback system; got "
                             f"{K.noutputs} x {K.ninputs}.")
        else:
            Sy, Su = np.eye(p), np.eye(m)
    A, B, C, D = _arrays(G)
    loop = (A, np.hstack([B, B]), np.vstack([C, C]), np.block([[D, D], [D, D]]))  # [r, v] -> [y, y]
    Ak, Bk, Ck, Dk = _arrays(K)
    k_full = (Ak, Bk @ Sy, sign * (Su @ Ck), sign * (Su @ Dk @ Sy))
    A, B, C, D = _star_arrays(loop, k_full, p, m, "feedback loop")
    return named_statespace(A, B, C, D, _timebase(G, K), G.input_labels, G.output_labels, "feedback loop")
