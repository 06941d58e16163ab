"""An independent test structure: a free-free small satellite on bungees, measured in numpy/scipy.

The structure (z up, metres, SI units throughout)
-------------------------------------------------
* **Bus**: a 0.5 x 0.5 x 0.5 m box frame of 20 mm square aluminium tubes (2 mm wall), one
  element per edge, with 3 kg of panels and electronics lumped at each of its 8 corners. The
  top edges on the +y and -y faces and the bottom edge on the +x face carry a middle node: the
  array roots ``bus_hinge_py`` / ``bus_hinge_my`` and the boom root ``bus_boom_root``.
* **Two solar-array strips** (groups ``array_py``, ``array_my``), 1.6 m along +y and -y from the
  array roots, three elements each, as an equivalent beam of 1.5 kg/m whose flap stiffness
  (about the strip's width) is 1 % of its in-plane stiffness.
* **A boom** (group ``boom``), 1.2 m along +x from the boom root, an aluminium tube of 25 mm
  outer diameter and 1.5 mm wall in three elements, with a 0.8 kg tip mass.
* **Bungees**: soft springs to ground at the 4 top corners (80 N/m vertical, 20 N/m
  horizontal), suspension modes below 1 Hz.
* 1 % classical modal damping in every mode; 20 nodes x 6 = 120 DOF.

The frame element is the 3-D Euler-Bernoulli beam with consistent mass written here in numpy
(Przemieniecki, *Theory of Matrix Structural Analysis*, 1968, eqs. 5.116 and 11.34), its
element axes as the usual convention (local z from global Z, or global X for near-vertical
members). The truth's response is never computed with robustctl.

The test
--------
Two shakers at once drive the bus (``F1`` vertically at the bottom corner ``bus_ppm``, ``F2``
sideways at ``bus_mpm``) with independent band-limited random forces, measured at the stingers
(0.3 % force-gauge noise); six accelerometers (1 % noise of each channel's RMS) read ``a1`` the
driving point of F1, ``a2``/``a3`` the array tips (flap), ``a4``/``a5`` the boom tip (y, z) and
``a6`` a bus top corner (x). The time response is the exact discretisation of the modal state
space: every mode is a first-order complex recursion under a first-order-hold force on a grid
``OVERSAMPLE`` times finer than the acquisition (:func:`simulate`), sampled at 256 Hz. The MIMO
H1 estimate ``H = G_yu G_uu^-1`` (Bendat & Piersol, *Random Data*, eq. 7.27) and the partial
coherence come from ``scipy.signal.csd`` with Hann windows (:func:`mimo_h1`).

Hidden effects (switches of :func:`measure`, any combination)
--------------------------------------------------------------
``"hinge_1axis"`` the +y array's root is a hinge about x (the flap axis) of 1500 N m/rad;
``"hinge_iso"`` the same hinge with 1500 N m/rad about all three axes (the library's joint form);
``"accel_mass"`` a 40 g accelerometer mount at each sensor node; ``"resonator"`` a 1 kg box on a
12 Hz mount (z) on the bus top corner ``bus_pmp`` (an added mode, not in any library);
``"stiffer"`` +4 % stiffness everywhere; ``"swapped"`` the cables of a1 and a2 exchanged;
``"tip_mass"`` 0.15 kg more at the boom tip; ``"harness"`` 0.25 kg of cable harness clamped at
the bus corner ``bus_mmp``; ``"attachment"`` 80 g of hardware between F1's force gauge and the
structure (at ``bus_ppm``); ``()`` is the null case.

:func:`nominal_model` is the same structure as ``rc.Frame`` inside ``rc.PhysicalModel`` with
free parameters ``E_bus``, ``E_array``, ``E_boom`` and ``zeta_modal``.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg as sla
import scipy.signal as ss

import robustctl as rc

__all__ = [
    "EFFECTS", "NODES", "INPUTS", "OUTPUTS", "SatCase", "truth_matrices", "truth_frf", "simulate",
    "mimo_h1", "measure", "nominal_model", "structure_frame",
]

# ---------------------------------------------------------------------------- geometry
E_AL, G_AL, RHO_AL = 70e9, 70e9 / 2.66, 2700.0
ZETA = 0.01
FS = 256.0
OVERSAMPLE = 16
BAND = (2.0, 80.0)


def _tube_square(b: float, t: float) -> dict:
    bi = b - 2 * t
    inertia = (b**4 - bi**4) / 12.0
    bm = b - t
    return dict(A=b * b - bi * bi, Iy=inertia, Iz=inertia, J=4 * bm**4 * t / (4 * bm))


def _tube_round(d: float, t: float) -> dict:
    di = d - 2 * t
    inertia = np.pi / 64 * (d**4 - di**4)
    return dict(A=np.pi / 4 * (d * d - di * di), Iy=inertia, Iz=inertia, J=2 * inertia)


SEC_BUS = _tube_square(0.02, 0.002)
SEC_BOOM = _tube_round(0.025, 0.0015)
# the array strip as an equivalent beam: 1.5 kg/m, flap EI = 500 N m^2, in-plane 100 x that
SEC_ARRAY = dict(A=1.5 / RHO_AL, Iy=500.0 / E_AL, Iz=5e4 / E_AL, J=2e-8)

H = 0.25  # half the bus size
NODES: dict[str, tuple[float, float, float]] = {}
for _sx, _x in (("p", H), ("m", -H)):
    for _sy, _y in (("p", H), ("m", -H)):
        for _sz, _z in (("p", 2 * H), ("m", 0.0)):
            NODES[f"bus_{_sx}{_sy}{_sz}"] = (_x, _y, _z)
NODES["bus_hinge_py"] = (0.0, H, 2 * H)
NODES["bus_hinge_my"] = (0.0, -H, 2 * H)
NODES["bus_boom_root"] = (H, 0.0, 0.0)
for _k in (1, 2, 3):
    NODES[f"array_py_{_k}"] = (0.0, H + 1.6 * _k / 3, 2 * H)
    NODES[f"array_my_{_k}"] = (0.0, -H - 1.6 * _k / 3, 2 * H)
    NODES[f"boom_{_k}"] = (H + 1.2 * _k / 3, 0.0, 0.0)

# members: (group, n1, n2); the three split bus edges go through their middle nodes
_BUS_EDGES = []
_corners = [n for n in NODES if n.startswith("bus_") and len(n) == 7]
for _i, _a in enumerate(_corners):
    for _b in _corners[_i + 1:]:
        if sum(u != v for u, v in zip(NODES[_a], NODES[_b])) == 1:
            _BUS_EDGES.append((_a, _b))
_SPLIT = {("bus_mpp", "bus_ppp"): "bus_hinge_py", ("bus_mmp", "bus_pmp"): "bus_hinge_my",
          ("bus_pmm", "bus_ppm"): "bus_boom_root"}
MEMBERS: list[tuple[str, str, str]] = []
for _a, _b in _BUS_EDGES:
    key = tuple(sorted((_a, _b)))
    if key in _SPLIT:
        MEMBERS += [("bus", key[0], _SPLIT[key]), ("bus", _SPLIT[key], key[1])]
    else:
        MEMBERS.append(("bus", _a, _b))
for _side in ("py", "my"):
    _prev = f"bus_hinge_{_side}"
    for _k in (1, 2, 3):
        MEMBERS.append((f"array_{_side}", _prev, f"array_{_side}_{_k}"))
        _prev = f"array_{_side}_{_k}"
_prev = "bus_boom_root"
for _k in (1, 2, 3):
    MEMBERS.append(("boom", _prev, f"boom_{_k}"))
    _prev = f"boom_{_k}"
SECTIONS = {"bus": SEC_BUS, "array_py": SEC_ARRAY, "array_my": SEC_ARRAY, "boom": SEC_BOOM}
E_PARAM = {"bus": "E_bus", "array_py": "E_array", "array_my": "E_array", "boom": "E_boom"}

MASSES = {n: 3.0 for n in _corners} | {"boom_3": 0.8}
BUNGEE_NODES = [n for n in _corners if n.endswith("p")]
K_BUNGEE = {"x": 20.0, "y": 20.0, "z": 80.0}

INPUTS = {"F1": ("bus_ppm", "z"), "F2": ("bus_mpm", "y")}
OUTPUTS = {"a1": ("bus_ppm", "z"), "a2": ("array_py_3", "z"), "a3": ("array_my_3", "z"),
           "a4": ("boom_3", "y"), "a5": ("boom_3", "z"), "a6": ("bus_ppp", "x")}
_AXIS = {"x": 0, "y": 1, "z": 2, "rx": 3, "ry": 4, "rz": 5}

HINGE_K = 1500.0  # N m/rad
ACCEL_MASS = 0.040  # kg
RESONATOR = ("bus_pmp", "z", 1.0, 12.0)  # node, direction, kg, Hz
TIP_MASS = 0.15  # kg
HARNESS = ("bus_mmp", 0.25)  # a cable harness clamped at a bus corner: node, kg
ATTACHMENT = 0.080  # kg of hardware between F1's force gauge and the structure
EFFECTS = ("hinge_1axis", "hinge_iso", "accel_mass", "resonator", "stiffer", "swapped", "tip_mass",
           "harness", "attachment")


# ---------------------------------------------------------------------------- numpy FEM
def _beam_local(L, E, G, rho, A, Iy, Iz, J):
    """Element-axis stiffness and consistent mass (12 x 12) of a 3-D Euler-Bernoulli beam,
    DOFs ``[u v w rx ry rz]`` per node (Przemieniecki eqs. 5.116, 11.34)."""
    k = np.zeros((12, 12))
    m = np.zeros((12, 12))
    for i, c in ((0, E * A / L), (3, G * J / L)):
        k[np.ix_([i, i + 6], [i, i + 6])] += c * np.array([[1, -1], [-1, 1]])
    for i, c in ((0, rho * A * L / 6), (3, rho * (Iy + Iz) * L / 6)):
        m[np.ix_([i, i + 6], [i, i + 6])] += c * np.array([[2, 1], [1, 2]])
    kb = np.array([[12, 6 * L, -12, 6 * L], [6 * L, 4 * L * L, -6 * L, 2 * L * L],
                   [-12, -6 * L, 12, -6 * L], [6 * L, 2 * L * L, -6 * L, 4 * L * L]]) / L**3
    mb = rho * A * L / 420 * np.array([[156, 22 * L, 54, -13 * L], [22 * L, 4 * L * L, 13 * L, -3 * L * L],
                                       [54, 13 * L, 156, -22 * L], [-13 * L, -3 * L * L, -22 * L, 4 * L * L]])
    v = [1, 5, 7, 11]  # v, rz: rz = dv/dx
    w = [2, 4, 8, 10]  # w, ry: ry = -dw/dx
    s = np.diag([1.0, -1.0, 1.0, -1.0])
    k[np.ix_(v, v)] += E * Iz * kb
    k[np.ix_(w, w)] += E * Iy * s @ kb @ s
    m[np.ix_(v, v)] += mb
    m[np.ix_(w, w)] += s @ mb @ s
    return k, m


def _rotation(x1, x2):
    ex = (x2 - x1) / np.linalg.norm(x2 - x1)
    orient = np.array([1.0, 0.0, 0.0]) if abs(ex[2]) > 0.9 else np.array([0.0, 0.0, 1.0])
    ez = orient - orient @ ex * ex
    ez /= np.linalg.norm(ez)
    R = np.vstack([ex, np.cross(ez, ex), ez])
    return np.kron(np.eye(4), R)


def _node_index(extra: tuple[str, ...] = ()) -> dict[str, int]:
    return {n: i for i, n in enumerate((*NODES, *extra))}


@functools.lru_cache(maxsize=32)
def truth_matrices(effects: tuple[str, ...] = ()) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(M, K, B, C)`` of the truth with the hidden ``effects``: forces in N, accelerations in
    m/s^2 (``C`` maps the DOFs whose second derivative the sensors read)."""
    unknown = set(effects) - set(EFFECTS)
    if unknown:
        raise ValueError(f"unknown effects {sorted(unknown)}; choose from {EFFECTS}")
    hinge = "hinge_1axis" in effects or "hinge_iso" in effects
    extra = ("hinge_twin",) if hinge else ()
    idx = _node_index(extra)
    n = 6 * len(idx) + ("resonator" in effects)
    M, K = np.zeros((n, n)), np.zeros((n, n))
    e_scale = 1.04 if "stiffer" in effects else 1.0
    for group, a, b in MEMBERS:
        if hinge and group == "array_py" and a == "bus_hinge_py":
            a = "hinge_twin"
        xa, xb = np.array(NODES.get(a, NODES["bus_hinge_py"])), np.array(NODES[b])
        kl, ml = _beam_local(np.linalg.norm(xb - xa), E_AL * e_scale, G_AL * e_scale, RHO_AL,
                             **SECTIONS[group])
        T = _rotation(xa, xb)
        dofs = np.r_[6 * idx[a]:6 * idx[a] + 6, 6 * idx[b]:6 * idx[b] + 6]
        K[np.ix_(dofs, dofs)] += T.T @ kl @ T
        M[np.ix_(dofs, dofs)] += T.T @ ml @ T
    masses = dict(MASSES)
    if "tip_mass" in effects:
        masses["boom_3"] += TIP_MASS
    if "harness" in effects:
        masses[HARNESS[0]] += HARNESS[1]
    if "attachment" in effects:
        masses[INPUTS["F1"][0]] += ATTACHMENT
    if "accel_mass" in effects:
        for node, _ in OUTPUTS.values():
            masses[node] = masses.get(node, 0.0) + ACCEL_MASS
    for node, m in masses.items():
        for d in range(3):
            M[6 * idx[node] + d, 6 * idx[node] + d] += m
    for node in BUNGEE_NODES:
        for ax, k in K_BUNGEE.items():
            K[6 * idx[node] + _AXIS[ax], 6 * idx[node] + _AXIS[ax]] += k * e_scale
    if "resonator" in effects:
        node, ax, m, f = RESONATOR
        k = m * (2 * np.pi * f) ** 2
        i, r = 6 * idx[node] + _AXIS[ax], n - 1
        M[r, r] += m
        K[np.ix_([i, r], [i, r])] += k * np.array([[1, -1], [-1, 1]])
    B = np.zeros((n, len(INPUTS)))
    for j, (node, ax) in enumerate(INPUTS.values()):
        B[6 * idx[node] + _AXIS[ax], j] = 1.0
    C = np.zeros((len(OUTPUTS), n))
    for j, (node, ax) in enumerate(OUTPUTS.values()):
        C[j, 6 * idx[node] + _AXIS[ax]] = 1.0
    if "swapped" in effects:
        C[[0, 1]] = C[[1, 0]]
    if hinge:
        # the twin shares the root's translations and the rotations the hinge does not free
        free = (3, 4, 5) if "hinge_iso" in effects else (3,)
        twin, root = 6 * idx["hinge_twin"], 6 * idx["bus_hinge_py"]
        keep = [d for d in range(n) if not (twin <= d < twin + 6 and (d - twin) not in free)]
        T = np.eye(n)[:, keep]
        for d in range(6):
            if d not in free:
                T[twin + d, keep.index(root + d)] = 1.0
        for d in free:
            K[np.ix_([root + d, twin + d], [root + d, twin + d])] += HINGE_K * np.array([[1, -1], [-1, 1]])
        M, K, B, C = T.T @ M @ T, T.T @ K @ T, T.T @ B, C @ T
    return M, K, B, C


