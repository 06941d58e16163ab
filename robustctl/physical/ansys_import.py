"""The user's ANSYS model: a modal ``.rst`` result and ``.full`` matrices (via ansys-mapdl-reader).

* :func:`read_ansys_modes` / :func:`load_ansys_modes` — the modes of a modal analysis
  (``ANTYPE,MODAL``): frequencies and the nodal displacements ``UX UY UZ ROTX ROTY ROTZ`` of each
  mode (MAPDL normalises them to unit modal mass by default, ``MODOPT,...,NRMKEY=OFF``) as
  :class:`~robustctl.frd_io.geometry.ModeShapes` or ``rc.modal_model`` with signals named
  ``"12:T3"`` (node 12, UZ);
* :func:`read_ansys_matrices` / :func:`load_ansys_matrices` — the assembled mass and stiffness
  of a ``.full`` file (``WRFULL``), constrained DOFs removed, as ``rc.structural_model`` with
  optional property-group partitions and lumped masses
  (:func:`~robustctl.physical.fe_model.fe_structural_model`);
* :func:`load_ansys_geometry` — node coordinates and element edges of the ``.rst`` mesh.

``units=`` names the consistent unit system of the model (``"m-kg-s"``, ``"mm-t-s"`` ...);
everything returned is SI.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import scipy.sparse as sp

from ..errors import DataError
from ..frd_io.geometry import Geometry, ModeShapes, dof_label
from .fe_model import fe_modal_model
from .nastran_import import _existing, _si_structural_model, _units

__all__ = [
    "read_ansys_modes",
    "load_ansys_modes",
    "read_ansys_matrices",
    "load_ansys_matrices",
    "load_ansys_geometry",
]

_ANSYS_DOFS = {"UX": 0, "UY": 1, "UZ": 2, "ROTX": 3, "ROTY": 4, "ROTZ": 5}


def _reader():
    try:
        from ansys.mapdl import reader
    except ImportError as exc:
        raise DataError(
            f"reading ANSYS files needs ansys-mapdl-reader ({exc}); install it with "
            "'pip install ansys-mapdl-reader' or 'pip install robustctl[ansys]'."
        ) from None
    return reader


def _read(path: Any, what: str, kind: str):
    reader = _reader()
    p = _existing(path, what)
    try:
        obj = reader.read_binary(str(p))
    except Exception as exc:  # the reader raises many kinds on foreign files
        raise DataError(
            f"ansys-mapdl-reader could not read {p.name} ({type(exc).__name__}: {exc})."
        ) from None
    if kind == "rst" and not hasattr(obj, "time_values"):
        raise DataError(f"{p.name} is not a result file (.rst); give the modal analysis result.")
    if kind == "full" and not hasattr(obj, "load_km"):
        raise DataError(f"{p.name} is not a .full matrix file; write one with WRFULL after the modal solve.")
    return p, obj


def read_ansys_modes(rst: str | os.PathLike, *, units: str = "m-kg-s", name: str | None = None) -> ModeShapes:
    """The modes of an ANSYS modal analysis result as mode shapes over nodes, in SI.

    Parameters
    ----------
    rst : path
        ``.rst`` of ``ANTYPE,MODAL`` (its result sets are the modes, time values their
        frequencies in Hz).
    units : str
        Consistent unit system of the model (``UNIT_SYSTEMS``).
    name : str, optional

    Returns
    -------
    ModeShapes
        Unit modal mass (MAPDL's default normalisation; a result written with
        ``MODOPT,...,NRMKEY=ON``, normalised to a unit largest displacement, is not recognised
        and must be re-solved with the default), ``present`` from the result's DOFs.

    Raises
    ------
    DataError
        Missing reader or file, not a modal result, unknown units.
    """
    path, res = _read(rst, "the ANSYS result file", "rst")
    length, mass = _units(units)
    kan = int(getattr(res, "_resultheader", {}).get("kan", 2))
    if kan != 2:
        raise DataError(
            f"{path.name} holds analysis type {kan}, not a modal analysis (2); give the modal result."
        )
    f_hz = np.asarray(res.time_values, dtype=float)
    nnum = None
    shapes, present = [], None
    for k in range(f_hz.size):
        num, disp = res.nodal_displacement(k)
        dofs = list(res.result_dof(k))
        if nnum is None:
            nnum = np.asarray(num, dtype=np.int64)
            present = np.zeros((nnum.size, 6), bool)
            for d in dofs:
                if d in _ANSYS_DOFS:
                    present[:, _ANSYS_DOFS[d]] = True
        full = np.zeros((nnum.size, 6))
        for col, d in enumerate(dofs):
            if d in _ANSYS_DOFS:
                full[:, _ANSYS_DOFS[d]] = np.asarray(disp)[:, col]
        shapes.append(full)
    # unit modal mass in file units: phi_SI = length / sqrt(mass) phi (rotations 1 / sqrt(mass))
    scale = np.array([length] * 3 + [1.0] * 3) / np.sqrt(mass)
    return ModeShapes(
        f_hz=f_hz,
        node_ids=nnum,
        shapes=np.asarray(shapes) * scale,
        present=present,
        unit="m",
        name=name or path.stem,
    )


def load_ansys_modes(
    rst: str | os.PathLike,
    inputs: Sequence[str] | Mapping[str, str],
    outputs: Sequence[str] | Mapping[str, str],
    *,
    units: str = "m-kg-s",
    **options: Any,
):
    """A modal model from an ANSYS modal result (MACE eqs. 2-4); signals ``"node:T3"``.

    :func:`read_ansys_modes` then :func:`~robustctl.physical.fe_model.fe_modal_model`.

    Parameters
    ----------
    rst, units
        The ``.rst`` of an ``ANTYPE,MODAL`` analysis and the model's consistent unit system, as
        for :func:`read_ansys_modes`.
    inputs, outputs, **options
        Force inputs, sensor outputs (``"node:T3"``) and the keywords of
        :func:`~robustctl.physical.fe_model.fe_modal_model`, as for
        :func:`~robustctl.physical.nastran_import.load_nastran_modes`.
    """
    return fe_modal_model(read_ansys_modes(rst, units=units), inputs, outputs, **options)


def read_ansys_matrices(full: str | os.PathLike):
    """Mass and stiffness of a ``.full`` file over its free DOFs.

    Parameters
    ----------
    full : path
        ``.full`` written by MAPDL (``WRFULL`` or a modal solve).

    Returns
    -------
    mass, stiffness : scipy.sparse.csr_matrix (n, n)
        In the file's units; DOFs whose rows of both matrices are zero (constrained DOFs the
        file keeps) are removed.
    dof_labels : tuple of str
        ``"node:component"`` per row (``UX`` -> ``T1`` ... ``ROTZ`` -> ``R3``).
    """
    path, f = _read(full, "the ANSYS .full file", "full")
    try:
        dof_ref, k, m = f.load_km(sort=True)
    except Exception as exc:
        raise DataError(
            f"could not load the matrices of {path.name} ({type(exc).__name__}: {exc})."
        ) from None
    k, m = sp.csr_matrix(k, dtype=float), sp.csr_matrix(m, dtype=float)
    # MAPDL stores the upper triangles of the symmetric matrices: mirror them
    for name in ("k", "m"):
        a = k if name == "k" else m
        if sp.tril(a, -1).count_nonzero() == 0:
            a = (a + sp.triu(a, 1).T).tocsr()
        k, m = (a, m) if name == "k" else (k, a)
    used = np.asarray(abs(k).sum(axis=1) + abs(m).sum(axis=1)).ravel() != 0
    idx = np.flatnonzero(used)
    labels = tuple(dof_label(int(n), int(c)) for n, c in np.asarray(dof_ref)[idx])
    return m[idx][:, idx].tocsr(), k[idx][:, idx].tocsr(), labels


def load_ansys_matrices(
    full: str | os.PathLike,
    *,
    groups: Mapping[str, Any] | None = None,
    units: str = "m-kg-s",
    name: str | None = None,
    **options: Any,
):
    """``rc.structural_model`` from an ANSYS ``.full`` file (MACE eq. 1).

    Parameters
    ----------
    full : path
    groups : mapping group -> (n, n) matrix, optional
        Stiffness partitions over the same free DOFs (a ``.full`` holds only the total; export
        each property group's stiffness separately, e.g. from a second ``.full``).
    units : str
        Consistent unit system of the model; matrices become SI.
    name : str, optional
        The model's name (default: the file's stem).
    **options
        ``inputs``, ``outputs`` (required), ``lumped_masses``, ``output_kind``, ``damping``,
        ``n_modes``, ``band_hz`` of :func:`~robustctl.physical.fe_model.fe_structural_model`
        (DOFs ``"12:T3"``).

    Returns
    -------
    PhysicalModel
    """
    M, K, labels = read_ansys_matrices(full)
    n = M.shape[0]
    for g, a in (groups or {}).items():
        if a.shape != (n, n):
            raise DataError(
                f"group {g!r} is {a.shape[0]}x{a.shape[1]}; the free DOFs of the .full file are {n}."
            )
    return _si_structural_model(M, K, dict(groups or {}), labels, units, full, name, **options)


def load_ansys_geometry(
    rst: str | os.PathLike,
    *,
    units: str = "m-kg-s",
    sensors: Mapping[str, Any] | None = None,
    name: str | None = None,
) -> Geometry:
    """Node coordinates (m) and element edges of the mesh stored in an ANSYS result file.

    Parameters
    ----------
    rst : path
    units : str
        Consistent unit system of the model.
    sensors : mapping channel -> "node:direction", optional
    name : str, optional

    Returns
    -------
    Geometry
    """
    path, res = _read(rst, "the ANSYS result file", "rst")
    length, _ = _units(units)
    nnum = np.asarray(res.mesh.nnum, dtype=np.int64)
    xyz = np.asarray(res.mesh.nodes, dtype=float)[:, :3] * length
    lines = np.zeros((0, 2), np.int64)
    try:
        grid = res.grid
        edges = grid.extract_all_edges()
        ids = np.asarray(edges.point_data["ansys_node_num"], dtype=np.int64)
        cells = np.asarray(edges.lines).reshape(-1, 3)[:, 1:]
        pairs = np.sort(ids[cells], axis=1)
        lines = np.unique(pairs, axis=0)
    except Exception:  # no VTK mesh in the file: nodes only
        lines = np.zeros((0, 2), np.int64)
    geo = Geometry(nnum, xyz, lines, unit="m", name=name or path.stem)
    return geo.with_sensors(sensors) if sensors else geo
