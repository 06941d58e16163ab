"""The generalized plant: nominal model, uncertainty and performance weights in one LFT.

:func:`generalized_plant` builds the interconnection structure ``P`` of the mu framework
(Balas & Doyle, Caltech seed paper, Fig. 1: ``Delta`` closes the upper channels, ``K`` the
lower ones) from a nominal model and weights:

* additive uncertainty ``G + W_a Delta`` (seed eq. 2, the weight of eq. 14),
* input and output multiplicative uncertainty ``G (I + Delta W_i)``, ``(I + Delta W_o) G``
  (seed eq. 3; the seed takes 4 % on both),
* performance weights on the sensors (the seed's performance specification), a weight on
  the control, weighted disturbances at the plant input and/or output and sensor noise.

The signal flow (``u`` the control, ``d`` disturbances, ``n`` noise)::

    u_G    = u + w_im + W_di d_in                  plant input
    y_add  = G u_G + [W_a] w_add                   additive uncertainty enters
    y_true = y_add + w_om + W_do d_out             output multiplicative uncertainty enters
    y      = y_true + W_n n                        measurement
    z_add  = [W_a] u_G,  z_im = W_i u,  z_om = W_o y_add
    z_perf = [W_p y_true; W_u u]

with ``Delta_add: z_add -> w_add``, ``Delta_im: z_im -> w_im`` and ``Delta_om: z_om -> w_om``
(the additive weight sits on the ``z`` side when it acts on the plant inputs, on the ``w``
side when it is ``ny x ny``). Every piece is a named system; the static wiring is one
named gain and ``P = Fu(wiring, diag(G, W...))`` by :func:`robustctl.interconnect.upper_lft`,
so the plant's own signal names stay visible (``unc_add_in[S1]``, ``perf_y[S2]``, ``A1``).

Conventions (CONTRACTS.md): ``w = [uncertainty inputs in block order..., performance
inputs...]``, ``z = [uncertainty outputs in block order..., performance outputs...]``;
block ``i`` has ``rows`` = its number of ``w`` channels and ``cols`` = its number of ``z``
channels (``Delta_i`` maps ``z_i -> w_i``); the performance block is last.
"""

from __future__ import annotations

import html
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..checks import flag, is_default_names
from ..errors import ModelError
from ..interconnect import PartitionedPlant, PicklesStateSpaces, block_diagonal, upper_lft
from ..lti import as_statespace, freqresp_array, is_stable
from ..physical.uncertain import UncertainModel
from ..plots import single_axes
from ..signals import select_signals
from ..table import Table
from .uncertainty.blocks import Block, BlockStructure
from .uncertainty.system import PlantLFT, UncertainSystem

__all__ = ["GeneralizedPlant", "PlantWeight", "generalized_plant", "mixed_sensitivity"]

#: relative singular-value level below which D12 / D21 count as rank deficient
RANK_TOL = 1e-10


# ============================================================================ result types
@dataclass(frozen=True)
class PlantWeight(PicklesStateSpaces):
    """One weight used in a generalized plant.

    Attributes
    ----------
    role : str
        What it weights (``"additive uncertainty"``, ``"performance on the sensors"`` ...).
    system : control.StateSpace
        The weight as used (SISO weights are repeated on the diagonal).
    """

    role: str
    system: Any

    @property
    def size(self) -> str:
        """``"n_out x n_in"``."""
        return f"{self.system.noutputs} x {self.system.ninputs}"

    def gain(self, f_hz: float) -> float:
        """Largest singular value of the weight at ``f_hz`` (Hz; ``inf`` for the feedthrough)."""
        if np.isinf(f_hz):
            return float(np.linalg.norm(np.asarray(self.system.D, float), 2))
        G = np.atleast_2d(np.asarray(self.system(2j * np.pi * f_hz), dtype=complex))
        return float(np.linalg.norm(G, 2))


