"""Independent truths and their H1 estimates for the verdict tests of diagnose.

Every truth's frequency response is computed here with numpy from mass, stiffness and pointing
matrices (a modal sum of the undamped modes with modal damping ``zeta``, ``eigh`` of ``(K, M)``),
never with robustctl's modal state space; every estimate is an H1 estimate made here:

* :func:`periodic_h1` -- a measured (continuous, not held) periodic force with whole periods per
  segment, ``n_avg`` segments: each segment's force spectrum is complex Gaussian at every line,
  the output is ``G U`` plus white sensor noise, and H1 and the ordinary coherence are the
  averaged cross and auto spectra (Bendat & Piersol eq. 9.41); no leakage, independent lines.
* :func:`random_h1` -- a random force measured through a load cell: the exact discrete response
  of the continuous truth to a band-limited (first-order-hold interpolated, i.e. continuous)
  force, by ``scipy.signal.lsim`` on an oversampled grid, then decimated, white sensor noise, and
  ``scipy.signal.csd`` / ``welch`` with a Hann window (correlated neighbouring bins, leakage).

The data carry the number of averages (``meta["n_averages"]``) so that the noise model is the
coherence one, and nothing else: no estimator settings (the model is compared as the plain FRF).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.signal as ss

import robustctl as rc

ZETA = 0.02


# ---------------------------------------------------------------------------- exact responses
def modal_frf(M, K, B, C, kinds, f_hz, zeta=ZETA):
    """``G(j w)`` (nf, n_out, n_in) of ``M q'' + C_modal q' + K q = B u``, ``y = C q^(kind)``.

    ``kinds`` per output: "displacement", "velocity" or "acceleration" (multiplies by
    ``(j w)^k``). Modal damping ``zeta`` on every mode (rigid modes undamped are not allowed).
    """
    w2, phi = sla.eigh(K, M)
    wn = np.sqrt(np.maximum(w2, 0.0))
    w = 2 * np.pi * np.asarray(f_hz, dtype=float)
    s = 1j * w
    den = wn[None, :] ** 2 + 2 * zeta * wn[None, :] * s[:, None] + s[:, None] ** 2  # (nf, nm)
    cb, bc = C @ phi, phi.T @ B  # (no, nm), (nm, ni)
    g = np.einsum("om,fm,mi->foi", cb, 1.0 / den, bc)
    power = np.array([{"displacement": 0, "velocity": 1, "acceleration": 2}[k] for k in kinds])
    return g * (s[:, None, None] ** power[None, :, None])


def periodic_h1(g, n_avg=64, noise=0.05, seed=0, inputs=None, outputs=None, f_hz=None):
    """H1 and coherence of a periodic measured force, one SIMO experiment per input column.

    ``noise``: sensor-noise amplitude per line relative to each output's RMS response (over the
    band) to that input. Returns FrequencyData with ``meta["n_averages"] = n_avg``.
    """
    rng = np.random.default_rng(seed)
    nf, no, ni = g.shape
    h1 = np.empty_like(g)
    coh = np.empty(g.shape)
    for i in range(ni):
        u = (rng.standard_normal((n_avg, nf)) + 1j * rng.standard_normal((n_avg, nf))) / np.sqrt(2)
        y = g[None, :, :, i] * u[:, :, None]
        level = noise * np.sqrt(np.mean(np.abs(g[:, :, i]) ** 2, axis=0))  # (no,)
        y = y + level * (rng.standard_normal(y.shape) + 1j * rng.standard_normal(y.shape)) / np.sqrt(2)
        suy = np.sum(y * np.conj(u)[:, :, None], axis=0)
        suu = np.sum(np.abs(u) ** 2, axis=0)
        syy = np.sum(np.abs(y) ** 2, axis=0)
        h1[:, :, i] = suy / suu[:, None]
        coh[:, :, i] = np.abs(suy) ** 2 / (suu[:, None] * syy)
    return rc.FrequencyData(f_hz, h1, inputs=inputs, outputs=outputs, coherence=coh,
                            meta={"n_averages": int(n_avg)})


def random_h1(M, K, B, C, kinds, fs=200.0, n_samples=2**16, nperseg=1024, noise=0.05, seed=0,
              inputs=None, outputs=None, band=(1.0, 60.0), zeta=ZETA):
    """H1 of a random measured force (SIMO per input): continuous truth, Hann-windowed Welch."""
    n = M.shape[0]
    w2, phi = sla.eigh(K, M)  # mass-normalised modes
    wn = np.sqrt(w2)
    Minv = np.linalg.inv(M)
    # the damping matrix of modal damping zeta: C = M phi diag(2 zeta wn) phi^T M
    Cmat = M @ phi @ np.diag(2 * zeta * wn) @ phi.T @ M
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ K, -Minv @ Cmat]])
    Bs = np.vstack([np.zeros((n, B.shape[1])), Minv @ B])
    rows, ds = [], []
    for o, kind in enumerate(kinds):
        c = C[o]
        if kind == "displacement":
            rows.append(np.concatenate([c, np.zeros(n)]))
            ds.append(np.zeros(B.shape[1]))
        elif kind == "velocity":
            rows.append(np.concatenate([np.zeros(n), c]))
            ds.append(np.zeros(B.shape[1]))
        else:
            rows.append(c @ A[n:, :])
            ds.append(c @ (Minv @ B))
    Cs, Ds = np.array(rows), np.array(ds)
    rng = np.random.default_rng(seed)
    over = 8
    t = np.arange(n_samples * over) / (fs * over)
    exps = []
    for i in range(B.shape[1]):
        bl, al = ss.butter(6, min(band[1] * 1.2, 0.45 * fs) / (0.5 * fs * over))
        u = ss.lfilter(bl, al, rng.standard_normal(t.size))
        sys = ss.StateSpace(A, Bs[:, [i]], Cs, Ds[:, [i]])
        _, y, _ = ss.lsim(sys, u, t, interp=True)
        u, y = u[::over], np.atleast_2d(y.T).T[::over]
        y = y + noise * y.std(axis=0) * rng.standard_normal(y.shape)
        f, puu = ss.welch(u, fs, window="hann", nperseg=nperseg)
        g = np.empty((f.size, len(kinds)), complex)
        coh = np.empty((f.size, len(kinds)))
        for o in range(len(kinds)):
            _, puy = ss.csd(u, y[:, o], fs, window="hann", nperseg=nperseg)
            _, pyy = ss.welch(y[:, o], fs, window="hann", nperseg=nperseg)
            g[:, o] = puy / puu
            coh[:, o] = np.abs(puy) ** 2 / (puu * pyy)
        keep = (f >= band[0]) & (f <= band[1])
        exps.append((f[keep], g[keep], coh[keep]))
    f = exps[0][0]
    g = np.stack([e[1] for e in exps], axis=2)
    coh = np.stack([e[2] for e in exps], axis=2)
    n_avg = 1 + (n_samples - nperseg) // (nperseg // 2)
    return rc.FrequencyData(f, g, inputs=inputs, outputs=outputs, coherence=coh,
                            meta={"n_averages": int(n_avg)})


# ---------------------------------------------------------------------------- structures
CHAIN_M = np.diag([1.0, 1.2, 0.8, 0.6])
CHAIN_SPRINGS = np.array([1.2e4, 9e3, 7e3, 5e3])  # ground-1, 1-2, 2-3, 3-4


def chain_stiffness(k):
    n = len(k)
    K = np.zeros((n, n))
    K[0, 0] += k[0]
    for j in range(1, n):
        K[j - 1, j - 1] += k[j]
        K[j, j] += k[j]
        K[j - 1, j] -= k[j]
        K[j, j - 1] -= k[j]
    return K


def chain_model(n=4, outputs=("a2", "a3", "a4"), inputs=("F4",)):
    """The spring-mass chain (``n`` masses) as a user's matrix model: ``s_k`` scales all springs."""
    M = CHAIN_M[:n, :n]
    K0 = chain_stiffness(CHAIN_SPRINGS[:n])
    par = rc.Parameter("s_k", 1.0, "", (0.5, 2.0), meaning="stiffness scale of every spring")
    return rc.structural_model(
        M, lambda th: th["s_k"] * K0,
        inputs={name: f"dof {name[1:]}" for name in inputs},
        outputs={name: (f"dof {name[1:]}", "acceleration") for name in outputs},
        damping=ZETA, params=[par], name=f"{n}-mass chain",
    )


