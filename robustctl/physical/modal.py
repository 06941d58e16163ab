"""Modal state space of a structure (MACE eqs. 1-4).

The second-order model ``M q'' + C q' + K q = b u`` is written in mass-normalised modal
coordinates ``q = Phi eta`` (``Phi^T M Phi = I``, ``Phi^T K Phi = Omega^2``) with modal
damping ``2 zeta Omega`` plus the projected concentrated damping ``Phi^T Cs Phi`` (MACE
eq. 2), so the state is ``x = [eta, eta_dot]`` and

.. math::

    A = \\begin{bmatrix} 0 & I \\\\ -\\Omega^2 & -2\\zeta\\Omega - \\Phi^T C_s \\Phi \\end{bmatrix},
    \\quad B = \\begin{bmatrix} 0 \\\\ \\Phi^T b \\end{bmatrix}            (MACE eqs. 2, 3)

Outputs are displacement rows ``[c Phi, 0]``, rate rows ``[0, c Phi]`` (MACE eq. 4) or
acceleration rows, which need a feedthrough: ``y = c Phi eta'' = c Phi (-Omega^2 eta -
(2 zeta Omega + Phi^T Cs Phi) eta_dot) + c Phi Phi^T b u``.

Units: frequencies in Hz at the surface (``f_hz``, ``band_hz``), rad/s inside
(``omega``); damping ratios are dimensionless; rigid-body damping rates are in 1/s.
"""

from __future__ import annotations

import hashlib
import inspect
import threading
from collections import OrderedDict
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import control
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..checks import check_band, flag, integer, positive_number
from ..errors import ModelError
from ..table import Table
from .eigen import solve_modes
from .structure_base import OUTPUT_KINDS, StructuralMatrices, Structure

__all__ = [
    "ModalData",
    "modal_decomposition",
    "modal_statespace",
    "modal_dynamics",
    "modal_data_statespace",
]

#: Above this many DOFs the residual flexibility of a free-free structure (singular K) is
#: refused rather than computed from a full dense eigensolution.
_DENSE_RESIDUAL_LIMIT = 3000


@dataclass(frozen=True, eq=False)
class ModalData:
    """Modal model of a structure: what MACE eqs. 2-4 are built from.

    Attributes
    ----------
    omega : ndarray, shape (n_modes,)
        Natural frequencies in rad/s, ascending (0 for rigid-body modes).
    zeta : ndarray, shape (n_modes,)
        Modal damping ratios (bands already applied).
    input_shapes : ndarray, shape (n_modes, n_in)
        Modal input matrix ``Phi^T b`` (mass-normalised shapes at the actuators).
    output_shapes : ndarray, shape (n_out, n_modes)
        Modal output matrix ``c Phi`` (mass-normalised shapes at the sensors).
    output_kinds : tuple of str
        ``"displacement"``, ``"velocity"`` or ``"acceleration"`` per output.
    inputs, outputs : tuple of str
        Signal names.
    modal_concentrated_damping : ndarray, shape (n_modes, n_modes)
        ``Phi^T Cs Phi`` in 1/s (zero when the structure has no concentrated damping).
    rigid_body_rate : float
        Damping rate (1/s) put on the diagonal of the velocity block for rigid-body modes.
    residual : ndarray, shape (n_out, n_in) or None
        Static flexibility ``c (K^+ - Phi Omega^-2 Phi^T) b`` of the truncated modes (m/N),
        when residual flexibility was requested; the state space uses it as the
        feedthrough of displacement rows only.
    shapes : ndarray, shape (n_dof, n_modes) or None
        Full mode shapes, when the data came from a structure.
    """

    omega: np.ndarray
    zeta: np.ndarray
    input_shapes: np.ndarray
    output_shapes: np.ndarray
    output_kinds: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    modal_concentrated_damping: np.ndarray = field(default=None)  # type: ignore[assignment]
    rigid_body_rate: float = 0.0
    residual: np.ndarray | None = None
    shapes: np.ndarray | None = None

    def __post_init__(self) -> None:
        n = self.omega.size
        if self.modal_concentrated_damping is None:
            object.__setattr__(self, "modal_concentrated_damping", np.zeros((n, n)))

    @property
    def f_hz(self) -> np.ndarray:
        """Natural frequencies in Hz."""
        return self.omega / (2 * np.pi)

    @property
    def n_modes(self) -> int:
        return int(self.omega.size)

    def statespace(self):
        """The modal state space (MACE eqs. 2-4) with named signals."""
        return _assemble(self)

    def table(self) -> Table:
        """Mode table: frequency, damping and the largest input/output participation."""
        rows = []
        for k in range(self.n_modes):
            b = np.abs(self.input_shapes[k])
            c = np.abs(self.output_shapes[:, k])
            rows.append((
                k + 1,
                float(self.f_hz[k]),
                float(self.zeta[k]),
                self.inputs[int(np.argmax(b))] if b.size else "",
                float(b.max()) if b.size else 0.0,
                self.outputs[int(np.argmax(c))] if c.size else "",
                float(c.max()) if c.size else 0.0,
            ))
        return Table(
            ("mode", "f (Hz)", "zeta", "strongest input", "|Phi^T b|", "strongest output", "|c Phi|"),
            rows,
            title=f"{self.n_modes} modes",
        )