@dataclass(frozen=True, repr=False)
class GeneralizedPlant(PartitionedPlant):
    """A :class:`~robustctl.interconnect.PartitionedPlant` with its block structure.

    Parameters
    ----------
    P, nmeas, ncon
        As for PartitionedPlant: inputs ``[w..., u...]``, outputs ``[z..., y...]``.
    blocks : BlockStructure
        Uncertainty blocks in order, then one full ``"performance"`` block when there are
        performance channels; ``sum(rows) = nw`` and ``sum(cols) = nz``.
    n_perf_w, n_perf_z : int
        Number of performance inputs (last ``w``) and outputs (last ``z``).
    weights : tuple of PlantWeight
        The weights the plant was built from (for tables and reports).
    """

    blocks: BlockStructure | None = None
    n_perf_w: int = 0
    n_perf_z: int = 0
    weights: tuple[PlantWeight, ...] = field(default=())

    def __post_init__(self) -> None:
        super().__post_init__()
        if not isinstance(self.blocks, BlockStructure):
            raise ModelError(f"a generalized plant needs a BlockStructure; got {self.blocks!r}.")
        if (self.blocks.n_in, self.blocks.n_out) != (self.nw, self.nz):
            raise ModelError(
                f"the blocks {self.blocks.mussv().tolist()} need nw = {self.blocks.n_in} and "
                f"nz = {self.blocks.n_out}; the plant has nw = {self.nw}, nz = {self.nz}."
            )
        if (self.n_perf_w > 0) != (self.n_perf_z > 0):
            raise ModelError(
                f"performance channels come in pairs: n_perf_w = {self.n_perf_w}, n_perf_z = {self.n_perf_z}."
            )
        if self.n_perf_w:
            last = self.blocks[-1]
            if (last.kind, last.rows, last.cols) != ("full", self.n_perf_w, self.n_perf_z):
                raise ModelError(
                    f"the last block must be the full {self.n_perf_w} x {self.n_perf_z} performance "
                    f"block; got {last}."
                )

    # ------------------------------------------------------------------ groups
    @property
    def uncertainty_blocks(self) -> BlockStructure | None:
        """The blocks without the performance block (None when there is no uncertainty)."""
        blocks = self.blocks.blocks[:-1] if self.n_perf_w else self.blocks.blocks
        return BlockStructure(blocks) if blocks else None

    @property
    def perf_w_names(self) -> list[str]:
        """Names of the performance inputs (disturbances, noise, references)."""
        return self.w_names[self.nw - self.n_perf_w:]

    @property
    def perf_z_names(self) -> list[str]:
        """Names of the performance outputs."""
        return self.z_names[self.nz - self.n_perf_z:]

    def nominal_performance(self):
        """``P`` restricted to the performance channels: ``[perf w, u] -> [perf z, y]`` (Delta = 0)."""
        ins = self.perf_w_names + self.u_names
        outs = self.perf_z_names + self.y_names
        return PartitionedPlant(select_signals(self.P, ins, outs), self.nmeas, self.ncon)

    # ------------------------------------------------------------------ reports
    def table(self) -> Table:
        """One row per block: kind, size, and the names of its w and z channels."""
        rows = []
        w, z = self.w_names, self.z_names
        for blk, cs, rs in zip(self.blocks, self.blocks.row_slices(), self.blocks.col_slices()):
            rows.append((blk.name or "-", blk.kind, f"{blk.rows} x {blk.cols}",
                         _short(w[rs]), _short(z[cs])))
        rows.append(("control", "K", f"{self.ncon} x {self.nmeas}", _short(self.u_names),
                     _short(self.y_names)))
        return Table(("block", "kind", "size (w x z)", "w channels (Delta out)", "z channels (Delta in)"),
                     rows, title="Generalized plant: blocks and channels")

    def weight_table(self) -> Table:
        """One row per weight: role, size, states, gain at 0 Hz and at infinity."""
        rows = [(wt.role, wt.size, wt.system.nstates, wt.gain(0.0), wt.gain(np.inf)) for wt in self.weights]
        return Table(("weight", "size", "states", "gain at 0 Hz", "gain at inf"), rows,
                     title="Weights of the generalized plant")

    def plot(self, f_hz: Any = None, fig: Any = None) -> Any:
        """Largest singular value of every weight (and of the nominal ``y <- u``) against frequency.

        Parameters
        ----------
        f_hz : array_like, optional
            Frequencies in Hz (default: 400 log-spaced points over 1e-3 to 1e3 Hz).
        fig : matplotlib Figure, optional

        Returns
        -------
        matplotlib Figure
        """
        f = np.geomspace(1e-3, 1e3, 400) if f_hz is None else np.asarray(f_hz, dtype=float)
        fig, ax = single_axes(fig, 8.0, 4.5)
        for wt in self.weights:
            g = freqresp_array(wt.system, f)
            ax.loglog(f, np.linalg.norm(g, ord=2, axis=(1, 2)), label=f"{wt.role} ({wt.size})")
        nominal = freqresp_array(self.nominal_performance().sub("y", "u"), f)
        ax.loglog(f, np.linalg.norm(nominal, ord=2, axis=(1, 2)), "k--", lw=1, label="nominal y <- u")
        ax.set_xlabel("frequency (Hz)")
        ax.set_ylabel("largest singular value")
        ax.set_title("Weights of the generalized plant")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
        return fig

    def summary(self) -> str:
        """A few sentences in plain words."""
        unc = self.uncertainty_blocks
        unc_text = (
            f"{len(unc)} uncertainty block(s) ({', '.join(b.name or b.kind for b in unc)})"
            if unc else "no uncertainty block"
        )
        perf = (f"a {self.n_perf_w} x {self.n_perf_z} performance block" if self.n_perf_w
                else "no performance channel")
        return (
            f"Generalized plant with {self.P.nstates} states: w = {self.nw}, u = {self.ncon} -> "
            f"z = {self.nz}, y = {self.nmeas}; {unc_text} and {perf}; mussv blocks "
            f"{self.blocks.mussv().tolist()}; {len(self.weights)} weight(s)."
        )

    def _repr_html_(self) -> str:
        return f"<p>{html.escape(self.summary())}</p>" + self.table()._repr_html_() + (
            self.weight_table()._repr_html_() if self.weights else ""
        )

    def __repr__(self) -> str:
        return (
            f"GeneralizedPlant(states={self.P.nstates}, w={self.nw}, u={self.nu}, z={self.nz}, "
            f"y={self.ny}, blocks={self.blocks.mussv().tolist()})"
        )