@functools.lru_cache(maxsize=32)
def _modes(effects: tuple[str, ...]):
    M, K, B, C = truth_matrices(effects)
    w2, phi = sla.eigh(K, M)
    return np.sqrt(np.maximum(w2, 0.0)), phi.T @ B, C @ phi


def truth_frf(f_hz: Any, effects: tuple[str, ...] = (), zeta: float = ZETA) -> np.ndarray:
    """The exact accelerance (m/s^2/N) of the truth, shape (nf, 6, 2), by the modal sum."""
    wn, pb, cp = _modes(tuple(effects))
    s = 2j * np.pi * np.asarray(f_hz, dtype=float)
    h = s[:, None] ** 2 / (wn[None] ** 2 + 2 * zeta * wn[None] * s[:, None] + s[:, None] ** 2)
    return np.einsum("om,fm,mi->foi", cp, h, pb)


def simulate(force: np.ndarray, dt: float, effects: tuple[str, ...] = (), zeta: float = ZETA,
             every: int = 1) -> np.ndarray:
    """Exact accelerations (n, 6) at every ``every``-th sample of a first-order-hold force.

    Each mode ``eta'' + 2 zeta w eta' + w^2 eta = f_m`` is ``eta = 2 Re(r z)`` with
    ``z' = lambda z + f_m``, ``r = 1 / (lambda - conj(lambda))``; under a force linear between
    the samples ``dt`` apart ``z_{k+1} = a z_k + (I0 - I1) f_k + I1 f_{k+1}`` with
    ``a = e^{lambda dt}``, ``I0 = (a - 1) / lambda``, ``I1 = (a - 1) / (lambda^2 dt) - 1 / lambda``
    (the exact integrals). Over ``every`` fine steps this is one step of ``a^every`` driven by
    the ``every + 1`` force samples of the step (a matrix product), and
    ``eta'' = f_m - 2 zeta w eta' - w^2 eta`` at the kept samples. ``force`` has
    ``every * n + 1`` rows (n, 2) for ``n + 1`` output samples.
    """
    wn, pb, cp = _modes(tuple(effects))
    n_out = (force.shape[0] - 1) // every + 1
    lam = -zeta * wn + 1j * wn * np.sqrt(1 - zeta**2)
    r = 1.0 / (lam - np.conj(lam))
    a = np.exp(lam * dt)
    i0 = (a - 1) / lam
    i1 = (a - 1) / (lam**2 * dt) - 1 / lam
    j = np.arange(every + 1)[:, None]
    taps = np.where(j <= every - 1, a ** (every - 1 - j) * (i0 - i1), 0) + np.where(
        j >= 1, a ** (every - j) * i1, 0)  # (every + 1, modes)
    fine = force[: every * (n_out - 1) + 1]
    drive = np.zeros((n_out - 1, wn.size), complex)
    for i in range(force.shape[1]):
        blocks = np.lib.stride_tricks.sliding_window_view(fine[:, i], every + 1)[::every]
        drive += blocks @ (taps * pb[:, i][None])
    fm = force[::every][:n_out] @ pb.T
    y = np.zeros((n_out, cp.shape[0]))
    for m in range(wn.size):
        z = np.empty(n_out, complex)
        z[0] = 0.0
        z[1:] = ss.lfilter([1.0], [1.0, -a[m] ** every], drive[:, m])
        eta = 2 * (r[m] * z).real
        deta = 2 * (r[m] * lam[m] * z).real
        acc = fm[:, m] - 2 * zeta * wn[m] * deta - wn[m] ** 2 * eta
        y += acc[:, None] * cp[:, m][None]
    return y


