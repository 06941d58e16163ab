"""The uncertain system: named uncertain elements combined with systems by arithmetic.

``G(Delta) = Fu(M, Delta)`` with ``Delta = diag(Delta_1 (x) I_{r_1}, ...)``, one block per
element (a real or complex scalar repeated ``r_j`` times, or ``r_j`` copies of a dynamics
block), each normalised to the unit ball (:mod:`.elements`). Sums, products, feedback,
inverses and concatenations of LFTs are LFTs of the stacked perturbation (Zhou, Doyle &
Glover 1996, sec. 10.2; :mod:`.lft_algebra`); after every operation the channels of one
element are grouped into one repeated block and the copies the structure does not need are
removed by the structured Kalman reduction of Beck & Doyle (1999) (:func:`.lft_algebra.
reduce_scalar_blocks`), so e.g. ``k * G + k * H`` uses ``k`` once, not twice.

The operators follow python-control: ``G1 * G2`` is the series connection ``u -> G2 -> G1``,
``G.feedback(K, sign=-1)`` is ``u = r - K y`` (the one loop sign of robustctl; see
:mod:`robustctl.robust.conventions`), ``1 / G`` the inverse where the feedthrough is
invertible. MATLAB ``uss``, RobustAndOptimalControl.jl ``UncertainSS``.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...checks import check_seed, integer, is_default_names
from ...errors import SynthesisError
from ...lti import as_statespace
from .blocks import Block, BlockStructure
from .elements import UncertainComplex, UncertainDynamics, UncertainReal, register_system
from .lft_algebra import Raw, close_channels, connect, invert, permute_delta, reduce_scalar_blocks

__all__ = ["UncertainSystem", "LFTData", "PlantLFT", "as_uncertain", "append", "hstack", "vstack"]

_ELEMENTS = (UncertainReal, UncertainComplex, UncertainDynamics)


@dataclass(frozen=True)
class LFTData:
    """``G = Fu(M, Delta)`` (MATLAB ``lftdata``).

    Attributes
    ----------
    M : control.StateSpace or Raw
        Inputs ``[w; u]``, outputs ``[z; y]``; a :class:`.lft_algebra.Raw` when complex.
    blocks : BlockStructure
        One block per element (named after it): ``"real"``/``"complex"`` repeated scalars of
        multiplicity ``r``, ``"full"`` ``ny x nu`` blocks (one per copy of a dynamics element).
    elements : tuple
        The elements in block order (a dynamics element once per copy).
    """

    M: Any
    blocks: BlockStructure
    elements: tuple


@dataclass(frozen=True)
class PlantLFT:
    """An uncertain system's LFT as :func:`robustctl.robust.plant.generalized_plant` takes it.

    Attributes
    ----------
    M : control.StateSpace
        Inputs ``[w; u]``, outputs ``[z; y]`` (``w``/``z`` named ``<element>_w[i]``/``_z[i]``).
    nominal : control.StateSpace
        ``Fu(M, 0)`` with the system's signal names (the ranges' centres).
    n_delta, n_z : int
        Number of ``w`` and ``z`` channels.
    blocks : BlockStructure
        The elements' blocks in channel order.
    remainder : None
        No remainder cover (the field an ``UncertainModel`` has).
    """

    M: Any
    nominal: Any
    n_delta: int
    n_z: int
    blocks: BlockStructure
    remainder: Any = None


class UncertainSystem:
    """An uncertain LTI system ``Fu(M, Delta)`` with named elements and named signals.

    Build it by arithmetic (``rc.ureal("k", 2, percent=10) * G``, ``G.feedback(K)``, ...) or
    with :func:`as_uncertain`. Elements are normalised to the unit ball; values given to
    :meth:`substitute` are in the elements' own units.

    Attributes
    ----------
    raw : Raw
        The partitioned realisation (inputs ``[w; u]``, outputs ``[z; y]``).
    blocks : tuple of (element, copies)
        In channel order; a scalar element's block has ``copies`` w- and z-channels, a
        dynamics element's ``copies * ny`` w- and ``copies * nu`` z-channels.
    inputs, outputs : tuple of str
    dt : float
        0 for continuous time, else the sample time (s).
    """

    __array_priority__ = 1000

    def __init__(self, raw: Raw, blocks: tuple, inputs: Any, outputs: Any, dt: float = 0.0):
        self.raw = raw
        self.blocks = tuple(blocks)
        self.inputs = tuple(inputs)
        self.outputs = tuple(outputs)
        self.dt = float(dt or 0.0)
        if len(self.inputs) != raw.nu or len(self.outputs) != raw.ny:
            raise SynthesisError(
                f"an uncertain system needs one name per input ({raw.nu}) and output ({raw.ny}); "
                f"got {len(self.inputs)} and {len(self.outputs)}.")

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_element(cls, e: Any) -> UncertainSystem:
        """The one-element system (``Fu([[0, I], [h I, c]], delta)``)."""
        if isinstance(e, UncertainReal):
            D = np.array([[0.0, 1.0], [e.half_range, e.center]])
        elif isinstance(e, UncertainComplex):
            D = np.array([[0.0, 1.0], [e.radius, e.nominal]], complex)
        elif isinstance(e, UncertainDynamics):
            D = np.block([[np.zeros((e.nu, e.ny)), np.eye(e.nu)],
                          [e.bound * np.eye(e.ny), np.zeros((e.ny, e.nu))]])
        else:
            raise SynthesisError(f"not an uncertain element: {e!r}.")
        ny, nu = e.shape
        nw, nz = ny, nu
        raw = Raw(np.zeros((0, 0)), np.zeros((0, nw + nu), D.dtype), np.zeros((nz + ny, 0), D.dtype),
                  D, nw, nz)
        ins = [f"u[{i}]" for i in range(nu)]
        outs = [f"y[{i}]" for i in range(ny)]
        return cls(raw, ((e, 1),), ins, outs)

    @classmethod
    def from_system(cls, G: Any) -> UncertainSystem:
        """A certain system (anything :func:`robustctl.lti.as_statespace` takes) without elements."""
        ss = as_statespace(G, name="system")
        A, B, C, D = (np.asarray(x, float) for x in (ss.A, ss.B, ss.C, ss.D))
        return cls(Raw(A, B, C, D, 0, 0), (), ss.input_labels, ss.output_labels, ss.dt or 0.0)

    # ------------------------------------------------------------------ structure
    @property
    def elements(self) -> dict:
        """``{name: element}`` in block order."""
        return {e.name: e for e, _ in self.blocks}

    @property
    def multiplicity(self) -> dict:
        """``{name: copies}``: how often each element appears in the LFT."""
        return {e.name: c for e, c in self.blocks}

    @property
    def shape(self) -> tuple[int, int]:
        return (self.raw.ny, self.raw.nu)

    @property
    def ninputs(self) -> int:
        return self.raw.nu

    @property
    def noutputs(self) -> int:
        return self.raw.ny

    @property
    def nstates(self) -> int:
        return self.raw.nx

    def _widths(self) -> tuple[list[int], list[int]]:
        return ([c * e.shape[0] for e, c in self.blocks], [c * e.shape[1] for e, c in self.blocks])

    def block_structure(self) -> BlockStructure:
        """The structure of ``Delta`` for mu-analysis (real parameters as real blocks)."""
        out = []
        for e, c in self.blocks:
            if isinstance(e, UncertainReal):
                out.append(Block("real", c, c, e.name))
            elif isinstance(e, UncertainComplex):
                out.append(Block("complex", c, c, e.name))
            else:
                out += [Block("full", e.ny, e.nu, e.name if k == 0 else f"{e.name}#{k + 1}")
                        for k in range(c)]
        if not out:
            raise SynthesisError("this system has no uncertain elements (no block structure).")
        return BlockStructure(tuple(out))

    def lft(self) -> LFTData:
        """``M`` and the block structure with ``G = Fu(M, Delta)`` (MATLAB ``lftdata``)."""
        import control

        r = self.raw
        names_w, names_z = [], []
        for e, c in self.blocks:
            nw, nz = c * e.shape[0], c * e.shape[1]
            names_w += [f"{e.name}_w[{i}]" for i in range(nw)]
            names_z += [f"{e.name}_z[{i}]" for i in range(nz)]
        elems = tuple(e for e, c in self.blocks for _ in range(c if isinstance(e, UncertainDynamics) else 1))
        bs = self.block_structure() if self.blocks else None
        if any(np.iscomplexobj(x) for x in (r.A, r.B, r.C, r.D)):
            return LFTData(r, bs, elems)
        M = control.ss(r.A, r.B, r.C, r.D, self.dt or 0, inputs=names_w + list(self.inputs),
                       outputs=names_z + list(self.outputs))
        return LFTData(M, bs, elems)

    def plant_lft(self) -> PlantLFT:
        """The LFT for :func:`robustctl.robust.plant.generalized_plant` (real matrices only).

        Raises
        ------
        SynthesisError
            No elements, complex data (a complex nominal), or a discrete-time system.
        """
        import control

        if not self.blocks:
            raise SynthesisError("this system has no uncertain elements; pass it as a plain system.")
        if self.dt:
            raise SynthesisError("the generalized plant is continuous-time; map the system with "
                                 "rc.d2c first.")
        data = self.lft()
        if not isinstance(data.M, control.StateSpace):
            raise SynthesisError(
                "a complex uncertain element with a complex nominal makes the plant complex; "
                "python-control's systems are real. Use a real nominal (the complex radius stays).")
        r = self.raw
        nominal = control.ss(r.A, r.B[:, r.nw:], r.C[r.nz:], r.D[r.nz:, r.nw:],
                             inputs=list(self.inputs), outputs=list(self.outputs))
        return PlantLFT(data.M, nominal, r.nw, r.nz, data.blocks)

    # ------------------------------------------------------------------ normalisation
    def _normalized(self, values: dict, fill_nominal: bool, strict: bool = True) -> dict:
        """``{name: normalised value}`` (a number, or a Raw of normalised dynamics); names of
        other elements are refused when ``strict`` (else ignored: samples of a larger system)."""
        out = {}
        known = self.elements
        unknown = set(values) - set(known)
        if unknown and strict:
            raise SynthesisError(
                f"no uncertain element named {sorted(unknown)}; the elements are {list(known)}.")
        for name, e in known.items():
            if name not in values:
                if fill_nominal:
                    out[name] = (0.0 if isinstance(e, (UncertainComplex, UncertainDynamics))
                                 else e.to_normalized(e.nominal))
                continue
            v = values[name]
            if isinstance(e, UncertainDynamics):
                out[name] = _dynamics_raw(v, e, self.dt)
            else:
                out[name] = e.to_normalized(v)
        return out

    # ------------------------------------------------------------------ substitution
    def substitute(self, values: dict | None = None, **kw: Any):
        """Fix some elements at values (their own units; MATLAB ``usubs``).

        Parameters
        ----------
        values : dict, optional
            ``{name: value}``: a number for a real or complex element, a matrix or a system
            (``ny x nu``, norm within the bound) for a dynamics element. Keywords work too.

        Returns
        -------
        UncertainSystem or control.StateSpace
            The system of the remaining elements; a ``control.StateSpace`` (named signals) when
            none remains and the result is real.
        """
        vals = dict(values or {}, **kw)
        norm = self._normalized(vals, fill_nominal=False)
        return self._close(norm)

    def _close(self, norm: dict):
        """Close the named elements' channels with their normalised values."""
        wid_w, wid_z = self._widths()
        sw, sz = np.cumsum([0, *wid_w]), np.cumsum([0, *wid_z])
        first_w, first_z, rest_w, rest_z, deltas, keep = [], [], [], [], [], []
        for k, (e, c) in enumerate(self.blocks):
            rw, rz = np.arange(sw[k], sw[k + 1]), np.arange(sz[k], sz[k + 1])
            if e.name in norm:
                first_w.append(rw)
                first_z.append(rz)
                deltas.append(_repeat(norm[e.name], c, e))
            else:
                rest_w.append(rw)
                rest_z.append(rz)
                keep.append((e, c))
        if not deltas:
            return self
        cat = lambda xs: np.concatenate([np.zeros(0, int), *xs])  # noqa: E731
        p = permute_delta(self.raw, cat(first_w + rest_w), cat(first_z + rest_z))
        nwc, nzc = int(sum(x.size for x in first_w)), int(sum(x.size for x in first_z))
        delta = _stack_raw(deltas)
        closed = close_channels(p, nwc, nzc, delta)
        out = UncertainSystem(closed, tuple(keep), self.inputs, self.outputs, self.dt)
        if keep:
            return out
        return out.statespace_or_self()

    def statespace_or_self(self):
        """A ``control.StateSpace`` when there are no elements and the matrices are real."""
        import control

        r = self.raw
        if self.blocks or any(np.iscomplexobj(x) and np.any(np.imag(x) != 0) for x in (r.A, r.B, r.C, r.D)):
            return self
        return control.ss(np.real(r.A), np.real(r.B), np.real(r.C), np.real(r.D), self.dt or 0,
                          inputs=list(self.inputs), outputs=list(self.outputs))

    @property
    def nominal(self):
        """The system at every element's nominal value (dynamics at zero)."""
        return self._close(self._normalized({}, fill_nominal=True))

    def statespace(self):
        """The nominal system as a ``control.StateSpace`` (``rc.as_statespace`` reads this, as
        for an ``UncertainModel``): where a certain model is expected, the nominal is used."""
        nom = self.nominal
        if isinstance(nom, UncertainSystem):
            raise SynthesisError("the nominal of this system is complex (a complex nominal value); "
                                 "python-control's systems are real.")
        return nom

    def poles(self) -> np.ndarray:
        """Poles of the nominal system (all elements at their nominal values)."""
        nom = self.nominal
        if isinstance(nom, UncertainSystem):
            return np.linalg.eigvals(nom.raw.A)
        return np.linalg.eigvals(np.asarray(nom.A))

    def delta_response(self, f_hz: Any) -> np.ndarray:
        """``M11(j w)``, the ``w -> z`` channels of the LFT, (nf, nz, nw): what mu analyses.

        Parameters
        ----------
        f_hz : array_like
            Frequencies (Hz).
        """
        r = self.raw
        return raw_response(r, np.atleast_1d(np.asarray(f_hz, float)), self.dt)[:, : r.nz, : r.nw]

    # ------------------------------------------------------------------ sampling
    def sample(self, n: int = 1, seed: Any = 0) -> list[dict]:
        """``n`` seeded random values of every element (MATLAB ``usample``): reals uniform in
        their range, complex scalars uniform in their disc, dynamics as stable systems of norm
        within the bound (:meth:`.elements.UncertainDynamics.sample`).

        Returns
        -------
        list of dict
            ``{name: value}`` per sample, for :meth:`substitute` or :meth:`freqresp`.
        """
        n = integer(n, "n", SynthesisError, lo=1)
        rng = np.random.default_rng(check_seed(seed, "seed", SynthesisError))
        out = []
        for _ in range(n):
            d = {}
            for e, _c in self.blocks:
                d[e.name] = e.sample(rng, self.dt) if isinstance(e, UncertainDynamics) else e.sample(rng)
            out.append(d)
        return out

    def freqresp(self, f_hz: Any, values: Any = None) -> np.ndarray:
        """Frequency response ``Fu(M(j w), Delta(j w))``, (nf, ny, nu), or (n, nf, ny, nu) for a
        list of value dicts (e.g. :meth:`sample`'s, for plots); unnamed elements at nominal,
        names of elements this system lacks ignored.

        Parameters
        ----------
        f_hz : array_like
            Frequencies (Hz).
        values : dict, list of dict or None
        """
        f = np.atleast_1d(np.asarray(f_hz, dtype=float))
        many = isinstance(values, (list, tuple))
        sets = list(values) if many else [values or {}]
        Mf = raw_response(self.raw, f, self.dt)
        nw, nz = self.raw.nw, self.raw.nz
        M11, M12, M21, M22 = Mf[:, :nz, :nw], Mf[:, :nz, nw:], Mf[:, nz:, :nw], Mf[:, nz:, nw:]
        out = []
        for vals in sets:
            norm = self._normalized(vals, fill_nominal=True, strict=False)
            if nw == 0:
                out.append(M22)
                continue
            Dl = np.zeros((f.size, nw, nz), complex)
            wid_w, wid_z = self._widths()
            r0 = c0 = 0
            for (e, c), ww, wz in zip(self.blocks, wid_w, wid_z):
                Dl[:, r0:r0 + ww, c0:c0 + wz] = _block_response(_repeat(norm[e.name], c, e), f, self.dt)
                r0, c0 = r0 + ww, c0 + wz
            X = np.linalg.solve(np.eye(nz) - M11 @ Dl, M12)
            out.append(M22 + M21 @ Dl @ X)
        return np.stack(out) if many else out[0]

    # ------------------------------------------------------------------ algebra
    def _combine(self, parts: list[UncertainSystem], E, F, H, J, inputs, outputs) -> UncertainSystem:
        # parts without states (gains, elements) take the time base of the others
        dts = {p.dt for p in parts if p.nstates or p.dt}
        if len(dts) > 1:
            raise SynthesisError(f"cannot combine systems with different sample times {sorted(dts)} (s; "
                                 "0 is continuous); map one with rc.d2c or control.c2d first.")
        raw = connect([p.raw for p in parts], *(np.asarray(x, float) for x in (E, F, H, J)))
        blocks = [b for p in parts for b in p.blocks]
        return _merged(raw, blocks, inputs, outputs, dts.pop() if dts else 0.0)

    def __add__(self, other):
        a, b = _broadcast_pair(self, as_uncertain(other, self.dt))
        ny, nu = a.shape
        if b.shape != (ny, nu):
            raise SynthesisError(f"cannot add a {ny}x{nu} and a {b.shape[0]}x{b.shape[1]} system.")
        ins = b.inputs if is_default_names(a.inputs, "u") else a.inputs
        outs = b.outputs if is_default_names(a.outputs, "y") else a.outputs
        return self._combine([a, b], np.zeros((2 * nu, 2 * ny)), np.vstack([np.eye(nu)] * 2),
                             np.hstack([np.eye(ny)] * 2), np.zeros((ny, nu)), ins, outs)

    def __radd__(self, other):
        return as_uncertain(other, self.dt) + self

    def __neg__(self):
        ny, nu = self.shape
        return self._combine([self], np.zeros((nu, ny)), np.eye(nu), -np.eye(ny), np.zeros((ny, nu)),
                             self.inputs, self.outputs)

    def __sub__(self, other):
        return self + (-as_uncertain(other, self.dt))

    def __rsub__(self, other):
        return as_uncertain(other, self.dt) + (-self)

    def __mul__(self, other):
        """``self * other``: the series connection ``u -> other -> self``."""
        return series(as_uncertain(other, self.dt), self)

    def __rmul__(self, other):
        return series(self, as_uncertain(other, self.dt))

    def __matmul__(self, other):
        return self * other

    def __truediv__(self, other):
        return self * as_uncertain(other, self.dt).inv()

    def __rtruediv__(self, other):
        return as_uncertain(other, self.dt) * self.inv()

    def __pow__(self, n):
        if not isinstance(n, numbers.Integral) or isinstance(n, bool):
            raise SynthesisError(f"an uncertain system's power must be an integer; got {n!r}.")
        if self.shape[0] != self.shape[1]:
            raise SynthesisError("only a square uncertain system has powers.")
        base = self if n >= 0 else self.inv()
        out = as_uncertain(np.eye(self.shape[0]), self.dt)
        for _ in range(abs(int(n))):
            out = out * base
        return out

    def inv(self) -> UncertainSystem:
        """``G^-1`` (needs an invertible feedthrough; inputs and outputs swap names)."""
        return _merged(invert(self.raw), list(self.blocks), self.outputs, self.inputs, self.dt)

    def feedback(self, other: Any = 1, sign: int = -1) -> UncertainSystem:
        """The loop ``y = G u``, ``u = r + sign * K y`` (python-control's ``feedback``; the
        default ``sign=-1`` is negative feedback, robustctl's one loop sign)."""
        if sign not in (1, -1):
            raise SynthesisError(f"sign must be +1 or -1; got {sign!r}.")
        K = as_uncertain(other, self.dt)
        K = _broadcast_to(K, (self.shape[1], self.shape[0]))
        ny, nu = self.shape
        if K.shape != (nu, ny):
            raise SynthesisError(f"the feedback system must be {nu}x{ny}; got {K.shape[0]}x{K.shape[1]}.")
        E = np.block([[np.zeros((nu, ny)), sign * np.eye(nu)], [np.eye(ny), np.zeros((ny, nu))]])
        F = np.vstack([np.eye(nu), np.zeros((ny, nu))])
        H = np.hstack([np.eye(ny), np.zeros((ny, nu))])
        return self._combine([self, K], E, F, H, np.zeros((ny, nu)), self.inputs, self.outputs)

    def series(self, other: Any) -> UncertainSystem:
        """``u -> self -> other`` (MATLAB ``series(self, other)``)."""
        return series(self, as_uncertain(other, self.dt))

    def parallel(self, other: Any) -> UncertainSystem:
        return self + other

    def __getitem__(self, key) -> UncertainSystem:
        rows, cols = key if isinstance(key, tuple) else (key, slice(None))
        ri = np.atleast_1d(np.arange(self.shape[0])[rows])
        ci = np.atleast_1d(np.arange(self.shape[1])[cols])
        ny, nu = self.shape
        F = np.eye(nu)[:, ci]
        H = np.eye(ny)[ri]
        return self._combine([self], np.zeros((nu, ny)), F, H, np.zeros((ri.size, ci.size)),
                             [self.inputs[i] for i in ci], [self.outputs[i] for i in ri])

    def minreal(self) -> UncertainSystem:
        """The structurally minimal realisation: states and repeated scalars not reachable or
        not observable through the LFT removed (Beck & Doyle 1999). Like ``control.minreal``
        it drops hidden modes, unstable ones included: analyse internal stability before."""
        raw, widths = reduce_scalar_blocks(self.raw, self._widths()[0],
                                           [not isinstance(e, UncertainDynamics) for e, _ in self.blocks],
                                           states=True)
        blocks = [(e, w if not isinstance(e, UncertainDynamics) else c)
                  for (e, c), w in zip(self.blocks, widths)]
        return UncertainSystem(raw, tuple(b for b in blocks if b[1] > 0), self.inputs, self.outputs, self.dt)

    def with_names(self, inputs: Any = None, outputs: Any = None) -> UncertainSystem:
        """The same system with new signal names."""
        return UncertainSystem(self.raw, self.blocks, inputs or self.inputs, outputs or self.outputs, self.dt)

    # ------------------------------------------------------------------ presentation
    def __repr__(self) -> str:
        ny, nu = self.shape
        kind = "continuous" if not self.dt else f"dt={self.dt:g} s"
        head = (f"UncertainSystem({ny} output{'s' * (ny != 1)} x {nu} input{'s' * (nu != 1)}, "
                f"{self.nstates} states, {kind}")
        if not self.blocks:
            return head + ", no uncertain elements)"
        lines = [f"  {e.describe()}, {c} occurrence{'s' * (c != 1)}" for e, c in self.blocks]
        return head + ")\n" + "\n".join(lines)