def chain_matrices(n=4, outputs=("a2", "a3", "a4"), inputs=("F4",), s_k=1.0, added=None, spring=None):
    """Truth matrices of the chain in numpy: ``added`` {dof: kg}, ``spring`` {dof: N/m} to ground."""
    M = CHAIN_M[:n, :n].copy()
    K = s_k * chain_stiffness(CHAIN_SPRINGS[:n])
    for d, v in (added or {}).items():
        M[d - 1, d - 1] += v
    for d, v in (spring or {}).items():
        K[d - 1, d - 1] += v
    B = np.zeros((n, len(inputs)))
    for j, name in enumerate(inputs):
        B[int(name[1:]) - 1, j] = 1.0
    C = np.zeros((len(outputs), n))
    for j, name in enumerate(outputs):
        C[j, int(name[1:]) - 1] = 1.0
    return M, K, B, C, ["acceleration"] * len(outputs)


# hub with two arms: hub rotation (dof 1, kg m^2), each arm two lateral DOFs at radii r1 < r2
HUB_J = 0.5
ARM_M = (0.4, 0.3)
ARM_R = (0.3, 0.6)
ARM_K = (4e3, 2.5e3)  # root and tip springs of each arm (N/m)


def hub_matrices(k_scale=1.0, added=None, spring=None):
    """Hub rotation theta plus arms' lateral deflections (relative to rigid rotation), 5 DOFs:
    ``q = [theta, a1, a2, b1, b2]``; absolute lateral motion of arm node ``x = r theta + q``."""
    n = 5
    # absolute coordinates z = T q with z = [theta, x_a1, x_a2, x_b1, x_b2]
    T = np.eye(n)
    for arm in range(2):
        for j in range(2):
            T[1 + 2 * arm + j, 0] = ARM_R[j] * (1 if arm == 0 else -1)
    Mz = np.diag([HUB_J, *ARM_M, *ARM_M])
    # springs act on relative deflections: root (q1), tip - root (q2 - q1)
    Kq = np.zeros((n, n))
    for arm in range(2):
        i1, i2 = 1 + 2 * arm, 2 + 2 * arm
        Kq[i1, i1] += ARM_K[0]
        Kq[i1, i1] += ARM_K[1]
        Kq[i2, i2] += ARM_K[1]
        Kq[i1, i2] -= ARM_K[1]
        Kq[i2, i1] -= ARM_K[1]
    Kq[0, 0] += 800.0  # torsional restraint of the hub (N m/rad)
    M = T.T @ Mz @ T
    K = k_scale * Kq
    for d, v in (added or {}).items():  # absolute point mass at a node: d in 2..5 (z index)
        e = T[d - 1]
        M = M + v * np.outer(e, e)
    for d, v in (spring or {}).items():  # a spring on the model's own DOF d (in the library)
        K = K.copy()
        K[d - 1, d - 1] += v
    return M, K, T


