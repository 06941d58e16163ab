"""The Caltech two-story truss of Balas & Doyle ("Identification of flexible structures
for robust control", the Caltech seed) as a frame FEM with actuators, sensors and filters.

Geometry and hardware (numbers from the seed unless marked *derived* or *assumed*)
-----------------------------------------------------------------------------------
* The truss hangs from a rigid mounting structure fixed to the ceiling (z = 0, z up, the
  structure below). Three longerons per story, welded (fixed-fixed) into brackets.
  Story 1 (top): 0.838 m columns of 6.35 mm aluminium rod; story 2: 0.759 m columns of
  4.76 mm rod. Each column is ``n_elements_per_member`` Euler-Bernoulli beam elements
  (groups ``longerons_story_1`` and ``longerons_story_2``).
* Platforms are equilateral triangles with 0.457 m sides: platform 1 (between the
  stories) 2.36 kg, platform 2 (bottom) 1.55 kg. Each is a rigid body: a centre node with
  the plate mass and the rotary inertia of a thin triangular plate (``I_zz = m a^2/12``,
  ``I_xx = I_yy = m a^2/24``, *derived*: 0.0411 and 0.0270 kg m^2 polar), rigidly linked
  to the longeron-end nodes.
* The longerons stand at radius ``r = 0.22 m`` from the platform centre (*assumed*: the
  triangle's circumradius is 0.264 m, *derived*; the brackets sit inside the corners).
  Corners lie at 45, 165 and 285 degrees, so that actuator 1 acts perpendicular to the
  45-degree sensor 3 (the seed: "actuator 1 excites the direction perpendicular to
  sensor 3").
* Weld brackets ``m_bracket`` = 0.1 kg at every longeron end on a platform (two per corner
  of platform 1, one per corner of platform 2; *assumed*).
* Three voice-coil actuators (inputs ``A1, A2, A3``) hang from the mounting structure and
  push along the story-1 face diagonals: diagonal ``i`` runs from the ceiling above
  longeron ``i`` to the platform-1 corner of longeron ``i+1``. As in the seed's NASTRAN
  model, each diagonal is a beam (group ``diagonals``; 6.35 mm aluminium rod, *assumed*)
  riding in the actuator bearing, which leaves its axial motion free and holds it in the
  two transverse directions (transverse springs ``k_bearing``, *assumed* 2e5 N/m, at 85 %
  of the diagonal length). The force acts on the platform-1 corner along the diagonal,
  positive away from the actuator (downwards).
* Actuator gain: +-1.37 kg force at +-5 V, i.e. 1.37 * 9.80665 / 5 = 2.687 N/V (*derived*).
* Three accelerometers (outputs ``S1, S2, S3``) on platform 2 read x, y and the
  45-degree direction; they sit 0.12 m from the centre (*assumed*) at 90, 0 and 225
  degrees: S1 and S2 also see torsion, S3 (on its own axis) does not. Mass
  ``m_accelerometer`` = 0.1 kg each (*assumed*: QA-1400 plus mounting block). Scaling
  0.016 g/V, i.e. 1 / (0.016 * 9.80665) = 6.373 V/(m/s^2) (*derived*), followed by the
  seed's 100-Hz fourth-order Butterworth filter.
* The offset mass on platform 2 that lowers the torsion frequencies: ``m_offset`` =
  0.5 kg at ``r_offset`` = 0.20 m from the centre at 35 degrees (*assumed*; the seed only
  says "small"). It breaks the three-fold symmetry, so the bending pairs split by about
  1 % and the actuator-1-to-sensor-3 response (A1S3), which would vanish in the perfectly
  symmetric truss, is about 1/11 of A1S1 in RMS over 0.5-5.5 Hz -- the seed's "order of
  magnitude below that of the other actuator 1 transfer functions".
* Gravity is on (``"gravity"`` tag): the hanging longerons carry the weight below them
  in tension (about 18 N per story-1 column and 7 N per story-2 column, *derived* by the
  preload iteration), whose geometric stiffness -- the pendulum stiffness of the hanging
  stories -- raises the bending frequencies.
* Modal damping ``zeta_modal`` = 1.5 % (the mean of the seed's Table I, 0.9-1.8 %).

Modal frequencies (nominal parameters, 3 elements per member, gravity on; measured by the
tests and ``benchmarks/bench_physical.py``; :func:`truss_modes` prints them)
-------------------------------------------------------------------------------------------
======  ======================  =========  =========  ========  ========
mode    type                    this (Hz)  NASTRAN    test      vs test
======  ======================  =========  =========  ========  ========
1, 2    first bending pair      1.067      0.991      1.17      -9 %
                                1.075      0.992      1.19      -10 %
3       first torsion           1.910      2.004      2.26      -15 %
4, 5    second bending pair     2.483      2.069      2.66      -7 %
                                2.499      2.100      2.75      -9 %
6       second torsion          4.329      3.832      4.43      -2 %
======  ======================  =========  =========  ========  ========

So the model sits between the seed's NASTRAN and test columns for the bending modes
(+8 % and +20 % on NASTRAN), 5 % below NASTRAN for first torsion and 13 % above it for
second torsion, and 2-15 % below test throughout -- the direction the seed's taut wires
explain. The offset mass splits each bending pair by about 1 %. The local bending modes
of the longerons lie at 38.4-42.7 Hz (seed: 37-43 Hz); the diagonals add local modes at
32.2-32.4 Hz. Without gravity the global modes drop by 6-11 % (to 0.951 ... 4.059 Hz; gravity raises
them by 7-12 %).

The seed explains its FEM-versus-test gap by the accelerometer wires, taut along the
columns, stiffening the longerons: :meth:`Frame.add_group_tension` on the groups
``longerons_story_1`` / ``longerons_story_2`` represents exactly that: 5 N of added
tension in every longeron raises the six global modes by 2.5-4.4 % (gravity itself gives
only 7-18 N).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from ..physical.electronics import butterworth_stage, gain_stage
from ..physical.fem import Frame
from ..physical.modal import modal_dynamics
from ..physical.model import PhysicalModel
from ..table import Table
from ._assembly import (
    G_STANDARD,
    check_band_hz,
    check_flags,
    check_int,
    get_param,
    param,
    rod_section,
    triangle_plate_inertia,
    unit,
)

__all__ = [
    "caltech_truss",
    "truss_modes",
    "CALTECH_NASTRAN_HZ",
    "CALTECH_TEST_HZ",
    "CALTECH_TEST_DAMPING",
]

#: Table I of the seed: NASTRAN and experimental natural frequencies (Hz) and damping.
CALTECH_NASTRAN_HZ = (0.991, 0.992, 2.004, 2.069, 2.100, 3.832)
CALTECH_TEST_HZ = (1.17, 1.19, 2.26, 2.66, 2.75, 4.43)
CALTECH_TEST_DAMPING = (0.018, 0.018, 0.010, 0.016, 0.018, 0.009)
#: Mode types of Table I, in order.
CALTECH_MODE_TYPES = ("bending", "bending", "torsion", "bending", "bending", "torsion")

# Geometry (m): seed values, and assumptions documented in the module docstring.
H_STORY_1 = 0.838
H_STORY_2 = 0.759
D_ROD_1 = 6.35e-3
D_ROD_2 = 4.76e-3
D_DIAGONAL = 6.35e-3
SIDE = 0.457
R_LONGERON = 0.22
CORNER_DEG = (165.0, 285.0, 45.0)  # longerons 1, 2, 3
BEARING_FRACTION = 0.85
R_SENSOR = 0.12
SENSOR_POS_DEG = (90.0, 0.0, 225.0)  # S1, S2, S3 positions on platform 2 (S3 on its own axis)
SENSOR_DIR_DEG = (0.0, 90.0, 45.0)  # S1 reads x, S2 y, S3 at 45 degrees
OFFSET_DIR_DEG = 35.0

INPUTS = ("A1", "A2", "A3")
OUTPUTS = ("S1", "S2", "S3")
GROUPS = ("longerons_story_1", "longerons_story_2", "diagonals")


def _params(gravity: bool, diagonals: bool) -> list:
    """The truss's parameters. As in MACE, only the uncertain ones are free (updated by
    default): the rods' Young's modulus, the platform and offset masses (with bolts and
    brackets of unknown weight) and the modal damping. Densities, weighed hardware,
    measured positions and calibrated electronics are fixed; ``model.with_params`` frees them."""
    s = ("structure",)
    p = [
        param("E_aluminium", 69e9, "Pa", (55e9, 80e9), "Young's modulus of the aluminium rods", s),
        param("rho_aluminium", 2700.0, "kg/m^3", (2500.0, 2900.0), "density of the aluminium rods", s,
              free=False),
        param("nu_aluminium", 0.33, "", (0.25, 0.40), "Poisson's ratio of aluminium (G = E / 2(1+nu))", s,
              free=False),
        param("m_platform_1", 2.36, "kg", (1.8, 3.2), "mass of the 9.52 mm platform-1 plate (seed)", s),
        param("m_platform_2", 1.55, "kg", (1.2, 2.1), "mass of the 6.35 mm platform-2 plate (seed)", s),
        param("m_bracket", 0.10, "kg", (0.0, 0.4), "mass of one longeron weld bracket on a platform", s,
              free=False),
        param("m_accelerometer", 0.10, "kg", (0.0, 0.3), "mass of one accelerometer with its block", s,
              free=False),
        param("m_offset", 0.50, "kg", (0.0, 1.5), "offset mass on platform 2 that lowers torsion", s),
        param("r_offset", 0.20, "m", (0.0, 0.25), "distance of the offset mass from the platform-2 centre",
              s, free=False),
        param("zeta_modal", 0.015, "", (0.001, 0.05), "modal damping ratio of every mode (Table I)",
              ("damping",)),
        param("k_actuator", 1.37 * G_STANDARD / 5.0, "N/V", (1.0, 5.0),
              "voice-coil force per volt (1.37 kgf at 5 V)", ("electronics",), free=False),
        param("k_accelerometer", 1.0 / (0.016 * G_STANDARD), "V/(m/s^2)", (2.0, 20.0),
              "accelerometer scaling (0.016 g per volt)", ("electronics",), free=False),
        param("f_sensor_filter", 100.0, "Hz", (50.0, 200.0),
              "cutoff of the 4th-order Butterworth sensor filter", ("electronics",),
              free=False),
    ]
    if diagonals:
        p.append(param("k_bearing", 2e5, "N/m", (1e3, 1e7),
                       "transverse stiffness of a voice-coil bearing holding a diagonal", s, free=False))
    if gravity:
        p.append(param("g_local", 9.81, "m/s^2", (9.7, 9.9), "local gravitational acceleration",
                       ("gravity",), free=False))
    return p


def _corner(angle_deg: float, radius: float, z: float) -> np.ndarray:
    a = math.radians(angle_deg)
    return np.array([radius * math.cos(a), radius * math.sin(a), z])


def _frame(theta: Mapping[str, float], n_el: int, diagonals: bool):
    """Assemble the truss Frame for the parameter values ``theta``."""
    g = get_param(theta, "g_local", 0.0)
    fr = Frame(gravity=g, gravity_direction=(0.0, 0.0, -1.0))
    E, rho, nu = theta["E_aluminium"], theta["rho_aluminium"], theta["nu_aluminium"]
    G = E / (2.0 * (1.0 + nu))
    z1, z2 = -H_STORY_1, -H_STORY_1 - H_STORY_2
    sec1, sec2 = rod_section(D_ROD_1), rod_section(D_ROD_2)

    p1 = fr.add_node("platform_1", (0.0, 0.0, z1))
    p2 = fr.add_node("platform_2", (0.0, 0.0, z2))
    top, c1, c2 = [], [], []
    for i, ang in enumerate(CORNER_DEG, start=1):
        top.append(fr.add_node(f"ceiling_{i}", _corner(ang, R_LONGERON, 0.0)))
        c1.append(fr.add_node(f"platform_1_corner_{i}", _corner(ang, R_LONGERON, z1)))
        c2.append(fr.add_node(f"platform_2_corner_{i}", _corner(ang, R_LONGERON, z2)))
        fr.fix(top[-1])
    for i in range(3):
        fr.add_beam("longerons_story_1", top[i], c1[i], E=E, G=G, rho=rho, **sec1, n_elements=n_el)
        fr.add_beam("longerons_story_2", c1[i], c2[i], E=E, G=G, rho=rho, **sec2, n_elements=n_el)
        fr.add_rigid_link(p1, c1[i])
        fr.add_rigid_link(p2, c2[i])
        fr.add_mass(c1[i], 2.0 * theta["m_bracket"])
        fr.add_mass(c2[i], theta["m_bracket"])
    fr.add_mass(p1, theta["m_platform_1"], inertia=triangle_plate_inertia(theta["m_platform_1"], SIDE))
    fr.add_mass(p2, theta["m_platform_2"], inertia=triangle_plate_inertia(theta["m_platform_2"], SIDE))

    for k, (pos, direction) in enumerate(zip(SENSOR_POS_DEG, SENSOR_DIR_DEG), start=1):
        node = fr.add_node(f"accelerometer_{k}", _corner(pos, R_SENSOR, z2))
        fr.add_rigid_link(p2, node)
        fr.add_mass(node, theta["m_accelerometer"])
        fr.add_output(OUTPUTS[k - 1], node, _corner(direction, 1.0, 0.0), kind="acceleration")
    if theta["m_offset"] > 0:
        node = fr.add_node("offset_mass", _corner(OFFSET_DIR_DEG, theta["r_offset"], z2))
        fr.add_rigid_link(p2, node)
        fr.add_mass(node, theta["m_offset"])

    sec_d = rod_section(D_DIAGONAL)
    for i in range(3):
        j = (i + 1) % 3
        upper = np.asarray(_corner(CORNER_DEG[i], R_LONGERON, 0.0))
        lower = np.asarray(_corner(CORNER_DEG[j], R_LONGERON, z1))
        direction = unit(lower - upper)  # from the actuator down to platform 1
        if diagonals:
            bearing = fr.add_node(f"bearing_{i + 1}", lower + BEARING_FRACTION * (upper - lower))
            fr.add_beam("diagonals", c1[j], bearing, E=E, G=G, rho=rho, **sec_d, n_elements=n_el)
            t1 = unit(np.cross(direction, (0.0, 0.0, 1.0)))
            t2 = np.cross(direction, t1)
            fr.add_spring(bearing, theta["k_bearing"], t1)
            fr.add_spring(bearing, theta["k_bearing"], t2)
        fr.add_force_input(INPUTS[i], c1[j], direction, kind="force")
    return fr


def caltech_truss(
    *,
    n_elements_per_member: int = 3,
    gravity: bool = True,
    diagonals: bool = True,
    n_modes: int | None = None,
    band_hz: tuple[float, float] | None = (0.0, 60.0),
    name: str = "Caltech truss",
) -> PhysicalModel:
    """The Caltech seed's two-story hanging truss: 3 voice coils in, 3 accelerometers out.

    Parameters
    ----------
    n_elements_per_member : int
        Beam elements per longeron and per diagonal (1..12). Three resolve the first local
        bending modes of the longerons (37-43 Hz in the seed) to within about 1 %.
    gravity : bool
        Include the gravity preload (geometric stiffness of the hanging longerons, tag
        ``"gravity"``). ``caltech_truss().without("gravity")`` gives the same model as
        ``gravity=False``.
    diagonals : bool
        Model the three actuator diagonals as beams held transversely by the voice-coil
        bearings (the seed's NASTRAN model does); ``False`` applies the actuator forces
        directly to platform 1.
    n_modes, band_hz : optional
        Modal truncation (default: every mode up to 60 Hz, i.e. the six global modes and
        the local longeron and diagonal modes).
    name : str
        Model name for tables and plots.

    Returns
    -------
    PhysicalModel
        Inputs ``A1, A2, A3`` (actuator volts), outputs ``S1, S2, S3`` (sensor volts after
        the 100-Hz Butterworth filters). Parameters: see ``model.params``; electronics are
        tagged ``"electronics"`` (they do not re-solve the eigenproblem when changed).

    Examples
    --------
    >>> import robustctl as rc
    >>> model = rc.examples.caltech_truss()
    >>> model.inputs, model.outputs
    (('A1', 'A2', 'A3'), ('S1', 'S2', 'S3'))
    """
    n_el = check_int(n_elements_per_member, "n_elements_per_member", 1, 12)
    band_hz = check_band_hz(band_hz)
    check_flags(gravity=gravity, diagonals=diagonals)
    params = _params(bool(gravity), bool(diagonals))

    def structure(theta: Mapping[str, float]):
        return _frame(theta, n_el, bool(diagonals))

    io_stages = (
        gain_stage({a: "k_actuator" for a in INPUTS}, side="inputs", name="voice-coil gains (N/V)"),
        gain_stage({s: "k_accelerometer" for s in OUTPUTS}, side="outputs",
                   name="accelerometer scaling (V/(m/s^2))"),
        butterworth_stage(list(OUTPUTS), 4, "f_sensor_filter",
                          name="100-Hz 4th-order Butterworth sensor filters"),
    )
    return PhysicalModel(
        params=params,
        dynamics=modal_dynamics(n_modes=n_modes, band_hz=band_hz, damping_param="zeta_modal"),
        structure=structure,
        io_stages=io_stages,
        name=name,
        meta={
            "seed": "Balas & Doyle, Caltech truss",
            "nastran_hz": CALTECH_NASTRAN_HZ,
            "test_hz": CALTECH_TEST_HZ,
            "test_damping": CALTECH_TEST_DAMPING,
            "mode_types": CALTECH_MODE_TYPES,
            "band_of_interest_hz": (0.5, 5.5),
            "element_groups": GROUPS if diagonals else GROUPS[:2],
            "sample_rate_hz": 200.0,
        },
    )


def truss_modes(model: PhysicalModel, n_modes: int = 12, **overrides: float):
    """Table of the truss's lowest modes with their type, beside the seed's Table I.

    A mode is ``"bending"`` when the platforms translate more than they twist (rotation
    about the vertical axis times the longeron radius), ``"torsion"`` otherwise, and
    ``"local"`` when the platforms hardly move (less than 20 % of the largest nodal
    translation: bending of longerons or diagonals between the platforms).

    Parameters
    ----------
    model : PhysicalModel
        A :func:`caltech_truss` model (any effects applied).
    n_modes : int
        Number of lowest modes listed.
    **overrides : float
        Parameter values to use instead of the model's.

    Returns
    -------
    robustctl.table.Table
        Columns ``mode``, ``f (Hz)``, ``type``, ``NASTRAN (Hz)``, ``test (Hz)`` (the seed's
        values for the first six modes).
    """
    f_hz, types = _classify(model, n_modes, overrides)
    rows = []
    for k, (f, t) in enumerate(zip(f_hz, types)):
        nas = CALTECH_NASTRAN_HZ[k] if k < 6 else None
        test = CALTECH_TEST_HZ[k] if k < 6 else None
        rows.append((k + 1, float(f), t, nas, test))
    return Table(("mode", "f (Hz)", "type", "NASTRAN (Hz)", "test (Hz)"), rows, title=f"{model.name}: modes")


def _classify(model: PhysicalModel, n_modes: int, overrides: Mapping[str, float]):
    n = check_int(n_modes, "n_modes", 1, 500)
    frame = model.build_structure(**overrides)
    mats = frame.matrices()
    f_hz, phi = frame.modes(n_modes=min(n, mats.n_dof))
    labels = list(mats.dof_labels)
    trans = np.array([lab.split()[-1] in ("ux", "uy", "uz") for lab in labels])

    def rows(node: str, dofs: tuple[str, ...]) -> list[int]:
        return [labels.index(f"{node} {d}") for d in dofs]

    types = []
    for k in range(f_hz.size):
        v = phi[:, k]
        biggest = float(np.abs(v[trans]).max())
        t_amp = max(float(np.hypot(*v[rows(p, ("ux", "uy"))])) for p in ("platform_1", "platform_2"))
        r_amp = max(R_LONGERON * abs(float(v[rows(p, ("rz",))[0]])) for p in ("platform_1", "platform_2"))
        if max(t_amp, r_amp) < 0.2 * biggest:
            types.append("local")
        else:
            types.append("bending" if t_amp > r_amp else "torsion")
    return f_hz, types