# ---------------------------------------------------------------------------- damping
def _damping_vector(damping: Any, n: int) -> np.ndarray:
    zeta = np.asarray(damping, dtype=float)
    if zeta.ndim == 0:
        zeta = np.full(n, float(zeta))
    elif zeta.shape != (n,):
        raise ModelError(
            f"damping has {zeta.size} values for {n} kept modes; give one damping ratio "
            "or one per kept mode."
        )
    if not np.all(np.isfinite(zeta)) or np.any(zeta < 0):
        raise ModelError(f"modal damping ratios must be finite and >= 0; got {zeta}.")
    return zeta


def _apply_bands(zeta: np.ndarray, f_hz: np.ndarray, bands) -> np.ndarray:
    """``zeta`` with each band's factor applied: ``(lo_hz, hi_hz, factor)`` scales the modes
    in ``[lo_hz, hi_hz]`` Hz, ``(first, last, factor, "mode")`` the elastic modes ``first`` to
    ``last`` (1-based by ascending frequency, rigid-body modes not counted)."""
    zeta = zeta.copy()
    elastic = np.flatnonzero(f_hz > 0)
    elastic = elastic[np.argsort(f_hz[elastic], kind="stable")]
    for band in bands:
        if len(band) == 4 and band[3] == "mode":
            first, last, factor = int(band[0]), int(band[1]), band[2]
            if not 1 <= first <= last:
                raise ModelError(
                    f"a modal damping mode group needs 1 <= first <= last; got ({first}, {last})."
                )
            if last > elastic.size:
                raise ModelError(
                    f"the modal damping group of modes {first}-{last} needs {last} elastic modes; "
                    f"the dynamics keep {elastic.size}. Keep more modes or choose lower ones."
                )
            inside = np.zeros(zeta.size, dtype=bool)
            inside[elastic[first - 1 : last]] = True
        else:
            lo, hi, factor = band[:3]
            inside = (f_hz >= lo) & (f_hz <= hi)
            if not np.any(inside):
                raise ModelError(
                    f"the modal damping band [{lo:g}, {hi:g}] Hz contains no kept mode (kept modes "
                    f"span {f_hz.min():.4g}-{f_hz.max():.4g} Hz); move the band onto a mode."
                )
        if factor < 0 or not np.isfinite(factor):
            raise ModelError(f"a modal damping factor must be finite and >= 0; got {factor}.")
        zeta[inside] *= factor
    return zeta


# ---------------------------------------------------------------------------- decomposition
def _check_mats(mats: StructuralMatrices) -> None:
    n = mats.n_dof
    if mats.mass.shape[0] != n:
        raise ModelError(
            f"the input matrix has {n} rows but the mass matrix has {mats.mass.shape[0]} DOFs; "
            "give one row per DOF."
        )
    if mats.output_matrix.ndim != 2 or mats.output_matrix.shape[1] != n:
        raise ModelError(
            f"the output matrix has shape {mats.output_matrix.shape}; it needs one column per "
            f"DOF ({n})."
        )
    if len(mats.inputs) != mats.input_matrix.shape[1] or len(mats.outputs) != mats.output_matrix.shape[0]:
        raise ModelError("the structural matrices have a different number of signal names and vectors.")
    bad = [k for k in mats.output_kinds if k not in OUTPUT_KINDS]
    if bad or len(mats.output_kinds) != len(mats.outputs):
        raise ModelError(f"output kinds must be one of {OUTPUT_KINDS} per output; got {mats.output_kinds}.")


