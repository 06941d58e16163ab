"""The user's Nastran model: OP2 modes, OP4/DMIG matrices and BDF grid geometry (via pyNastran).

* :func:`read_nastran_modes` / :func:`load_nastran_modes` — an OP2 real-eigenvector result
  (frequencies from the LAMA table, generalised masses, shapes at every grid point and
  component) as :class:`~robustctl.frd_io.geometry.ModeShapes` or directly as
  ``rc.modal_model`` with signals named ``"1001:T3"`` (MACE eqs. 2-4).
* :func:`read_nastran_matrices` / :func:`load_nastran_matrices` — mass, stiffness and one
  stiffness partition per property group from an OP4 file or DMIG cards in a BDF/punch file,
  as ``rc.structural_model`` with one superparameter per group (``k_<group>``, a stiffness
  factor, 1 = as modelled) and optional lumped masses (``m_<name>``, kg), so MACE-style
  updating acts on the user's own model:
  ``K(theta) = K + sum_g (k_g - 1) K_g`` (Glaese & Miller, MACE 0-g models, eq. 7 sensitivities
  of superelement parameters).
* :func:`load_bdf_geometry` — GRID coordinates (basic system) and element edges for figures.

Nastran has no unit system of its own; ``units=`` names the consistent system the model was
built in (``"m-kg-s"``, ``"mm-t-s"``, ``"mm-kg-s"``, ``"in-lbf-s"``) and everything returned is SI.

pyNastran 1.4.1 declares ``numpy<2`` but only its use of ``numpy.in1d`` (removed in numpy 2.4)
breaks on newer numpy; :func:`_pynastran` provides that one alias (``numpy.isin`` of the
flattened array, the documented equivalent) before importing it.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp

from ..errors import DataError
from ..frd_io.geometry import Geometry, ModeShapes, dof_label, parse_dof
from .fe_model import fe_modal_model, fe_structural_model

__all__ = [
    "UNIT_SYSTEMS",
    "read_nastran_modes",
    "load_nastran_modes",
    "read_nastran_matrices",
    "load_nastran_matrices",
    "load_bdf_geometry",
    "write_nastran_modes",
    "write_nastran_matrices",
]

#: Consistent unit systems: (metres per length unit, kilograms per mass unit).
UNIT_SYSTEMS = {
    "m-kg-s": (1.0, 1.0),
    "mm-t-s": (1e-3, 1e3),
    "mm-kg-s": (1e-3, 1.0),
    "in-lbf-s": (0.0254, 4.4482216152605 / 0.0254),  # mass unit lbf s^2/in
}
_LENGTH_NAMES = {"m-kg-s": "m", "mm-t-s": "mm", "mm-kg-s": "mm", "in-lbf-s": "in"}


def _pynastran():
    """Import pyNastran (with the ``numpy.in1d`` alias numpy >= 2.4 lacks) or say how to get it."""
    if not hasattr(np, "in1d"):

        def in1d(ar1, ar2, assume_unique=False, invert=False, **kwargs):
            return np.isin(np.asarray(ar1).ravel(), ar2, assume_unique=assume_unique, invert=invert, **kwargs)

        np.in1d = in1d
    try:
        import pyNastran  # noqa: F401
        from pyNastran.bdf.bdf import BDF
        from pyNastran.op2.op2 import OP2
        from pyNastran.op4.op4 import OP4
    except ImportError as exc:
        raise DataError(
            f"reading Nastran files needs pyNastran ({exc}); install it with "
            "'pip install pyNastran --no-deps' (its numpy<2 pin is stricter than needed) or "
            "'pip install robustctl[nastran]'."
        ) from None
    return OP2, OP4, BDF


def _units(units: str) -> tuple[float, float]:
    if units not in UNIT_SYSTEMS:
        raise DataError(
            f"units={units!r} is not a known consistent unit system; use one of {sorted(UNIT_SYSTEMS)} "
            "(the system the Nastran model was built in)."
        )
    return UNIT_SYSTEMS[units]


def _existing(path: Any, what: str) -> Path:
    if not isinstance(path, (str, os.PathLike)):
        raise DataError(f"{what} must be a file path; got {type(path).__name__}.")
    p = Path(path)
    if not p.is_file():
        raise DataError(f"cannot read {what} {str(p)!r}: no such file.")
    return p


class _Quiet:
    """A logger that drops pyNastran's chatter."""

    def debug(self, *a, **k): ...
    def info(self, *a, **k): ...
    def warning(self, *a, **k): ...
    def error(self, *a, **k): ...
    def exception(self, *a, **k): ...
    def critical(self, *a, **k): ...