def _short(names: Sequence[str], keep: int = 4) -> str:
    names = list(names)
    return ", ".join(names) if len(names) <= keep else ", ".join(names[:keep]) + f", ... ({len(names)})"


# ============================================================================ weights
def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)


def _weight(spec: Any, what: str, *, n_in: int | None = None, n_out: int | None = None):
    """A weight as a ``control.StateSpace``: stable, proper, continuous-time, of the asked size.

    ``spec``: a number ``c > 0`` (``c I``), a SISO system (repeated on the diagonal), a MIMO
    system or a result with ``.weight`` (a cover). ``n_in`` / ``n_out``: required numbers of
    inputs / outputs (None: any); a number or a SISO weight is repeated to the fixed one.
    """
    import control

    n_rep = n_in if n_in is not None else n_out
    if hasattr(spec, "weight") and not isinstance(spec, (control.LTI, np.ndarray)):
        spec = spec.weight
    if _is_number(spec):
        c = float(spec)
        if not np.isfinite(c) or c <= 0:
            raise ModelError(
                f"{what} must be a number > 0 (e.g. 0.04 for 4 %) or a stable weight system; got {spec!r}. "
                "Pass None to leave it out."
            )
        return control.ss(np.zeros((0, 0)), np.zeros((0, n_rep)), np.zeros((n_rep, 0)), c * np.eye(n_rep))
    if isinstance(spec, control.TransferFunction):
        _check_proper(spec, what)
    W = as_statespace(spec, name=what)
    if W.isdtime(strict=True):
        raise ModelError(f"{what} is discrete-time (dt={W.dt}); weights are continuous-time.")
    if not is_stable(W, margin=0.0):
        poles = np.linalg.eigvals(np.asarray(W.A, float))
        bad = poles[poles.real >= 0]
        raise ModelError(
            f"{what} must be stable; it has poles {np.round(bad, 6).tolist()} rad/s in the closed right "
            "half plane, which no controller can move (they are not reachable from u). Move them into the "
            "left half plane, e.g. an integrator 1/s becomes 1/(s + 1e-3)."
        )
    if (W.ninputs, W.noutputs) == (1, 1) and n_rep > 1:
        return _repeat(W, n_rep)
    if (n_in is not None and W.ninputs != n_in) or (n_out is not None and W.noutputs != n_out):
        want = f"{'k' if n_out is None else n_out} x {'k' if n_in is None else n_in}"
        raise ModelError(
            f"{what} must be SISO (repeated on each channel) or {want} (outputs x inputs); "
            f"got {W.noutputs} x {W.ninputs}."
        )
    return W


def _additive_weight(spec: Any, nu: int, ny: int):
    """SISO or ``nu x nu`` (on the plant inputs), or ``ny x ny`` (on the plant outputs)."""
    what = "additive (the additive uncertainty weight)"
    try:
        return _weight(spec, what, n_in=nu, n_out=nu)
    except ModelError as exc:
        if ny == nu or "must be SISO" not in str(exc):
            raise
    try:
        return _weight(spec, what, n_in=ny, n_out=ny)
    except ModelError as exc:
        raise ModelError(
            f"{what} must be SISO, {nu} x {nu} (on the plant inputs) or {ny} x {ny} (on the plant outputs); "
            f"{exc}"
        ) from exc


def _check_proper(tf: Any, what: str) -> None:
    for i in range(tf.noutputs):
        for j in range(tf.ninputs):
            num = np.trim_zeros(np.atleast_1d(np.asarray(tf.num_array[i, j], float)), "f")
            den = np.trim_zeros(np.atleast_1d(np.asarray(tf.den_array[i, j], float)), "f")
            if num.size > den.size:
                raise ModelError(
                    f"{what} is improper (numerator degree {num.size - 1} > denominator degree "
                    f"{den.size - 1} in channel ({i}, {j})); add poles above the band of interest, "
                    "e.g. s/(s/1000 + 1) instead of s."
                )


def _repeat(W: Any, n: int):
    """``diag(W, ..., W)`` (n copies) of a SISO weight."""
    import control

    copies = [control.ss(W.A, W.B, W.C, W.D, inputs=[f"i{k}"], outputs=[f"o{k}"]) for k in range(n)]
    return block_diagonal(*copies)


