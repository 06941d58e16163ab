"""Bring your own model: mass/stiffness matrices or modal data as a PhysicalModel.

The three ways a user brings a model (DESIGN.md):

* :func:`frame_model` — the built-in frame FEM (:class:`~robustctl.physical.fem.Frame`), built
  by a function of the named parameters;
* :func:`structural_model` — the user's own mass and stiffness matrices (arrays, or
  functions of the parameter values so that updating can change them);
* :func:`modal_model` — frequencies, damping ratios and mass-normalised mode shapes at
  the actuator and sensor DOFs exported from an external FE code (NASTRAN, ANSYS ...).

Each gives a :class:`~robustctl.physical.model.PhysicalModel` whose state space is the
modal model of MACE eqs. 1-4; electronics and input/output effects apply to all,
structural effects (added mass, springs ...) to :func:`frame_model` and
:func:`structural_model`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from ..errors import ModelError
from .fem import Frame
from .matrices import MatrixStructure
from .modal import _modal_data_from_arrays, modal_dynamics
from .model import PhysicalModel
from .parameters import Parameter
from .reduction import band_limited

__all__ = ["frame_model", "structural_model", "modal_model", "MODAL_DAMPING_PARAM"]

#: Name of the modal damping-ratio parameter added to every model built here.
MODAL_DAMPING_PARAM = "zeta_modal"

Theta = Mapping[str, float]


def _resolve(value: Any, theta: Theta) -> Any:
    return value(theta) if callable(value) else value


def _check_params(params: Sequence[Parameter]) -> tuple[Parameter, ...]:
    params = tuple(params)
    for p in params:
        if not isinstance(p, Parameter):
            raise ModelError(f"params must be Parameter objects; got {type(p).__name__}.")
    return params


def _damping_param(
    value: float,
    name: str = MODAL_DAMPING_PARAM,
    meaning: str = "modal damping ratio of every mode (MACE: 1 % articulated, 0.1 % tight truss)",
) -> Parameter:
    value = float(value)
    if not np.isfinite(value) or not 0 <= value < 1:
        raise ModelError(f"the modal damping ratio must lie in [0, 1); got {value!r} (0.01 is 1 %).")
    return Parameter(
        name, value, "", bounds=(0.0, 1.0), rel_step=1e-2, abs_step=1e-5, meaning=meaning, tags=("damping",)
    )


def _with_damping(params: tuple[Parameter, ...], damping: Any) -> tuple[tuple[Parameter, ...], Any]:
    """Add ``zeta_modal`` for a scalar damping (unless the user gave one); an array stays fixed."""
    if np.ndim(damping) == 0:
        if MODAL_DAMPING_PARAM in {p.name for p in params}:
            return params, None
        return params + (_damping_param(damping),), None
    return params, np.asarray(damping, dtype=float)


def _check_build(model: PhysicalModel) -> PhysicalModel:
    """Refuse bad input now rather than at the first frequency response: build the model once
    (a large structure through its lowest modes only, :func:`~robustctl.physical.reduction.band_limited`:
    the full dense build of thousands of DOFs costs seconds and ``O(n_dof^2)`` memory)."""
    band_limited(model, _LOWEST_HZ).statespace()
    return model


#: The frequency (Hz) below which :func:`_check_build` looks at a large structure's modes (the
#: reduction keeps at least its lowest mode and the residual modes of the inputs).
_LOWEST_HZ = 1e-9


def structural_model(
    mass: Any,
    stiffness: Any,
    *,
    inputs: Mapping[str, Any],
    outputs: Mapping[str, tuple[Any, str]],
    damping: float | Sequence[float] = 0.01,
    params: Sequence[Parameter] = (),
    n_modes: int | None = None,
    band_hz: tuple[float, float] | None = None,
    concentrated_damping: Any = None,
    dof_labels: Sequence[str] | None = None,
    stiffness_groups: Mapping[str, Any] | Callable[[Theta], Mapping[str, Any]] | None = None,
    geometric_stiffness: Mapping[str, Any] | None = None,
    tagged: Mapping[str, Sequence[Any]] | Callable[[Theta], Mapping[str, Any]] | None = None,
    rigid_body_damping: float = 0.0,
    residual_flexibility: bool = False,
    nodes: Mapping[int, Sequence[float]] | None = None,
    lines: Sequence[tuple[int, int]] = (),
    name: str = "structural model",
) -> PhysicalModel:
    """A PhysicalModel from the user's own mass and stiffness matrices (MACE eqs. 1-4).

    Parameters
    ----------
    mass, stiffness : array_like, sparse, or callable ``theta -> matrix``
        Mass (kg) and stiffness (N/m) matrices of the free DOFs; a callable receives the
        parameter values by name (``lambda th: th["k"] * K_unit``) so updating can change
        them.
    inputs : mapping name -> force vector (n,) or DOF label
        Generalised force per unit input (N per unit).
    outputs : mapping name -> (vector (n,) or DOF label, kind)
        Sensor row and kind: ``"displacement"`` (m), ``"velocity"`` (m/s) or
        ``"acceleration"`` (m/s^2, with the feedthrough of MACE eq. 4).
    damping : float or sequence of float
        Modal damping ratio. A scalar becomes the parameter ``"zeta_modal"`` (added
        automatically unless ``params`` has one); a per-mode sequence stays fixed.
    params : sequence of Parameter
        The physical parameters the callables read.
    n_modes, band_hz :
        Modal truncation (lowest ``n_modes`` / modes in ``[lo, hi]`` Hz); all modes by default.
    concentrated_damping : array_like, sparse or callable, optional
        Dashpot matrix ``Cs`` (N s/m) of MACE eq. 2.
    dof_labels, stiffness_groups, geometric_stiffness, tagged :
        See :class:`~robustctl.physical.matrices.MatrixStructure`; ``tagged`` parts
        (e.g. ``{"suspension": (dK, dC)}``) are removed by ``model.without("suspension")``.
    rigid_body_damping, residual_flexibility :
        See :func:`~robustctl.physical.modal.modal_decomposition`.
    nodes, lines : optional
        Node coordinates ``{id: (x, y, z)}`` (m) and node pairs to draw; with ``dof_labels``
        of the form ``"node:direction"`` (``"3:X"``) the model has ``model.geometry()`` and
        ``model.mode_shapes()`` for :func:`robustctl.plot_mode_shapes`.
    name : str
        Shown in tables and plots.

    Returns
    -------
    PhysicalModel

    Raises
    ------
    ModelError
        Non-symmetric or singular mass, negative mass or stiffness, wrong vector lengths,
        unknown output kinds, a band without modes (checked by building the model once).

    Examples
    --------
    >>> import numpy as np, robustctl as rc
    >>> K = 1e3 * np.array([[2.0, -1.0], [-1.0, 1.0]])
    >>> model = rc.structural_model(np.eye(2), K, inputs={"F": "dof 2"},
    ...                             outputs={"x2": ("dof 2", "displacement")})
    >>> model.param_names
    ('zeta_modal',)
    """
    params, fixed_damping = _with_damping(_check_params(params), damping)

    def build(theta: Theta) -> MatrixStructure:
        return MatrixStructure(
            _resolve(mass, theta),
            _resolve(stiffness, theta),
            _resolve(concentrated_damping, theta),
            inputs=inputs,
            outputs=outputs,
            dof_labels=dof_labels,
            stiffness_groups=_resolve(stiffness_groups, theta),
            geometric_stiffness=_resolve(geometric_stiffness, theta),
            tagged=_resolve(tagged, theta),
            nodes=nodes,
            lines=lines,
        )

    matrix_args = (mass, stiffness, concentrated_damping, stiffness_groups, geometric_stiffness, tagged)
    if any(callable(a) for a in matrix_args):
        structure = build
    else:
        # constant matrices: validate once (symmetry, Cholesky, eigvalsh of K), not on every
        # build -- a damping-only change would otherwise cost as much as the eigensolution
        template = build({})

        def structure(theta: Theta) -> MatrixStructure:
            return template.copy()

    dynamics = modal_dynamics(
        n_modes,
        band_hz,
        MODAL_DAMPING_PARAM,
        default_damping=0.01 if fixed_damping is None else fixed_damping,
        rigid_body_damping=rigid_body_damping,
        residual_flexibility=residual_flexibility,
    )
    if fixed_damping is not None:
        base = dynamics

        def dynamics(theta, struct):  # a fixed per-mode damping ignores any zeta_modal
            return base({}, struct)

    return _check_build(PhysicalModel(params, dynamics, structure=structure, name=name))


def frame_model(
    frame: Frame | Callable[[Theta], Frame],
    params: Sequence[Parameter] = (),
    *,
    damping: float = 0.01,
    n_modes: int | None = None,
    band_hz: tuple[float, float] | None = None,
    name: str | None = None,
) -> PhysicalModel:
    """A PhysicalModel of the built-in frame FEM with named parameters (MACE eqs. 1-4).

    Parameters
    ----------
    frame : Frame or callable ``theta -> Frame``
        The structure. A callable receives the parameter values by name (``theta["E"]``) and
        builds a new :class:`~robustctl.physical.fem.Frame` each call, so updating changes
        them; a Frame is used as it stands (each build gets its own copy), for a model whose
        only parameters are the damping and the effects diagnose adds.
    params : sequence of Parameter
        The physical parameters the callable reads; ``free=False`` ones stay fixed in
        :func:`robustctl.update`.
    damping : float
        Modal damping ratio of every mode: the parameter ``"zeta_modal"`` (unless ``params``
        has one).
    n_modes, band_hz : optional
        Modal truncation (lowest ``n_modes`` / modes in ``[lo, hi]`` Hz); all modes by default.
    name : str, optional
        Shown in tables and plots (default: the frame's name).

    Returns
    -------
    PhysicalModel
        Inputs and outputs named as the frame's; structural effects (added mass, springs,
        stiffer element groups, taut wires ...) apply; ``model.geometry()`` and
        ``model.mode_shapes()`` draw it.

    Raises
    ------
    ModelError
        ``frame`` is neither a Frame nor a callable returning one, a parameter is not a
        :class:`Parameter`, or the frame cannot be built (checked once here).

    Examples
    --------
    >>> import robustctl as rc
    >>> def cantilever(th):
    ...     fr = rc.Frame()
    ...     for k in range(3):
    ...         fr.add_node(f"n{k}", (0.5 * k, 0.0, 0.0))
    ...     fr.add_beam("beam", "n0", "n2", E=th["E"], G=th["E"] / 2.6, rho=2700.0, A=1e-4,
    ...                 Iy=1e-9, Iz=1e-9, J=2e-9)
    ...     fr.fix("n0")
    ...     fr.add_force_input("F", "n2", "z")
    ...     return fr.add_output("a_tip", "n2", "z")
    >>> model = rc.frame_model(cantilever, [rc.Parameter("E", 69e9, "Pa", bounds=(50e9, 80e9))])
    >>> model.param_names
    ('E', 'zeta_modal')
    """
    params, _ = _with_damping(_check_params(params), float(damping))
    if isinstance(frame, Frame):
        template = frame

        def structure(theta: Theta) -> Frame:
            return template.without()

        label = template.name
    elif callable(frame):
        structure, label = frame, "frame model"
    else:
        raise ModelError(
            f"frame must be a robustctl.Frame or a function theta -> Frame; got {type(frame).__name__}."
        )
    dynamics = modal_dynamics(n_modes, band_hz, MODAL_DAMPING_PARAM)
    model = PhysicalModel(params, dynamics, structure=structure, name=name or label)
    built = model.build_structure()
    if not isinstance(built, Frame):
        raise ModelError(
            f"the frame function returned a {type(built).__name__}; it must return a robustctl.Frame."
        )
    return _check_build(model)


def modal_model(
    freqs_hz: Any,
    damping: Any,
    shapes_at_inputs: Any,
    shapes_at_outputs: Any,
    *,
    inputs: Sequence[str],
    outputs: Sequence[str],
    output_kind: str | Sequence[str] = "acceleration",
    params: Sequence[Parameter] = (),
    name: str = "modal model",
) -> PhysicalModel:
    """A PhysicalModel from modal data exported by an external FE code (MACE eqs. 2-4).

    Parameters
    ----------
    freqs_hz : array_like (n_modes,) or callable ``theta -> array``
        Natural frequencies in Hz (0 for rigid-body modes).
    damping : float, array_like (n_modes,) or callable
        Modal damping ratios. A scalar becomes the parameter ``"zeta_modal"``; an array
        becomes one parameter per mode, ``"zeta_mode_1"`` ... (in the order given), so
        updating can adjust each damping ratio as MACE did; a callable is used as is.
    shapes_at_inputs : array_like (n_in, n_modes) or callable
        Mass-normalised mode shapes at the actuator DOFs (``(Phi^T b)^T``, per unit input).
    shapes_at_outputs : array_like (n_out, n_modes) or callable
        Mass-normalised mode shapes at the sensor DOFs (``c Phi``).
    inputs, outputs : sequence of str
        Signal names, one per row of the shapes.
    output_kind : str or sequence of str
        ``"displacement"``, ``"velocity"`` or ``"acceleration"`` (all outputs, or one each).
    params : sequence of Parameter
        Parameters the callables read.
    name : str
        Shown in tables and plots.

    Returns
    -------
    PhysicalModel
        Without a structure: input/output effects and electronics apply, structural
        effects are refused with a clear message.
    """
    params = _check_params(params)
    names = {p.name for p in params}
    if callable(damping):
        zeta_of = damping
    elif np.ndim(damping) == 0:
        if MODAL_DAMPING_PARAM not in names:
            params = params + (_damping_param(damping),)

        def zeta_of(theta):
            return theta[MODAL_DAMPING_PARAM]
    else:
        zetas = np.asarray(damping, dtype=float).reshape(-1)
        keys = [f"zeta_mode_{k + 1}" for k in range(zetas.size)]
        params = params + tuple(
            _damping_param(z, key, f"modal damping ratio of mode {k + 1}")
            for k, (key, z) in enumerate(zip(keys, zetas))
            if key not in names
        )

        def zeta_of(theta):
            return np.array([theta[key] for key in keys])

    def dynamics(theta: Theta, _structure: Any):
        data = _modal_data_from_arrays(
            _resolve(freqs_hz, theta), zeta_of(theta), _resolve(shapes_at_inputs, theta),
            _resolve(shapes_at_outputs, theta), inputs, outputs, output_kind,
        )
        return data.statespace()

    return _check_build(PhysicalModel(params, dynamics, name=name))