# ---------------------------------------------------------------------------- OP2 modes
def read_nastran_modes(
    op2: str | os.PathLike, *, subcase: int | None = None, units: str = "m-kg-s", name: str | None = None
) -> ModeShapes:
    """Real eigenvectors of an OP2 file (SOL 103) as mode shapes over grid points, in SI.

    Parameters
    ----------
    op2 : path
        OP2 written with ``PARAM,POST,-1`` (eigenvector table OUGV1/BOUGV1, eigenvalue table LAMA).
    subcase : int, optional
        Subcase id (default: the only one; several refuse with the list).
    units : str
        Consistent unit system of the model (key of :data:`UNIT_SYSTEMS`); shapes are converted
        so that ``phi^T M phi`` is the generalised mass in kg and translations are in m.
    name : str, optional

    Returns
    -------
    ModeShapes
        ``f_hz = sqrt(|lambda|) / 2 pi`` from the eigenvalues, ``generalized_mass`` from LAMA
        (1.0 when the file has no LAMA table, as for the default ``NORM=MASS``: see Notes),
        ``present`` marks the components of grid points (scalar points carry only T1).

    Notes
    -----
    Without a LAMA table the shapes are taken as mass-normalised (Nastran's default ``EIGRL``
    normalisation); a file written with ``NORM=MAX`` needs its LAMA table. Components are in
    each grid's displacement frame (CD); for grids with ``CD != 0`` write the OP2 with
    ``PARAM,OUGCORD,BASIC`` so that ``"1001:T1"`` means basic X everywhere
    (:func:`load_bdf_geometry` refuses such grids for the same reason).

    Raises
    ------
    DataError
        Missing file, no eigenvector table, several subcases without ``subcase=``, an
        eigenvector/eigenvalue count mismatch, unknown ``units``.

    See Also
    --------
    load_nastran_modes, robustctl.physical.fe_model.fe_modal_model

    References
    ----------
    MSC Nastran DMAP Programmer's Guide, OUGV1 and LAMA data blocks (OP2 output, PARAM,POST,-1).
    Glaese, R. M. & Miller, D. W., "Derivation of 0-g structural control models from analysis
    and 1-g experimentation", the modal model of eqs. 2-4 built from these shapes.
    """
    OP2, _, _ = _pynastran()
    path = _existing(op2, "the OP2 file")
    length, mass = _units(units)
    model = OP2(log=_Quiet(), debug=None)
    try:
        model.read_op2(str(path), build_dataframe=False)
    except Exception as exc:  # pyNastran raises many kinds on corrupt input
        raise DataError(
            f"pyNastran could not read {path.name} as an OP2 file ({type(exc).__name__}: {exc})."
        ) from None
    vectors = dict(model.eigenvectors)
    if not vectors:  # modal displacements (pyNastran's own OP2 writer stores eigenvectors so)
        vectors = {k: v for k, v in model.displacements.items() if getattr(v, "analysis_code", 0) == 2}
    if not vectors:
        raise DataError(
            f"{path.name} has no real eigenvector table; write the modal solution (SOL 103) with "
            "PARAM,POST,-1 and DISPLACEMENT(PLOT)=ALL."
        )
    if subcase is None:
        if len(vectors) > 1:
            raise DataError(f"{path.name} holds the subcases {sorted(vectors)}; choose one with subcase=.")
        key = next(iter(vectors))
    elif subcase in vectors:
        key = subcase
    else:
        raise DataError(f"{path.name} has no subcase {subcase}; it holds {sorted(vectors)}.")
    vec = vectors[key]
    if np.iscomplexobj(vec.data):
        raise DataError(
            f"{path.name} holds complex eigenvectors (SOL 107/110); export the real modes of SOL 103 and "
            "give the damping with damping=."
        )
    data = np.asarray(vec.data, dtype=float)  # (n_modes, n_nodes, 6)
    grid = np.asarray(vec.node_gridtype)
    eig = np.asarray(getattr(vec, "eigns", [np.nan] * data.shape[0]), dtype=float)
    gm = np.ones(data.shape[0])
    lama = list(model.eigenvalues.values())
    if len(lama) > 1:  # one LAMA per subcase: the one whose eigenvalues the eigenvector table carries
        same = [
            t
            for t in lama
            if len(t.eigenvalues) == data.shape[0]
            and np.allclose(np.asarray(t.eigenvalues, float), eig, rtol=1e-5)
        ]
        if len(same) != 1:
            raise DataError(
                f"{path.name} holds {len(lama)} eigenvalue (LAMA) tables and {len(same)} match subcase "
                f"{key}; write one modal subcase per OP2."
            )
        lama = same
    if lama:
        table = lama[0]
        if len(table.eigenvalues) != data.shape[0]:
            raise DataError(
                f"{path.name}: the LAMA table has {len(table.eigenvalues)} modes but the eigenvector table "
                f"{data.shape[0]}; write both from the same subcase."
            )
        eig = np.asarray(table.eigenvalues, dtype=float)
        gm = np.asarray(table.generalized_mass, dtype=float)
    if not np.all(np.isfinite(eig)):
        raise DataError(f"{path.name}: the eigenvector table carries no eigenvalues; add the LAMA table.")
    f_hz = np.sqrt(np.abs(eig)) / (2 * np.pi)
    present = np.ones((grid.shape[0], 6), bool)
    present[grid[:, 1] != 1, 1:] = False  # scalar/extra points: one component
    # SI: translations x length, generalised mass x mass (so phi / sqrt(gm) is per sqrt(kg))
    scale = np.array([length] * 3 + [1.0] * 3)
    return ModeShapes(
        f_hz=f_hz,
        node_ids=grid[:, 0],
        shapes=data * scale,
        present=present,
        generalized_mass=gm * mass,
        unit="m",
        name=name or path.stem,
    )