# ============================================================================ wiring
class _Wiring:
    """Static sum nodes between named sources and sinks, closed around ``diag(components)``.

    Sources are the external inputs (w, u) and the component outputs; sinks are the
    component inputs and the external outputs (z, y). Each sink is a dict source -> gain.
    """

    def __init__(self) -> None:
        self.components: list[Any] = []
        self.sinks: dict[str, dict[str, float]] = {}

    def component(self, key: str, system: Any, inputs: list[dict[str, float]]) -> list[dict[str, float]]:
        """Add ``system`` fed by the signals ``inputs``; return its outputs as signals."""
        import control

        ins = [f"{key}:in[{i}]" for i in range(system.ninputs)]
        outs = [f"{key}:out[{i}]" for i in range(system.noutputs)]
        self.components.append(control.ss(system.A, system.B, system.C, system.D, inputs=ins, outputs=outs))
        for name, sig in zip(ins, inputs, strict=True):
            self.sinks[name] = sig
        return [{o: 1.0} for o in outs]

    def close(self, w: list[str], u: list[str], z: list[tuple[str, dict]], y: list[tuple[str, dict]]):
        """``Fu(wiring, diag(components))`` with inputs ``w + u`` and outputs ``z + y``."""
        import control

        comp_in = [n for c in self.components for n in c.input_labels]
        comp_out = [n for c in self.components for n in c.output_labels]
        sinks = comp_in + [n for n, _ in z] + [n for n, _ in y]
        equations = [self.sinks[n] for n in comp_in] + [e for _, e in z] + [e for _, e in y]
        sources = comp_out + list(w) + list(u)
        D = np.zeros((len(sinks), len(sources)))
        index = {n: j for j, n in enumerate(sources)}
        for i, eq in enumerate(equations):
            for src, g in eq.items():
                D[i, index[src]] += g
        wiring = control.ss(np.zeros((0, 0)), np.zeros((0, len(sources))), np.zeros((len(sinks), 0)), D,
                            inputs=sources, outputs=sinks)
        return upper_lft(wiring, block_diagonal(*self.components))


def _signals(names: Sequence[str]) -> list[dict[str, float]]:
    return [{n: 1.0} for n in names]


def _add(*vectors: list[dict[str, float]] | None) -> list[dict[str, float]]:
    """Elementwise sum of signal vectors (None entries skipped)."""
    vectors = [v for v in vectors if v is not None]
    out = [dict() for _ in vectors[0]]
    for v in vectors:
        if len(v) != len(out):
            raise ModelError("internal: adding signal vectors of different lengths.")
        for acc, sig in zip(out, v):
            for k, g in sig.items():
                acc[k] = acc.get(k, 0.0) + g
    return out


def _labels(prefix: str, names: Sequence[str], count: int) -> list[str]:
    """``prefix[name]`` per channel when the count matches the plant's names, else ``prefix[i]``.

    python-control's default names (``u[0]``, ``y[0]``) say nothing and give ``prefix[0]``.
    """
    default = is_default_names(names, "u") or is_default_names(names, "y")
    if count == len(names) and not default:
        return [f"{prefix}[{n}]" for n in names]
    return [f"{prefix}[{i}]" for i in range(count)]


# ============================================================================ generalized plant
def _disturbance_specs(disturbances: Any) -> dict[str, Any]:
    if disturbances is None:
        return {}
    if isinstance(disturbances, Mapping):
        unknown = set(disturbances) - {"input", "output"}
        if unknown:
            raise ModelError(
                f"disturbances takes a weight (at the plant input) or a dict with keys 'input' and/or "
                f"'output'; got keys {sorted(unknown)}."
            )
        return {k: v for k, v in disturbances.items() if v is not None}
    return {"input": disturbances}