register_system(UncertainSystem.from_element)


# ---------------------------------------------------------------------------- helpers
def as_uncertain(x: Any, dt: float = 0.0) -> UncertainSystem:
    """``x`` as an :class:`UncertainSystem`: itself, an element, a system, or a number/matrix
    (a static gain).

    Parameters
    ----------
    x : UncertainSystem, uncertain element, system, number or 2-D array
    dt : float
        Sample time (s) given to an element or a gain (0: continuous); systems keep theirs.

    Returns
    -------
    UncertainSystem

    Examples
    --------
    >>> import robustctl as rc, control
    >>> G = rc.as_uncertain(control.tf([1], [1, 1])) * rc.ureal("k", 2.0, percent=10)
    >>> G.multiplicity
    {'k': 1}
    """
    if isinstance(x, UncertainSystem):
        return x
    if hasattr(x, "multiplicity") and hasattr(x, "n_delta") and hasattr(x, "axes"):  # an UncertainModel
        M = x.M
        A, B, C, D = (np.asarray(m, float) for m in (M.A, M.B, M.C, M.D))
        blocks = tuple((UncertainReal(n, 0.0, -1.0, 1.0), r) for n, r in zip(x.names, x.multiplicity))
        return UncertainSystem(Raw(A, B, C, D, x.n_delta, x.n_delta), blocks, x.nominal.input_labels,
                               x.nominal.output_labels)
    if isinstance(x, _ELEMENTS):
        out = UncertainSystem.from_element(x)
        return UncertainSystem(out.raw, out.blocks, out.inputs, out.outputs, dt) if dt else out
    if isinstance(x, (numbers.Number, np.ndarray, list, tuple)) and not isinstance(x, bool):
        D = np.atleast_2d(np.asarray(x))
        if D.ndim != 2 or D.dtype == object or not np.all(np.isfinite(D)):
            raise SynthesisError(f"a static gain must be a finite number or 2-D matrix; got {x!r}.")
        D = D.astype(complex if np.iscomplexobj(D) else float)
        raw = Raw(np.zeros((0, 0)), np.zeros((0, D.shape[1]), D.dtype),
                  np.zeros((D.shape[0], 0), D.dtype), D, 0, 0)
        return UncertainSystem(raw, (), [f"u[{i}]" for i in range(D.shape[1])],
                               [f"y[{i}]" for i in range(D.shape[0])], dt)
    return UncertainSystem.from_system(x)