def load_nastran_modes(
    op2: str | os.PathLike,
    inputs: Sequence[str] | Mapping[str, str],
    outputs: Sequence[str] | Mapping[str, str],
    *,
    subcase: int | None = None,
    units: str = "m-kg-s",
    **options: Any,
):
    """A modal model from a Nastran OP2 eigenvector result (MACE eqs. 2-4).

    ``modes = read_nastran_modes(op2, ...)`` then :func:`fe_modal_model`. Inputs are forces
    in N, outputs in m, m/s or m/s^2 (SI whatever ``units``).

    Parameters
    ----------
    op2, subcase, units
        The OP2 file (SOL 103, ``PARAM,POST,-1``), its subcase id and the model's consistent
        unit system, as for :func:`read_nastran_modes`.
    inputs, outputs
        Force inputs and sensor outputs: DOF names ``"node:T3"`` or a mapping signal name ->
        DOF name (:func:`~robustctl.physical.fe_model.fe_modal_model`).
    **options
        ``damping``, ``output_kind``, ``geometry``, ``n_modes``, ``band_hz``, ``name`` of
        :func:`~robustctl.physical.fe_model.fe_modal_model`: the modal damping ratio (or
        ``"file"``), the sensor kind, the geometry for figures, the modal truncation (count or
        band in Hz) and the model's name.

    Examples
    --------
    >>> model = rc.load_nastran_modes("truss.op2", inputs=["1001:T3"],            # doctest: +SKIP
    ...                               outputs=["1004:T3", "1005:T1"], damping=0.005)
    """
    return fe_modal_model(read_nastran_modes(op2, subcase=subcase, units=units), inputs, outputs, **options)