def generalized_plant(
    nominal: Any,
    *,
    additive: Any = None,
    input_mult: Any = None,
    output_mult: Any = None,
    performance: Any = None,
    control_weight: Any = None,
    disturbances: Any = None,
    noise: Any = None,
    mult_structure: str = "full",
    check_rank: bool = True,
    additive_input: str = "plant",
) -> GeneralizedPlant:
    """The mu / H-infinity interconnection of a nominal model with uncertainty and performance weights.

    Caltech seed paper, Fig. 1 (``Delta`` on the upper channels, ``K`` on the lower ones);
    additive uncertainty eq. (2) with a weight like eq. (14); multiplicative eq. (3).

    Parameters
    ----------
    nominal : system, UncertainSystem or UncertainModel
        Anything ``rc.as_statespace`` takes (PhysicalModel, MeasurementModel, StateSpace,
        transfer function): ``nu`` inputs (actuators, the control ``u``) and ``ny`` outputs
        (sensors, the measurement ``y``). Its names name ``u`` and ``y``. An
        :class:`~robustctl.robust.uncertainty.system.UncertainSystem` (``rc.ureal`` ... times a
        system) brings its LFT: its elements' channels come first in ``w`` and ``z`` and their
        blocks (real, complex, full, named after the elements) first in ``.blocks``; the
        nominal ``G`` is the LFT at ``Delta = 0`` (ranges' centres). An
        :class:`~robustctl.physical.uncertain.UncertainModel` (``upd.uncertain()``) brings its
        real parameters: their channels come first in ``w`` and ``z`` and their repeated real
        scalar blocks first in ``.blocks`` (then the weights' blocks, as below). Its
        remainder cover (:func:`~robustctl.robust.uncertainty.cover.cover_remainder`), if any, is the
        weight of its kind (additive or multiplicative; that argument must then be None).
    additive : weight, optional
        Additive uncertainty ``G + W_a Delta``: a SISO weight (``W_a I``), an ``nu x nu``
        system (on the plant inputs), an ``ny x ny`` system (on the outputs), or a cover
        result with ``.weight``. Block ``"additive"``: ``ny x nu``.
    input_mult, output_mult : number or weight, optional
        Multiplicative uncertainty at the plant input ``G (I + Delta W_i)`` / output
        ``(I + Delta W_o) G``: a number (0.04 = 4 %, a constant weight) or a weight system.
        Blocks ``"input multiplicative"`` (``nu x nu``) and ``"output multiplicative"`` (``ny x ny``).
    performance : weight, optional
        Weight ``W_p`` on the true sensor outputs (the seed's performance on the sensors);
        SISO or ``k x ny``. Outputs ``perf_y[...]``.
    control_weight : number or weight, optional
        Weight ``W_u`` on the control (SISO or ``k x nu``); outputs ``perf_u[...]``.
    disturbances : weight or dict, optional
        A weight ``W_d`` (disturbances at the plant input, ``nu`` outputs: SISO or ``nu x k``),
        or ``{"input": W_di, "output": W_do}`` (output disturbances add to the sensors).
        Inputs ``dist[...]`` and ``dist_out[...]``.
    noise : number or weight, optional
        Sensor-noise weight ``W_n`` (SISO or ``ny x k``); inputs ``noise[...]``.
    mult_structure : {"full", "diagonal", "repeated"}
        Structure of each multiplicative ``Delta``: one full complex block (default; couples
        the channels), one complex scalar per channel (``"diagonal"``: independent actuator /
        sensor errors), or one repeated complex scalar ``delta I`` (``"repeated"``). The
        channels, and so ``P``, are the same; only ``blocks`` changes.
    additive_input : {"plant", "control"}
        What the additive block reads: ``"plant"`` (default) the total plant input ``u_G = u
        + input perturbation + input disturbance`` (the additive error acts on what the plant
        receives), ``"control"`` the controller's ``u`` only. With ``"plant"`` and unit input
        disturbances, ``W_a Delta`` sees the disturbance directly, so the closed loop
        ``d -> z_add`` has a feedthrough ``W_a(inf)`` and, with a unit performance channel on
        the same path, ``gamma >= sqrt(2)`` for any controller; ``"control"`` removes that floor.
    check_rank : bool
        Refuse a plant whose ``D12`` (u -> z) lacks full column rank or ``D21`` (w -> y)
        lacks full row rank, which the Riccati H-infinity solution needs (default). The
        message names the missing weight; ``False`` builds it anyway (mu analysis, LMI
        synthesis). No tiny weight is ever added silently.

    Returns
    -------
    GeneralizedPlant
        ``w = [unc_add_in[y..], unc_inmult_in[u..], unc_outmult_in[y..], dist.., dist_out..,
        noise..]``, ``u`` = nominal input names; ``z = [unc_add_out[u..], unc_inmult_out[u..],
        unc_outmult_out[y..], perf_y.., perf_u..]``, ``y`` = nominal output names. Block order:
        additive, input multiplicative, output multiplicative, performance.

    Raises
    ------
    ModelError
        A weight that is improper, unstable, discrete-time or of the wrong size; a
        multiplicative level <= 0; performance outputs without performance inputs (or the
        reverse); nothing to build; a rank-deficient D12 / D21 (``check_rank=True``).
    """

    check_rank = flag(check_rank, "check_rank", ModelError)
    if additive_input not in ("plant", "control"):
        raise ModelError(f"additive_input must be 'plant' (u + input perturbation + disturbance) or "
                         f"'control' (u only); got {additive_input!r}.")
    if isinstance(nominal, UncertainSystem):
        nominal = nominal.plant_lft()
    unc = nominal if _is_uncertain_model(nominal) else None
    G = unc.nominal if unc is not None else as_statespace(nominal, name="nominal")
    if G.isdtime(strict=True):
        raise ModelError(
            f"the nominal model is discrete-time (dt={G.dt}); the generalized plant is continuous-time."
        )
    _mult_blocks(mult_structure, ["check"], "")  # refuse a bad structure before any work
    if unc is not None and unc.remainder is not None:
        additive, input_mult, output_mult = _with_remainder(unc.remainder, additive, input_mult, output_mult)
    W = _plant_weights(G, additive, input_mult, output_mult, performance, control_weight, disturbances, noise,
                       parametric=unc is not None)
    gp = _PlantBuilder(G, W, mult_structure, unc, additive_input).build()
    if check_rank:
        _check_regular(gp)
    return gp