def _broadcast_to(s: UncertainSystem, shape: tuple[int, int]) -> UncertainSystem:
    """A 1x1 system as ``ones(p, 1) s ones(1, m)`` for + and as ``s I`` for square products."""
    if s.shape == (1, 1) and shape != (1, 1):
        p, m = shape
        left = as_uncertain(np.ones((p, 1)), s.dt)
        right = as_uncertain(np.ones((1, m)), s.dt)
        return series(series(right, s), left)
    return s


def _scalar_times(s: UncertainSystem, n: int) -> UncertainSystem:
    return append(*([s] * n)) if n > 1 else s


def _broadcast_pair(a: UncertainSystem, b: UncertainSystem):
    if a.shape == (1, 1) and b.shape != (1, 1):
        return _broadcast_to(a, b.shape).with_names(b.inputs, b.outputs), b
    if b.shape == (1, 1) and a.shape != (1, 1):
        return a, _broadcast_to(b, a.shape)
    return a, b


def series(first: UncertainSystem, second: UncertainSystem) -> UncertainSystem:
    """``u -> first -> second`` (a 1x1 factor acts as a scalar on every channel)."""
    if first.shape == (1, 1) and second.shape[1] != 1:
        first = _scalar_times(first, second.shape[1])
    elif second.shape == (1, 1) and first.shape[0] != 1:
        second = _scalar_times(second, first.shape[0])
    if first.shape[0] != second.shape[1]:
        raise SynthesisError(
            f"series connection needs matching sizes: {first.shape[0]} outputs into "
            f"{second.shape[1]} inputs.")
    n1y, n1u = first.shape
    n2y, n2u = second.shape
    E = np.zeros((n1u + n2u, n1y + n2y))
    E[n1u:, :n1y] = np.eye(n1y)
    F = np.vstack([np.eye(n1u), np.zeros((n2u, n1u))])
    H = np.hstack([np.zeros((n2y, n1y)), np.eye(n2y)])
    ins, outs = first.inputs, second.outputs
    if is_default_names(ins, "u") and n2u == n1u and not is_default_names(second.inputs, "u"):
        ins = second.inputs  # a gain or an element in front keeps the system's input names
    if is_default_names(outs, "y") and n1y == n2y and not is_default_names(first.outputs, "y"):
        outs = first.outputs
    return first._combine([first, second], E, F, H, np.zeros((n2y, n1u)), ins, outs)


