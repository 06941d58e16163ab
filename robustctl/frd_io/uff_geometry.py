"""Test geometry and mode shapes in universal files (via pyuff).

Datasets read and written:

* 15 / 2411 — nodes (label, coordinates, definition and displacement coordinate systems);
* 2420 — coordinate systems: a node's displacement system turns a sensor's direction code
  into any direction (a tangential accelerometer on a truss corner);
* 82 — trace lines (a node list, ``0`` lifts the pen); 2412 — elements (their edges are drawn);
* 55 — mode shapes at nodes (normal modes: frequency, modal mass, viscous damping ratio;
  complex modes: eigenvalue);
* 58 — FRF records: their response node and direction place each channel on the structure,
  so ``load_frd(path)`` channels map to nodes without a hand-written table.

Coordinates are read in the file's length unit; ``unit=`` names it (``"m"``, ``"mm"``, ``"in"``)
and everything returned is in metres.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DataError
from ..frd import FrequencyData
from .geometry import Geometry, ModeShapes
from .uff import _uff_names

__all__ = ["load_uff_geometry", "load_uff_modes", "write_uff_geometry", "LENGTH_UNITS"]

#: Metres per length unit.
LENGTH_UNITS = {"m": 1.0, "mm": 1e-3, "cm": 1e-2, "in": 0.0254, "ft": 0.3048}


def _read_sets(path: Any) -> list[dict]:
    import pyuff

    if not isinstance(path, (str, os.PathLike)) or not Path(path).is_file():
        raise DataError(f"cannot read the universal file {str(path)!r}: no such file.")
    try:
        uff = pyuff.UFF(str(path))
        types = [int(t) for t in uff.get_set_types()]
        sets = uff.read_sets(list(range(len(types)))) if types else []
    except Exception as exc:  # pyuff raises bare Exceptions
        raise DataError(f"not a readable universal file ({type(exc).__name__}: {exc}).") from None
    sets = [sets] if isinstance(sets, dict) else list(sets)
    if len(sets) != len(types):
        raise DataError(f"pyuff read {len(sets)} of the {len(types)} datasets; the file is corrupt.")
    return sets


def _length(unit: str) -> float:
    if unit not in LENGTH_UNITS:
        raise DataError(f"unit={unit!r} is not a known length unit; use one of {sorted(LENGTH_UNITS)}.")
    return LENGTH_UNITS[unit]


def _coordinate_systems(sets: list[dict]) -> dict[int, np.ndarray]:
    """Label -> 3x3 matrix whose rows are the system's x, y, z axes in global coordinates."""
    out = {}
    for s in sets:
        if int(s["type"]) != 2420:
            continue
        for lab, typ, mat in zip(s["CS_sys_labels"], s["CS_types"], s["CS_matrices"]):
            if int(typ) != 0:
                raise DataError(
                    f"coordinate system {lab} is {'cylindrical' if int(typ) == 1 else 'spherical'}; only "
                    "Cartesian displacement systems are supported (export directions in a Cartesian system)."
                )
            out[int(lab)] = np.asarray(mat, dtype=float).reshape(4, 3)[:3]
    return out


def _nodes(sets: list[dict]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    ids, xyz, disp = [], [], []
    for s in sets:
        if int(s["type"]) in (15, 2411):
            ids.extend(np.asarray(s["node_nums"], dtype=np.int64).ravel().tolist())
            xyz.append(np.column_stack([s["x"], s["y"], s["z"]]))
            disp.extend(
                np.asarray(s.get("disp_cs", np.zeros(len(s["node_nums"]))), dtype=np.int64).ravel().tolist()
            )
    if not ids:
        return np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0, np.int64)
    return np.asarray(ids), np.vstack(xyz).astype(float), np.asarray(disp)


def _lines(sets: list[dict]) -> list[tuple[int, int]]:
    lines = set()
    for s in sets:
        t = int(s["type"])
        if t == 82:
            nodes = [int(n) for n in np.asarray(s["nodes"]).ravel()]
            for a, b in zip(nodes, nodes[1:]):
                if a and b and a != b:
                    lines.add((min(a, b), max(a, b)))
        elif t == 2412:  # pyuff: descriptor -> list of elements (plus legacy duplicates by name)
            for key, val in s.items():
                if not isinstance(key, (int, np.integer)) or not isinstance(val, list):
                    continue
                for elem in val:
                    c = [int(n) for n in np.asarray(elem["nodes_nums"]).ravel()]
                    pairs = zip(c, c[1:] + c[:1]) if len(c) > 2 else zip(c, c[1:])
                    lines.update((min(a, b), max(a, b)) for a, b in pairs if a != b)
    return sorted(lines)


