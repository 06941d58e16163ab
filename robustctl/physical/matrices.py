"""A user's own mass and stiffness matrices as a :class:`Structure`.

The matrices given are the complete model ``M q'' + Cs q' + K q = b u``. Named pieces of
them let physical effects act the same way they act on the built-in frame FEM:

* ``stiffness_groups`` — named contributions *included in* ``stiffness`` (the springs
  between masses 1 and 2, the struts of one bay ...). ``scale_group_stiffness(g, f)``
  adds ``(f - 1) K_g``.
* ``geometric_stiffness`` — per group, the geometric stiffness per newton of tension
  (1/m); ``add_group_tension(g, T)`` adds ``T K_G,g``. Without it tension is refused.
* ``tagged`` — named parts *included in* the matrices that ``without(tags)`` removes,
  e.g. ``tagged={"suspension": (dK, dC)}`` for MACE's 0-g prediction. A part is a tuple
  ``(dK,)``, ``(dK, dC)`` or ``(dK, dC, dM)`` (``None`` for an absent matrix).

Locations are DOFs, labelled ``"dof 1"`` ... ``"dof n"`` unless ``dof_labels`` is given.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
import scipy.sparse as sp

from ..errors import DataError, ModelError
from ..frd_io.geometry import parse_dof
from .eigen import _check_mass_definite, _check_square_symmetric, _dense
from .shapes import matrix_geometry, matrix_mode_shapes
from .structure_base import OUTPUT_KINDS, STINGER_LENGTH, StructuralMatrices, Structure, stinger_stiffness

__all__ = ["MatrixStructure"]

#: Largest size for which the definiteness of M and K is checked at construction (larger
#: models are checked by the eigensolver).
_DEFINITENESS_CHECK_LIMIT = 800


def _matrix(a: Any, n: int | None, what: str):
    """A float matrix (dense or CSR): square, finite, symmetric, and of size ``n`` when given."""
    mat = _float_matrix(a, what)
    if mat.shape[0] == 0 or mat.ndim != 2:
        raise ModelError(f"the {what} matrix is empty (shape {mat.shape}); give an n x n matrix, n >= 1.")
    _check_square_symmetric(what, mat)
    if n is not None and mat.shape[0] != n:
        raise ModelError(
            f"the {what} matrix is {mat.shape[0]}x{mat.shape[1]} but the model has {n} DOFs; "
            "all matrices must have the size of the mass matrix."
        )
    return mat


def _float_matrix(a: Any, what: str):
    """``a`` as a real float matrix (dense or CSR); refuses text, ragged lists and complex values
    (``astype(float)`` would drop the imaginary part with only a ComplexWarning)."""
    try:
        if sp.issparse(a):
            kind = a.dtype.kind
            mat = sp.csr_matrix(a, dtype=float) if kind in "biuf" else None
        else:
            arr = np.asarray(a)
            kind = arr.dtype.kind
            mat = np.array(arr, dtype=float, ndmin=2) if kind in "iuf" else None
    except (TypeError, ValueError) as exc:
        raise ModelError(f"the {what} matrix must be an array of real numbers ({exc}).") from None
    if mat is None:
        what_kind = "complex" if kind == "c" else f"dtype {kind!r}"
        raise ModelError(f"the {what} matrix must hold real numbers; got {what_kind} values.")
    return mat


def _check_damping(damping, labels: Sequence[str]) -> None:
    """A concentrated damping matrix must be positive semi-definite: a negative dashpot feeds
    energy in and makes the model unstable (the modal damping ``Phi^T C Phi`` is then indefinite)."""
    diag = damping.diagonal()
    bad = np.flatnonzero(diag < 0)
    if bad.size:
        raise ModelError(
            f"concentrated_damping has a negative diagonal entry at {labels[bad[0]]!r} ({diag[bad[0]]:g}); "
            "dashpot constants must be >= 0 (a negative one makes the model unstable)."
        )
    if damping.shape[0] <= _DEFINITENESS_CHECK_LIMIT:
        lam = np.linalg.eigvalsh(_dense(damping))
        if lam.min() < -1e-9 * max(abs(lam).max(), 1e-300):
            raise ModelError(
                f"concentrated_damping is not positive semi-definite (eigenvalue {lam.min():.3g}); a "
                "damping matrix with a negative direction makes the model unstable."
            )


def _check_definite(mass, stiffness, labels: Sequence[str]) -> None:
    """Negative diagonals always; definiteness (dense) only for small models, larger ones are
    checked by the eigensolver when the modes are computed."""
    for what, mat in (("mass", mass), ("stiffness", stiffness)):
        diag = mat.diagonal()
        bad = np.flatnonzero(diag < 0)
        if bad.size:
            raise ModelError(
                f"the {what} matrix has a negative diagonal entry at {labels[bad[0]]!r} "
                f"({diag[bad[0]]:g}); masses and stiffnesses must be >= 0."
            )
    if mass.shape[0] <= _DEFINITENESS_CHECK_LIMIT:
        _check_mass_definite(mass)  # symmetry and finiteness were checked by _matrix
        lam = np.linalg.eigvalsh(_dense(stiffness))
        if lam.min() < -1e-9 * max(abs(lam).max(), 1e-300):
            raise ModelError(
                f"the stiffness matrix is not positive semi-definite (eigenvalue {lam.min():.3g}); "
                "check for negative springs or a sign error in an off-diagonal term."
            )


def _labels(dof_labels: Sequence[str] | None, n: int) -> tuple[str, ...]:
    if dof_labels is None:
        return tuple(f"dof {i + 1}" for i in range(n))
    labels = tuple(str(x) for x in dof_labels)
    if len(labels) != n or len(set(labels)) != n:
        raise ModelError(f"dof_labels must be {n} unique names (one per DOF); got {len(labels)}.")
    return labels


class MatrixStructure(Structure):
    """A structure given by its own mass, stiffness and concentrated-damping matrices.

    Parameters
    ----------
    mass, stiffness : array_like or sparse, shape (n, n)
        Symmetric mass (kg, positive definite) and stiffness (N/m, positive semi-definite).
    damping : array_like or sparse, shape (n, n), optional
        Concentrated damping ``Cs`` (N s/m) of MACE eq. 2 (dashpots); modal damping is
        added by the modal state space.
    inputs : mapping name -> vector (n,) or DOF label
        Generalised force per unit input (the pointing vector b of MACE eq. 3).
    outputs : mapping name -> (vector (n,) or DOF label, kind)
        Output pointing row and kind (``"displacement"``, ``"velocity"``, ``"acceleration"``).
    dof_labels : sequence of str, optional
        One label per DOF (default ``"dof 1"`` ...).
    stiffness_groups : mapping name -> (n, n) matrix, optional
        Named contributions included in ``stiffness``.
    geometric_stiffness : mapping group -> (n, n) matrix, optional
        Geometric stiffness per unit tension (1/m) of a group (for ``add_group_tension``).
    tagged : mapping tag -> tuple of matrices, optional
        Parts ``(dK[, dC[, dM]])`` included in the matrices that ``without`` removes.
    nodes : mapping node id -> (x, y, z), optional
        Node coordinates (m) for drawing: with DOFs labelled ``"node:direction"`` (``"3:X"``)
        the structure has a :meth:`geometry` and :meth:`mode_shapes`.
    lines : sequence of (int, int), optional
        Node pairs drawn as lines (members, springs).
    """

    def __init__(
        self,
        mass: Any,
        stiffness: Any,
        damping: Any = None,
        *,
        inputs: Mapping[str, Any],
        outputs: Mapping[str, tuple[Any, str]],
        dof_labels: Sequence[str] | None = None,
        stiffness_groups: Mapping[str, Any] | None = None,
        geometric_stiffness: Mapping[str, Any] | None = None,
        tagged: Mapping[str, Sequence[Any]] | None = None,
        nodes: Mapping[int, Sequence[float]] | None = None,
        lines: Sequence[tuple[int, int]] = (),
    ) -> None:
        self._M = _matrix(mass, None, "mass")
        n = self._M.shape[0]
        self._labels = _labels(dof_labels, n)
        self._K = _matrix(stiffness, n, "stiffness")
        self._C = None if damping is None else _matrix(damping, n, "damping")
        _check_definite(self._M, self._K, self._labels)
        if self._C is not None:
            _check_damping(self._C, self._labels)
        self._inputs, self._b = self._input_vectors(inputs)
        self._outputs, self._c, self._kinds = self._output_vectors(outputs)
        self._groups = {
            str(g): _matrix(k, n, f"stiffness group {g!r}") for g, k in (stiffness_groups or {}).items()
        }
        self._geometric = {}
        for g, kg in (geometric_stiffness or {}).items():
            if g not in self._groups:
                raise ModelError(
                    f"geometric stiffness is given for {g!r}, which is not a stiffness group; "
                    f"groups: {sorted(self._groups)}."
                )
            self._geometric[g] = _matrix(kg, n, f"geometric stiffness of {g!r}")
        self._tagged = {str(t): self._tagged_part(t, part) for t, part in (tagged or {}).items()}
        self._raw_outputs = dict(outputs)
        self._nodes = None if nodes is None else {int(k): tuple(v) for k, v in nodes.items()}
        self._lines = tuple(tuple(pair) for pair in lines)
        if self._nodes is not None:
            self.geometry()  # refuse labels that name no node now, not at the first drawing

    # ------------------------------------------------------------------ construction helpers
    @property
    def n_dof(self) -> int:
        return self._M.shape[0]

    def _vector(self, v: Any, what: str) -> np.ndarray:
        if isinstance(v, str):
            e = np.zeros(self.n_dof)
            e[self._dof(v)] = 1.0
            return e
        try:
            vec = np.asarray(v, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            vec = np.full(1, np.nan)
        if vec.size != self.n_dof or not np.all(np.isfinite(vec)):
            raise ModelError(
                f"the vector of {what} has {vec.size} entries; it needs one finite entry per DOF "
                f"({self.n_dof}), or give a DOF label such as {self._labels[0]!r}."
            )
        return vec

    def _input_vectors(self, inputs: Mapping[str, Any]):
        if not isinstance(inputs, Mapping):
            raise ModelError(f"inputs must be a dict name -> force vector or DOF label; got {inputs!r}.")
        if not inputs:
            raise ModelError("give at least one input: inputs={'F': force_vector_or_dof_label}.")
        names = tuple(str(k) for k in inputs)
        b = np.column_stack([self._vector(v, f"input {k!r}") for k, v in inputs.items()])
        return names, b

    def _output_vectors(self, outputs: Mapping[str, tuple[Any, str]]):
        if not isinstance(outputs, Mapping):
            raise ModelError(f"outputs must be a dict name -> (vector or DOF label, kind); got {outputs!r}.")
        if not outputs:
            raise ModelError(
                "give at least one output: outputs={'x': (vector_or_dof_label, 'displacement')}."
            )
        rows, kinds = [], []
        for name, spec in outputs.items():
            if isinstance(spec, str) or len(spec) != 2 or spec[1] not in OUTPUT_KINDS:
                raise ModelError(
                    f"output {name!r} must be (vector or DOF label, kind) with kind one of "
                    f"{OUTPUT_KINDS}; got {spec!r}."
                )
            rows.append(self._vector(spec[0], f"output {name!r}"))
            kinds.append(spec[1])
        return tuple(str(k) for k in outputs), np.vstack(rows), tuple(kinds)

    def _tagged_part(self, tag: str, part: Any) -> tuple:
        part = (part,) if not isinstance(part, (tuple, list)) else tuple(part)
        if not 1 <= len(part) <= 3:
            raise ModelError(
                f"tagged part {tag!r} must be (dK,), (dK, dC) or (dK, dC, dM); got {len(part)} items."
            )
        names = ("stiffness", "damping", "mass")
        mats = tuple(None if p is None else _matrix(p, self.n_dof, f"{names[i]} of tagged part {tag!r}")
                     for i, p in enumerate(part))
        return mats + (None,) * (3 - len(mats))

    def _dof(self, location: str) -> int:
        try:
            return self._labels.index(location)
        except ValueError:
            shown = list(self._labels[:6]) + (["..."] if self.n_dof > 6 else [])
            raise ModelError(f"unknown location {location!r}; the DOFs are {shown}.") from None

    def copy(self) -> MatrixStructure:
        """An independent copy without re-validating: effects replace matrices and dict
        entries (never modify an array in place), so sharing the arrays is safe."""
        new = object.__new__(type(self))
        new.__dict__.update(self.__dict__)
        new._groups, new._geometric = dict(self._groups), dict(self._geometric)
        new._tagged = dict(self._tagged)
        return new

    # ------------------------------------------------------------------ Structure contract
    def matrices(self) -> StructuralMatrices:
        """The current matrices (copies; effects and removals applied)."""
        own = StructuralMatrices(self._M, self._K, self._C, self._b, self._c, self._kinds, self._inputs,
                                 self._outputs, self._labels, self.modal_damping_bands())
        return own.copy()

    def geometry(self):
        """Nodes, lines and sensors (:func:`~robustctl.physical.shapes.matrix_geometry`)."""
        if self._nodes is None:
            return super().geometry()
        return matrix_geometry(self._nodes, self._labels, self._raw_outputs, self._lines)

    def mode_shapes(self, n_modes: int | None = None, band_hz: Sequence[float] | None = None):
        """Every node's translation per undamped mode
        (:func:`~robustctl.physical.shapes.matrix_mode_shapes`)."""
        if self._nodes is None:
            return super().mode_shapes(n_modes, band_hz)
        sm = self.matrices()
        return matrix_mode_shapes(sm.mass, sm.stiffness, self._labels, self.geometry().node_ids, n_modes,
                                  band_hz)

    def without(self, tags: Iterable[str]) -> MatrixStructure:
        """Subtract the tagged parts carrying one of ``tags`` (unknown tags are ignored:
        ``PhysicalModel.without`` passes every excluded tag, e.g. ``"gravity"``)."""
        for tag in set(tags) & set(self._tagged):
            dK, dC, dM = self._tagged.pop(tag)
            if dK is not None:
                self._K = self._K - dK
            if dM is not None:
                self._M = self._M - dM
            if dC is not None:
                if self._C is None:
                    raise ModelError(
                        f"tagged part {tag!r} has a damping matrix but the structure has no "
                        "concentrated damping to remove it from; include it in the damping matrix."
                    )
                self._C = self._C - dC
        return self

    def locations(self) -> tuple[str, ...]:
        return self._labels

    def element_groups(self) -> tuple[str, ...]:
        return tuple(self._groups)

    def tension_groups(self) -> tuple[str, ...]:
        """The stiffness groups given a geometric stiffness (only they can carry a tension)."""
        return tuple(g for g in self._groups if g in self._geometric)

    def tags(self) -> tuple[str, ...]:
        """Tags of the parts :meth:`without` can remove."""
        return tuple(self._tagged)

    def _pointing(self, side: str, name: str) -> np.ndarray:
        names = self._outputs if side == "output" else self._inputs
        if name not in names:
            raise ModelError(f"unknown {side} {name!r}; the structure has {side}s {list(names)}.")
        k = names.index(name)
        return self._c[k] if side == "output" else self._b[:, k]

    def signal_location(self, side: str, name: str) -> str | None:
        """The DOF a sensor row or force column points at, when it points at one DOF only."""
        v = np.abs(self._pointing(side, name))
        if not np.any(v > 0):
            return None
        k = int(np.argmax(v))
        return self._labels[k] if np.count_nonzero(v > 1e-12 * v[k]) == 1 else None

    def signal_moves(self, side: str, name: str) -> list[tuple[str, str | None]]:
        """The DOFs next (by index) to the one a sensor row or force column points at most: the
        neighbouring DOFs of the output/input map (a user's matrices carry no geometry)."""
        v = np.abs(self._pointing(side, name))
        if not np.any(v > 0):
            return []
        k = int(np.argmax(v))
        if np.count_nonzero(v > 1e-12 * v[k]) > 1:  # a distributed pointing: no single DOF to move
            return []
        return [(self._labels[j], None) for j in (k - 1, k + 1) if 0 <= j < self.n_dof]

    def move_signal(self, side: str, name: str, location: str, direction: str | None, weight: float):
        """Point ``name`` at DOF ``location``: ``(1 - weight) old + weight e_k`` (scaled like the old
        pointing's largest entry)."""
        old = self._pointing(side, name)
        e = np.zeros(self.n_dof)
        k_old = int(np.argmax(np.abs(old)))
        e[self._dof(location)] = old[k_old]
        new = (1.0 - float(weight)) * old + float(weight) * e
        k = (self._outputs if side == "output" else self._inputs).index(name)
        if side == "output":
            self._c = self._c.copy()
            self._c[k] = new
        else:
            self._b = self._b.copy()
            self._b[:, k] = new
        return self

    def _add_diagonal(self, which: str, location: str, value: float, direction: str | None, what: str):
        if direction is not None:
            raise ModelError(
                f"the locations of a MatrixStructure are single DOFs; {what} takes direction=None, "
                f"got {direction!r}."
            )
        value = float(value)
        if not np.isfinite(value):
            raise ModelError(f"the {what} must be finite; got {value!r}.")
        i = self._dof(location)
        e = sp.csr_matrix(([value], ([i], [i])), shape=(self.n_dof, self.n_dof))
        mat = getattr(self, which)
        if mat is None:
            mat = e if sp.issparse(self._M) else e.toarray()
        else:
            mat = mat + e if sp.issparse(mat) else mat + e.toarray()
        setattr(self, which, mat)
        return self

    def add_mass(self, location: str, mass: float) -> MatrixStructure:
        """Add ``mass`` (kg, or kg m^2 at a rotational DOF) to the diagonal at ``location``."""
        return self._add_diagonal("_M", location, mass, None, "added mass")

    def add_spring(self, location: str, stiffness: float, direction: str | None = None) -> MatrixStructure:
        """Add a grounded spring (N/m) at the DOF ``location``."""
        return self._add_diagonal("_K", location, stiffness, direction, "spring")

    def add_dashpot(self, location: str, damping: float, direction: str | None = None) -> MatrixStructure:
        """Add a grounded dashpot (N s/m) at the DOF ``location`` (concentrated damping Cs)."""
        return self._add_diagonal("_C", location, damping, direction, "dashpot")

    def add_resonator(self, location: str, mass: float, stiffness: float,
                      direction: str | None = None) -> MatrixStructure:
        """Attach a spring-mass at the DOF ``location``: a new DOF ``"<location>~resonator"`` of
        ``mass`` (kg) joined by ``stiffness`` (N/m); every matrix, group and pointing gains a zero
        row and column for it (the resonator carries no sensor or force)."""
        if direction is not None:
            raise ModelError(
                f"the locations of a MatrixStructure are single DOFs; a resonator takes direction=None, "
                f"got {direction!r}."
            )
        m, k = float(mass), float(stiffness)
        if not (np.isfinite(m) and m > 0 and np.isfinite(k) and k >= 0):
            raise ModelError(
                f"a resonator needs a mass > 0 (kg) and a stiffness >= 0 (N/m); got {m!r}, {k!r}.")
        i, n = self._dof(location), self.n_dof
        label = f"{location}~resonator"
        while label in self._labels:
            label += "'"

        def pad(a: Any) -> Any:
            if a is None:
                return None
            if sp.issparse(a):
                return sp.block_diag((a, sp.csr_matrix((1, 1))), format="csr")
            return np.pad(np.asarray(a, dtype=float), ((0, 1), (0, 1)))

        tie = sp.csr_matrix(([k, -k, -k, k], ([i, i, n, n], [i, n, i, n])), shape=(n + 1, n + 1))
        added = sp.csr_matrix(([m], ([n], [n])), shape=(n + 1, n + 1))
        K, M = pad(self._K), pad(self._M)
        self._K = K + tie if sp.issparse(K) else K + tie.toarray()
        self._M = M + added if sp.issparse(M) else M + added.toarray()
        self._C = pad(self._C)
        self._groups = {g: pad(a) for g, a in self._groups.items()}
        self._geometric = {g: pad(a) for g, a in self._geometric.items()}
        self._tagged = {t: tuple(pad(a) for a in part) for t, part in self._tagged.items()}
        self._b = np.vstack([self._b, np.zeros((1, self._b.shape[1]))])
        self._c = np.hstack([self._c, np.zeros((self._c.shape[0], 1))])
        self._labels = tuple(self._labels) + (label,)
        return self

    def add_stinger(self, input_name: str, lateral_stiffness: float,
                    length: float = STINGER_LENGTH) -> MatrixStructure:
        """Restrain the drive point of force input ``input_name`` as its stinger does
        (:func:`~robustctl.physical.structure_base.stinger_stiffness`: ``lateral_stiffness`` in N/m,
        ``length`` in m) on the DOFs of the drive's node: the input must point at one DOF labelled
        ``"node:direction"`` (``"12:Z"``, an FE import's labels), and the node's other DOFs take the
        stinger's stiffness (a DOF the matrices do not have is held by the model already)."""
        loc = self.signal_location("input", input_name)
        try:
            node, vec = parse_dof(loc) if loc is not None else (None, None)
        except DataError:
            node = None
        if node is None or not np.any(vec[:3]):
            raise ModelError(
                f"input {input_name!r} does not act on one translational DOF labelled 'node:direction' "
                f"(it acts on {loc!r}); a stinger needs the drive node's DOFs, e.g. dof_labels=['12:X', ...]."
            )
        k = float(lateral_stiffness)
        if not np.isfinite(k):
            raise ModelError(f"the stinger's lateral stiffness must be finite (N/m); got "
                             f"{lateral_stiffness!r}.")
        if k == 0.0:
            return self
        dofs, rows = [], []
        for j, lab in enumerate(self._labels):
            try:
                nd, v = parse_dof(lab)
            except DataError:
                continue
            if nd == node:
                dofs.append(j)
                rows.append(v)
        P = np.array(rows)
        block = P @ stinger_stiffness(vec[:3], k, length) @ P.T
        n = self.n_dof
        ii, jj = np.meshgrid(dofs, dofs, indexing="ij")
        dK = sp.csr_matrix((block.ravel(), (ii.ravel(), jj.ravel())), shape=(n, n))
        self._K = self._K + dK if sp.issparse(self._K) else self._K + dK.toarray()
        return self

    def add_coupling(self, location: str, partner: str, stiffness: float) -> MatrixStructure:
        """Add ``stiffness`` (N/m, N m/rad; negative softens) between DOFs ``location`` and ``partner``:
        ``K += k (e_a - e_b)(e_a - e_b)^T``."""
        k = float(stiffness)
        a, b = self._dof(location), self._dof(partner)
        if a == b or not np.isfinite(k):
            raise ModelError(f"a coupling needs two different DOFs and a finite stiffness; got {location!r}, "
                             f"{partner!r}, {stiffness!r}.")
        n = self.n_dof
        dK = sp.csr_matrix(([k, -k, -k, k], ([a, a, b, b], [a, b, a, b])), shape=(n, n))
        self._K = self._K + dK if sp.issparse(self._K) else self._K + dK.toarray()
        return self

    def add_coupling_damping(self, location: str, partner: str, damping: float) -> MatrixStructure:
        """Add a dashpot of ``damping`` (N s/m, N m s/rad) between DOFs ``location`` and ``partner``:
        ``Cs += c (e_a - e_b)(e_a - e_b)^T`` (concentrated damping, MACE eq. 2's ``C_s``)."""
        c = float(damping)
        a, b = self._dof(location), self._dof(partner)
        if a == b or not (np.isfinite(c) and c >= 0):
            raise ModelError(f"a dashpot between DOFs needs two different DOFs and a damping >= 0 (N s/m); "
                             f"got {location!r}, {partner!r}, {damping!r}.")
        n = self.n_dof
        dC = sp.csr_matrix(([c, -c, -c, c], ([a, a, b, b], [a, b, a, b])), shape=(n, n))
        if self._C is None:
            self._C = dC if sp.issparse(self._M) else dC.toarray()
        else:
            self._C = self._C + dC if sp.issparse(self._C) else self._C + dC.toarray()
        return self

    def _group(self, group: str) -> Any:
        if group not in self._groups:
            raise ModelError(
                f"unknown element group {group!r}; this structure's groups are {list(self._groups)} "
                "(name stiffness contributions with stiffness_groups={...})."
            )
        return self._groups[group]

    def scale_group_stiffness(self, group: str, factor: float) -> MatrixStructure:
        """Multiply the stiffness contribution of ``group`` by ``factor`` (>= 0)."""
        kg = self._group(group)
        factor = float(factor)
        if not np.isfinite(factor) or factor < 0:
            raise ModelError(f"a stiffness factor must be finite and >= 0; got {factor!r}.")
        self._K = self._K + (factor - 1.0) * kg
        self._groups[group] = factor * kg
        return self

    def add_group_tension(self, group: str, tension: float) -> MatrixStructure:
        """Add ``tension`` (N) times the group's geometric stiffness per unit tension."""
        self._group(group)
        if group not in self._geometric:
            raise ModelError(
                f"tension is not applicable to group {group!r} of a MatrixStructure: no geometric "
                "stiffness was given; pass geometric_stiffness={group: K_G_per_newton}."
            )
        self._K = self._K + float(tension) * self._geometric[group]
        return self