# ---------------------------------------------------------------------------- OP4 / DMIG matrices
def _dmig_matrices(path: Path, names: Sequence[str] | None):
    """DMIG cards of a BDF/punch file as CSR matrices over one common (grid, component) order."""
    model = _bdf(path, xref=False)
    if not model.dmig:
        raise DataError(
            f"{path.name} has no DMIG cards; export the matrices (e.g. EXTSEOUT or OUTPUT4) or give an OP4."
        )
    wanted = list(model.dmig) if names is None else list(names)
    keys: set[tuple[int, int]] = set()
    parts = {}
    for nm in wanted:
        if nm not in model.dmig:
            raise DataError(f"{path.name} has no DMIG {nm!r}; it has {sorted(model.dmig)}.")
        d = model.dmig[nm]
        if d.is_complex:
            raise DataError(f"DMIG {nm!r} is complex; mass and stiffness must be real.")
        gci = np.asarray(d.GCi, dtype=np.int64).reshape(-1, 2)
        gcj = np.asarray(d.GCj, dtype=np.int64).reshape(-1, 2)
        gci[gci[:, 1] == 0, 1] = 1  # scalar points: component 0 -> 1
        gcj[gcj[:, 1] == 0, 1] = 1
        keys.update(map(tuple, gci.tolist()))
        keys.update(map(tuple, gcj.tolist()))
        parts[nm] = (gci, gcj, np.asarray(d.Real, dtype=float), int(d.matrix_form))
    order = sorted(keys)
    where = {k: i for i, k in enumerate(order)}
    n = len(order)
    out = {}
    for nm, (gci, gcj, val, form) in parts.items():
        r = np.array([where[tuple(x)] for x in gci.tolist()], dtype=np.int64)
        c = np.array([where[tuple(x)] for x in gcj.tolist()], dtype=np.int64)
        a = sp.coo_matrix((val, (r, c)), shape=(n, n)).tocsr()
        if form == 6:  # symmetric: one triangle given
            off = r != c
            a = a + sp.coo_matrix((val[off], (c[off], r[off])), shape=(n, n)).tocsr()
        out[nm] = a
    labels = tuple(dof_label(g, comp - 1) for g, comp in order)
    return out, labels


def _bdf(path: Path, xref: bool):
    """A pyNastran BDF of a full deck, or of bulk data alone (punch files, ``BEGIN BULK`` without
    executive and case control: read as a punch deck without that line)."""
    import io

    _, _, BDF = _pynastran()
    with open(path, errors="replace") as fh:
        text = fh.read()
    source: Any = str(path)
    punch = "CEND" not in text.upper()
    if punch:
        lines = [ln for ln in text.splitlines(keepends=True) if ln.strip().upper() != "BEGIN BULK"]
        source = io.StringIO("".join(lines))
    model = BDF(log=_Quiet(), debug=None)
    try:
        model.read_bdf(source, xref=xref, validate=False, punch=punch)
    except Exception as exc:  # pyNastran raises many kinds on foreign decks
        raise DataError(f"pyNastran could not read {path.name} ({type(exc).__name__}: {exc}).") from None
    return model


def _op4_matrices(path: Path, names: Sequence[str] | None):
    _, OP4, _ = _pynastran()
    try:
        mats = OP4(log=_Quiet()).read_op4(
            str(path), matrix_names=None if names is None else list(names), precision="double"
        )
    except Exception as exc:
        raise DataError(
            f"pyNastran could not read {path.name} as an OP4 file ({type(exc).__name__}: {exc})."
        ) from None
    out = {}
    for nm, m in mats.items():
        data = m.data
        a = sp.csr_matrix(data) if sp.issparse(data) else np.asarray(data)
        if np.iscomplexobj(a.data if sp.issparse(a) else a):
            raise DataError(f"OP4 matrix {nm!r} is complex; mass and stiffness must be real.")
        out[str(nm).strip()] = sp.csr_matrix(a, dtype=float)
    return out, None


