"""LQG design from process and sensor noise intensities: ``rc.lqg(sys, Q, R, W, V, ...)``.

The MACE procedure (Glaese & Miller's controllers were LQG designs on the
disturbance-to-performance and disturbance-to-sensor transfer functions): the named plant's
inputs are split into control inputs ``u`` and disturbance inputs ``d`` (where process
noise of intensity ``W`` enters), its outputs into measurements ``y`` (with sensor noise of
intensity ``V``) and performance outputs ``p`` (weighted by ``Q``); the controller
minimises ``E[p^T Q p + u^T R u]`` in steady state.

The design is the H2 problem on the partitioned plant (Zhou, Doyle & Glover 1996, ch. 14:
LQG as a special H2 problem)::

    w = [W^(1/2) d-noise; V^(1/2) sensor noise],  z = [Q^(1/2) p; R^(1/2) u],
    P = [[A, B_d W^(1/2), 0, B_u], [Q^(1/2) C_p, Q^(1/2) D_pd W^(1/2), 0, Q^(1/2) D_pu],
         [0, 0, 0, R^(1/2)], [C_y, D_yd W^(1/2), V^(1/2), D_yu]]

solved by :func:`robustctl.robust.h2.synthesis.h2syn`, so that ``cost = ||Fl(P, K)||_2^2`` is verified on
the closed loop. Without named disturbances, ``W`` is the intensity of a noise on every
state (``dx = A x + B_u u + w_x``); without named performance outputs, ``Q`` weights the
states. The gains are those of the separate LQR and Kalman filter (certainty equivalence):
continuous ``u = -K_r x_hat``, ``K_r = R^-1 (B_u^T X + N^T)``; discrete: the current
estimator ``x(k|k)``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import control
import numpy as np

from ...checks import real_array
from ...errors import SynthesisError
from ...interconnect import PartitionedPlant, PicklesStateSpaces
from ...lti import as_statespace
from ...table import Table, result_html
from ..partitioned import as_partitioned
from .synthesis import H2Result, _plot_closed_loop, h2syn

__all__ = ["LQGResult", "lqg"]


@dataclass(frozen=True)
class LQGResult(PicklesStateSpaces):
    """An LQG controller and its verified closed loop.

    Attributes
    ----------
    K : control.StateSpace
        The controller ``u = +K y``, robustctl's one loop sign (:mod:`robustctl.robust.conventions`;
        positive feedback, so ``K`` is the negative of the textbook observer-based controller
        ``u = -K_r x_hat``, ``x_hat' = (A - B K_r - L C) x_hat + L y``, that MATLAB's ``lqg``
        returns for ``u = -K y``). Inputs: the plant's measurement names; outputs: its control
        names; the plant's time base.
    cost : float
        ``E[p^T Q p + u^T R u]`` in steady state (= ``||Fl(P, K)||_2^2``, verified on the closed loop).
    lqr_gain : ndarray
        ``K_r`` of the state feedback ``u = -K_r x`` (ncon x n).
    kalman_gain : ndarray
        Continuous: ``L`` of ``dx_hat = A x_hat + B u + L (y - C x_hat - D u)`` (n x nmeas);
        discrete: the filtered-state gain ``x(k|k) = x(k|k-1) + L e(k)``.
    plant : PartitionedPlant
        The H2 problem solved (noise and weights built in).
    closed_loop : control.StateSpace
        ``Fl(P, K)``: unit noises -> weighted performance and control.
    h2 : H2Result
        The underlying H2 design (Riccati solutions X, Y).
    info : dict
        ``controls``, ``measurements``, ``disturbances``, ``performance`` (names), ``discrete``.
    """

    K: Any
    cost: float
    lqr_gain: np.ndarray
    kalman_gain: np.ndarray
    plant: Any
    closed_loop: Any
    h2: H2Result
    info: dict = field(default_factory=dict)

    def table(self) -> Table:
        """Key numbers of the design."""
        i = self.info
        rows = [
            ("cost E[p'Qp + u'Ru]", self.cost),
            ("controller order", self.K.nstates),
            ("controls", ", ".join(i.get("controls", []))),
            ("measurements", ", ".join(i.get("measurements", []))),
            ("process noise on", ", ".join(i.get("disturbances", [])) or "states"),
            ("performance", ", ".join(i.get("performance", [])) or "states"),
            ("closed loop stable", True),
        ]
        return Table(("quantity", "value"), rows, title="LQG design", digits=8)

    def summary(self) -> str:
        """A few sentences in plain words."""
        i = self.info
        base = "discrete-time" if i.get("discrete") else "continuous-time"
        return (
            f"LQG {base} controller of order {self.K.nstates} from {len(i.get('measurements', []))} "
            f"measurement(s) to {len(i.get('controls', []))} control input(s), closed as u = +K y "
            "(positive feedback; the textbook u = -K_r x_hat controller is -K).\n"
            f"Steady-state cost E[p'Qp + u'Ru] = {self.cost:.8g} (verified as the closed loop's "
            "squared H2 norm)."
        )

    def plot(self, f_hz: Any = None, fig: Any = None) -> Any:
        """Singular values of the closed loop noise -> weighted outputs over frequency (Hz)."""
        title = "LQG closed loop (unit noises -> weighted outputs)"
        return _plot_closed_loop(self.closed_loop, f_hz, fig, title)

    def _repr_html_(self) -> str:
        return result_html(self.summary(), self.table())

    def __repr__(self) -> str:
        return f"LQGResult(cost={self.cost:.8g}, order={self.K.nstates})"


def _names(value: Any, known: Sequence[str], what: str) -> list[str]:
    if value is None:
        return []
    if isinstance(value, str):
        value = [value]
    try:
        out = [str(v) for v in value]
    except TypeError as exc:
        raise SynthesisError(f"{what} must be a list of signal names; got {value!r}.") from exc
    for v in out:
        if v not in known:
            raise SynthesisError(f"{what}: {v!r} is not a signal of the plant; its signals: {list(known)}.")
    if len(set(out)) != len(out):
        raise SynthesisError(f"{what} names a signal twice: {out}.")
    return out


def _matrix(value: Any, size: int, what: str, definite: bool) -> np.ndarray:
    """A symmetric PSD (PD with ``definite``) ``size x size`` weight; a scalar or vector means diagonal."""
    M = real_array(value, what, SynthesisError)
    if M.ndim == 0:
        M = M * np.eye(size)
    elif M.ndim == 1:
        M = np.diag(M)
    if M.shape != (size, size):
        raise SynthesisError(
            f"{what} must be a {size}x{size} matrix (or a scalar / diagonal); got shape {M.shape}."
        )
    if not np.allclose(M, M.T, rtol=1e-10, atol=1e-14 * max(1.0, float(np.abs(M).max()))):
        raise SynthesisError(f"{what} must be symmetric.")
    M = (M + M.T) / 2
    ev = np.linalg.eigvalsh(M) if size else np.zeros(0)
    tol = 1e-12 * max(1.0, float(np.abs(ev).max()) if size else 1.0)
    if size and (ev.min() <= tol if definite else ev.min() < -tol):
        kind = "positive definite" if definite else "positive semidefinite"
        raise SynthesisError(f"{what} must be {kind}; its smallest eigenvalue is {ev.min():.3g}.")
    return M


def _sqrtm(M: np.ndarray) -> np.ndarray:
    ev, V = np.linalg.eigh(M)
    return (V * np.sqrt(np.clip(ev, 0.0, None))) @ V.T


def lqg(
    sys: Any,
    Q: Any,
    R: Any,
    W: Any,
    V: Any,
    *,
    controls: Sequence[str] | None = None,
    measurements: Sequence[str] | None = None,
    disturbances: Sequence[str] | None = None,
    performance: Sequence[str] | None = None,
) -> LQGResult:
    """LQG controller from weights and noise intensities, on a plant with named signals.

    Parameters
    ----------
    sys : control.StateSpace, PhysicalModel, PartitionedPlant, ...
        The plant (continuous, or discrete with ``dt``), inputs ``[d..., u...]`` and outputs
        ``[p..., y...]`` in any order, told apart by name. A partitioned plant
        (``rc.as_partitioned``, ``rc.sampled_plant``, a GeneralizedPlant) brings its own
        partition: by default its ``w`` are the disturbances, ``u`` the controls, ``z`` the
        performance outputs and ``y`` the measurements.
    Q : array_like
        Weight on the performance outputs (``len(performance)`` square) or, without
        ``performance``, on the states (n x n); symmetric positive semidefinite (a scalar or a
        vector means a diagonal).
    R : array_like
        Weight on the control inputs (ncon square), positive definite.
    W : array_like
        Intensity (continuous: PSD in units^2/Hz two-sided, ``E[w(t) w(s)^T] = W delta(t-s)``;
        discrete: covariance per sample) of the process noise on the ``disturbances`` inputs
        or, without them, on every state; positive semidefinite.
    V : array_like
        Intensity of the sensor noise on the measurements (nmeas square), positive definite.
    controls, measurements : list of str, optional
        Input and output names the controller uses (default: every input not in
        ``disturbances``, every output not in ``performance``).
    disturbances, performance : list of str, optional
        Inputs where process noise enters and outputs that are weighted by ``Q``.

    Returns
    -------
    LQGResult
        ``K`` (named measurement -> control), ``cost``, the LQR and Kalman gains, the H2
        problem and its verified closed loop.

    Raises
    ------
    SynthesisError
        Unknown or repeated names, weights of the wrong shape or not (semi)definite, a
        continuous plant with a direct path from the noise to the performance outputs
        (infinite cost), or a plant that is not stabilisable/detectable (named as in h2syn).

    See Also
    --------
    h2syn, h2norm

    References
    ----------
    Zhou, Doyle & Glover (1996), Robust and Optimal Control, ch. 14 (LQG as an H2 problem).
    Glaese & Miller, "Derivation of 0-g structural control models from analysis and 1-g
    experimentation" (the MACE LQG designs).
    """
    if isinstance(sys, PartitionedPlant):
        plant = as_partitioned(sys, who="lqg")
        G = plant.P
        controls = list(plant.u_names) if controls is None else controls
        measurements = list(plant.y_names) if measurements is None else measurements
        disturbances = list(plant.w_names) if disturbances is None else disturbances
        performance = list(plant.z_names) if performance is None else performance
    else:
        G = as_statespace(sys, name="sys")
    ins, outs = list(G.input_labels), list(G.output_labels)
    dist = _names(disturbances, ins, "disturbances")
    perf = _names(performance, outs, "performance")
    ctrl = _names(controls, ins, "controls") if controls is not None else [i for i in ins if i not in dist]
    meas = _names(measurements, outs, "measurements") if measurements is not None else [
        o for o in outs if o not in perf
    ]
    if set(ctrl) & set(dist) or set(meas) & set(perf):
        raise SynthesisError(
            "a signal cannot be both a control and a disturbance (or a measurement and a performance output)."
        )
    if not ctrl or not meas:
        raise SynthesisError(
            "lqg needs at least one control input and one measurement; name them with controls= and "
            "measurements=."
        )
    A, B, C, D = (np.asarray(m, dtype=float) for m in (G.A, G.B, G.C, G.D))
    n = A.shape[0]
    iu = [ins.index(c) for c in ctrl]
    iy = [outs.index(c) for c in meas]
    if dist:
        idd = [ins.index(c) for c in dist]
        Bd, Dyd = B[:, idd], D[np.ix_(iy, idd)]
    else:
        Bd, Dyd = np.eye(n), np.zeros((len(iy), n))
    if perf:
        ip = [outs.index(c) for c in perf]
        Cp, Dpu = C[ip], D[np.ix_(ip, iu)]
        Dpd = D[np.ix_(ip, idd)] if dist else np.zeros((len(ip), n))
    else:
        Cp, Dpu, Dpd = np.eye(n), np.zeros((n, len(iu))), np.zeros((n, Bd.shape[1]))
    Qm = _matrix(Q, Cp.shape[0], "Q (performance weight)" if perf else "Q (state weight)", definite=False)
    Rm = _matrix(R, len(iu), "R (control weight)", definite=True)
    Wm = _matrix(W, Bd.shape[1], "W (process noise intensity)", definite=False)
    Vm = _matrix(V, len(iy), "V (sensor noise intensity)", definite=True)
    q, r, w, v = _sqrtm(Qm), _sqrtm(Rm), _sqrtm(Wm), _sqrtm(Vm)
    nd, nv, nu, npf = Bd.shape[1], len(iy), len(iu), Cp.shape[0]
    Bu, Cy, Dyu = B[:, iu], C[iy], D[np.ix_(iy, iu)]
    PA = A
    PB = np.hstack([Bd @ w, np.zeros((n, nv)), Bu])
    PC = np.vstack([q @ Cp, np.zeros((nu, n)), Cy])
    PD = np.block([
        [q @ Dpd @ w, np.zeros((npf, nv)), q @ Dpu],
        [np.zeros((nu, nd + nv)), r],
        [Dyd @ w, v, Dyu],
    ])
    w_names = [f"noise {d}" for d in dist] if dist else [f"process noise {s}" for s in G.state_labels]
    w_names += [f"noise {y}" for y in meas]
    z_names = [f"Q^1/2 {p}" for p in perf] if perf else [f"Q^1/2 {s}" for s in G.state_labels]
    z_names += [f"R^1/2 {u}" for u in ctrl]
    Pss = control.ss(PA, PB, PC, PD, G.dt, inputs=w_names + ctrl, outputs=z_names + meas,
                     states=list(G.state_labels), name="LQG plant")
    plant = PartitionedPlant(Pss, len(meas), len(ctrl))
    discrete = G.dt not in (0, None)
    if not discrete and np.any(q @ Dpd @ w):
        raise SynthesisError(
            "lqg: the process noise reaches the weighted performance outputs directly (D from "
            "disturbances to performance is nonzero), so the continuous-time cost is infinite. Fix: "
            "weight outputs without direct feedthrough, or design in discrete time."
        )
    try:
        res = h2syn(plant)
    except SynthesisError as exc:
        raise SynthesisError(
            f"lqg: {exc} (In LQG terms: every unstable or undamped mode must be moved by the controls "
            "and seen by the measurements, and excited by the process noise or weighted by Q.)"
        ) from exc
    info = {
        "controls": ctrl, "measurements": meas, "disturbances": dist, "performance": perf,
        "discrete": discrete,
    }
    L = -res.L if not discrete else res.L
    return LQGResult(
        K=res.K, cost=float(res.norm**2), lqr_gain=-res.F, kalman_gain=L, plant=plant,
        closed_loop=res.closed_loop, h2=res, info=info,
    )
