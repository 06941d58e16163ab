"""A corpus of laboratory-like data that robustctl did not simulate itself.

Every truth is built here in numpy: mass, stiffness and (classical, modal) damping matrices of
five structures -- a 3-D two-storey frame, a 12-DOF plate-like grid, a hub with two arms, a
10-mass mast and a two-span beam -- with force vectors and sensor rows. Their responses are
computed exactly, without ``rc.simulate_experiment`` and without ``robustctl.measure.estimator``:

* a measured (continuous) force: a band-limited force that repeats over the whole record, so
  the sampled response is its exact steady state, ``Y_k = G(j w_k) U_k`` (``np.fft``);
* a held command (a DAC's zero-order hold): the exact sampled response of the held input,
  ``Y_k = G_zoh(e^{j w_k T}) U_k``, with ``G_zoh`` from ``scipy.signal.cont2discrete``;
* random excitation (Gaussian lines over the whole record: random for every Welch segment) or
  periodic excitation (a random-phase multisine whose period is one segment: whole periods);
* an impact test (band-limited hammer pulses, one record per hit).

White sensor noise is added, and the H1 estimate is made by ``rc.estimate_frf`` (the
"measurement" tool; ``rc.estimate_frf_impact`` for the hits) told how the data were made.

Each case returns a :class:`LabCase` ``(truth, data, description)``: the truth as a
``rc.structural_model`` reproducing the exact FRF (to 1e-7), the FrequencyData, and a dict
describing the case. :func:`measure` takes ``scales`` (the truth's parameter values, e.g. a
stiffness group off by 10 %), ``modify`` (a callable ``(M, K) -> (M, K)`` for a hidden change
of the matrices) and ``transform`` (a callable ``(f_hz, G) -> G`` applied to the exact response
of the structure: a sensor delay, a swapped cable, a sign flip ...), so hidden effects can be
planted in data made the same way.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
from scipy.linalg import eigh
from scipy.signal import cont2discrete

import robustctl as rc

__all__ = [
    "Structure", "LabCase", "frame_3d", "plate_grid", "hub_two_arms", "mast", "two_span_beam",
    "STRUCTURES", "measure", "impact_test", "CASES", "case",
]


# ---------------------------------------------------------------------------- structures
@dataclass
class Structure:
    """A structure as numpy matrices: ``M = sum_g m_g M_g``, ``K = sum_g k_g K_g`` (scales 1 at the
    nominal values), classical damping ``zeta`` in every mode, force vectors and sensor rows."""

    name: str
    mass_groups: dict[str, np.ndarray]
    stiffness_groups: dict[str, np.ndarray]
    inputs: dict[str, np.ndarray]
    outputs: dict[str, tuple[np.ndarray, str]]
    zeta: float = 0.02
    meanings: dict[str, str] = field(default_factory=dict)

    @property
    def n_dof(self) -> int:
        return next(iter(self.mass_groups.values())).shape[0]

    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(self.mass_groups) + tuple(self.stiffness_groups)

    def matrices(self, scales: Mapping[str, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
        s = {n: 1.0 for n in self.param_names} | dict(scales or {})
        M = sum(s[n] * m for n, m in self.mass_groups.items())
        K = sum(s[n] * k for n, k in self.stiffness_groups.items())
        return M, K

    def model(self, name: str | None = None) -> Any:
        """The PhysicalModel of the nominal structure: one dimensionless scale per mass and
        stiffness group (1 = nominal) and the modal damping ``zeta_modal``."""
        params = [
            rc.Parameter(n, 1.0, "-", (0.2, 5.0), meaning=self.meanings.get(n, f"scale of {n}"))
            for n in self.param_names
        ]
        mg, kg = self.mass_groups, self.stiffness_groups
        return rc.structural_model(
            lambda th: sum(th[n] * m for n, m in mg.items()),
            lambda th: sum(th[n] * k for n, k in kg.items()),
            inputs=self.inputs, outputs=self.outputs, damping=self.zeta, params=params,
            name=name or self.name,
        )

    def state_space(self, scales=None, modify=None) -> tuple[np.ndarray, ...]:
        """``(A, B, C, D)`` of the truth, state ``[q, dq/dt]``, with classical modal damping
        ``C_d = M Phi diag(2 zeta w) Phi^T M`` (Phi mass-normalised)."""
        M, K = self.matrices(scales)
        if modify is not None:
            M, K = modify(M, K)
        w2, phi = eigh(K, M)
        w = np.sqrt(w2)
        Cd = M @ phi @ np.diag(2.0 * self.zeta * w) @ phi.T @ M
        n = M.shape[0]
        Minv = np.linalg.inv(M)
        A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ K, -Minv @ Cd]])
        F = np.column_stack(list(self.inputs.values()))
        B = np.vstack([np.zeros((n, F.shape[1])), Minv @ F])
        rows, D = [], []
        for row, kind in self.outputs.values():
            row = np.asarray(row, dtype=float)
            if kind == "displacement":
                rows.append(np.concatenate([row, np.zeros(n)]))
                D.append(np.zeros(F.shape[1]))
            elif kind == "velocity":
                rows.append(np.concatenate([np.zeros(n), row]))
                D.append(np.zeros(F.shape[1]))
            else:  # acceleration: row @ (-M^-1 K q - M^-1 C dq + M^-1 F u)
                rows.append(np.concatenate([-row @ Minv @ K, -row @ Minv @ Cd]))
                D.append(row @ Minv @ F)
        return A, B, np.array(rows), np.array(D)

    def frf(self, f_hz: Any, scales=None, modify=None) -> np.ndarray:
        """The exact FRF ``C (j w I - A)^-1 B + D``, shape (nf, n_out, n_in)."""
        A, B, C, D = self.state_space(scales, modify)
        s = 2j * np.pi * np.asarray(f_hz, dtype=float)
        return _evaluate(A, B, C, D, s)

    def held_frf(self, f_hz: Any, fs: float, scales=None, modify=None) -> np.ndarray:
        """The exact sampled response behind a zero-order hold at ``fs`` (scipy's cont2discrete)."""
        A, B, C, D = self.state_space(scales, modify)
        Ad, Bd, Cd, Dd, _ = cont2discrete((A, B, C, D), 1.0 / fs, method="zoh")
        z = np.exp(2j * np.pi * np.asarray(f_hz, dtype=float) / fs)
        return _evaluate(Ad, Bd, Cd, Dd, z)


def _evaluate(A, B, C, D, points) -> np.ndarray:
    lam, V = np.linalg.eig(A)
    CV, W = C @ V, np.linalg.solve(V, B)
    return np.einsum("ok,fk,ki->foi", CV, 1.0 / (points[:, None] - lam[None, :]), W) + D[None]


def _spring(n: int, i: int, j: int | None, k: float) -> np.ndarray:
    """Stiffness matrix of a spring ``k`` between DOFs i and j (j None: to ground)."""
    K = np.zeros((n, n))
    K[i, i] += k
    if j is not None:
        K[j, j] += k
        K[i, j] -= k
        K[j, i] -= k
    return K


def _unit(n: int, *entries: tuple[int, float]) -> np.ndarray:
    v = np.zeros(n)
    for i, a in entries:
        v[i] = a
    return v


def frame_3d() -> Structure:
    """A two-storey 3-D frame: floors with x, y and twist DOFs (6), four columns per storey at
    the corners of a 4 m x 3 m plan, the floors' mass centres offset (coupled bending-torsion)."""
    n = 6
    half = np.array([2.0, 1.5])
    corners = [(-1, -1), (1, -1), (1, 1), (-1, 1)]

    def storey(lower: int | None, upper: int, kx: float, ky: float) -> np.ndarray:
        K = np.zeros((n, n))
        for cx, cy in corners:
            x, y = cx * half[0], cy * half[1]
            # column at (x, y): x-stiffness on u + (-y) theta, y-stiffness on v + x theta
            for k, row in ((kx, {0: 1.0, 2: -y}), (ky, {1: 1.0, 2: x})):
                t = np.zeros(n)
                for dof, a in row.items():
                    t[3 * upper + dof] += a
                    if lower is not None:
                        t[3 * lower + dof] -= a
                K += k * np.outer(t, t)
        return K

    def floor(j: int, m: float, ex: float, ey: float) -> np.ndarray:
        J = m * (4.0**2 + 3.0**2) / 12.0
        Mf = np.zeros((n, n))
        idx = [3 * j, 3 * j + 1, 3 * j + 2]
        Mf[np.ix_(idx, idx)] = [[m, 0.0, -m * ey], [0.0, m, m * ex],
                                [-m * ey, m * ex, J + m * (ex**2 + ey**2)]]
        return Mf

    return Structure(
        "3-D frame",
        {"m_floor_1": floor(0, 800.0, 0.3, 0.2), "m_floor_2": floor(1, 600.0, -0.25, 0.15)},
        {"k_columns_1": storey(None, 0, 2.0e6, 1.5e6), "k_columns_2": storey(0, 1, 1.5e6, 1.2e6)},
        {"Fx2": _unit(n, (3, 1.0)), "Fy2": _unit(n, (4, 1.0))},
        {"ax1": (_unit(n, (0, 1.0), (2, -1.5)), "acceleration"),
         "ay1": (_unit(n, (1, 1.0), (2, 2.0)), "acceleration"),
         "ax2": (_unit(n, (3, 1.0)), "acceleration"),
         "ay2": (_unit(n, (4, 1.0), (5, 2.0)), "acceleration")},
        zeta=0.02,
        meanings={"k_columns_1": "column stiffness, storey 1", "k_columns_2": "column stiffness, storey 2",
                  "m_floor_1": "floor 1 mass", "m_floor_2": "floor 2 mass"},
    )


def plate_grid() -> Structure:
    """A 12-DOF plate-like grid: 3 x 4 masses moving out of plane, springs to the neighbours
    (shear-plate abstraction) and to ground at the four corners."""
    rows, cols = 3, 4
    n = rows * cols
    at = {(r, c): r * cols + c for r in range(rows) for c in range(cols)}
    K_plate = np.zeros((n, n))
    for (r, c), i in at.items():
        if c + 1 < cols:
            K_plate += _spring(n, i, at[(r, c + 1)], 4.0e4)
        if r + 1 < rows:
            K_plate += _spring(n, i, at[(r + 1, c)], 5.0e4)
    K_support = sum(_spring(n, at[rc_], None, 2.0e4) for rc_ in ((0, 0), (0, cols - 1), (rows - 1, 0),
                                                                  (rows - 1, cols - 1)))
    m = np.full(n, 2.0)
    m[at[(1, 1)]] = m[at[(1, 2)]] = 3.0
    return Structure(
        "plate grid", {"m_plate": np.diag(m)}, {"k_plate": K_plate, "k_supports": K_support},
        {"F5": _unit(n, (at[(1, 1)], 1.0))},
        {"a1": (_unit(n, (at[(0, 0)], 1.0)), "acceleration"),
         "a5": (_unit(n, (at[(1, 1)], 1.0)), "acceleration"),
         "a8": (_unit(n, (at[(1, 3)], 1.0)), "acceleration"),
         "a11": (_unit(n, (at[(2, 2)], 1.0)), "acceleration")},
        zeta=0.015,
        meanings={"k_plate": "plate (neighbour) stiffness", "k_supports": "corner support stiffness",
                  "m_plate": "plate mass"},
    )


def hub_two_arms() -> Structure:
    """A hub (rotation, torsion spring to ground) with two three-mass arms: arm masses move
    tangentially, coupled to the hub rotation by their radius (a spacecraft-like layout)."""
    radius = 0.5
    n = 7  # hub rotation, arm A (3), arm B (3)
    J_hub = np.zeros((n, n))
    J_hub[0, 0] = 2.0
    M_arms = np.diag([0.0, 1.0, 0.8, 0.6, 1.0, 0.8, 0.5])
    K_arms = np.zeros((n, n))
    for first, k_arm in ((1, 3.0e3), (4, 2.5e3)):
        for j in range(3):
            t = np.zeros(n)
            t[first + j] = 1.0
            if j == 0:
                t[0] = -radius  # relative to the hub rim
            else:
                t[first + j - 1] = -1.0
            K_arms += k_arm * (1.0 - 0.2 * j) * np.outer(t, t)
    K_hub = _spring(n, 0, None, 5.0e2)
    return Structure(
        "hub with two arms", {"m_hub": J_hub, "m_arms": M_arms}, {"k_hub": K_hub, "k_arms": K_arms},
        {"T_hub": _unit(n, (0, 1.0))},
        {"hub_rate": (_unit(n, (0, 1.0)), "velocity"),
         "tipA": (_unit(n, (3, 1.0)), "acceleration"),
         "tipB": (_unit(n, (6, 1.0)), "acceleration")},
        zeta=0.01,
        meanings={"k_hub": "hub torsion spring", "k_arms": "arm bending stiffness",
                  "m_hub": "hub inertia", "m_arms": "arm masses"},
    )


def mast() -> Structure:
    """A 10-mass mast: a chain grounded at its base, stiffness tapering upwards, a tip mass."""
    n = 10
    K = np.zeros((n, n))
    for j in range(n):
        K += _spring(n, j, None if j == 0 else j - 1, 1.2e5 * (1.0 - 0.06 * j))
    m = np.full(n, 12.0)
    m[-1] = 20.0
    return Structure(
        "10-mass mast", {"m_mast": np.diag(m)}, {"k_mast": K}, {"F_tip": _unit(n, (n - 1, 1.0))},
        {"a3": (_unit(n, (2, 1.0)), "acceleration"), "a6": (_unit(n, (5, 1.0)), "acceleration"),
         "a10": (_unit(n, (9, 1.0)), "acceleration")},
        zeta=0.01, meanings={"k_mast": "mast stiffness", "m_mast": "mast masses"},
    )


def two_span_beam() -> Structure:
    """A two-span beam (pinned at both ends and at the middle support), eight lumped masses;
    Euler-Bernoulli stiffness ``EI / h^3 D2^T D2`` of the second difference with the supports
    as fixed nodes."""
    nodes = 11  # 0, 5, 10 are supports
    free = [j for j in range(nodes) if j not in (0, 5, 10)]
    n = len(free)
    h = 0.5
    D2 = np.zeros((nodes - 2, nodes))
    for j in range(1, nodes - 1):
        D2[j - 1, j - 1:j + 2] = [1.0, -2.0, 1.0]
    Kfull = 2.0e4 / h**3 * D2.T @ D2
    K = Kfull[np.ix_(free, free)]
    left = [k for k, j in enumerate(free) if j < 5]
    K_left = np.zeros_like(K)
    K_left[np.ix_(left, left)] = K[np.ix_(left, left)]
    m = np.full(n, 4.0)
    return Structure(
        "two-span beam", {"m_beam": np.diag(m)}, {"k_span_left": K_left, "k_span_right": K - K_left},
        {"F2": _unit(n, (1, 1.0))},
        {"a2": (_unit(n, (1, 1.0)), "acceleration"), "a4": (_unit(n, (3, 1.0)), "acceleration"),
         "a7": (_unit(n, (6, 1.0)), "acceleration")},
        zeta=0.02,
        meanings={"k_span_left": "bending stiffness, left span (coupled rows)",
                  "k_span_right": "bending stiffness, right span", "m_beam": "beam masses"},
    )


STRUCTURES: dict[str, Callable[[], Structure]] = {
    "frame": frame_3d, "grid": plate_grid, "hub": hub_two_arms, "mast": mast, "beam": two_span_beam,
}


# ---------------------------------------------------------------------------- measurement
class LabCase(NamedTuple):
    truth: Any
    data: rc.FrequencyData
    description: dict


def _band_lines(f: np.ndarray, band: tuple[float, float]) -> np.ndarray:
    return (f >= band[0]) & (f <= band[1])


def measure(
    structure: Structure,
    *,
    input_kind: str = "measured",
    excitation: str = "random",
    fs: float = 200.0,
    nperseg: int = 1024,
    n_averages: int = 64,
    force_band: tuple[float, float] | None = None,
    noise: float = 0.01,
    seed: int = 0,
    scales: Mapping[str, float] | None = None,
    modify: Callable | None = None,
    transform: Callable | None = None,
    inputs: list[str] | None = None,
) -> rc.FrequencyData:
    """One experiment per input (joined by ``rc.combine_experiments``) with white sensor noise
    ``noise`` x each output's RMS; H1 by ``rc.estimate_frf`` told how the data were made.

    Random excitation: Gaussian lines over a record of ``n_averages * nperseg / 2 + nperseg / 2``
    samples (50 % overlap). Periodic: a random-phase multisine with period ``nperseg`` repeated
    ``n_averages`` times, rectangular window, no overlap (whole periods per segment).
    ``force_band`` (Hz): where the input has power (default 0.2 Hz to 0.45 fs for a measured
    force, the whole band for a held command).
    """
    rng = np.random.default_rng(seed)
    names = list(structure.inputs) if inputs is None else list(inputs)
    if excitation == "random":
        n_total = n_averages * nperseg // 2 + nperseg // 2
    elif excitation == "periodic":
        n_total = n_averages * nperseg
    else:
        raise ValueError(f"measure makes random or periodic excitation; got {excitation!r}")
    f = np.fft.rfftfreq(n_total, 1.0 / fs)
    if excitation == "periodic":  # every line of the segment's FFT up to Nyquist carries power
        lo, hi = force_band or (0.0, fs / 2)
    else:
        lo, hi = force_band or ((0.2, 0.45 * fs) if input_kind == "measured" else (0.0, fs / 2))
    lines = _band_lines(f, (max(lo, 1e-12), hi)) & (f > 0)
    if excitation == "periodic":
        lines &= (np.arange(f.size) % n_averages) == 0  # period nperseg: every n_averages-th line
    fl = f[lines]
    if input_kind == "measured":
        G = structure.frf(fl, scales, modify)
    else:
        G = structure.held_frf(fl, fs, scales, modify)
    if transform is not None:
        G = transform(fl, G)
    out_names = list(structure.outputs)
    all_inputs = list(structure.inputs)
    exps = []
    for name in names:
        col = all_inputs.index(name)
        U = np.zeros(f.size, complex)
        if excitation == "random":
            U[lines] = rng.standard_normal(lines.sum()) + 1j * rng.standard_normal(lines.sum())
        else:
            U[lines] = np.exp(2j * np.pi * rng.random(lines.sum()))
        Y = np.zeros((f.size, len(out_names)), complex)
        Y[lines] = G[:, :, col] * U[lines, None]
        u = np.fft.irfft(U, n_total)
        y = np.fft.irfft(Y, n_total, axis=0)
        y = y + noise * np.std(y, axis=0) * rng.standard_normal(y.shape)
        if excitation == "random":
            d = rc.estimate_frf(u, y, fs, nperseg=nperseg, inputs=[name], outputs=out_names,
                                input_kind=input_kind, excitation="random")
        else:
            d = rc.estimate_frf(u, y, fs, nperseg=nperseg, noverlap=0, window="boxcar", inputs=[name],
                                outputs=out_names, input_kind=input_kind, excitation="periodic",
                                period=nperseg)
        exps.append(d)
    return exps[0] if len(exps) == 1 else rc.combine_experiments(exps)


def impact_test(
    structure: Structure,
    *,
    fs: float = 256.0,
    n_samples: int = 4096,
    n_hits: int = 8,
    pulse_s: float = 0.004,
    noise: float = 0.003,
    seed: int = 0,
    scales=None,
    modify=None,
    transform=None,
    input_name: str | None = None,
) -> rc.FrequencyData:
    """Hammer hits on one input: a half-sine pulse of ``pulse_s`` seconds (its analytic
    spectrum, band-limited below 0.45 fs), each record the exact steady state of the hit
    repeated every record (the response has decayed: ``n_samples / fs`` long records), white
    noise on force and responses; ``rc.estimate_frf_impact`` without windows."""
    rng = np.random.default_rng(seed)
    name = input_name or next(iter(structure.inputs))
    col = list(structure.inputs).index(name)
    f = np.fft.rfftfreq(n_samples, 1.0 / fs)
    lines = (f > 0) & (f < 0.45 * fs)
    G = structure.frf(f[lines], scales, modify)
    if transform is not None:
        G = transform(f[lines], G)
    w = 2 * np.pi * f[lines]
    a = np.pi / pulse_s  # half-sine sin(a t), 0 <= t <= pulse_s: its Fourier transform
    spectrum = a * (1.0 + np.exp(-1j * w * pulse_s)) / (a**2 - w**2 + 0j)
    forces, responses = [], []
    level = None  # instrument noise: the same level in every hit (set by the first, nominal hit)
    for _ in range(n_hits):
        amp = 100.0 * (1.0 + 0.2 * rng.standard_normal())
        start = 8 + int(rng.integers(0, 4))
        U = np.zeros(f.size, complex)
        U[lines] = amp * fs * spectrum * np.exp(-1j * w * start / fs)
        Y = np.zeros((f.size, G.shape[1]), complex)
        Y[lines] = G[:, :, col] * U[lines, None]
        u = np.fft.irfft(U, n_samples)
        y = np.fft.irfft(Y, n_samples, axis=0)
        if level is None:
            level = (noise * 0.01 * np.max(np.abs(u)), noise * np.std(y, axis=0))
        u = u + level[0] * rng.standard_normal(u.shape)
        y = y + level[1] * rng.standard_normal(y.shape)
        forces.append(u)
        responses.append(y)
    return rc.estimate_frf_impact(np.array(forces), np.array(responses), fs, exp_window=None,
                                  force_window=None, inputs=[name], outputs=list(structure.outputs))


# ---------------------------------------------------------------------------- the cases
def _case(key: str, kind: str, excitation: str, band: tuple[float, float], **kw: Any):
    def make(seed: int = 0, **more: Any) -> LabCase:
        st = STRUCTURES[key]()
        opts = {**kw, **more}
        if excitation == "impact":
            data = impact_test(st, seed=seed, **opts)
        else:
            data = measure(st, input_kind=kind, excitation=excitation, seed=seed, **opts)
        truth = st.model(f"{st.name} (truth)").with_values(**dict(opts.get("scales") or {}))
        return LabCase(truth, data, {
            "structure": st.name, "key": key, "input_kind": kind, "excitation": excitation,
            "band": band, "seed": seed,
        })
    return make


#: name -> ``make(seed=0, **measure options) -> LabCase``; ``band`` (Hz) in the description is
#: where the case is judged (inside the force band, modes included).
CASES: dict[str, Callable[..., LabCase]] = {
    "frame_measured_random": _case("frame", "measured", "random", (1.0, 60.0), fs=200.0, nperseg=1024),
    "frame_held_random": _case("frame", "held", "random", (1.0, 60.0), fs=200.0, nperseg=1024),
    "grid_measured_periodic": _case("grid", "measured", "periodic", (2.0, 60.0), fs=200.0, nperseg=1024),
    "hub_held_random": _case("hub", "held", "random", (0.5, 40.0), fs=100.0, nperseg=1024),
    "mast_measured_random": _case("mast", "measured", "random", (1.0, 40.0), fs=100.0, nperseg=1024),
    "beam_held_periodic": _case("beam", "held", "periodic", (2.0, 90.0), fs=200.0, nperseg=512),
    "beam_measured_random": _case("beam", "measured", "random", (2.0, 80.0), fs=200.0, nperseg=1024),
    "grid_impact": _case("grid", "measured", "impact", (2.0, 60.0)),
}


def case(name: str, seed: int = 0, **options: Any) -> LabCase:
    """``CASES[name](seed, **options)``."""
    return CASES[name](seed, **options)