def read_nastran_matrices(path: str | os.PathLike, names: Sequence[str] | None = None):
    """Matrices of an OP4 file or DMIG cards of a BDF/punch file.

    Parameters
    ----------
    path : path
        ``.op4`` (ASCII or binary, read by pyNastran's OP4 reader) or a BDF/punch file with DMIG
        cards (``.bdf``, ``.dat``, ``.pch``, ``.nas``).
    names : sequence of str, optional
        Matrices to read (default all).

    Returns
    -------
    matrices : dict name -> scipy.sparse.csr_matrix
    dof_labels : tuple of str or None
        ``"grid:component"`` per row for DMIG (sorted by grid, then component); None for OP4,
        which carries no DOF names.
    """
    p = _existing(path, "the matrix file")
    if p.suffix.lower() == ".op4":
        return _op4_matrices(p, names)
    return _dmig_matrices(p, names)


def _si_transform(labels: Sequence[str] | None, n: int, units: str) -> tuple[float, np.ndarray]:
    """``(e, t)`` with ``A_SI = e * T A T``, ``T = diag(t)``: energy unit in J, 1/length on translations."""
    length, mass = _units(units)
    if length == 1.0 and mass == 1.0:
        return 1.0, np.ones(n)
    if labels is None:
        raise DataError(
            f"units={units!r} needs to know which DOFs rotate; give dof_labels ('1001:T1' ...) "
            "for the OP4 rows."
        )
    t = np.array([1.0 / length if parse_dof(lb)[1][:3].any() else 1.0 for lb in labels])
    return mass * length**2, t


def _si_structural_model(
    mass: Any,
    stiffness: Any,
    groups: Mapping[str, Any],
    labels: Sequence[str] | None,
    units: str,
    source: str | os.PathLike,
    name: str | None,
    **fe_options: Any,
):
    """``fe_structural_model`` of file matrices in ``units``, made SI by :func:`_si_transform`.

    Parameters
    ----------
    mass, stiffness : (n, n) matrix
        In the file's units; ``stiffness=None`` sums the group partitions.
    groups : mapping group -> (n, n) matrix
        Stiffness partitions over the same DOFs (file units).
    labels : sequence of str or None
        ``"grid:component"`` per row.
    units : str
        Consistent unit system of the file (:data:`UNIT_SYSTEMS`).
    source : path
        The file; its stem names the model when ``name`` is None.
    name : str or None
    **fe_options
        ``inputs``, ``outputs``, ``lumped_masses``, ``output_kind``, ``damping``, ``n_modes``,
        ``band_hz`` of :func:`~robustctl.physical.fe_model.fe_structural_model`.

    Returns
    -------
    PhysicalModel
        Mass in kg, stiffness in N/m (N m/rad on rotations): ``A_SI = e * T A T``.
    """
    n = mass.shape[0]
    e, t = _si_transform(labels, n, units)
    tt = sp.diags(t)

    def si(a):
        return (e * (tt @ sp.csr_matrix(a) @ tt)).tocsr()

    parts = {g: si(a) for g, a in groups.items()}
    if stiffness is not None:
        K = si(stiffness)
    elif parts:
        K = sum(parts.values(), sp.csr_matrix((n, n)))
    else:
        raise DataError("give stiffness= (the complete stiffness matrix) or groups= (its partitions).")
    return fe_structural_model(
        si(mass), K, dof_labels=labels, groups=parts, name=name or Path(source).stem, **fe_options
    )


def _nastran_labels(dof_labels: Any, n: int, found: Sequence[str] | None) -> tuple[str, ...] | None:
    if dof_labels is None:
        return None if found is None else tuple(found)
    labels = tuple(str(x) for x in dof_labels)
    for lb in labels:
        parse_dof(lb)
    if len(labels) != n:
        raise DataError(
            f"dof_labels has {len(labels)} names but the matrices have {n} rows; give one 'grid:component' "
            "name per row, in the matrix's DOF order (the a-set or g-set order of the OP4 export)."
        )
    return labels