def _residual_flexibility(
    mats: StructuralMatrices, omega: np.ndarray, phi: np.ndarray, includes_lowest: bool
) -> np.ndarray:
    """Static flexibility of the truncated flexible modes, ``c (K^+ - Phi_k Omega_k^-2 Phi_k^T) b``.

    Rigid-body modes carry no static flexibility and are excluded from both terms. When the
    kept modes start at the lowest one and it is flexible, ``K`` is invertible and
    ``c K^-1 b`` is solved directly; otherwise the flexible modes of a full (dense) solution
    are summed.
    """
    b, c = mats.input_matrix, mats.output_matrix
    flex = omega > 0
    kept = (c @ phi[:, flex]) @ ((phi[:, flex].T @ b) / omega[flex, None] ** 2)
    n = mats.n_dof
    if includes_lowest and omega[0] > 0:  # no rigid-body mode at all: K is invertible
        K = mats.stiffness
        x = spla.spsolve(sp.csc_matrix(K), b) if sp.issparse(K) else np.linalg.solve(np.asarray(K), b)
        full = c @ np.asarray(x).reshape(n, -1)
    elif n <= _DENSE_RESIDUAL_LIMIT:
        w_all, phi_all = solve_modes(mats.mass, mats.stiffness, sparse=False)
        f_all = w_all > 0
        full = (c @ phi_all[:, f_all]) @ ((phi_all[:, f_all].T @ b) / w_all[f_all, None] ** 2)
    else:
        if np.any(~flex):
            raise ModelError(
                f"residual flexibility of a free-free structure with {n} DOFs is not supported; "
                "constrain the rigid-body motion or set residual_flexibility=False."
            )
        full = c @ spla.spsolve(sp.csc_matrix(mats.stiffness), b).reshape(n, -1)
        if not np.all(np.isfinite(full)):
            raise ModelError(
                "the stiffness matrix is singular (free-free structure), so the residual flexibility "
                "is undefined; constrain the rigid-body motion or set residual_flexibility=False."
            )
    return full - kept


def modal_decomposition(
    mats: StructuralMatrices,
    *,
    n_modes: int | None = None,
    band_hz: tuple[float, float] | None = None,
    damping: float | np.ndarray = 0.01,
    rigid_body_damping: float = 0.0,
    residual_flexibility: bool = False,
) -> ModalData:
    """Modes, damping and modal input/output matrices of a structure (MACE eqs. 2-4).

    Parameters
    ----------
    mats : StructuralMatrices
        Mass (kg), stiffness (N/m), concentrated damping ``Cs`` (N s/m), pointing vectors.
    n_modes : int, optional
        Keep the ``n_modes`` lowest modes (all modes when neither this nor ``band_hz``).
    band_hz : (float, float), optional
        Keep the modes with natural frequency in ``[lo, hi]`` Hz.
    damping : float or array_like
        Modal damping ratio ``zeta`` (MACE uses 0.01 for articulated structures, 0.001 for
        tight trusses): one value or one per kept mode. ``mats.modal_damping_bands``
        multiply the ratio of the modes in each band.
    rigid_body_damping : float
        Damping rate in 1/s placed on the velocity diagonal of rigid-body (0 Hz) modes,
        where ``2 zeta omega`` vanishes; 0 (default) keeps their double integrators exact.
        A small positive value moves them to ``s = -rigid_body_damping``.
    residual_flexibility : bool
        Keep the static response of the truncated modes as a feedthrough on displacement
        outputs ("static correction" of modal truncation). Default off: the pure modal
        model of MACE eq. 4. Velocity and acceleration outputs get no correction.

    Returns
    -------
    ModalData

    Raises
    ------
    ModelError
        Bad matrices, a band without modes, negative damping, wrong vector lengths.
    """
    _check_mats(mats)
    undamped = _undamped_modal_data(mats, n_modes, band_hz, residual_flexibility)
    return _damped(undamped, damping, mats.modal_damping_bands, rigid_body_damping)