def _with_remainder(rem: Any, additive: Any, input_mult: Any, output_mult: Any) -> tuple[Any, Any, Any]:
    """The weights with an UncertainModel's remainder cover in the slot of its kind."""
    slots = {"additive": 0, "input multiplicative": 1, "output multiplicative": 2}
    given = [additive, input_mult, output_mult]
    k = slots.get(getattr(rem, "kind", None))
    if k is None:
        raise ModelError(
            f"the uncertain model's remainder has an unknown kind {getattr(rem, 'kind', None)!r}.")
    if given[k] is not None:
        name = ("additive", "input_mult", "output_mult")[k]
        raise ModelError(
            f"the uncertain model carries a {rem.kind} remainder cover and {name}= is given too: one "
            f"{rem.kind} weight per plant. Cover both in the remainder (rc.cover_remainder over the data and "
            f"models), or pass um.with_remainder(None) to use {name}= alone."
        )
    given[k] = rem.weight
    return given[0], given[1], given[2]


def _is_uncertain_model(x: Any) -> bool:
    """An :class:`~robustctl.physical.uncertain.UncertainModel` (a parametric LFT) or an
    uncertain system's :class:`~robustctl.robust.uncertainty.system.PlantLFT`."""
    return isinstance(x, (UncertainModel, PlantLFT))


def _plant_weights(G, additive, input_mult, output_mult, performance, control_weight, disturbances,
                   noise, parametric: bool = False) -> dict[str, Any]:
    """Every weight sized and checked (None where not given); refuse unpaired performance channels."""
    nu, ny = G.ninputs, G.noutputs
    dist = _disturbance_specs(disturbances)
    specs = {
        "Wa": (additive, None),
        "Wi": (input_mult, dict(what="input_mult (input multiplicative weight)", n_in=nu, n_out=nu)),
        "Wo": (output_mult, dict(what="output_mult (output multiplicative weight)", n_in=ny, n_out=ny)),
        "Wp": (performance, dict(what="performance (the performance weight)", n_in=ny)),
        "Wu": (control_weight, dict(what="control_weight", n_in=nu)),
        "Wdi": (dist.get("input"), dict(what="disturbances (the input-disturbance weight)", n_out=nu)),
        "Wdo": (dist.get("output"), dict(what="disturbances (the output-disturbance weight)", n_out=ny)),
        "Wn": (noise, dict(what="noise (the sensor-noise weight)", n_out=ny)),
    }
    W: dict[str, Any] = {}
    for key, (spec, kw) in specs.items():
        if spec is None:
            W[key] = None
        elif key == "Wa":
            W[key] = _additive_weight(spec, nu, ny)
        else:
            W[key] = _weight(spec, kw.pop("what"), **kw)
    n_perf_w = sum(W[k].ninputs for k in ("Wdi", "Wdo", "Wn") if W[k] is not None)
    n_perf_z = sum(W[k].noutputs for k in ("Wp", "Wu") if W[k] is not None)
    _check_performance_pairs(n_perf_w, n_perf_z)
    if n_perf_w == 0 and all(W[k] is None for k in ("Wa", "Wi", "Wo")) and not parametric:
        raise ModelError(
            "nothing to build: give at least one uncertainty weight (additive, input_mult, output_mult) "
            "or performance channels (performance/control_weight with disturbances/noise)."
        )
    return W