def load_nastran_matrices(
    path: str | os.PathLike,
    *,
    mass: str = "MAA",
    stiffness: str | None = "KAA",
    groups: Mapping[str, str] | None = None,
    dof_labels: Sequence[str] | None = None,
    units: str = "m-kg-s",
    name: str | None = None,
    **options: Any,
):
    """``rc.structural_model`` from Nastran mass and stiffness matrices with property-group
    superparameters (MACE eq. 1 with ``K(theta) = K + sum_g (k_g - 1) K_g``).

    Parameters
    ----------
    path : path
        OP4 file or BDF/punch file with DMIG cards (see :func:`read_nastran_matrices`).
    mass : str
        Name of the mass matrix (kg after ``units``).
    stiffness : str or None
        Name of the complete stiffness matrix (including the groups); None builds it as the
        sum of the group partitions.
    groups : mapping group -> matrix name, optional
        Stiffness partition of each property group (``{"longerons": "KPBAR1"}``), included in
        ``stiffness``. Each becomes a parameter ``k_<group>`` (stiffness factor, 1 = as modelled)
        and a stiffness group of the structure (``rc.GroupStiffness`` and diagnose see it).
    dof_labels : sequence of str, optional
        ``"grid:component"`` of each row; required for OP4 (it carries no DOF names) when
        inputs, outputs or lumped masses are named by DOF; DMIG files name their own rows.
    units : str
        The model's consistent unit system (:data:`UNIT_SYSTEMS`); matrices become SI.
    name : str, optional
        The model's name (default: the file's stem).
    **options
        The keywords of :func:`~robustctl.physical.fe_model.fe_structural_model`:
        ``inputs``, ``outputs`` (required): DOF names or a mapping name -> DOF name / force
        vector (``["1001:T3"]`` names the signal after the DOF; ``{"F": "1001:T3"}`` renames
        it; an output value may also be ``(dof, kind)``); ``lumped_masses``: mapping name ->
        grid id or DOF names, a parameter ``m_<name>`` (kg, 0 = as modelled) adding mass to
        the translations of that grid (``{"tip": 1004}``) or to the listed DOFs
        (``{"tip": ["1004:T3"]}``); ``fixed_groups``: groups whose factor ``k_<group>`` is
        not a free update parameter (a seam or bolted joint diagnose is to judge as a
        ``stiffness change of <group>`` candidate rather than absorb into the update:
        ``groups={"panels": "KPANEL", "seam": "KSEAM"}, fixed_groups=["seam"]``);
        ``output_kind``, ``damping``, ``n_modes``, ``band_hz`` as for
        :func:`robustctl.structural_model`.

    Returns
    -------
    PhysicalModel

    Raises
    ------
    DataError
        Missing matrix or file, size mismatch, a group larger than the model, a DOF the
        matrices do not have (named, with the fix).

    See Also
    --------
    read_nastran_matrices, robustctl.physical.fe_model.fe_structural_model, robustctl.update

    References
    ----------
    MSC Nastran DMAP Programmer's Guide, OUTPUT4 (OP4) format and the DMIG bulk data entry.
    Glaese & Miller (MACE 0-g models), eq. 1 (second-order model) and eq. 7 (finite-difference
    sensitivities of the superparameters that ``rc.update`` uses).
    """
    groups = dict(groups or {})
    names = [mass] + ([stiffness] if stiffness else []) + list(groups.values())
    stored, found = read_nastran_matrices(path)
    by_upper = {k.upper(): v for k, v in stored.items()}  # Nastran names are case-blind
    mats = {}
    for nm in names:
        if str(nm).upper() not in by_upper:
            raise DataError(f"{Path(path).name} has no matrix {nm!r}; it has {sorted(stored)}.")
        mats[nm] = by_upper[str(nm).upper()]
    n = mats[mass].shape[0]
    for nm in names:
        if mats[nm].shape != (n, n):
            raise DataError(
                f"matrix {nm!r} is {mats[nm].shape[0]}x{mats[nm].shape[1]}; the mass matrix is {n}x{n}."
            )
    labels = _nastran_labels(dof_labels, n, found)
    stiff = mats[stiffness] if stiffness else None
    parts = {g: mats[m] for g, m in groups.items()}
    return _si_structural_model(mats[mass], stiff, parts, labels, units, path, name, **options)