def append(*systems: Any) -> UncertainSystem:
    """Block-diagonal concatenation (MATLAB ``append``/``blkdiag``), names kept."""
    ss = [as_uncertain(s) for s in systems]
    if not ss:
        raise SynthesisError("append needs at least one system.")
    nu = sum(s.shape[1] for s in ss)
    ny = sum(s.shape[0] for s in ss)
    return ss[0]._combine(ss, np.zeros((nu, ny)), np.eye(nu), np.eye(ny), np.zeros((ny, nu)),
                          _unique([n for s in ss for n in s.inputs]),
                          _unique([n for s in ss for n in s.outputs]))


def hstack(*systems: Any) -> UncertainSystem:
    """``[G1, G2, ...]``: inputs side by side, outputs summed (MATLAB ``[G1 G2]``)."""
    ss = [as_uncertain(s) for s in systems]
    ny = ss[0].shape[0]
    if any(s.shape[0] != ny for s in ss):
        raise SynthesisError("hstack needs systems with the same number of outputs.")
    nu = sum(s.shape[1] for s in ss)
    H = np.hstack([np.eye(ny)] * len(ss))
    return ss[0]._combine(ss, np.zeros((nu, ny * len(ss))), np.eye(nu), H, np.zeros((ny, nu)),
                          _unique([n for s in ss for n in s.inputs]), ss[0].outputs)