class _PlantBuilder:
    """The signal flow of the module docstring, one step per uncertainty / performance piece."""

    def __init__(self, G: Any, W: dict[str, Any], mult_structure: str, unc: Any = None,
                 additive_input: str = "plant") -> None:
        self.G, self.W, self.structure, self.unc = G, W, mult_structure, unc
        self.additive_input = additive_input
        self.u_names, self.y_names = list(G.input_labels), list(G.output_labels)
        self.net = _Wiring()
        self.u = _signals(self.u_names)
        self.w_names: list[str] = []
        self.z_eqs: list[tuple[str, dict]] = []
        self.blocks: list[Block] = []
        self.weights: list[PlantWeight] = []

    def _channels(self, prefix: str, names: Sequence[str], key: str) -> list[str]:
        W = self.W[key]
        return [] if W is None else _labels(prefix, names, W.ninputs)

    def _weighted(self, key: str, names: list[str]):
        return None if self.W[key] is None else self.net.component(key, self.W[key], _signals(names))

    def _record(self, key: str, role: str) -> bool:
        if self.W[key] is not None:
            self.weights.append(PlantWeight(role, self.W[key]))
        return self.W[key] is not None

    def build(self) -> GeneralizedPlant:
        W, u_names, y_names = self.W, self.u_names, self.y_names
        d_in = self._channels("dist", u_names, "Wdi")
        d_out = self._channels("dist_out", y_names, "Wdo")
        noise = self._channels("noise", y_names, "Wn")
        w_im = _labels("unc_inmult_in", u_names, len(u_names)) if W["Wi"] is not None else []
        uG = _add(self.u, _signals(w_im) if w_im else None, self._weighted("Wdi", d_in))
        y_add = self._additive(uG)
        self._input_mult(w_im)
        y_true = self._output_mult(y_add)
        if W["Wdo"] is not None:
            y_true = _add(y_true, self._weighted("Wdo", d_out))
        y_meas = _add(y_true, self._weighted("Wn", noise)) if W["Wn"] is not None else y_true
        self.w_names += d_in + d_out + noise
        n_perf_w, n_perf_z = self._performance(y_true, d_in + d_out + noise)
        P = self.net.close(self.w_names, u_names, self.z_eqs, list(zip(y_names, y_meas)))
        return GeneralizedPlant(P, len(y_names), len(u_names), BlockStructure(tuple(self.blocks)),
                                n_perf_w, n_perf_z, tuple(self.weights))

    def _additive(self, uG):
        """``y_add = G u_G + W_a Delta_add (...)``; the weight on the z side (inputs) or w side (outputs)."""
        if self.unc is None:
            gout = self.net.component("G", self.G, uG)
        else:  # the parametric LFT's channels first: one repeated real scalar block per axis
            unc = self.unc
            nd = unc.n_delta
            nz = getattr(unc, "n_z", nd)
            w_par = list(unc.M.input_labels[:nd])
            outs = self.net.component("G", unc.M, _signals(w_par) + uG)
            self.w_names += w_par
            self.z_eqs += list(zip(list(unc.M.output_labels[:nz]), outs[:nz]))
            if isinstance(unc, PlantLFT):
                self.blocks += list(unc.blocks.blocks)
            else:
                self.blocks += [Block("real", r, r, name) for name, r in zip(unc.names, unc.multiplicity)]
            gout = outs[nz:]
        if not self._record("Wa", "additive uncertainty"):
            return gout
        ny, nu = len(self.y_names), len(self.u_names)
        w_add = _labels("unc_add_in", self.y_names, ny)
        Wa = self.W["Wa"]
        src = uG if self.additive_input == "plant" else self.u
        if (Wa.ninputs, Wa.noutputs) == (nu, nu):
            z_add, y_add = self.net.component("Wa", Wa, src), _add(gout, _signals(w_add))
        else:
            z_add, y_add = src, _add(gout, self._weighted("Wa", w_add))
        self.w_names += w_add
        self.z_eqs += list(zip(_labels("unc_add_out", self.u_names, nu), z_add))
        self.blocks.append(Block("full", ny, nu, "additive"))
        return y_add

    def _input_mult(self, w_im: list[str]) -> None:
        """``z_im = W_i u``; ``w_im`` adds to the plant input."""
        if self._record("Wi", "input multiplicative uncertainty"):
            self.w_names += w_im
            z = self.net.component("Wi", self.W["Wi"], self.u)
            self.z_eqs += list(zip(_labels("unc_inmult_out", self.u_names, len(self.u_names)), z))
            self.blocks += _mult_blocks(self.structure, self.u_names, "input multiplicative")

    def _output_mult(self, y_add):
        """``z_om = W_o y_add``, ``y_true = y_add + w_om``."""
        if not self._record("Wo", "output multiplicative uncertainty"):
            return y_add
        ny = len(self.y_names)
        w_om = _labels("unc_outmult_in", self.y_names, ny)
        self.w_names += w_om
        z = self.net.component("Wo", self.W["Wo"], y_add)
        self.z_eqs += list(zip(_labels("unc_outmult_out", self.y_names, ny), z))
        self.blocks += _mult_blocks(self.structure, self.y_names, "output multiplicative")
        return _add(y_add, _signals(w_om))

    def _performance(self, y_true, perf_w: list[str]) -> tuple[int, int]:
        """``z_perf = [W_p y_true; W_u u]`` and the performance block last."""
        for key, role in (("Wdi", "input disturbance"), ("Wdo", "output disturbance"),
                          ("Wn", "sensor noise")):
            self._record(key, role)
        n_z = 0
        for key, role, prefix, names, source in (
            ("Wp", "performance on the sensors", "perf_y", self.y_names, y_true),
            ("Wu", "control weight", "perf_u", self.u_names, self.u),
        ):
            if self._record(key, role):
                z = self.net.component(key, self.W[key], source)
                self.z_eqs += list(zip(_labels(prefix, names, self.W[key].noutputs), z))
                n_z += len(z)
        if perf_w:
            self.blocks.append(Block("full", len(perf_w), n_z, "performance"))
        return len(perf_w), n_z


def _mult_blocks(structure: str, names: Sequence[str], label: str) -> list[Block]:
    """The blocks of one multiplicative uncertainty over ``names`` channels."""
    n = len(names)
    if not isinstance(structure, str):
        structure = repr(structure)  # refused below, by name
    if structure == "full":
        return [Block("full", n, n, label)]
    if structure == "diagonal":
        return [Block("full", 1, 1, f"{label} [{name}]") for name in names]
    if structure == "repeated":
        return [Block("complex", n, n, label)]
    raise ModelError(f"mult_structure must be 'full', 'diagonal' or 'repeated'; got {structure!r}.")