def _axis(code: int, cs: np.ndarray | None) -> np.ndarray | None:
    """Global unit vector of a UFF direction code (+-1..3) in a displacement system."""
    if abs(code) not in (1, 2, 3):
        return None
    axes = np.eye(3) if cs is None else cs
    v = np.sign(code) * axes[abs(code) - 1]
    return v / np.linalg.norm(v)


def load_uff_geometry(path: str | os.PathLike, *, unit: str = "m", name: str | None = None) -> Geometry:
    """Nodes, trace lines and sensor placement of a universal file.

    Parameters
    ----------
    path : path
        ``.uff``/``.unv`` with datasets 15 or 2411 (nodes), optionally 2420 (coordinate
        systems), 82/2412 (lines, elements) and 58 (FRFs: their response node and direction
        place the output channels, named as :func:`robustctl.load_frd` names them).
    unit : str
        Length unit of the coordinates (:data:`LENGTH_UNITS`); the geometry is in metres.
    name : str, optional

    Returns
    -------
    Geometry

    Raises
    ------
    DataError
        No node dataset, lines or records at undefined nodes, a displacement system that is
        not defined or not Cartesian.

    See Also
    --------
    load_uff_modes, write_uff_geometry, robustctl.load_frd

    References
    ----------
    SDRC I-DEAS Universal File Format, datasets 15, 82, 2411, 2412, 2420 and 58.
    """
    scale = _length(unit)
    sets = _read_sets(path)
    ids, xyz, disp = _nodes(sets)
    if ids.size == 0:
        raise DataError(
            f"{Path(path).name} has no node dataset (15 or 2411); add the test geometry's nodes to the file."
        )
    systems = _coordinate_systems(sets)
    disp_of = dict(zip(ids.tolist(), disp.tolist()))
    sensors = {}
    for s in sets:
        if int(s["type"]) != 58 or int(s.get("func_type", 0)) != 4:
            continue
        channel, _ = _uff_names(s)
        node, code = int(s.get("rsp_node", 0)), int(s.get("rsp_dir", 0))
        if node not in disp_of:
            continue  # a record at a node without coordinates (or robustctl's running index)
        cs_label = int(disp_of[node])
        if cs_label not in (0, 1) and cs_label not in systems:
            raise DataError(
                f"node {node} (channel {channel!r}) uses displacement system {cs_label}, which the file "
                "does not "
                "define; add dataset 2420 or export directions in the global system."
            )
        vec = _axis(code, systems.get(cs_label))
        if vec is not None:
            sensors.setdefault(channel, (node, vec))
    return Geometry(
        ids,
        xyz * scale,
        np.array(_lines(sets), dtype=np.int64).reshape(-1, 2),
        sensors,
        unit="m",
        name=name or Path(path).stem,
    )


