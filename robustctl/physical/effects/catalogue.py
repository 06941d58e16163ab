"""Candidate effects of a model at every location, with secant steps calibrated on the model."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from ...budget import Deadline, as_deadline
from ...checks import check_band, flag
from ...errors import FitError, ModelError
from ...executors import parallel_map_shared
from ...threads import limit_blas
from .. import reduction
from ..eigen import solve_modes
from ..matrices import MatrixStructure
from ..model import PhysicalModel
from ..reduction import REDUCE_MIN_DOF
from . import io_effects, lab, setup, structural  # noqa: F401 - defining the classes registers them
from .base import (
    _N_CAL_MODES,
    DAMPING_TARGET,
    SHIFT_TARGET,
    SWEEPS,
    CandidateContext,
    Effect,
    _close,
    _directions,
    _signals,
    _structure_info,
)

#: Every registered effect class by kind (:attr:`Effect.registry`, filled as the classes are defined).
EFFECT_KINDS: dict[str, type[Effect]] = Effect.registry


# ============================================================================ candidates
def _context(model: PhysicalModel, band, joints=None, supports=None) -> CandidateContext:
    """What the effect classes need to make their candidates on ``model`` (``band`` in Hz or None,
    ``joints`` and ``supports`` named by the user)."""
    outs, ins = _signals(model, "output"), _signals(model, "input")
    if model.structure is None:
        return CandidateContext(model, outs, ins, band=band)
    info = _structure_info(model)
    struct = model.build_structure()
    dirs = _directions(struct.matrices().dof_labels, info["locations"])
    return CandidateContext(model, outs, ins, struct, info, dirs, band=band, joints=dict(joints or {}),
                            supports=dict(supports or {}))


def _check_joints(joints) -> dict:
    """``joints`` as ``{name: (dof_a, dof_b, k0)}``, or a ModelError saying what is wrong."""
    if joints is None:
        return {}
    try:
        out = {str(n): (str(a), str(b), float(k)) for n, (a, b, k) in dict(joints).items()}
    except (TypeError, ValueError) as exc:
        raise ModelError(
            f"joints must be {{name: (dof_a, dof_b, k0)}} (two DOF labels and the modelled stiffness); {exc}."
        ) from None
    bad = [n for n, (_, _, k) in out.items() if not (np.isfinite(k) and k > 0)]
    if bad:
        raise ModelError(f"joints {bad}: the modelled stiffness k0 must be finite and > 0.")
    return out


def _check_supports(supports) -> dict:
    """``supports`` as ``{name: (dofs, k0s)}`` (a tuple of DOF labels and one modelled grounded
    stiffness per DOF), or a ModelError saying what is wrong."""
    if supports is None:
        return {}
    form = ("supports must be {name: (dofs, k0)}: the DOF labels the support holds (one label or a list) "
            "and the grounded stiffness the model has at each (N/m or N m/rad; one number or one per DOF)")
    try:
        items = dict(supports).items()
        out = {}
        for name, (dofs, k0) in items:
            dofs = (str(dofs),) if isinstance(dofs, str) else tuple(str(d) for d in dofs)
            k = np.atleast_1d(np.asarray(k0, dtype=float)).reshape(-1)
            out[str(name)] = (dofs, tuple(float(x) for x in (np.full(len(dofs), k[0]) if k.size == 1 else k)))
    except (TypeError, ValueError) as exc:
        raise ModelError(f"{form}; {exc}.") from None
    bad = [n for n, (d, k) in out.items() if not d or len(k) != len(d) or len(set(d)) < len(d)
           or not all(np.isfinite(x) and x > 0 for x in k)]
    if bad:
        raise ModelError(f"supports {bad}: {form}; each DOF once, each k0 finite and > 0.")
    return out


def _generate(ctx: CandidateContext, sweeps: Sequence[str], points: bool = True) -> list[Effect]:
    """The candidates of every registered class, sweep by sweep, place by place, class by class
    (the order of :data:`~robustctl.physical.effects.base.SWEEPS` and of the registry)."""
    cands: list[Effect] = []
    for sweep in sweeps:
        if sweep == "location" and not points:
            continue
        classes = [cls for cls in Effect.registry.values() if cls.sweep == sweep]
        for where in ctx.places(sweep) if classes else ():
            for cls in classes:
                cands += cls.candidates_at(ctx, where)
    return cands


@limit_blas
def candidates(
    model: PhysicalModel,
    *,
    band: tuple[float, float] | None = None,
    kinds: Iterable[str] | None = None,
    points: bool = True,
    locations: Iterable[str] | None = None,
    calibrate: bool = True,
    time_budget_s: float | None = None,
    executor: Any = None,
    joints: dict | None = None,
    supports: dict | None = None,
) -> list[Effect]:
    """The effects applicable to ``model``, one per kind and location, at their neutral value.

    I/O effects (delays, first- and second-order sensor and actuator low-passes on all
    channels, a gain error per sensor, a misalignment per sensor pair) apply to any model, and
    so do the test-setup errors of :mod:`.setup` (a swapped pair of outputs or inputs, a sign
    flip and a units slip of each channel; on a structural model also each sensor and actuator
    at a neighbouring node or DOF or along another axis). Frame FEM models get a semi-rigid
    joint candidate (:class:`JointSpring`) per beam joint, and a hinge about each global axis,
    screened over their whole range (rigid to nearly pinned), a flexible support per clamped node,
    and a rotational dashpot (:class:`FrameJointDamping`) per joint the frame models as flexible.
    Every structural model gets the transducers' own mass, one parameter for all sensor mounts
    (and one with the drive points), the stinger's restraint of each driving point
    (:class:`StingerConstraint`: a frame's point forces, a matrix DOF labelled ``"node:direction"``)
    and, when ``band`` is given, attached resonators (a spring-mass that adds a mode) at the sensor
    and drive-point mounts on a grid of frequencies over the band (:mod:`.lab`). The classes make
    their own candidates (:meth:`Effect.candidates_at`), place by place of their
    :attr:`Effect.sweep`, in the order of :attr:`Effect.registry`.
    Structural effects need a structural model: an added mass, a suspension spring and a
    dashpot per location and direction (nodes of the frame FEM, each DOF of a user's
    matrices), a suspension pendulum (horizontal x-y stiffness) per node of a structure
    under gravity, a stiffness change and a tension per element group, gravity preload
    on/off (frame FEM), and a modal damping change per octave-wide group of modes.

    Parameters
    ----------
    model : PhysicalModel
    band : (float, float), optional
        Frequency band in Hz of interest: modal damping groups and step calibration use
        the modes inside it.
    kinds : iterable of str, optional
        Keep only these kinds (see :data:`EFFECT_KINDS`).
    points : bool
        Include the point effects (mass, spring, dashpot at every location).
    locations : iterable of str, optional
        Put point effects only at these locations (e.g. where hardware sits); default all.
    calibrate : bool
        Set each structural candidate's secant step (``Effect.scale``) so that it changes
        the most affected modal ``w^2`` by :data:`SHIFT_TARGET` (a dashpot: the damping
        ratio by :data:`DAMPING_TARGET`), from one eigensolution and one assembly per
        candidate (first-order perturbation, ``dw^2 = phi^T (dK - w^2 dM) phi``).
    time_budget_s : float, Deadline or None
        Optional wall-clock budget (s) of the calibration (``rc.diagnose`` passes its own
        :class:`~robustctl.budget.Deadline`); a :class:`~robustctl.errors.FitError` when it runs
        out (a candidate list cut short would be a different list). Default None: no clock.
    executor : concurrent.futures.Executor, optional
        Calibrates the candidates in parallel (the model travels to each worker once); the
        steps equal the serial ones.
    joints : dict, optional
        Joints of a matrix model, ``name -> (dof_a, dof_b, k0)`` (the two DOF labels and the
        connection's stiffness in the model, N/m or N m/rad): a :class:`DofPairJoint` candidate
        each, screened from as modelled to pinned, and a :class:`JointDamping` candidate.
    supports : dict, optional
        Supports of a matrix or FE model, ``name -> (dofs, k0)`` (the DOF labels the support holds,
        one label or a list, and the grounded stiffness the model has at each, N/m or N m/rad: one
        number, or one per DOF): a :class:`DofSupportFlexibility` candidate each, screened from as
        modelled to free.

    Returns
    -------
    list of Effect
    """
    if not isinstance(model, PhysicalModel):
        raise ModelError(f"candidates needs a PhysicalModel; got {type(model).__name__}.")
    band = check_band(band)
    points, calibrate = flag(points, "points", ModelError), flag(calibrate, "calibrate", ModelError)
    deadline = as_deadline(time_budget_s, FitError)
    if kinds is not None:
        kinds = set(kinds)
        unknown = sorted(kinds - set(EFFECT_KINDS))
        if unknown:
            raise ModelError(f"unknown effect kinds {unknown}; known kinds: {sorted(EFFECT_KINDS)}.")
    ctx = _context(model, band, _check_joints(joints), _check_supports(supports))
    cands = _generate(ctx, SWEEPS[:-1], points)
    if model.structure is not None:
        if locations is not None:
            cands = _at_locations(model, cands, locations)
        if kinds is not None:
            cands = [c for c in cands if c.kind in kinds]
        modes = _modes(model, band)
        if calibrate:
            cands = _calibrate(model, cands, band, deadline, executor, modes=modes)[2]
        omega, number = modes[0], modes[3]
        f_hz = omega / (2 * np.pi)
        inside = np.ones(f_hz.size, dtype=bool) if band is None else (f_hz >= band[0]) & (f_hz <= band[1])
        cands += _generate(replace(ctx, modes=(f_hz[inside], number[inside])), SWEEPS[-1:])
    taken = set(model.param_names)
    cands = [c for c in cands if not taken.intersection(c.param_names)]
    if kinds is not None:
        cands = [c for c in cands if c.kind in kinds]
    return cands


def _at_locations(model: PhysicalModel, cands: list[Effect], locations: Iterable[str]) -> list[Effect]:
    """Keep point effects only at ``locations`` (checked against the model)."""
    locations = (locations,) if isinstance(locations, str) else tuple(locations)
    known = _structure_info(model)["locations"]
    for loc in locations:
        if loc not in known:
            raise ModelError(
                f"unknown location {loc!r}; the model has locations {list(known)}." + _close(loc, known)
            )
    return [c for c in cands if c.sweep != "location" or c.location in locations]


# ---------------------------------------------------------------------------- calibration
def _dense(a) -> np.ndarray:
    return a.toarray() if hasattr(a, "toarray") else np.asarray(a, dtype=float)


def _working(a, n_dof: int):
    """A matrix as the calibration works on it: dense below
    :data:`~robustctl.physical.reduction.REDUCE_MIN_DOF` DOFs (the results of the examples stay
    bit for bit), sparse CSR above (a dense ``n_dof x n_dof`` copy per candidate made the
    calibration of thousands of candidates ``O(n_dof^3)`` in time and ``O(n_dof^2)`` in memory)."""
    import scipy.sparse as sp

    if n_dof < REDUCE_MIN_DOF:
        return _dense(a)
    return sp.csr_matrix(a, dtype=float)


def _lowest_elastic(M, K, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The lowest modes of a large structure (sparse shift-invert Lanczos) up to and including
    :data:`_N_CAL_MODES` elastic ones (rigid-body modes, 0 rad/s, come first and are counted
    apart), or all ``n - 2`` that Lanczos can give."""
    k = _N_CAL_MODES + 6
    while True:
        omega, phi = solve_modes(M, K, n_modes=min(k, n - 2), sparse=True)
        if np.count_nonzero(omega > 0) >= _N_CAL_MODES or k >= n - 2:
            return omega, phi
        k *= 2


def _modes(model: PhysicalModel, band):
    mats = model.build_structure().matrices()
    n = mats.n_dof
    M, K = _working(mats.mass, n), _working(mats.stiffness, n)
    if n >= REDUCE_MIN_DOF and band is not None:  # the modes up to the band: Lanczos, not dense
        omega, phi = solve_modes(M, K, band_hz=(0.0, float(band[1])), sparse=True)
    elif n >= REDUCE_MIN_DOF:  # the lowest elastic modes: Lanczos (a dense eigh is O(n^2) memory)
        omega, phi = _lowest_elastic(M, K, n)
    else:
        omega, phi = solve_modes(M, K)
    keep = omega > 0
    if band is not None:
        f = omega / (2 * np.pi)
        inside = keep & (f >= band[0]) & (f <= band[1])
        keep = inside if np.any(inside) else keep
    idx = np.flatnonzero(keep)[:_N_CAL_MODES] if band is None else np.flatnonzero(keep)
    number = idx - np.count_nonzero(omega <= 0) + 1  # among the elastic modes, from 1
    return omega[idx], phi[:, idx], (M, K, mats), number


@limit_blas
def calibrate(
    model: PhysicalModel, effects: Sequence[Effect], band: tuple[float, float] | None = None
) -> list:
    """Structural effects with secant steps calibrated on ``model`` (I/O effects unchanged).

    Each structural effect's ``scale`` becomes the size that changes the most affected
    modal ``w^2`` (modes in ``band`` Hz, else the lowest 12) by :data:`SHIFT_TARGET` to
    first order (a dashpot: a damping ratio by :data:`DAMPING_TARGET`); effects that cannot
    change the modes at all (a spring on a clamped node) are dropped.

    Parameters
    ----------
    model : PhysicalModel
    effects : sequence of Effect
    band : (float, float), optional
        Hz.

    Returns
    -------
    list of Effect
    """
    if model.structure is None or not any(e.domain == "structure" for e in effects):
        return list(effects)
    return _calibrate(model, list(effects), band)[2]


def _probe_copies(model: PhysicalModel):
    """A function returning fresh, cheap copies of the model's structure for probing effects,
    and the matrices of that structure.

    The structure is built once; each probe works on a copy (``Frame.without()`` shares the
    frozen components, ``MatrixStructure.copy()`` the arrays). A frame's gravity preload is
    switched off in the copies: the calibration needs the effect's own first-order ``dM``,
    ``dK`` (the preload's response to the effect is second order and costs a static
    iteration per candidate, most of the time of a full rebuild).
    """
    base = model.build_structure()
    if hasattr(base, "copy"):  # a MatrixStructure (its without() works in place)

        def fresh():
            return base.copy()

    elif hasattr(base, "set_gravity"):  # a Frame: copy containers, gravity preload off

        def fresh():
            return base.without("gravity")

    else:

        def fresh():
            return model.build_structure()

    return fresh, fresh().matrices()


def _changes_preload(effect: Effect, model: PhysicalModel, struct) -> bool:
    """Whether an effect changes a frame's gravity preload to first order
    (:meth:`Effect.changes_preload`: an added mass, a spring along gravity), which changes the
    pendulum stiffness of the suspension modes."""
    if not getattr(struct, "gravity_enabled", False):
        return False
    return effect.changes_preload(np.asarray(getattr(struct, "_gdir", (0.0, 0.0, 1.0)), dtype=float))


def _calibrate(
    model: PhysicalModel, cands: list[Effect], band, deadline: Deadline | None = None,
    executor: Any = None, modes: tuple | None = None,
) -> tuple[np.ndarray, np.ndarray, list]:
    """Give each structural candidate a secant step that moves the modes by about 2 %
    (:data:`SHIFT_TARGET` of ``w^2``; first-order perturbation ``phi^T (dK - w^2 dM) phi``,
    Rayleigh quotient, e.g. Geradin & Rixen, *Mechanical Vibrations*, sec. 2.9).

    ``deadline`` (a :class:`~robustctl.budget.Deadline`) is checked before each candidate.
    ``executor`` calibrates the candidates in parallel (:func:`robustctl.executors.parallel_map_shared`;
    each is calibrated alone, so the steps equal the serial ones). ``modes`` is
    ``_modes(model, band)`` when the caller has it."""
    omega, phi, (_, _, mats0), _ = _modes(model, band) if modes is None else modes  # with the preload
    if omega.size == 0:
        return omega, phi, cands
    fresh, mats_base = _probe_copies(model)
    if mats_base.n_dof != phi.shape[0]:  # gravity alone holds some DOFs: probe the full model
        fresh, mats_base = model.build_structure, mats0
    n0, nb = mats0.n_dof, mats_base.n_dof
    full = (_working(mats0.mass, n0), _working(mats0.stiffness, n0), mats0)
    light = (_working(mats_base.mass, nb), _working(mats_base.stiffness, nb), mats_base)
    shared = (model, model.build_structure(), omega, phi, fresh, full, light, deadline or Deadline(None),
              len(cands))
    steps = parallel_map_shared(_calibrate_one, shared, list(enumerate(cands)), executor, desc="calibration")
    return omega, phi, [c for c in steps if c is not None]


def _modal_diagonal(phi: np.ndarray, d: np.ndarray) -> np.ndarray:
    """``diag(Phi^T D Phi)`` by one matrix product (an einsum over three indices is 10x slower)."""
    return np.sum(phi * (d @ phi), axis=0)


def _calibrate_one(shared: tuple, item: tuple[int, Effect]) -> Effect | None:
    """One candidate of :func:`_calibrate` with its step (unchanged when it has none to set),
    or None when it cannot change the modes (``shared`` from :func:`_calibrate`)."""
    model, nominal, omega, phi, fresh, full, light, deadline, n = shared
    k, c = item
    if deadline.expired():
        raise FitError(
            f"time_budget_s={deadline.budget_s:g} s ran out while calibrating candidate {k + 1} of "
            f"{n}; raise time_budget_s, or pass fewer candidates (kinds=, locations=)."
        )
    if c.domain != "structure" or c.calibration == "none" or c.switch:
        return c  # nothing to calibrate (a switch), or its step was set when it was made
    unit = c.calibration_unit
    j = _point_dof(c, nominal, phi)
    if j is not None:  # a unit mass, spring or dashpot on one DOF: its modal diagonal is phi_j^2
        p2 = phi[j] ** 2
        mass, stiffness, damping = c.point_unit
        if c.calibration == "damping":
            dz = p2 * damping / (2 * omega)
            size = DAMPING_TARGET / dz.max() if dz.max() > 0 else None
        else:
            rel = p2 * (mass if stiffness == 0 else stiffness / omega**2)
            size = SHIFT_TARGET / rel.max() if rel.max() > 0 else None
        return _with_size(c, size)
    probe = c.with_values(**{c._value_fields[0]: unit})
    heavy = _changes_preload(c, model, nominal)
    M0, K0, mats_ref = full if heavy else light
    struct = model.build_structure() if heavy else fresh()
    mats = probe._stage_fn()({probe.param_names[0]: unit}, struct).matrices()
    if mats.n_dof != M0.shape[0]:
        return c
    n = M0.shape[0]
    dM = _working(mats.mass, n) - M0
    dK = _working(mats.stiffness, n) - K0
    if c.calibration == "damping":
        C = _working(mats.damping, n) if mats.damping is not None else 0.0 * M0
        C0 = _working(mats_ref.damping, n) if mats_ref.damping is not None else 0.0 * M0
        dz = np.abs(_modal_diagonal(phi, C - C0)) / (2 * omega) / unit
        size = DAMPING_TARGET / dz.max() if dz.max() > 0 else None
    else:
        dw2 = np.abs(_modal_diagonal(phi, dK) - omega**2 * _modal_diagonal(phi, dM)) / unit
        rel = dw2 / omega**2
        size = SHIFT_TARGET / rel.max() if rel.max() > 0 else None
    return _with_size(c, size)


def _point_dof(c: Effect, nominal: Any, phi: np.ndarray) -> int | None:
    """The DOF of a mass, grounded spring or dashpot on one DOF of a
    :class:`~robustctl.physical.matrices.MatrixStructure` of at least
    :data:`robustctl.physical.reduction.REDUCE_MIN_DOF` DOFs (the structures diagnose reduces),
    else None: its unit change is ``e_j e_j^T``, so ``diag(Phi^T dK Phi) = phi_j^2`` needs no
    probe structure (a rebuild and three sparse differences per candidate, 24 s for the 6,000 of
    a 2,000-DOF grid). Smaller structures keep the probe, and their steps bit for bit."""
    if (c.point_unit is None or len(c.param_names) != 1
            or getattr(c, "direction", None) is not None
            or not isinstance(nominal, MatrixStructure) or nominal.n_dof < reduction.REDUCE_MIN_DOF
            or phi.shape[0] != nominal.n_dof):
        return None
    try:
        return int(nominal._dof(c.location))
    except ModelError:
        return None


def _with_size(c: Effect, size: float | None) -> Effect | None:
    """``c`` with its calibrated step, capped at half its range; None when it has none."""
    if size is None or not np.isfinite(size):
        return None  # the effect cannot change this model's modes (e.g. a spring on a clamped node)
    lo, hi = c.parameters[0].bounds
    size = min(size, 0.5 * (hi - lo) if np.isfinite(hi - lo) else size)
    return c.with_scale(size)