def _check_performance_pairs(n_perf_w: int, n_perf_z: int) -> None:
    if n_perf_z and not n_perf_w:
        raise ModelError(
            "performance outputs (performance= / control_weight=) need performance inputs: give "
            "disturbances= (e.g. at the plant input) and/or noise= (sensor noise)."
        )
    if n_perf_w and not n_perf_z:
        raise ModelError(
            "disturbances= / noise= need performance outputs: give performance= (a weight on the sensors) "
            "and/or control_weight= (a weight on u)."
        )


def _rank(M: np.ndarray) -> int:
    if M.size == 0:
        return 0
    sv = np.linalg.svd(M, compute_uv=False)
    return int(np.sum(sv > RANK_TOL * max(1.0, sv[0])))


def _check_regular(gp: GeneralizedPlant) -> None:
    """Full-rank D12 and D21 (Zhou, Doyle & Glover 1996, sec. 14.1 assumption A2 / (A3))."""
    m = gp.matrices()
    r12, r21 = _rank(m["D12"]), _rank(m["D21"])
    fix = "or pass check_rank=False to build it anyway (mu analysis, hinfsyn(method='lmi'))."
    if r12 < gp.ncon:
        raise ModelError(
            f"D12 (u -> z at infinite frequency) has rank {r12} < ncon = {gp.ncon}: some control input "
            "is not penalised at high frequency, which the Riccati H-infinity solution needs. Give "
            "control_weight= (e.g. 1e-3, a small weight on u) or a constant input_mult=, " + fix
        )
    if r21 < gp.nmeas:
        raise ModelError(
            f"D21 (w -> y at infinite frequency) has rank {r21} < nmeas = {gp.nmeas}: some sensor is "
            "noise free at high frequency, which the Riccati H-infinity solution needs. Give noise= "
            "(e.g. 1e-3, sensor noise) or a constant output_mult=, " + fix
        )


# ============================================================================ mixed sensitivity
def mixed_sensitivity(G: Any, W1: Any = None, W2: Any = None, W3: Any = None) -> GeneralizedPlant:
    """Mixed-sensitivity plant ``z = [W1 S; W2 K S; W3 T] r`` (MATLAB / python-control ``augw``).

    ``P = [[W1, -W1 G], [0, W2], [0, W3 G], [I, -G]]`` (Skogestad & Postlethwaite 2005,
    eq. 9.80): inputs ``[ref[y..], u]``, outputs ``[perf_e[..], perf_u[..], perf_y[..], e[y..]]``
    with the error ``e = r - G u`` as the measurement, so ``Fl(P, K)`` is
    ``[W1 S; W2 K S; W3 T]`` for ``u = K e``.

    Parameters
    ----------
    G : system
        Anything ``rc.as_statespace`` takes (``ny x nu``).
    W1, W2, W3 : weight, optional
        On the sensitivity ``S`` (SISO or ``k x ny``), on ``K S`` (SISO or ``k x nu``), on
        ``T`` (SISO or ``k x ny``); numbers are constant weights. At least one is needed.

    Returns
    -------
    GeneralizedPlant
        One full ``ny x nz`` performance block; no rank check (like ``augw``).
    """
    Gs = as_statespace(G, name="G")
    if Gs.isdtime(strict=True):
        raise ModelError(
            f"G is discrete-time (dt={Gs.dt}); the mixed-sensitivity plant is continuous-time (hinfsyn "
            "designs in continuous time): pass the continuous plant and discretise the controller afterwards."
        )
    nu, ny = Gs.ninputs, Gs.noutputs
    u_names, y_names = list(Gs.input_labels), list(Gs.output_labels)
    W = [None if spec is None else _weight(spec, what, n_in=n)
         for spec, n, what in ((W1, ny, "W1 (weight on S)"), (W2, nu, "W2 (weight on KS)"),
                               (W3, ny, "W3 (weight on T)"))]
    if all(w is None for w in W):
        raise ModelError("mixed_sensitivity needs at least one of W1, W2, W3.")
    net = _Wiring()
    r_names = _labels("ref", y_names, ny)
    gout = net.component("G", Gs, _signals(u_names))
    e = _add(_signals(r_names), [{k: -g for k, g in sig.items()} for sig in gout])
    z_eqs: list[tuple[str, dict]] = []
    weights: list[PlantWeight] = []
    for Wk, prefix, names, source, role in (
        (W[0], "perf_e", y_names, e, "W1 on S"),
        (W[1], "perf_u", u_names, _signals(u_names), "W2 on KS"),
        (W[2], "perf_y", y_names, gout, "W3 on T"),
    ):
        if Wk is not None:
            weights.append(PlantWeight(role, Wk))
            z_eqs += list(zip(_labels(prefix, names, Wk.noutputs), net.component(prefix, Wk, source)))
    e_names = _labels("e", y_names, ny)
    P = net.close(r_names, u_names, z_eqs, list(zip(e_names, e)))
    nz = len(z_eqs)
    return GeneralizedPlant(P, ny, nu, BlockStructure((Block("full", ny, nz, "performance"),)), ny, nz,
                            tuple(weights))