def _undamped_modal_data(mats: StructuralMatrices, n_modes, band_hz, residual_flexibility: bool) -> ModalData:
    """Everything of MACE eqs. 2-4 that does not depend on the modal damping ratios."""
    omega, phi = solve_modes(mats.mass, mats.stiffness, n_modes=n_modes, band_hz=band_hz)
    return ModalData(
        omega=omega,
        zeta=np.zeros(omega.size),
        input_shapes=phi.T @ mats.input_matrix,
        output_shapes=mats.output_matrix @ phi,
        output_kinds=tuple(mats.output_kinds),
        inputs=tuple(mats.inputs),
        outputs=tuple(mats.outputs),
        modal_concentrated_damping=_modal_damping_matrix(mats.damping, phi),
        residual=(
            _residual_flexibility(mats, omega, phi, band_hz is None) if residual_flexibility else None
        ),
        shapes=phi,
    )


def _modal_damping_matrix(cs: Any, phi: np.ndarray) -> np.ndarray:
    """``Phi^T Cs Phi``: the concentrated dashpots in modal coordinates (n_modes, n_modes)."""
    if cs is None:
        return np.zeros((phi.shape[1], phi.shape[1]))
    # sparse-safe: never densify a large Cs
    return phi.T @ np.asarray((cs if sp.issparse(cs) else np.asarray(cs, dtype=float)) @ phi)


def _same_matrix(a: Any, b: Any) -> bool:
    """Whether two (sparse or dense, or None) matrices hold the same values."""
    if a is None or b is None:
        return a is b
    if a is b:
        return True
    if a.shape != b.shape:
        return False
    if sp.issparse(a) or sp.issparse(b):
        return (sp.csr_matrix(a) != sp.csr_matrix(b)).nnz == 0
    return bool(np.array_equal(np.asarray(a), np.asarray(b)))


def _damped(data: ModalData, damping: Any, bands, rigid_body_damping: float) -> ModalData:
    """``data`` with damping ratios (bands applied) and the rigid-body damping rate."""
    if rigid_body_damping < 0 or not np.isfinite(rigid_body_damping):
        raise ModelError(f"rigid_body_damping is a rate in 1/s and must be >= 0; got {rigid_body_damping}.")
    zeta = _apply_bands(_damping_vector(damping, data.n_modes), data.f_hz, bands)
    return replace(data, zeta=zeta, rigid_body_rate=float(rigid_body_damping))


# ---------------------------------------------------------------------------- assembly
def _assemble(data: ModalData):
    """Build A, B, C, D of MACE eqs. 2-4 (plus the acceleration feedthrough)."""
    n = data.n_modes
    w = data.omega
    damp = np.diag(2 * data.zeta * w) + data.modal_concentrated_damping
    damp[np.diag_indices(n)] += np.where(w == 0, data.rigid_body_rate, 0.0)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-np.diag(w**2), -damp]])
    B = np.vstack([np.zeros_like(data.input_shapes), data.input_shapes])
    cphi = data.output_shapes
    n_out, n_in = cphi.shape[0], data.input_shapes.shape[1]
    C = np.zeros((n_out, 2 * n))
    D = np.zeros((n_out, n_in))
    for i, kind in enumerate(data.output_kinds):
        if kind == "displacement":
            C[i, :n] = cphi[i]
            if data.residual is not None:
                D[i] = data.residual[i]
        elif kind == "velocity":
            C[i, n:] = cphi[i]
        else:  # acceleration: c Phi eta'' with eta'' from the second block row of A, B
            C[i] = cphi[i] @ A[n:]
            D[i] = cphi[i] @ data.input_shapes
    return control.ss(A, B, C, D, inputs=list(data.inputs), outputs=list(data.outputs))


def modal_statespace(mats: StructuralMatrices, **options: Any):
    """Modal state space ``x = [eta, eta_dot]`` of a structure (MACE eqs. 1-4).

    ``modal_decomposition(mats, ...).statespace()``.

    Parameters
    ----------
    mats, n_modes, band_hz, damping, rigid_body_damping, residual_flexibility
        The structure (kg, N/m, N s/m), the modal truncation (count or band in Hz), the modal
        damping ratio, the rigid-body damping rate (1/s) and the static correction, as for
        :func:`modal_decomposition` (the function's signature is its signature; the keywords
        travel as ``**options``).

    Returns
    -------
    control.StateSpace
        Inputs and outputs named after ``mats.inputs`` / ``mats.outputs``, physical units
        (N in, m / m/s / m/s^2 out for translational DOFs).

    Examples
    --------
    >>> import numpy as np
    >>> from robustctl.physical.structure_base import StructuralMatrices
    >>> mats = StructuralMatrices(np.eye(1), 4 * np.pi**2 * np.eye(1), None, np.ones((1, 1)),
    ...                           np.ones((1, 1)), ("displacement",), ("F",), ("x",), ("dof 1",))
    >>> sys = modal_statespace(mats, damping=0.05)
    >>> round(float(abs(np.linalg.eigvals(sys.A)[0])) / (2 * np.pi), 6)
    1.0
    """
    return modal_decomposition(mats, **options).statespace()