def vstack(*systems: Any) -> UncertainSystem:
    """``[G1; G2; ...]``: one input, outputs stacked (MATLAB ``[G1; G2]``)."""
    ss = [as_uncertain(s) for s in systems]
    nu = ss[0].shape[1]
    if any(s.shape[1] != nu for s in ss):
        raise SynthesisError("vstack needs systems with the same number of inputs.")
    ny = sum(s.shape[0] for s in ss)
    F = np.vstack([np.eye(nu)] * len(ss))
    return ss[0]._combine(ss, np.zeros((nu * len(ss), ny)), F, np.eye(ny), np.zeros((ny, nu)),
                          ss[0].inputs, _unique([n for s in ss for n in s.outputs]))


def _unique(names: list[str]) -> list[str]:
    seen: dict[str, int] = {}
    out = []
    for n in names:
        k = seen.get(n, 0)
        out.append(n if k == 0 else f"{n}#{k + 1}")
        seen[n] = k + 1
    return out


def _merged(raw: Raw, blocks: list, inputs, outputs, dt: float) -> UncertainSystem:
    """Group each element's channels into one block, then drop the copies not needed."""
    order: dict[str, list] = {}
    wsz, zsz = [c * e.shape[0] for e, c in blocks], [c * e.shape[1] for e, c in blocks]
    sw, sz = np.cumsum([0, *wsz]), np.cumsum([0, *zsz])
    for k, (e, c) in enumerate(blocks):
        if e.name in order and order[e.name][0] is not e and not _same(order[e.name][0], e):
            raise SynthesisError(
                f"two different uncertain elements are both named {e.name!r}; give them distinct names.")
        ent = order.setdefault(e.name, [e, 0, [], []])
        ent[1] += c
        ent[2].append(np.arange(sw[k], sw[k + 1]))
        ent[3].append(np.arange(sz[k], sz[k + 1]))
    cat = lambda xs: np.concatenate([np.zeros(0, int), *xs])  # noqa: E731
    raw = permute_delta(raw, cat([x for v in order.values() for x in v[2]]),
                        cat([x for v in order.values() for x in v[3]]))
    new_blocks = [(v[0], v[1]) for v in order.values()]
    scalar = [not isinstance(e, UncertainDynamics) for e, _ in new_blocks]
    raw, widths = reduce_scalar_blocks(raw, [c * e.shape[0] for e, c in new_blocks], scalar)
    new_blocks = [(e, (w if s else c)) for (e, c), w, s in zip(new_blocks, widths, scalar)]
    keep = [b for b in new_blocks if b[1] > 0]  # an element that cancelled has no channels left
    return UncertainSystem(raw, tuple(keep), inputs, outputs, dt)