def load_uff_modes(path: str | os.PathLike, *, unit: str = "m", name: str | None = None) -> ModeShapes:
    """Mode shapes of dataset 55 records (one record per mode).

    Parameters
    ----------
    path : path
        Universal file with dataset 55 (analysis type 2, normal modes: frequency, modal mass,
        viscous damping ratio; or 3, complex modes: eigenvalue ``-sigma + j omega_d``).
    unit : str
        Length unit of the translations (:data:`LENGTH_UNITS`); translations become metres.
    name : str, optional

    Returns
    -------
    ModeShapes
        Sorted by frequency; ``present`` marks the components the records carry (3 or 6).

    Raises
    ------
    DataError
        No dataset 55, records over different node sets or with different analysis types.
    """
    scale = _length(unit)
    recs = [s for s in _read_sets(path) if int(s["type"]) == 55]
    if not recs:
        raise DataError(f"{Path(path).name} has no dataset 55 (mode shapes); export the modes as dataset 55.")
    kinds = {int(r.get("analysis_type", 2)) for r in recs}
    if not kinds <= {2, 3} or len(kinds) != 1:
        raise DataError(
            f"dataset 55 records have analysis types {sorted(kinds)}; only normal (2) or complex (3) "
            "modes of "
            "one kind are read."
        )
    nodes = np.asarray(recs[0]["node_nums"], dtype=np.int64).ravel()
    f, zeta, gm, shapes = [], [], [], []
    for r in recs:
        rn = np.asarray(r["node_nums"], dtype=np.int64).ravel()
        if not np.array_equal(rn, nodes):
            raise DataError(
                f"mode {r.get('mode_n', '?')} has shapes at {rn.size} nodes, the first mode at {nodes.size}; "
                "export every mode over the same nodes."
            )
        ncomp = 6 if int(r.get("n_data_per_node", 3)) == 6 else 3
        comps = [np.asarray(r[f"r{k + 1}"]).ravel() for k in range(ncomp)]
        shape = np.zeros((nodes.size, 6), dtype=complex if kinds == {3} else float)
        for k, c in enumerate(comps):
            shape[:, k] = c if kinds == {3} else np.real(c)
        shape[:, :3] *= scale
        shapes.append(shape)
        if kinds == {2}:
            f.append(float(r["freq"]))
            zeta.append(float(r.get("modal_damp_vis", np.nan)))
            m = float(r.get("modal_m", 0.0) or 0.0)
            gm.append(m * scale**2 if m > 0 else 1.0)
        else:
            lam = complex(r["eig"])
            wn = abs(lam)
            f.append(wn / (2 * np.pi))
            zeta.append(-lam.real / wn if wn > 0 else np.nan)
            gm.append(1.0)
    order = np.argsort(f, kind="stable")
    present = np.zeros((nodes.size, 6), bool)
    present[:, :ncomp] = True
    return ModeShapes(
        f_hz=np.asarray(f)[order],
        node_ids=nodes,
        shapes=np.asarray(shapes)[order],
        present=present,
        zeta=np.asarray(zeta)[order],
        generalized_mass=np.asarray(gm)[order],
        unit="m",
        name=name or Path(path).stem,
    )


def _axis_code(direction: np.ndarray) -> tuple[int, int]:
    """(system, code) writing ``direction``: a global axis (0, +-1..3), else -1 (own system)."""
    for k in range(3):
        if abs(abs(direction[k]) - 1.0) < 1e-12:
            return 0, int(np.sign(direction[k])) * (k + 1)
    return -1, 1


def _frame_along(direction: np.ndarray) -> np.ndarray:
    """A Cartesian system (rows x, y, z) whose x axis is ``direction``."""
    x = direction / np.linalg.norm(direction)
    helper = np.eye(3)[int(np.argmin(np.abs(x)))]
    y = np.cross(helper, x)
    y /= np.linalg.norm(y)
    return np.vstack([x, y, np.cross(x, y)])


def _mode_records(modes: ModeShapes, scale: float) -> list[dict]:
    """Dataset 55 records: normal modes (analysis type 2, frequency, modal mass, viscous damping
    ratio) or, for complex shapes, complex modes (type 3, eigenvalue ``-zeta w + j w sqrt(1 - zeta^2)``,
    translations only)."""
    import pyuff

    complex_modes = np.iscomplexobj(modes.shapes)
    if complex_modes and modes.present[:, 3:].any() and np.any(modes.shapes[:, :, 3:]):
        raise DataError("complex mode shapes in UFF dataset 55 hold translations only; drop the rotations.")
    ncomp = 3 if complex_modes or not modes.present[:, 3:].any() else 6
    out = []
    for k in range(modes.n_modes):
        sh = modes.shapes[k].copy()
        sh[:, :3] /= scale
        zeta = float(modes.zeta[k]) if np.isfinite(modes.zeta[k]) else 0.0
        common = dict(
            id1="robustctl mode shapes",
            id2=modes.name or "NONE",
            id3="NONE",
            id4="NONE",
            id5="NONE",
            model_type=1,
            data_ch=2,
            spec_data_type=8,
            n_data_per_node=ncomp,
            load_case=1,
            mode_n=k + 1,
            node_nums=modes.node_ids,
            **{f"r{c + 1}": sh[:, c] for c in range(ncomp)},
        )
        if complex_modes:
            w = 2 * np.pi * float(modes.f_hz[k])
            eig = complex(-zeta * w, w * np.sqrt(max(1.0 - zeta**2, 0.0)))
            out.append(
                pyuff.prepare_55(analysis_type=3, data_type=5, eig=eig, modal_a=0j, modal_b=0j, **common)
            )
        else:
            out.append(
                pyuff.prepare_55(
                    analysis_type=2,
                    data_type=2,
                    freq=float(modes.f_hz[k]),
                    modal_m=float(modes.generalized_mass[k]) / scale**2,
                    modal_damp_vis=zeta,
                    modal_damp_his=0.0,
                    **common,
                )
            )
    return out