#: one parameter list for both: what ``help`` and ``inspect.signature`` show of modal_statespace
modal_statespace.__signature__ = inspect.signature(modal_decomposition).replace(  # type: ignore[attr-defined]
    return_annotation=inspect.Signature.empty
)


def modal_data_statespace(
    freqs_hz: Any,
    damping: Any,
    shapes_at_inputs: Any,
    shapes_at_outputs: Any,
    *,
    inputs: Any,
    outputs: Any,
    output_kind: str | Any = "acceleration",
):
    """State space from modal data exported by an external FE code (MACE eqs. 2-4).

    Parameters
    ----------
    freqs_hz : array_like, shape (n_modes,)
        Natural frequencies in Hz (>= 0).
    damping : float or array_like, shape (n_modes,)
        Modal damping ratios.
    shapes_at_inputs : array_like, shape (n_in, n_modes)
        Mass-normalised mode shapes at the actuator DOFs, i.e. ``(Phi^T b)^T``.
    shapes_at_outputs : array_like, shape (n_out, n_modes)
        Mass-normalised mode shapes at the sensor DOFs, ``c Phi``.
    inputs, outputs : sequence of str
        Signal names.
    output_kind : str or sequence of str
        One kind for all outputs or one per output.
    """
    data = _modal_data_from_arrays(
        freqs_hz, damping, shapes_at_inputs, shapes_at_outputs, inputs, outputs, output_kind
    )
    return data.statespace()


def _names(names: Any, count: int, what: str) -> tuple[str, ...]:
    names = (names,) if isinstance(names, str) else tuple(str(n) for n in names)
    if len(names) != count or len(set(names)) != count:
        raise ModelError(f"give {count} unique {what} names (one per row of the shapes); got {names}.")
    return names


def _modal_data_from_arrays(freqs_hz, damping, b_shapes, c_shapes, inputs, outputs, output_kind) -> ModalData:
    f = np.atleast_1d(np.asarray(freqs_hz, dtype=float))
    if f.ndim != 1 or f.size == 0 or not np.all(np.isfinite(f)) or np.any(f < 0):
        raise ModelError(f"freqs_hz must be a 1-D array of finite frequencies >= 0 Hz; got {f}.")
    n = f.size
    bs = np.atleast_2d(np.asarray(b_shapes, dtype=float))
    cs = np.atleast_2d(np.asarray(c_shapes, dtype=float))
    for what, arr in (("shapes_at_inputs", bs), ("shapes_at_outputs", cs)):
        if arr.ndim != 2 or arr.shape[1] != n:
            raise ModelError(
                f"{what} has shape {arr.shape}; it must be (n_signals, n_modes) with n_modes = {n} "
                "(one column per frequency)."
            )
        if not np.all(np.isfinite(arr)):
            raise ModelError(f"{what} contains NaN or inf.")
    ins = _names(inputs, bs.shape[0], "input")
    outs = _names(outputs, cs.shape[0], "output")
    kinds = (output_kind,) * len(outs) if isinstance(output_kind, str) else tuple(output_kind)
    if len(kinds) != len(outs) or any(k not in OUTPUT_KINDS for k in kinds):
        raise ModelError(f"output_kind must be one of {OUTPUT_KINDS} (or one per output); got {output_kind}.")
    order = np.argsort(f, kind="stable")
    return ModalData(
        omega=2 * np.pi * f[order],
        zeta=_damping_vector(damping, n)[order],
        input_shapes=bs[:, order].T,
        output_shapes=cs[:, order],
        output_kinds=kinds,
        inputs=ins,
        outputs=outs,
    )