def _same(a, b) -> bool:
    return type(a) is type(b) and a.__dict__ == b.__dict__ if hasattr(a, "__dict__") else a == b


def _repeat(value: Any, copies: int, e: Any) -> Raw:
    """The normalised block ``value (x) I_copies`` as a realisation (inputs z, outputs w)."""
    if isinstance(value, Raw):
        return _stack_raw([value] * copies)
    v = complex(value) if isinstance(e, UncertainComplex) else float(np.real(value))
    D = v * np.eye(copies)
    return Raw(np.zeros((0, 0)), np.zeros((0, copies), D.dtype), np.zeros((copies, 0), D.dtype), D, 0, 0)


def _stack_raw(parts: list[Raw]) -> Raw:
    nu = sum(p.nu for p in parts)
    ny = sum(p.ny for p in parts)
    return connect(parts, np.zeros((nu, ny)), np.eye(nu), np.eye(ny), np.zeros((ny, nu)))


def _dynamics_raw(v: Any, e: UncertainDynamics, dt: float) -> Raw:
    """A value of a dynamics element (matrix or system) normalised by its bound."""
    if isinstance(v, Raw):
        return v
    if isinstance(v, (numbers.Number, np.ndarray, list, tuple)):
        D = np.atleast_2d(np.asarray(v)) / e.bound
        if D.shape != (e.ny, e.nu):
            raise SynthesisError(f"the value of {e.name} must be {e.ny}x{e.nu}; got {D.shape}.")
        return Raw(np.zeros((0, 0)), np.zeros((0, e.nu), D.dtype), np.zeros((e.ny, 0), D.dtype), D, 0, 0)
    ss = as_statespace(v, name=f"the value of {e.name}")
    if (ss.noutputs, ss.ninputs) != (e.ny, e.nu):
        raise SynthesisError(f"the value of {e.name} must be {e.ny}x{e.nu}; got {ss.noutputs}x{ss.ninputs}.")
    A, B, C, D = (np.asarray(x, float) for x in (ss.A, ss.B, ss.C, ss.D))
    return Raw(A, B, C / e.bound, D / e.bound, 0, 0)


def raw_response(r: Raw, f: np.ndarray, dt: float) -> np.ndarray:
    """Frequency response (n_f, n_out, n_in) of the state-space data ``r`` at ``f`` (Hz):
    ``C (s I - A)^-1 B + D`` with ``s = j 2 pi f`` (``z = exp(j 2 pi f dt)`` when ``dt`` > 0)."""
    s = np.exp(2j * np.pi * f * dt) if dt else 2j * np.pi * f
    if r.nx == 0:
        return np.broadcast_to(r.D, (f.size, *r.D.shape)).astype(complex)
    n = r.nx
    out = np.empty((f.size, *r.D.shape), complex)
    for k, sk in enumerate(s):
        out[k] = r.C @ np.linalg.solve(sk * np.eye(n) - r.A, r.B) + r.D
    return out


def _block_response(r: Raw, f: np.ndarray, dt: float) -> np.ndarray:
    return raw_response(r, f, dt)
