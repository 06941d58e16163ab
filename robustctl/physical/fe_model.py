"""FE models as PhysicalModels: mode shapes over nodes, and matrices with group superparameters.

Shared by every FE import (Nastran, ANSYS, UFF):

* :func:`fe_modal_model` — :class:`~robustctl.frd_io.geometry.ModeShapes` to ``rc.modal_model``
  with signals at DOFs (``"1001:T3"``) or at sensors placed by a geometry (MACE eqs. 2-4);
* :func:`fe_structural_model` — mass, stiffness and property-group partitions to
  ``rc.structural_model`` with one stiffness factor ``k_<group>`` per group and lumped masses
  ``m_<name>`` (kg): ``K(theta) = K + sum_g (k_g - 1) K_g`` and ``M(theta) = M + sum m_j E_j``,
  the superelement parameters MACE updates (Glaese & Miller, eqs. 1 and 7).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import scipy.sparse as sp

from ..errors import DataError
from ..frd_io.geometry import Geometry, ModeShapes, dof_label, parse_dof
from .builders import modal_model, structural_model
from .parameters import Parameter

__all__ = ["fe_modal_model", "fe_structural_model"]


def fe_modal_model(
    modes: ModeShapes,
    inputs: Sequence[str] | Mapping[str, str],
    outputs: Sequence[str] | Mapping[str, str],
    *,
    damping: Any = 0.01,
    output_kind: str | Sequence[str] = "acceleration",
    geometry: Geometry | None = None,
    n_modes: int | None = None,
    band_hz: tuple[float, float] | None = None,
    name: str | None = None,
):
    """``rc.modal_model`` from FE mode shapes, signals at grid points (MACE eqs. 2-4).

    Parameters
    ----------
    modes : ModeShapes
        From :func:`read_nastran_modes` or :func:`robustctl.load_uff_modes`.
    inputs, outputs : sequence of DOF names or mapping signal name -> DOF name
        ``["1001:T3", "1002:T1"]`` (signals named by grid point and direction), or
        ``{"A1": "1001:T3"}``; channel names placed by ``geometry.sensors`` are also accepted.
    damping : float, array or "file"
        Modal damping ratio (one, or one per kept mode); ``"file"`` takes each mode's ratio from
        ``modes.zeta`` (UFF dataset 55 carries it).
    output_kind : str or sequence of str
        ``"displacement"`` (m), ``"velocity"`` or ``"acceleration"`` (m/s^2).
    geometry : Geometry, optional
        Sensor placement (node and any direction) for channel names.
    n_modes, band_hz : optional
        Keep the lowest ``n_modes`` / the modes in ``[lo, hi]`` Hz.
    name : str, optional

    Returns
    -------
    PhysicalModel

    See Also
    --------
    robustctl.modal_model, robustctl.load_nastran_modes, robustctl.load_ansys_modes,
    robustctl.load_uff_modes

    References
    ----------
    Glaese & Miller (MACE 0-g models), eqs. 2-4: ``B = Phi^T b`` and ``C = c Phi`` from
    mass-normalised shapes ``phi / sqrt(m_gen)``.
    """
    keep = np.arange(modes.n_modes)
    if band_hz is not None:
        lo, hi = band_hz
        keep = keep[(modes.f_hz >= lo) & (modes.f_hz <= hi)]
    keep = keep[np.argsort(modes.f_hz[keep], kind="stable")]
    if n_modes is not None:
        keep = keep[: int(n_modes)]
    if keep.size == 0:
        raise DataError(
            f"no mode of {modes.name or 'the model'} is kept (band_hz={band_hz}, n_modes={n_modes})."
        )
    sel = modes.select(keep)
    in_names, in_dofs = _signals(inputs, "input")
    out_names, out_dofs = _signals(outputs, "output")
    b = sel.at(in_dofs, geometry=geometry, what="input")
    c = sel.at(out_dofs, geometry=geometry, what="output")
    if isinstance(damping, str):
        if damping != "file":
            raise DataError(f"damping must be a ratio, one ratio per mode, or 'file'; got {damping!r}.")
        if not np.all(np.isfinite(sel.zeta)):
            raise DataError(
                f"{modes.name or 'the mode shapes'} carry no damping ratio for some modes; give damping= "
                "(0.01 is 1 %)."
            )
        damping = sel.zeta
    elif np.ndim(damping) > 0:
        damping = np.asarray(damping, dtype=float).reshape(-1)
        if damping.size == modes.n_modes and keep.size != modes.n_modes:
            damping = damping[keep]
    return modal_model(
        sel.f_hz,
        damping,
        b,
        c,
        inputs=in_names,
        outputs=out_names,
        output_kind=output_kind,
        name=name or modes.name or "FE modal model",
    )


def _signals(spec: Any, what: str) -> tuple[list[str], list[str]]:
    if isinstance(spec, str):
        spec = [spec]
    if isinstance(spec, Mapping):
        names, dofs = [str(k) for k in spec], [str(v) for v in spec.values()]
    else:
        try:
            names = [str(s) for s in spec]
        except TypeError:
            raise DataError(
                f"{what}s must be DOF names ['1001:T3', ...] or {{name: '1001:T3'}}; got {spec!r}."
            ) from None
        dofs = list(names)
    if not names:
        raise DataError(f"give at least one {what}, e.g. {what}s=['1001:T3'].")
    return names, dofs


def fe_structural_model(
    mass: Any,
    stiffness: Any,
    *,
    inputs: Mapping[str, Any] | Sequence[str],
    outputs: Mapping[str, Any] | Sequence[str],
    dof_labels: Sequence[str] | None = None,
    groups: Mapping[str, Any] | None = None,
    lumped_masses: Mapping[str, Any] | None = None,
    output_kind: str = "acceleration",
    name: str | None = None,
    fixed_groups: Sequence[str] = (),
    **options: Any,
):
    """``rc.structural_model`` with property-group stiffness factors and lumped masses.

    Parameters
    ----------
    mass, stiffness : (n, n) array or sparse
        Mass (kg) and complete stiffness (N/m), SI, including the groups.
    inputs, outputs : sequence of DOF names or mapping name -> DOF name / vector
        ``["1001:T3"]`` names the signal after the DOF (``"1001:-3"`` pushes along -T3);
        ``{"F": "1001:T3"}`` renames it; an output value may be ``(dof, kind)``.
    dof_labels : sequence of str, optional
        ``"node:component"`` of each row (default ``"dof 1"`` ..., then signals need vectors).
    groups : mapping group -> (n, n) matrix, optional
        Stiffness partition of each property group (included in ``stiffness``): parameter
        ``k_<group>`` (factor, 1 = as modelled) and a stiffness group of the structure.
    fixed_groups : sequence of str
        Groups whose factor ``k_<group>`` is not free (``Parameter.free=False``): ``rc.update``
        and ``rc.diagnose`` leave it as modelled by default, and diagnose checks the group as a
        candidate effect (:class:`~robustctl.physical.effects.GroupStiffness`, ``stiffness change
        of <group>``) -- a joint, seam or bolted flange the test is to judge rather than absorb
        into the update. Default none: every group factor is an update parameter.
    lumped_masses : mapping name -> node id or DOF names, optional
        Parameter ``m_<name>`` (kg, 0 = as modelled) on the node's translations or the DOFs.
    output_kind, name :
        As for :func:`robustctl.structural_model`: the kind of every output (unless a mapping
        value says otherwise) and the model's name.
    **options
        ``damping``, ``n_modes``, ``band_hz`` and the other keywords of
        :func:`robustctl.structural_model` but the ones set here.

    Returns
    -------
    PhysicalModel

    See Also
    --------
    robustctl.structural_model, robustctl.load_nastran_matrices, robustctl.load_ansys_matrices

    References
    ----------
    Glaese & Miller (MACE 0-g models), eq. 1 with ``K(theta) = K + sum_g (k_g - 1) K_g``.
    """
    M, K = mass, stiffness
    K_groups = dict(groups or {})
    fixed = (fixed_groups,) if isinstance(fixed_groups, str) else tuple(str(g) for g in fixed_groups)
    unknown = sorted(set(fixed) - set(K_groups))
    if unknown:
        raise DataError(
            f"fixed_groups {unknown} are not groups of the model; it has groups {sorted(K_groups)}."
        )
    n = M.shape[0]
    labels = None if dof_labels is None else tuple(str(x) for x in dof_labels)
    dense = n <= 600
    if dense:
        M, K = (a.toarray() if sp.issparse(a) else np.asarray(a, float) for a in (M, K))
        K_groups = {g: a.toarray() if sp.issparse(a) else np.asarray(a, float) for g, a in K_groups.items()}
    else:
        M, K = sp.csr_matrix(M), sp.csr_matrix(K)
        K_groups = {g: sp.csr_matrix(a) for g, a in K_groups.items()}
    label_list = list(labels) if labels is not None else [f"dof {i + 1}" for i in range(n)]

    def dof(spec: Any, what: str):
        if not isinstance(spec, str):
            return spec
        if spec in label_list:
            return spec
        if labels is None:
            raise DataError(
                f"{what} {spec!r}: the matrix rows have no DOF names; pass dof_labels=['1001:T1', ...] "
                "(one per row) or a force vector."
            )
        node, vec = parse_dof(spec)
        comps = np.flatnonzero(vec)
        key = dof_label(node, int(comps[0]))
        if key not in label_list:
            have = sorted({lb for lb in label_list if lb.startswith(f"{node}:")})
            fix = (
                f"grid {node} has {have}; use one of them"
                if have
                else f"grid {node} is not in the matrices; check the grid id or the exported DOF set"
            )
            raise DataError(f"{what} {spec!r}: the model has no DOF {key}; {fix}.")
        if vec[comps[0]] < 0:
            v = np.zeros(n)
            v[label_list.index(key)] = -1.0
            return v
        return key

    in_map = inputs if isinstance(inputs, Mapping) else {str(s): str(s) for s in inputs}
    out_map = outputs if isinstance(outputs, Mapping) else {str(s): str(s) for s in outputs}
    b = {str(k): dof(v, f"input {k!r}") for k, v in in_map.items()}
    c = {}
    for k, v in out_map.items():
        spec, kind = v if isinstance(v, tuple) else (v, output_kind)
        c[str(k)] = (dof(spec, f"output {k!r}"), kind)

    params = [
        Parameter(
            f"k_{g}",
            1.0,
            "",
            bounds=(0.05, 20.0),
            rel_step=1e-3,
            meaning=f"stiffness factor of property group {g!r} (1 = as modelled)",
            tags=("stiffness",),
            free=g not in fixed,
        )
        for g in K_groups
    ]
    masses = {}
    for mname, where in (lumped_masses or {}).items():
        if labels is None:
            raise DataError(f"lumped mass {mname!r} needs DOF names; pass dof_labels= (one per row).")
        if isinstance(where, (int, np.integer)):
            dofs = [lb for lb in label_list if lb in {dof_label(where, c) for c in range(3)}]
            if not dofs:
                raise DataError(f"lumped mass {mname!r}: grid {where} has no translation in the matrices.")
        else:
            where = [where] if isinstance(where, str) else where
            dofs = [dof(str(s), f"lumped mass {mname!r}") for s in where]
        masses[mname] = [label_list.index(d) for d in dofs]
        params.append(
            Parameter(
                f"m_{mname}",
                0.0,
                "kg",
                bounds=(-1e6, 1e6),
                abs_step=1e-3,
                meaning=f"lumped mass added at {', '.join(dofs)}",
                tags=("mass",),
                neutral=0.0,
            )
        )

    def k_of(theta):
        k = K
        for g, kg in K_groups.items():
            f = float(theta.get(f"k_{g}", 1.0))
            if f != 1.0:
                k = k + (f - 1.0) * kg
        return k

    def m_of(theta):
        m = M
        for mname, idx in masses.items():
            dm = float(theta.get(f"m_{mname}", 0.0))
            if dm != 0.0:
                add = sp.csr_matrix((np.full(len(idx), dm), (idx, idx)), shape=(n, n))
                m = m + (add.toarray() if dense else add)
        return m

    def groups_of(theta):
        return {g: float(theta.get(f"k_{g}", 1.0)) * kg for g, kg in K_groups.items()}

    group_stiffness = groups_of if K_groups else None
    return structural_model(m_of, k_of, inputs=b, outputs=c, params=params, dof_labels=label_list,
                            stiffness_groups=group_stiffness, name=name, **options)
