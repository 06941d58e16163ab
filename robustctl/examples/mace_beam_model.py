"""A MACE-like test article (Glaese & Miller, "Derivation of zero-gravity structural control
models from analysis and ground experimentation", the MACE seed) as a 1-g frame FEM with
suspension, gravity preload, gimbal servo loops and the electronics of MACE Fig. 1.

Numbers come from the seed unless marked *derived* or *assumed*; the seed gives the
architecture and the suspension/servo/delay figures, not the dimensions of the hardware,
so the bus and payload sizes are assumptions chosen to put the first bending modes where
MACE Table 1 has them (0-g first vertical bending 2.10 Hz, first horizontal 3.31 Hz).

Structure (x along the bus, z up; SI units)
-------------------------------------------
* Bus: a straight segmented tube from x = -0.75 to +0.75 m of four 0.375 m polycarbonate
  struts (32 mm outer diameter, 2.4 mm wall, *assumed*; ``E_polycarbonate`` 2.4 GPa,
  1200 kg/m^3), ``n_elements_per_member`` beam elements each. Strut 2 (x = -0.375 ... 0)
  is the active member with its own modulus ``E_active_strut`` (3.6 GPa effective,
  *assumed*: its piezoelectric layers stiffen it; MACE saw a 15 % frequency change when
  it was fitted). Element groups ``bus_struts`` and ``active_strut``. Aluminium node
  fittings of ``m_bus_node`` = 0.3 kg at the five strut joints ``bus_1`` ... ``bus_5``.
* Reaction-wheel assembly at the centre (``bus_3``): ``m_rwa`` = 5 kg, 0.03 kg m^2 about
  each axis (*assumed*); three orthogonal torque inputs ``RWA x/y/z`` and three rate gyros
  ``RWA gyro x/y/z`` on the same axes (the seed).
* Two two-axis gimbals (the seed): the primary (pointing) gimbal at ``bus_1``, the
  secondary (disturbing) gimbal at ``bus_5``. Each is a gimbal node joined to the bus
  end by a hinge: stiff in translation (1e6 N/m) and about z (1e4 N m/rad), compliant
  about the two gimbal axes x and y (``k_gimbal_bearing`` = 0.3 N m/rad, *assumed*: cable
  harness and bearing drag; it keeps the open-loop payload modes off 0 Hz so the 0-g
  structure has exactly six rigid-body modes). The payload hangs below the gimbal
  pivot on a stiff aluminium arm (group ``gimbal_arms``), its centre of mass
  ``d_payload`` = 0.20 m below the axes (*assumed*), mass ``m_payload`` = 3 kg, solid
  cylinder inertia (radius 0.08 m, length 0.25 m). Motor torques act in equal and
  opposite pairs on payload and bus (``primary gimbal x`` ...); laser encoders read the
  payload angle relative to the bus (``primary encoder x`` ...); a two-axis rate-gyro
  platform in the primary payload reads its inertial rates (``primary gyro x/y``).
* Suspension (tag ``"suspension"``, the seed): three pneumatic-electric devices at the
  ceiling, above ``bus_1``, ``bus_3`` and ``bus_5``, modelled as vertical springs and
  dashpots on a node that can only move vertically, each carrying a 5 m graphite-epoxy
  load rod (Euler-Bernoulli beam, ``n_rod_elements`` elements, 2.1 mm diameter,
  *assumed*) pinned (clevis: translations joined, rotations free) to a 0.05 m bracket on
  top of the bus. The spring rates ``k_suspension_outer`` / ``k_suspension_centre`` are
  *derived*: together they give the seed's 0.2 Hz bounce at the nominal 17.0 kg, split
  1 : 2.6 : 1 so that the centre rod carries 2.6 times the tension of an outer rod (MACE
  Table 1: outer violin 7.26/7.34 Hz, centre 11.65 Hz, (11.65/7.26)^2 = 2.6, *derived*).
  Dashpots ``c_suspension`` = 0.6 N s/m (*assumed*, about 5 % bounce damping).
* Gravity (tag ``"gravity"``): MACE's iterative stress stiffening. The load rods carry
  the weight (pendulum 0.223 Hz = sqrt(g/5 m)/2 pi, *derived*; violin modes), the payload
  arms carry their payloads (the gimbal pendulum of "articulating appendages"), and the
  bracket posts the bus.

``model.without("suspension", "gravity")`` removes the suspension nodes, elements, springs,
dashpots and supports and the preload -- MACE's step to the 0-g model -- and equals
``mace_beam(zero_g=True)`` (built without them) to rounding.

I/O model (MACE Fig. 1)
-----------------------
Physical model -> motor gains (``k_gimbal_motor`` 0.5 N m/V, ``k_rwa_motor`` 0.2 N m/V,
*assumed*) -> rate-gyro dynamics (``f_gyro`` 80 Hz, ``zeta_gyro`` 0.6, *assumed*) and gyro
scaling (``k_gyro`` 10 V/(rad/s), *assumed*) -> 4th-order Bessel anti-aliasing filters
(``f_antialias`` 100 Hz, *assumed* for the seed's 500-Hz computer) -> the seed's 3.6 ms
sampling delay (``delay_sampling``, 2nd-order Pade) on the gyro outputs -> the four gimbal
servo loops, closed digitally on the encoders with the same delay: a PD compensator
``k (1 + s/w_lead)`` with a 2nd-order Butterworth roll-off, per axis (*derived* by loop
shaping on this model): about x ``k_servo_x`` 3.5 V/rad, lead 0.8 Hz, roll-off 10 Hz
(gain crossovers up to 3.4-4.4 Hz, phase margins >= 38 degrees, gain margin 10 dB);
about y ``k_servo_y`` 6 V/rad, lead 0.6 Hz, roll-off 4 Hz (crossovers up to 2.8 Hz,
phase margins >= 20 degrees, gain margin 8 dB), in 1 g and 0 g alike. The
seed's servos have "approximately 3 Hz" bandwidth; here the y axis stays lower because
the gimbal torque reacts on the bus end, whose end-slope resonances (16.6, 34 and 44 Hz,
1 % damped) are as large as the payload response at crossover and the sampling delay
leaves no phase for them -- a faster y servo needs a notch. The closed loops are
stable in 1 g and 0 g (the tests check it).

Channels: inputs ``primary gimbal x/y command`` (rad, servo references) and ``RWA x/y/z``
(V); outputs ``primary gyro x/y`` and ``RWA gyro x/y/z`` (V) -- MACE's MIMO control
channels. ``disturbance_inputs=True`` adds ``secondary gimbal x/y command`` (the scanning
disturbance) and ``encoder_outputs=True`` the four encoders (rad).

Modal figures (nominal parameters, 2 elements per strut, 6 per rod; :func:`mace_modes`)
-----------------------------------------------------------------------------------------
=============================  ============  ============  =====================
mode                           this 1 g (Hz) this 0 g (Hz) MACE Table 1 1 g / 0 g
=============================  ============  ============  =====================
rotary pendulum (yaw)          0.186         --            0.24
bounce                         0.192         --            0.2 (text)
pendulum x, y                  0.219, 0.220  --            0.23 (text)
tilt (pitch)                   0.257         --            0.44
compound pendulum (roll)       2.53          --            1.55
gimbal (payload swing)         1.06-1.72     0.23-0.76     3.1-5.5 (servoed)
first vertical bending         2.68          2.71          2.13 / 2.10
first horizontal bending       3.67          3.48          3.74 / 3.31
first violin (outer rods)      7.48          --            7.26, 7.34
first violin (centre rod)      12.3          --            11.65
=============================  ============  ============  =====================

The 0-g model has exactly six rigid-body modes. The first horizontal bending mode drops
by 5.2 % from 1 g to 0 g (MACE: 12.7 %): in this mode the hanging payloads swing
sideways about their gimbal x axes, and in 1 g their weight on the 0.2 m arms
(``m g d`` = 5.9 N m/rad per payload against the 0.3 N m/rad bearings) stiffens that
swing -- the gravity pendulum of "articulating appendages" the seed names -- while the
load rods add their pendulum stiffness at the bus ends. The first vertical bending mode
moves by 1.3 % only (MACE: 1.4 %), and downwards: in 1 g it also carries load-rod
motion (about 4 % of its kinetic energy).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..physical.electronics import bessel_stage, delay_stage, gain_stage, rate_gyro_stage, servo_stage
from ..physical.fem import Frame
from ..physical.modal import modal_dynamics
from ..physical.model import PhysicalModel, Stage
from ..signals import select_signals
from ..table import Table
from ._assembly import (
    check_band_hz,
    check_flags,
    check_int,
    cylinder_inertia,
    get_param,
    mapped_dynamics,
    param,
    rod_section,
    tube_section,
)

__all__ = ["mace_beam", "mace_modes", "classify_mace_modes", "MACE_TABLE1_HZ"]

#: MACE Table 1 (FEM column): 1-g and 0-g frequencies (Hz) of the modes this model mirrors.
MACE_TABLE1_HZ = {
    "suspension rotary pendulum": (0.24, None),
    "suspension tilt": (0.44, None),
    "suspension compound pendulum": (1.55, None),
    "first vertical bending": (2.13, 2.10),
    "first horizontal bending": (3.74, 3.31),
    "first violin": (7.26, None),
}

# Geometry and fixed hardware (m, kg, N/m): see the module docstring for the sources.
BUS_LENGTH = 1.5
N_STRUTS = 4
ACTIVE_STRUT = 1  # index of the active member (x = -0.375 ... 0)
TUBE_OD, TUBE_WALL = 0.032, 0.0024
ARM_OD, ARM_WALL = 0.040, 0.004
POST_HEIGHT = 0.05
ROD_LENGTH = 5.0
ROD_DIAMETER = 2.1e-3
PAYLOAD_RADIUS, PAYLOAD_LENGTH = 0.08, 0.25
K_HINGE = 1e6  # N/m, gimbal and clevis translations
K_HINGE_ROT = 1e4  # N m/rad, gimbal about its non-gimbal axis z
GIMBAL_FRAME_INERTIA = 1e-3  # kg m^2
BUS_NODE_INERTIA = 1e-4  # kg m^2
RWA_INERTIA = 0.03  # kg m^2
SUSPENSION_NODES = ("bus_1", "bus_3", "bus_5")
GIMBALS = {"primary": "bus_1", "secondary": "bus_5"}
AXES = ("x", "y")


# (name, value, unit, bounds, meaning) of the parameters, by tag group.
_STRUCTURE = (
    ("E_polycarbonate", 2.4e9, "Pa", (1.8e9, 3.2e9), "Young's modulus of the polycarbonate bus struts"),
    ("E_active_strut", 3.6e9, "Pa", (2.0e9, 8.0e9), "effective Young's modulus of the active strut"),
    ("rho_polycarbonate", 1200.0, "kg/m^3", (1100.0, 1300.0), "density of the bus struts"),
    ("E_aluminium", 70e9, "Pa", (60e9, 80e9), "Young's modulus of the gimbal arms and brackets"),
    ("m_bus_node", 0.3, "kg", (0.1, 0.6), "mass of one aluminium node fitting between struts"),
    ("m_rwa", 5.0, "kg", (3.0, 8.0), "mass of the reaction-wheel assembly"),
    ("m_gimbal", 0.6, "kg", (0.2, 1.5), "mass of one gimbal frame with its motors"),
    ("m_payload_primary", 3.0, "kg", (1.5, 5.0), "mass of the primary (pointing) payload"),
    ("m_payload_secondary", 3.0, "kg", (1.5, 5.0), "mass of the secondary (disturbing) payload"),
    ("d_payload", 0.20, "m", (0.05, 0.35), "distance of a payload's centre of mass below its gimbal axes"),
    ("k_gimbal_bearing", 0.3, "N m/rad", (0.01, 10.0), "cable and bearing stiffness about a gimbal axis"),
)
_ELECTRONICS = (
    ("k_gimbal_motor", 0.5, "N m/V", (0.1, 2.0), "gimbal torque-motor constant with its amplifier"),
    ("k_rwa_motor", 0.2, "N m/V", (0.05, 1.0), "reaction-wheel motor torque per volt"),
    ("k_gyro", 10.0, "V/(rad/s)", (1.0, 100.0), "rate-gyro scale factor"),
    ("f_gyro", 80.0, "Hz", (30.0, 300.0), "natural frequency of the rate-gyro dynamics"),
    ("zeta_gyro", 0.6, "", (0.2, 1.0), "damping ratio of the rate-gyro dynamics"),
    ("f_antialias", 100.0, "Hz", (50.0, 250.0), "cutoff of the 4th-order Bessel anti-aliasing filters"),
    ("delay_sampling", 3.6e-3, "s", (0.0, 10e-3), "sampling delay of the real-time computer (MACE)"),
)
_SERVO = (
    ("k_servo_x", 3.5, "V/rad", (0.1, 50.0), "proportional gain of the gimbal servos about x"),
    ("f_servo_lead_x", 0.8, "Hz", (0.1, 5.0), "rate-feedback corner of the gimbal servos about x"),
    ("f_servo_lowpass_x", 10.0, "Hz", (2.0, 100.0), "roll-off of the gimbal servos about x"),
    ("k_servo_y", 6.0, "V/rad", (0.1, 100.0), "proportional gain of the gimbal servos about y"),
    ("f_servo_lead_y", 0.6, "Hz", (0.1, 5.0), "rate-feedback corner of the gimbal servos about y"),
    ("f_servo_lowpass_y", 4.0, "Hz", (1.0, 100.0), "roll-off of the gimbal servos about y"),
)
_SUSPENSION = (
    ("k_suspension_outer", 4.88, "N/m", (0.5, 50.0), "vertical rate of an outer suspension device"),
    ("k_suspension_centre", 12.7, "N/m", (0.5, 100.0), "vertical rate of the centre suspension device"),
    ("c_suspension", 0.6, "N s/m", (0.0, 20.0), "vertical damping of a suspension device"),
    ("m_device", 0.2, "kg", (0.05, 1.0), "moving mass of a suspension device"),
    ("E_graphite", 130e9, "Pa", (80e9, 200e9), "axial Young's modulus of the graphite-epoxy load rods"),
    ("rho_graphite", 1600.0, "kg/m^3", (1400.0, 1800.0), "density of the load rods"),
)


def _params(zero_g: bool) -> list:
    p = [param(*row, ("structure",)) for row in _STRUCTURE]
    p.append(param("nu_polycarbonate", 0.37, "", (0.3, 0.42), "Poisson's ratio of polycarbonate",
                   ("structure",), free=False))
    p.append(param("zeta_modal", 0.01, "", (0.001, 0.05), "modal damping ratio (MACE: 1 % with articulation)",
                   ("damping",)))
    p += [param(*row, ("electronics",)) for row in _ELECTRONICS]
    p += [param(*row, ("electronics", "servo")) for row in _SERVO]
    if not zero_g:
        p += [param(*row, ("suspension",)) for row in _SUSPENSION]
        p.append(param("g_local", 9.81, "m/s^2", (9.7, 9.9), "local gravitational acceleration", ("gravity",),
                       free=False))
    return p


def _frame(theta: Mapping[str, float], n_el: int, n_rod: int, zero_g: bool):
    """Assemble the MACE-like Frame for the parameter values ``theta``."""
    g = 0.0 if zero_g else get_param(theta, "g_local", 9.81)
    fr = Frame(gravity=g, gravity_direction=(0.0, 0.0, -1.0), name="MACE-like bus")
    nu = theta["nu_polycarbonate"]
    rho = theta["rho_polycarbonate"]
    tube = tube_section(TUBE_OD, TUBE_WALL)
    xs = np.linspace(-BUS_LENGTH / 2, BUS_LENGTH / 2, N_STRUTS + 1)
    bus = [fr.add_node(f"bus_{i + 1}", (x, 0.0, 0.0)) for i, x in enumerate(xs)]
    for i in range(N_STRUTS):
        active = i == ACTIVE_STRUT
        E = theta["E_active_strut"] if active else theta["E_polycarbonate"]
        group = "active_strut" if active else "bus_struts"
        fr.add_beam(group, bus[i], bus[i + 1], E=E, G=E / (2 * (1 + nu)), rho=rho, **tube, n_elements=n_el)
    for node in bus:
        fr.add_mass(node, theta["m_bus_node"], inertia=(BUS_NODE_INERTIA,) * 3)
    centre = bus[N_STRUTS // 2]
    fr.add_mass(centre, theta["m_rwa"], inertia=(RWA_INERTIA,) * 3)

    E_al = theta["E_aluminium"]
    arm = tube_section(ARM_OD, ARM_WALL)
    al = {"E": E_al, "G": E_al / 2.66, "rho": 2700.0, **arm}
    for which, base in GIMBALS.items():
        x0 = fr.node_xyz(base)
        gim = fr.add_node(f"{which}_gimbal", x0)
        for d in ("x", "y", "z"):
            fr.add_spring(base, K_HINGE, d, node2=gim)
        fr.add_spring(base, K_HINGE_ROT, "rz", node2=gim)
        for d in AXES:
            fr.add_spring(base, theta["k_gimbal_bearing"], "r" + d, node2=gim)
        fr.add_mass(gim, theta["m_gimbal"], inertia=(GIMBAL_FRAME_INERTIA,) * 3)
        pay = fr.add_node(f"{which}_payload", x0 + (0.0, 0.0, -theta["d_payload"]))
        fr.add_beam("gimbal_arms", gim, pay, **al)
        m_pay = theta[f"m_payload_{which}"]
        fr.add_mass(pay, m_pay, inertia=cylinder_inertia(m_pay, PAYLOAD_RADIUS, PAYLOAD_LENGTH, "z"))
        for d in AXES:
            fr.add_force_input(f"{which} gimbal {d} (payload)", gim, "r" + d, kind="torque")
            fr.add_force_input(f"{which} gimbal {d} (bus)", base, "r" + d, kind="torque")
            fr.add_relative_output(f"{which} encoder {d}", base, gim, "r" + d, kind="displacement")
    for d in AXES:
        fr.add_output(f"primary gyro {d}", "primary_payload", "r" + d, kind="velocity")
    for d in ("x", "y", "z"):
        fr.add_force_input(f"RWA {d}", centre, "r" + d, kind="torque")
        fr.add_output(f"RWA gyro {d}", centre, "r" + d, kind="velocity")

    # suspension brackets stay on the article in 0 g (part of the bus hardware)
    tops = []
    for k, base in enumerate(SUSPENSION_NODES, start=1):
        top = fr.add_node(f"bracket_{k}", fr.node_xyz(base) + (0.0, 0.0, POST_HEIGHT))
        fr.add_beam("suspension_brackets", base, top, **al)
        tops.append(top)
    if zero_g:
        return fr

    su = ("suspension",)
    rod = {
        "E": get_param(theta, "E_graphite", 130e9),
        "rho": get_param(theta, "rho_graphite", 1600.0),
    }
    rod["G"] = rod["E"] / 26.0  # graphite-epoxy: low shear modulus (only rod torsion uses it)
    rod.update(rod_section(ROD_DIAMETER))
    for k, top in enumerate(tops, start=1):
        xyz = fr.node_xyz(top)
        clevis = fr.add_node(f"load_rod_{k}_bottom", xyz, tags=su)
        for d in ("x", "y", "z"):
            fr.add_spring(top, K_HINGE, d, node2=clevis, tags=su)
        device = fr.add_node(f"suspension_device_{k}", xyz + (0.0, 0.0, ROD_LENGTH), tags=su)
        fr.add_beam("load_rods", clevis, device, **rod, n_elements=n_rod, tags=su)
        fr.fix(device, ("x", "y", "rz"), tags=su)
        name = "k_suspension_centre" if k == 2 else "k_suspension_outer"
        fr.add_spring(device, get_param(theta, name, 5.0), "z", tags=su)
        fr.add_dashpot(device, get_param(theta, "c_suspension", 0.6), "z", tags=su)
        fr.add_mass(device, get_param(theta, "m_device", 0.2), tags=su)
    return fr


def _torque_pairs() -> dict[str, dict[str, float]]:
    return {
        f"{w} gimbal {d}": {f"{w} gimbal {d} (payload)": 1.0, f"{w} gimbal {d} (bus)": -1.0}
        for w in GIMBALS
        for d in AXES
    }


def mace_beam(
    *,
    n_elements_per_member: int = 2,
    n_rod_elements: int = 6,
    gravity: bool = True,
    suspension: bool = True,
    zero_g: bool = False,
    servo_loops: bool = True,
    disturbance_inputs: bool = False,
    encoder_outputs: bool = False,
    n_modes: int | None = None,
    band_hz: tuple[float, float] | None = (0.0, 60.0),
    name: str = "MACE-like bus",
) -> PhysicalModel:
    """A MACE-like suspended bus with gimbals, reaction wheels, servos and electronics.

    Parameters
    ----------
    n_elements_per_member : int
        Beam elements per bus strut (1..12).
    n_rod_elements : int
        Beam elements per 5 m load rod (2..40); each adds violin modes.
    gravity, suspension : bool
        Build the 1-g model with the gravity preload and/or the suspension (both on: MACE's
        1-g model). ``False`` is the same as ``model.without("gravity")`` /
        ``model.without("suspension")``.
    zero_g : bool
        Build the 0-g model from scratch: never add the suspension and gravity (their
        parameters do not exist). Equals ``mace_beam().without("suspension", "gravity")``.
    servo_loops : bool
        Close the four gimbal servo loops (MACE's first control layer). ``False`` leaves the
        gimbal motor inputs (V) open.
    disturbance_inputs : bool
        Also keep the secondary gimbal's command inputs (the scanning disturbance).
    encoder_outputs : bool
        Also keep the four gimbal encoders as outputs (rad).
    n_modes, band_hz : optional
        Modal truncation (default every mode up to 60 Hz, MACE's updating band).
    name : str
        Model name.

    Returns
    -------
    PhysicalModel
        Inputs ``primary gimbal x/y command`` (rad) and ``RWA x/y/z`` (V), outputs
        ``primary gyro x/y``, ``RWA gyro x/y/z`` (V); see the module docstring.

    Examples
    --------
    >>> import robustctl as rc
    >>> one_g = rc.examples.mace_beam()
    >>> zero_g = one_g.without("suspension", "gravity")   # MACE's 0-g prediction
    """
    n_el = check_int(n_elements_per_member, "n_elements_per_member", 1, 12)
    n_rod = check_int(n_rod_elements, "n_rod_elements", 2, 40)
    band_hz = check_band_hz(band_hz)
    check_flags(
        gravity=gravity, suspension=suspension, zero_g=zero_g, servo_loops=servo_loops,
        disturbance_inputs=disturbance_inputs, encoder_outputs=encoder_outputs,
    )
    zero_g = bool(zero_g)
    params = _params(zero_g)

    def structure(theta: Mapping[str, float]):
        return _frame(theta, n_el, n_rod, zero_g)

    dynamics = mapped_dynamics(
        modal_dynamics(n_modes=n_modes, band_hz=band_hz, damping_param="zeta_modal"),
        inputs=_torque_pairs(),
    )
    gimbal_inputs = [f"{w} gimbal {d}" for w in GIMBALS for d in AXES]
    gyros = [f"primary gyro {d}" for d in AXES] + [f"RWA gyro {d}" for d in ("x", "y", "z")]
    rwa = [f"RWA {d}" for d in ("x", "y", "z")]
    stages = [
        gain_stage({**{g: "k_gimbal_motor" for g in gimbal_inputs}, **{r: "k_rwa_motor" for r in rwa}},
                   side="inputs", name="motor torque constants (N m/V)"),
        rate_gyro_stage(gyros, "f_gyro", "zeta_gyro", name="rate-gyro dynamics"),
        gain_stage({g: "k_gyro" for g in gyros}, side="outputs", name="rate-gyro scale (V/(rad/s))"),
        bessel_stage(gyros, 4, "f_antialias", name="4th-order Bessel anti-aliasing filters"),
        delay_stage(gyros, "delay_sampling", 2, name="3.6 ms sampling delay (Pade)"),
    ]
    inputs = [f"primary gimbal {d}" for d in AXES] + rwa
    if servo_loops:
        for w in GIMBALS:
            for d in AXES:
                stages.append(servo_stage(
                    f"{w} encoder {d}", f"{w} gimbal {d}", f"k_servo_{d}", lead_hz=f"f_servo_lead_{d}",
                    lowpass_hz=f"f_servo_lowpass_{d}", delay_s="delay_sampling",
                    reference_input_name=f"{w} gimbal {d} command", name=f"{w} gimbal {d} servo",
                ))
        inputs = [f"primary gimbal {d} command" for d in AXES] + rwa
        if disturbance_inputs:
            inputs += [f"secondary gimbal {d} command" for d in AXES]
    elif disturbance_inputs:
        inputs += [f"secondary gimbal {d}" for d in AXES]
    outputs = list(gyros)
    if encoder_outputs:
        outputs += [f"{w} encoder {d}" for w in GIMBALS for d in AXES]
    stages.append(Stage("control channels", lambda theta, sys: select_signals(sys, inputs, outputs)))

    excluded = set()
    if not zero_g and not suspension:
        excluded.add("suspension")
    if not zero_g and not gravity:
        excluded.add("gravity")
    model = PhysicalModel(
        params=params,
        dynamics=dynamics,
        structure=structure,
        io_stages=tuple(stages),
        name=name + (" (0 g)" if zero_g else ""),
        meta={
            "seed": "Glaese & Miller, MACE",
            "table1_hz": MACE_TABLE1_HZ,
            "element_groups": ("bus_struts", "active_strut", "gimbal_arms", "suspension_brackets")
            + (() if zero_g else ("load_rods",)),
            "sample_rate_hz": 500.0,
            "zero_g": zero_g,
        },
    )
    return model.without(*sorted(excluded)) if excluded else model


def mace_modes(model: PhysicalModel, n_modes: int = 30, **overrides: float):
    """Table of the structural modes of a :func:`mace_beam` model with a plain-words type.

    The type comes from the shape: ``rigid body`` (0 Hz); ``violin`` (over half the kinetic
    energy in the load rods); ``vertical bending`` / ``horizontal bending`` (the bus nodes
    leave their best straight line in z / y by over 5 % of the largest modal amplitude);
    ``gimbal`` (a payload swings relative to the bus -- encoder angle times ``d_payload``
    -- more than the bus translates, with over 5 % of the kinetic energy in the payloads);
    ``torsion`` (the bus twists); below 3 Hz on a suspended model ``suspension`` (bounce,
    pendulum, tilt, compound pendulum: the bus moves as a rigid body); otherwise ``local``.

    Returns
    -------
    robustctl.table.Table
        Columns ``mode``, ``f (Hz)``, ``type``, ``rods %``, ``payloads %``, ``bus y flex``,
        ``bus z flex``.
    """
    info = classify_mace_modes(model, n_modes, **overrides)
    rows = [
        (k + 1, float(r["f_hz"]), r["type"], 100 * r["rods"], 100 * r["payloads"], r["flex_y"], r["flex_z"])
        for k, r in enumerate(info)
    ]
    return Table(
        ("mode", "f (Hz)", "type", "rods %", "payloads %", "bus y flex", "bus z flex"),
        rows,
        title=f"{model.name}: structural modes",
    )


def classify_mace_modes(model: PhysicalModel, n_modes: int = 30, **overrides: float) -> list[dict]:
    """Per-mode facts behind :func:`mace_modes` (frequency, energy shares, bus flexure, type)."""
    n = check_int(n_modes, "n_modes", 1, 2000)
    frame = model.build_structure(**overrides)
    mats = frame.matrices(sparse=False)
    f_hz, phi = frame.modes(n_modes=min(n, mats.n_dof))
    labels = [lab.rsplit(" ", 1) for lab in mats.dof_labels]
    M = np.asarray(mats.mass)
    rods = np.array(["load_rod" in node or node.startswith("suspension_device") for node, _ in labels])
    pay = np.array(["gimbal" in node or "payload" in node for node, _ in labels])
    bus_idx = {
        d: [labels.index([f"bus_{i + 1}", d]) for i in range(N_STRUTS + 1)] for d in ("uy", "uz", "rx")
    }
    bus_trans = [labels.index([f"bus_{i + 1}", d]) for i in range(N_STRUTS + 1) for d in ("ux", "uy", "uz")]
    enc = [i for i, name in enumerate(mats.outputs) if "encoder" in name]
    arm = get_param(model.values | dict(overrides), "d_payload", 0.2)
    out = []
    for k in range(f_hz.size):
        v = phi[:, k]
        ke = v * (M @ v)
        total = float(ke.sum()) or 1.0
        scale = float(np.abs(v).max()) or 1.0
        flex = {d: _flexure(v[idx]) / scale for d, idx in bus_idx.items()}
        swing = arm * float(np.abs(mats.output_matrix[enc] @ v).max()) if enc else 0.0
        r = {
            "f_hz": float(f_hz[k]),
            "rods": float(ke[rods].sum() / total),
            "payloads": float(ke[pay].sum() / total),
            "flex_y": flex["uy"],
            "flex_z": flex["uz"],
            "twist": flex["rx"],
            "swing": swing / max(float(np.abs(v[bus_trans]).max()), 1e-300),
        }
        if f_hz[k] < 1e-3:
            kind = "rigid body"
        elif r["rods"] > 0.5:
            kind = "violin"
        elif max(r["flex_y"], r["flex_z"]) > 0.05:
            kind = "horizontal bending" if r["flex_y"] > r["flex_z"] else "vertical bending"
        elif r["swing"] > 1.0 and r["payloads"] > 0.05:
            kind = "gimbal"
        elif r["twist"] > 0.05:
            kind = "torsion"
        else:
            kind = "suspension" if rods.any() and f_hz[k] < 3.0 else "local"
        r["type"] = kind
        out.append(r)
    return out


def _flexure(a: np.ndarray) -> float:
    """Largest deviation of the bus-node values ``a`` from their best straight line."""
    xs = np.linspace(-1.0, 1.0, a.size)
    return float(np.abs(a - np.polyval(np.polyfit(xs, a, 1), xs)).max())