HUB_OUT = ("xa2", "xb2", "xa1")
HUB_IN = ("T_hub", "Fa2")


def hub_pointing(T):
    """Sensor rows (accelerations of arm nodes a2, b2, a1) and inputs (hub torque, force at a2)."""
    C = np.array([T[2], T[4], T[1]])
    B = np.column_stack([T[0], T[2]])
    return B, C, ["acceleration"] * 3


def hub_model():
    """The hub with arms as a user's matrix model (``s_arm`` scales the arm springs)."""
    M, K, T = hub_matrices()
    B, C, kinds = hub_pointing(T)
    par = rc.Parameter("s_arm", 1.0, "", (0.5, 2.0), meaning="stiffness scale of the arm springs")
    labels = ["hub", "a1", "a2", "b1", "b2"]
    return rc.structural_model(
        M, lambda th: th["s_arm"] * K,
        inputs={name: B[:, j] for j, name in enumerate(HUB_IN)},
        outputs={name: (C[j], kinds[j]) for j, name in enumerate(HUB_OUT)},
        damping=ZETA, params=[par], dof_labels=[f"dof {k}" for k in range(1, 6)], name="hub with arms",
    ), labels


# a small portal frame (rc.Frame): two columns, one beam, a mass on the beam
H, W = 1.0, 1.2
STEEL = dict(E=2.1e11, G=8.1e10, rho=7850.0, A=4e-4, Iy=2e-8, Iz=3e-8, J=4e-8)