# ---------------------------------------------------------------------------- BDF geometry
def load_bdf_geometry(
    bdf: str | os.PathLike,
    *,
    units: str = "m-kg-s",
    sensors: Mapping[str, Any] | None = None,
    name: str | None = None,
) -> Geometry:
    """GRID coordinates (basic system, in m) and element edges of a Nastran bulk-data file.

    Parameters
    ----------
    bdf : path
        BDF/DAT file (with or without executive and case control).
    units : str
        Consistent unit system of the model (:data:`UNIT_SYSTEMS`); coordinates become metres.
    sensors : mapping channel -> "grid:direction", optional
        Sensor placement (see :meth:`Geometry.with_sensors`).
    name : str, optional

    Returns
    -------
    Geometry
        Lines are the edges of line elements (CBAR, CBEAM, CROD, CONROD, CBUSH, CELAS2 ...) and
        of shells (closed polygons of their corner grids).

    Raises
    ------
    DataError
        Missing file, no GRID cards, a grid whose displacement frame (CD) is not basic (its
        mode-shape components would be read in the wrong axes).
    """
    path = _existing(bdf, "the BDF file")
    length, _ = _units(units)
    try:
        model = _bdf(path, xref=True)
    except DataError:  # cards that do not cross-reference (a missing property): geometry only
        model = _bdf(path, xref=False)
    if not model.nodes:
        raise DataError(
            f"{path.name} has no GRID cards; give the bulk data file that defines the grid points."
        )
    ids = np.array(sorted(model.nodes), dtype=np.int64)
    xyz = []
    for nid in ids:
        node = model.nodes[int(nid)]
        cd = int(getattr(node, "cd", 0) or 0)
        if cd != 0:
            raise DataError(
                f"grid {nid} uses displacement frame CD={cd}; its shapes are not in basic axes. Re-run with "
                "PARAM,OUGCORD,BASIC (or set CD=0) so directions like 'X' mean the same at every grid."
            )
        try:
            pos = node.get_position()
        except Exception:
            if int(getattr(node, "cp", 0) or 0) != 0:
                raise DataError(
                    f"grid {nid} is defined in frame CP={node.cp} that the file does not define."
                ) from None
            pos = node.xyz
        xyz.append(np.asarray(pos, dtype=float) * length)
    lines = set()
    for elem in model.elements.values():
        nids = [int(x) for x in (elem.node_ids or []) if x is not None]
        if len(nids) < 2:
            continue
        edges = (
            zip(nids, nids[1:] + nids[:1])
            if len(nids) > 2 and elem.type.startswith(("CQUAD", "CTRIA"))
            else zip(nids, nids[1:])
        )
        for a, b in edges:
            if a != b:
                lines.add((min(a, b), max(a, b)))
    ids_set = set(ids.tolist())
    lines = sorted(ln for ln in lines if ln[0] in ids_set and ln[1] in ids_set)
    geo = Geometry(
        ids,
        np.array(xyz).reshape(-1, 3),
        np.array(lines, dtype=np.int64).reshape(-1, 2),
        unit="m",
        name=name or path.stem,
    )
    return geo.with_sensors(sensors) if sensors else geo


# ---------------------------------------------------------------------------- writers (round trips)
class _Trash:
    def write(self, *a): ...
    def close(self): ...