# ---------------------------------------------------------------------------- PhysicalModel hook
def _digest(mats: StructuralMatrices, *extra: Any) -> bytes:
    """A content hash of everything the undamped modes and modal input/output matrices depend
    on (not the dashpots ``Cs``: their modal matrix is recomputed from the cached shapes)."""
    h = hashlib.blake2b(digest_size=20)
    for a in (mats.mass, mats.stiffness, mats.input_matrix, mats.output_matrix):
        if a is None:
            h.update(b"none")
        elif sp.issparse(a):
            a = sp.csr_matrix(a)
            a.sum_duplicates()
            for part in (np.asarray(a.shape), a.data, a.indices, a.indptr):
                h.update(np.ascontiguousarray(part).tobytes())
        else:
            a = np.ascontiguousarray(a, dtype=float)
            h.update(np.asarray(a.shape).tobytes() + a.tobytes())
    h.update(repr((mats.output_kinds, mats.inputs, mats.outputs) + extra).encode())
    return h.digest()


class _ModeCache:
    """A small LRU of undamped modal data keyed by matrix content (thread-safe); entries
    are ``(ModalData, Cs)``, the dashpot matrix its modal damping matrix was made from.

    PhysicalModel rebuilds the structure for every parameter set, and its own cache keys
    on every parameter the build read, damping included; this cache lets a change of the
    modal damping ratio (a MACE update parameter) skip the eigensolution.
    """

    def __init__(self, size: int = 4) -> None:
        self._size = size
        self._store: OrderedDict[bytes, tuple] = OrderedDict()
        self._lock = threading.Lock()

    def __getstate__(self) -> dict:
        return {"size": self._size}  # pickled models (process executors) start with an empty cache

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["size"])

    def get(self, key: bytes, compute: Callable[[], tuple]) -> tuple:
        with self._lock:
            if key in self._store:
                self._store.move_to_end(key)
                return self._store[key]
        value = compute()
        with self._lock:
            self._store[key] = value
            while len(self._store) > self._size:
                self._store.popitem(last=False)
        return value


def modal_dynamics(
    n_modes: int | None = None,
    band_hz: tuple[float, float] | None = None,
    damping_param: str = "zeta_modal",
    *,
    default_damping: float | np.ndarray = 0.01,
    rigid_body_damping: float = 0.0,
    residual_flexibility: bool = False,
) -> Callable[[Mapping[str, float], Structure | None], Any]:
    """A ``dynamics`` callable ``(theta, structure) -> StateSpace`` for PhysicalModel.

    The modal damping ratio is read from ``theta[damping_param]`` when the model has that
    parameter, otherwise ``default_damping`` (a ratio, or one per kept mode) is used.
    Other arguments are those of :func:`modal_decomposition`. The eigensolution is cached
    by matrix content (last 4 structures), so changing only the damping, or building again
    with equal matrices, does not solve the eigenproblem again.
    """
    if n_modes is not None:
        n_modes = integer(n_modes, "n_modes", ModelError, lo=1)
    band_hz = check_band(band_hz, "band_hz")
    rigid_body_damping = positive_number(
        rigid_body_damping, "rigid_body_damping", ModelError, allow_zero=True
    )
    residual_flexibility = flag(residual_flexibility, "residual_flexibility", ModelError)
    cache = _ModeCache()

    def dynamics(theta: Mapping[str, float], structure: Structure | None):
        if structure is None:
            raise ModelError("modal_dynamics needs a structure; build the model with a structure callable.")
        zeta = theta.get(damping_param, default_damping)
        mats = structure.matrices()
        _check_mats(mats)
        key = _digest(mats, n_modes, band_hz, residual_flexibility)
        undamped, cs = cache.get(
            key, lambda: (_undamped_modal_data(mats, n_modes, band_hz, residual_flexibility), mats.damping)
        )
        if not _same_matrix(cs, mats.damping):  # other dashpots on the same modes: Phi^T Cs Phi only
            undamped = replace(undamped, modal_concentrated_damping=_modal_damping_matrix(mats.damping,
                                                                                          undamped.shapes))
        return _damped(undamped, zeta, mats.modal_damping_bands, rigid_body_damping).statespace()

    # what robustctl.physical.reduction.band_limited needs to evaluate the same model in
    # reduced coordinates: all modes kept, damping read the same way
    dynamics.reducible = n_modes is None and band_hz is None and not residual_flexibility
    dynamics.damping = lambda theta: theta.get(damping_param, default_damping)
    dynamics.rigid_body_damping = rigid_body_damping
    return dynamics