def mimo_h1(u: np.ndarray, y: np.ndarray, fs: float, nperseg: int):
    """MIMO H1 ``G_yu G_uu^-1`` (nf, no, ni) and the partial coherence of each channel with
    Hann windows, 50 % overlap (``scipy.signal.csd``); Bendat & Piersol eqs. 7.27, 7.35."""
    kw = dict(fs=fs, window="hann", nperseg=nperseg, noverlap=nperseg // 2, detrend=False)
    ni, no = u.shape[1], y.shape[1]
    f, _ = ss.csd(u[:, 0], u[:, 0], **kw)
    guu = np.empty((f.size, ni, ni), complex)
    gyu = np.empty((f.size, no, ni), complex)
    gyy = np.empty((f.size, no))
    for i in range(ni):
        for j in range(ni):
            guu[:, i, j] = ss.csd(u[:, i], u[:, j], **kw)[1]  # E[U_i^* U_j]
        for o in range(no):
            gyu[:, o, i] = ss.csd(u[:, i], y[:, o], **kw)[1]  # E[U_i^* Y_o]
    for o in range(no):
        gyy[:, o] = ss.csd(y[:, o], y[:, o], **kw)[1].real
    # scipy's csd(a, b) averages conj(A) B: gyu[o, i] = E[U_i^* Y_o] and with
    # suu[i, j] = E[U_i U_j^*] (the transpose of guu) Y = H U gives gyu = H suu
    suu = np.transpose(guu, (0, 2, 1))
    suu_inv = np.linalg.inv(suu)
    h = np.einsum("foi,fij->foj", gyu, suu_inv)
    explained = np.einsum("foi,fij,foj->fo", h, suu, np.conj(h)).real
    gnn = np.maximum(gyy - explained, 0.0)
    diag_inv = np.real(np.einsum("fii->fi", suu_inv))
    coh = 1.0 / (1.0 + gnn[:, :, None] * diag_inv[:, None, :] / np.maximum(np.abs(h) ** 2, 1e-300))
    return f, h, coh


@dataclass(frozen=True)
class SatCase:
    """One measured data set: the H1 estimate, the hidden effects and the settings."""

    data: Any
    effects: tuple[str, ...]
    seed: int
    description: dict


@functools.lru_cache(maxsize=16)
def measure(effects: tuple[str, ...] = (), seed: int = 0, duration: float = 240.0, nperseg: int = 4096,
            band: tuple[float, float] = BAND, force_noise: float = 0.003,
            accel_noise: float = 0.01) -> SatCase:
    """Run the two-shaker random test on the truth with hidden ``effects``.

    Forces: independent Gaussian noise low-passed at 100 Hz (8th-order Butterworth) on the
    fine grid, first-order-hold between its points; the first 30 s (transients) are dropped.
    Returns a :class:`SatCase` whose data carry the experiment (measured random force, Hann
    ``nperseg``, 50 % overlap, the number of averages). Cached per session.
    """
    effects = tuple(sorted(effects))
    rng = np.random.default_rng(seed)
    fs_fine = FS * OVERSAMPLE
    settle = 30.0
    n_fine = int(round((duration + settle) * FS)) * OVERSAMPLE + 1
    sos = ss.butter(8, 100.0, fs=fs_fine, output="sos")
    force = ss.sosfilt(sos, rng.standard_normal((n_fine, len(INPUTS))), axis=0) * 10.0
    y = simulate(force, 1.0 / fs_fine, effects, every=OVERSAMPLE)
    u = force[::OVERSAMPLE]
    start = int(round(settle * FS))
    u, y = u[start:], y[start:]
    u = u + force_noise * u.std(axis=0) * rng.standard_normal(u.shape)
    y = y + accel_noise * y.std(axis=0) * rng.standard_normal(y.shape)
    f, h, coh = mimo_h1(u, y, FS, nperseg)
    keep = (f >= band[0]) & (f <= band[1])
    n_avg = 1 + (u.shape[0] - nperseg) // (nperseg // 2)
    exp = rc.Experiment(input_kind="measured", excitation="random", fs_hz=FS, window="hann",
                        nperseg=nperseg, noverlap=nperseg // 2, n_averages=n_avg)
    data = rc.FrequencyData(f[keep], h[keep], inputs=tuple(INPUTS), outputs=tuple(OUTPUTS),
                            coherence=coh[keep], experiment=exp)
    desc = {"effects": effects, "seed": seed, "duration_s": duration, "nperseg": nperseg,
            "n_averages": n_avg, "force_noise": force_noise, "accel_noise": accel_noise}
    return SatCase(data, effects, seed, desc)


# ---------------------------------------------------------------------------- robustctl model
def structure_frame(theta) -> Any:
    """The nominal satellite as an ``rc.Frame`` for parameter values ``theta``."""
    fr = rc.Frame(name="satellite")
    for name, xyz in NODES.items():
        fr.add_node(name, xyz)
    for group, a, b in MEMBERS:
        E = theta[E_PARAM[group]]
        fr.add_beam(group, a, b, E=E, G=E / 2.66, rho=RHO_AL, **SECTIONS[group])
    for node, m in MASSES.items():
        fr.add_mass(node, m)
    for node in BUNGEE_NODES:
        for ax, k in K_BUNGEE.items():
            fr.add_spring(node, k, ax, tags=("suspension",))
    for name, (node, ax) in INPUTS.items():
        fr.add_force_input(name, node, ax)
    for name, (node, ax) in OUTPUTS.items():
        fr.add_output(name, node, ax, kind="acceleration")
    return fr


def nominal_model(name: str = "satellite") -> Any:
    """The satellite's nominal PhysicalModel: ``E_bus``, ``E_array``, ``E_boom`` (Pa) and
    ``zeta_modal`` free, every mode kept."""
    from robustctl.physical.modal import modal_dynamics
    from robustctl.physical.model import PhysicalModel

    params = [
        rc.Parameter("E_bus", E_AL, "Pa", (35e9, 140e9), meaning="Young's modulus of the bus tubes"),
        rc.Parameter("E_array", E_AL, "Pa", (35e9, 140e9),
                     meaning="equivalent modulus of the solar-array strips"),
        rc.Parameter("E_boom", E_AL, "Pa", (35e9, 140e9), meaning="Young's modulus of the boom tube"),
        rc.Parameter("zeta_modal", ZETA, "", (0.001, 0.05), rel_step=1e-2, abs_step=1e-5,
                     meaning="modal damping ratio of every mode"),
    ]
    return PhysicalModel(tuple(params), modal_dynamics(None, None, "zeta_modal"),
                         structure=structure_frame, name=name)