def portal_frame(E=2.1e11, joint=None, added=None, n_el=2, hinge=None):
    """The frame: columns ``c1`` (node b1 -> t1) and ``c2`` (b2 -> t2), beam ``beam`` (t1 -> t2),
    a 2 kg mass at ``t2``; sensors at ``t1`` (x, accel.) and ``t2`` (x, z); a force at ``t2`` along x
    and one at the beam's middle along z. ``hinge`` (N m/rad): the beam meets t1 through a hinge
    about y of that stiffness (``Frame.add_joint_flexibility``)."""
    fr = rc.Frame(name="portal")
    for name, xyz in (("b1", (0, 0, 0)), ("t1", (0, 0, H)), ("b2", (W, 0, 0)), ("t2", (W, 0, H)),
                      ("mid", (W / 2, 0, H))):
        fr.add_node(name, xyz)
    props = {**STEEL, "E": E, "G": E / 2.6}
    fr.add_beam("c1", "b1", "t1", **props, n_elements=n_el)
    fr.add_beam("c2", "b2", "t2", **props, n_elements=n_el)
    fr.add_beam("beam", "t1", "mid", **props, n_elements=1)
    fr.add_beam("beam", "mid", "t2", **props, n_elements=1)
    fr.fix("b1").fix("b2")
    fr.add_mass("t2", 2.0)
    fr.add_mass("t1", 1.0)
    fr.add_mass("mid", 0.5)
    for node, v in (added or {}).items():
        fr.add_mass(node, v)
    fr.add_output("S1", "t1", "x")
    fr.add_output("S2", "t2", "x")
    fr.add_output("S3", "mid", "z")
    fr.add_force_input("A1", "t2", "x")
    fr.add_force_input("A2", "mid", "z")
    if hinge is not None:
        fr.add_joint_flexibility("t1", "beam", 1.0 / hinge, axes=("ry",))
    return fr


def frame_model(hinge=None):
    """The portal frame as a PhysicalModel whose parameter ``E`` (Pa) updating may change (``hinge``:
    see :func:`portal_frame`)."""
    from robustctl.physical.modal import modal_dynamics
    from robustctl.physical.model import PhysicalModel

    par = rc.Parameter("E", 2.1e11, "Pa", (1e11, 4e11), meaning="Young's modulus of every member")
    zeta = rc.Parameter("zeta_modal", ZETA, "", (0.0, 0.2), rel_step=1e-2, abs_step=1e-5,
                        meaning="modal damping ratio")
    return PhysicalModel((par, zeta), modal_dynamics(None, None, "zeta_modal"),
                         structure=lambda th: portal_frame(E=th["E"], hinge=hinge), name="portal frame")


def structure_matrices(struct):
    """Dense ``(M, K, B, C, kinds)`` of a Structure (the truth measured by numpy/scipy)."""
    mats = struct.matrices()
    dense = [a.toarray() if hasattr(a, "toarray") else np.asarray(a) for a in (mats.mass, mats.stiffness)]
    return dense[0], dense[1], mats.input_matrix, mats.output_matrix, list(mats.output_kinds)