def write_nastran_modes(path: str | os.PathLike, modes: ModeShapes) -> None:
    """Write mode shapes as an OP2 file (LAMA eigenvalue table and OUGV1 eigenvectors, single
    precision as Nastran writes them) with pyNastran's table writers.

    pyNastran's ``OP2.write_op2`` leaves the LAMA table out, so the two tables are framed here
    the way it frames every table (header, table, ``[4, itable, 4, 4, 1, 4, 4, 0, 4]``, ``[4, 0, 4]``).

    Parameters
    ----------
    path : path
    modes : ModeShapes
        Real shapes in SI (m, rad); generalised masses in kg.
    """
    from struct import Struct

    OP2, _, _ = _pynastran()
    from pyNastran.op2.tables.lama_eigenvalues.lama_objects import RealEigenvalues
    from pyNastran.op2.tables.oug.oug_eigenvectors import RealEigenvectorArray
    from pyNastran.op2.writer.op2_writer import write_op2_header

    if np.iscomplexobj(modes.shapes):
        raise DataError("OP2 eigenvector tables hold real modes; these shapes are complex.")
    n = modes.n_modes
    numbers = np.arange(1, n + 1)
    eigs = (2 * np.pi * modes.f_hz) ** 2
    model = OP2(log=_Quiet(), debug=None)
    model.set_mode("msc")
    model.date = (1, 1, 2024)
    grid = np.column_stack([modes.node_ids, np.ones(modes.node_ids.size, int)])
    vec = RealEigenvectorArray.add_modal_case(
        "OUGV1", grid, modes.shapes.astype(np.float32), 1, numbers, eigs, modes.f_hz, is_sort1=True
    )
    vec.table_code = 7  # an eigenvector, not a displacement
    vec.data_code["table_code"] = 7
    lama = RealEigenvalues("modes", "LAMA", n)
    lama.mode[:] = numbers
    lama.extraction_order[:] = numbers
    lama.eigenvalues[:] = eigs
    lama.radians[:] = np.sqrt(eigs)
    lama.cycles[:] = modes.f_hz
    lama.generalized_mass[:] = modes.generalized_mass
    lama.generalized_stiffness[:] = modes.generalized_mass * eigs
    s3, s9 = Struct(b"<3i"), Struct(b"<9i")
    with open(path, "wb") as fh:
        write_op2_header(model, fh, _Trash(), s3, post=-1, endian=b"<")
        for table in (lama, vec):
            itable = table.write_op2(fh, _Trash(), -1, True, model.date, endian=b"<")
            fh.write(s9.pack(4, itable, 4, 4, 1, 4, 4, 0, 4))
            fh.write(s3.pack(4, 0, 4))
        fh.write(s3.pack(4, 0, 4))


def write_nastran_matrices(
    path: str | os.PathLike, matrices: Mapping[str, Any], *, dof_labels: Sequence[str] | None = None
) -> None:
    """Write symmetric real matrices (dense or sparse) as an ASCII OP4 file or as DMIG cards.

    Parameters
    ----------
    path : path
        ``.op4``: ASCII OP4 (pyNastran 1.4.1 writes no sparse binary OP4; its reader reads
        both). ``.bdf``/``.pch``/``.dat``/``.nas``: bulk data with one symmetric (``IFO=6``),
        double-precision ``DMIG`` per matrix (lower triangle, 16-character fields).
    matrices : mapping name -> (n, n) matrix
    dof_labels : sequence of str, optional
        ``"grid:component"`` per row; required for DMIG, which names its rows.
    """
    _, OP4, BDF = _pynastran()
    p = Path(path)
    if p.suffix.lower() == ".op4":
        from pyNastran.op2.result_objects.matrix import Matrix

        mats = {}
        for name, a in matrices.items():
            a = sp.coo_matrix(a) if sp.issparse(a) else np.asarray(a, dtype=float)
            mats[str(name)] = Matrix(str(name), 6, a)
        OP4(log=_Quiet()).write_op4(str(p), mats, precision="double", is_binary=False)
        return
    if dof_labels is None:
        raise DataError("DMIG cards name their rows: give dof_labels=['1001:T1', ...] (one per row).")
    keys = []
    for lb in dof_labels:
        node, vec = parse_dof(lb)
        keys.append((node, int(np.flatnonzero(vec)[0]) + 1))
    model = BDF(log=_Quiet(), debug=None)
    for name, a in matrices.items():
        low = sp.tril(sp.coo_matrix(a)).tocoo()
        if low.shape != (len(keys), len(keys)):
            raise DataError(
                f"matrix {name!r} is {low.shape[0]}x{low.shape[1]}; dof_labels name {len(keys)} rows."
            )
        order = np.lexsort((low.row, low.col))
        rows, cols, vals = low.row[order], low.col[order], low.data[order]
        model.add_dmig(
            str(name),
            6,
            2,
            2,
            0,
            0,
            [keys[c] for c in cols],
            [keys[r] for r in rows],
            [float(v) for v in vals],
        )
    model.write_bdf(str(p), size=16, is_double=True, enddata=True)