def write_uff_geometry(
    path: str | os.PathLike,
    geometry: Geometry,
    *,
    modes: ModeShapes | None = None,
    data: FrequencyData | None = None,
    unit: str = "m",
) -> None:
    """Write a geometry (and mode shapes, and FRFs placed at its sensors) as a universal file.

    Parameters
    ----------
    path : path
        New file (overwritten).
    geometry : Geometry
        Nodes (dataset 2411), lines (dataset 82) and sensors: a sensor along a global axis is
        written as that direction code; any other direction as +X of a displacement system
        (dataset 2420) of its own, so :func:`load_uff_geometry` gives the direction back.
    modes : ModeShapes, optional
        Written as dataset 55: normal modes (6 values per node when rotations are present), or
        complex modes for complex shapes (translations, eigenvalue from frequency and damping).
    data : FrequencyData, optional
        Written as dataset 58 FRF records whose response node/direction are the output's sensor
        (every output must be a sensor of ``geometry``).
    unit : str
        Length unit to write coordinates and translations in.

    Raises
    ------
    DataError
        Two sensors of different directions at one node (UFF gives a node one displacement
        system), an output of ``data`` that is not a sensor.
    """
    import pyuff

    scale = _length(unit)
    path = Path(path)
    disp = {int(n): 0 for n in geometry.node_ids}
    systems, codes = [], {}
    for ch, (node, direction) in geometry.sensors.items():
        cs, code = _axis_code(direction)
        if cs == -1:
            if disp[node] and not np.allclose(systems[disp[node] - 2][1][0], direction):
                raise DataError(
                    f"sensors at node {node} point along different non-axis directions; UFF gives a node one "
                    "displacement system, so place them at separate nodes."
                )
            if not disp[node]:
                systems.append((len(systems) + 2, _frame_along(direction)))
                disp[node] = systems[-1][0]
        codes[ch] = (node, code)
    ids = geometry.node_ids
    records = []
    if systems:
        records.append(
            pyuff.prepare_2420(
                Part_UID=1,
                Part_Name="robustctl sensors",
                CS_sys_labels=[s[0] for s in systems],
                CS_types=[0] * len(systems),
                CS_colors=[8] * len(systems),
                CS_names=[f"sensor cs {s[0]}" for s in systems],
                CS_matrices=[np.vstack([s[1], np.zeros(3)]) for s in systems],
            )
        )
    records.append(
        pyuff.prepare_2411(
            node_nums=ids,
            def_cs=np.ones(ids.size, int),
            disp_cs=np.array([disp[int(n)] or 1 for n in ids]),
            color=np.full(ids.size, 8),
            x=geometry.xyz[:, 0] / scale,
            y=geometry.xyz[:, 1] / scale,
            z=geometry.xyz[:, 2] / scale,
        )
    )
    if len(geometry.lines):
        seq: list[int] = []
        for a, b in geometry.lines.tolist():
            seq += [a, b, 0]
        records.append(
            pyuff.prepare_82(
                trace_num=1,
                n_nodes=len(seq) - 1,
                color=30,
                id="trace lines",
                nodes=np.array(seq[:-1], dtype=int),
            )
        )
    if modes is not None:
        records += _mode_records(modes, scale)
    if data is not None:
        from .uff import _signal_units, _uff_record, _uff_shape_id

        units, id3 = _signal_units(data), _uff_shape_id(data.replace(coherence=None))
        for o, out in enumerate(data.outputs):
            if out not in codes:
                raise DataError(
                    f"output {out!r} is not a sensor of the geometry; add it with geometry.with_sensors("
                    f"{{{out!r}: 'node:+Z'}}) before writing."
                )
            for i, inp in enumerate(data.inputs):
                rec = _uff_record(
                    data.f_hz, data.response[:, o, i], 4, o, i, (out, inp), (units[out], units[inp]), id3
                )
                rec["rsp_node"], rec["rsp_dir"] = codes[out]
                records.append(rec)
    if path.exists():
        path.unlink()
    try:
        pyuff.UFF(str(path)).write_sets(records, mode="add")
    except Exception as exc:  # pyuff raises bare Exceptions
        raise DataError(f"pyuff could not write the universal file ({exc}).") from None
