"""Glover-McFarlane loop shaping: ``rc.ncfsyn(G, W1, W2)`` -> :class:`LoopShapingResult`.

The plant is shaped, ``Gs = W2 G W1`` (W1 at the inputs: integral action, roll-off; W2 at the
outputs: sensor weights), and the shaped plant's normalized-coprime-factor stability margin
is maximised (McFarlane & Glover 1990, "Robust Controller Design Using Normalized Coprime
Factor Plant Descriptions"; Zhou, Doyle & Glover 1996, ch. 18 "H-infinity loop shaping"):

* ``b_opt = 1 / gamma_min = sqrt(1 - ||[Nt, Mt]||_H^2) = (1 + lambda_max(X Z))^-1/2`` with the
  Riccati solutions ``X``, ``Z`` of :func:`robustctl.robust.analysis.coprime.ncf_riccati` (Glover &
  McFarlane 1989, "Robust stabilization of normalized coprime factor plant descriptions with
  H-infinity-bounded uncertainty", IEEE TAC 34(8), 821-830);
* the central controller at ``gamma = factor gamma_min`` (``factor > 1``; MATLAB's default
  1.1), for ``Gs = (A, B, C, D)``, ``S = I + D^T D``, ``F = -S^-1 (D^T C + B^T X)``,
  ``L = (1 - gamma^2) I + X Z``::

      Ks = [A + B F + gamma^2 L^-T Z C^T (C + D F),  gamma^2 L^-T Z C^T;
            B^T X,                                   -D^T]

  (the central controller of McFarlane & Glover 1990 with a feedthrough ``D``; ZDG ch. 18;
  positive feedback ``u = Ks y``), which
  achieves ``b(Gs, Ks) >= 1 / gamma``;
* the controller for ``G`` is ``K = W1 Ks W2``, in the loop's named signals (inputs: the
  plant's outputs, outputs: its inputs), with ``u = K y``.

The achieved margin ``b(Gs, Ks) = 1 / ||[I; Ks] (I - Gs Ks)^-1 [I, Gs]||_inf`` is computed on
the closed loop (:func:`hinfnorm`), whose internal stability is checked.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import control
import numpy as np

from ...checks import positive_number
from ...errors import ModelError, SynthesisError
from ...interconnect import PartitionedPlant, PicklesStateSpaces
from ...lti import as_statespace, freqresp_array, is_stable, roundoff_margin
from ...plots import label_axes, single_axes
from ...table import Table, result_html
from ..continuous_equivalent import d2c
from ..h2.synthesis import default_grid_hz
from ..hinf.norm import hinfnorm_matrices
from ..hinf.synthesis import lower_lft_matrices
from ..mu.bounds import frequencies_hz
from ..partitioned import as_partitioned
from .coprime import ncf_riccati

__all__ = ["LoopShapingResult", "ncfsyn", "stability_margin"]


@dataclass(frozen=True)
class LoopShapingResult(PicklesStateSpaces):
    """A Glover-McFarlane loop-shaping design.

    Attributes
    ----------
    K : control.StateSpace
        The controller for ``G`` (``u = K y``, positive feedback): ``W1 Ks W2``, inputs named
        like ``G``'s outputs, outputs like its inputs.
    Ks : control.StateSpace
        The controller of the shaped plant.
    shaped : control.StateSpace
        ``Gs = W2 G W1``.
    b_opt : float
        The optimal margin ``1 / gamma_min`` of the shaped plant.
    b_achieved : float
        ``b(Gs, Ks)`` computed on the closed loop (between ``1 / gamma`` and ``b_opt``).
    gamma : float
        The gamma designed at (``factor gamma_min``).
    plant : control.StateSpace
        The plant ``G`` as given.
    info : dict
        ``gamma_min``, ``factor``, ``hankel_norm`` (``||[Nt, Mt]||_H``), ``closed_loop_max_real_pole``.
    """

    K: Any
    Ks: Any
    shaped: Any
    b_opt: float
    b_achieved: float
    gamma: float
    plant: Any = None
    info: dict = field(default_factory=dict)

    def table(self) -> Table:
        """Key numbers of the design."""
        i = self.info
        rows = [
            ("optimal margin b_opt = 1/gamma_min", self.b_opt),
            ("achieved margin b(Gs, Ks)", self.b_achieved),
            ("gamma (designed at)", self.gamma),
            ("gamma_min", i.get("gamma_min", np.nan)),
            ("Hankel norm ||[Nt, Mt]||_H", i.get("hankel_norm", np.nan)),
            ("controller order", self.K.nstates),
            ("slowest closed-loop pole Re (rad/s)", i.get("closed_loop_max_real_pole", np.nan)),
        ]
        return Table(("quantity", "value"), rows, title="Loop-shaping design (ncfsyn)", digits=8)

    def summary(self) -> str:
        """A few sentences in plain words."""
        return (
            f"Glover-McFarlane controller of order {self.K.nstates}: achieved stability margin "
            f"b = {self.b_achieved:.6g} (optimum {self.b_opt:.6g}, designed at gamma = {self.gamma:.6g}).\n"
            "The loop stays stable for any perturbation of the shaped plant's normalized coprime "
            f"factors of H-infinity size below {self.b_achieved:.4g} (and any plant within that nu-gap)."
        )

    def plot(self, f_hz: Any = None, fig: Any = None) -> Any:
        """Singular values of the shaped loop ``Gs`` and of the achieved loop ``-G K`` (Hz)."""
        f = default_grid_hz(self.shaped) if f_hz is None else frequencies_hz(f_hz)
        G = self.plant
        fig, ax = single_axes(fig, 7.0, 4.0)
        ax.loglog(f, np.linalg.svd(freqresp_array(self.shaped, f), compute_uv=False), "C0", lw=1)
        L = freqresp_array(G, f) @ freqresp_array(self.K, f)
        ax.loglog(f, np.linalg.svd(L, compute_uv=False), "C3--", lw=1)
        ax.plot([], [], "C0", label="shaped plant W2 G W1")
        ax.plot([], [], "C3--", label="loop G K")
        label_axes(ax, "frequency (Hz)", "singular values", f"Loop shaping, b = {self.b_achieved:.3g}")
        return fig

    def _repr_html_(self) -> str:
        return result_html(self.summary(), self.table())


def _four_block(A, B, C, D, Ak, Bk, Ck, Dk) -> tuple[float, float]:
    """``(1 / ||[I; K](I - G K)^-1 [I, G]||_inf, max Re of the closed-loop poles)``; 0 if unstable."""
    n = A.shape[0]
    p, m = D.shape
    # inputs [d1 (at y), d2 (at u), u], outputs [y; u; y] with y = d1 + G (u + d2)
    m_ = {
        "A": A, "B1": np.hstack([np.zeros((n, p)), B]), "B2": B,
        "C1": np.vstack([C, np.zeros((m, n))]), "C2": C,
        "D11": np.block([[np.eye(p), D], [np.zeros((m, p + m))]]), "D12": np.vstack([D, np.eye(m)]),
        "D21": np.hstack([np.eye(p), D]), "D22": D,
    }
    Acl, Bcl, Ccl, Dcl = lower_lft_matrices(m_, Ak, Bk, Ck, Dk)
    max_re = float(np.max(np.linalg.eigvals(Acl).real)) if Acl.size else -np.inf
    if not is_stable(Acl, roundoff_margin(Acl)):
        return 0.0, max_re
    g, _ = hinfnorm_matrices(Acl, Bcl, Ccl, Dcl, 1e-9)
    return 1.0 / g, max_re


def stability_margin(G: Any, K: Any) -> float:
    """The normalized-coprime-factor stability margin ``b(G, K)`` of the loop ``u = K y``.

    ``b(G, K) = 1 / ||[I; K] (I - G K)^-1 [I, G]||_inf`` (0 when the loop is not internally
    stable; Vinnicombe 2001, ch. 2; McFarlane & Glover 1990); continuous time.

    Parameters
    ----------
    G, K : system
        Plant (p x m) and controller (m x p), positive feedback ``u = K y``.

    Returns
    -------
    float
        In [0, 1].
    """
    Gs, Ks = as_statespace(G, name="G"), as_statespace(K, name="K")
    if (Ks.ninputs, Ks.noutputs) != (Gs.noutputs, Gs.ninputs):
        raise SynthesisError(f"K must map G's {Gs.noutputs} outputs to its {Gs.ninputs} inputs.")
    mats = [np.asarray(x, dtype=float) for x in (Gs.A, Gs.B, Gs.C, Gs.D, Ks.A, Ks.B, Ks.C, Ks.D)]
    return _four_block(*mats)[0]


def _weight(W: Any, size: int, what: str):
    """A weight as a state space: None is the identity, a number or matrix a static gain."""
    if W is None:
        W = np.eye(size)
    if isinstance(W, (int, float, np.number, np.ndarray, list, tuple)):
        M = np.asarray(W, dtype=float)
        M = M * np.eye(size) if M.ndim == 0 else M
        if M.ndim != 2 or not np.all(np.isfinite(M)):
            raise SynthesisError(f"{what} must be a system, a number or a {size}x{size} matrix; got {W!r}.")
        return control.ss([], [], [], M)
    return as_statespace(W, name=what)


def ncfsyn(G: Any, W1: Any = None, W2: Any = None, *, factor: float = 1.1) -> LoopShapingResult:
    """Glover-McFarlane H-infinity loop-shaping controller.

    Parameters
    ----------
    G : system or PartitionedPlant
        The plant, p outputs x m inputs, named. Continuous, or sampled (``dt > 0`` s): a
        sampled plant is designed through the bilinear map (:func:`_ncfsyn_sampled`). A
        partitioned plant (``rc.as_partitioned``, a GeneralizedPlant) gives its ``u -> y``
        part ``P22``: the plant the controller sees.
    W1 : system or array_like, optional
        Input (pre-compensator) weight, m x m (default identity): integral action, roll-off.
        With a sampled ``G``: sampled at the same ``dt``, or a constant.
    W2 : system or array_like, optional
        Output weight, p x p (default identity); as ``W1``.
    factor : float
        ``gamma = factor gamma_min`` (>= 1 + 1e-9; default 1.1, MATLAB's). Close to 1 gives the
        largest margin and a worse-conditioned controller.

    Returns
    -------
    LoopShapingResult
        ``K`` (for ``G``, ``u = K y``), ``Ks``, ``b_opt``, ``b_achieved``, ``gamma``; for a
        sampled ``G`` the controllers and the shaped plant are sampled at its ``dt``.

    Raises
    ------
    SynthesisError
        A sampled plant with a pole at ``z = -1`` or weights of another sample time,
        weights of the wrong shape, a shaped plant that is not stabilisable
        and detectable, a factor below 1, or a closed loop that fails its check.

    References
    ----------
    McFarlane & Glover (1990), Robust Controller Design Using Normalized Coprime Factor Plant
    Descriptions, LNCIS 138. Glover & McFarlane (1989), IEEE TAC 34(8), 821-830.

    Examples
    --------
    >>> import control, robustctl as rc
    >>> res = rc.ncfsyn(control.tf([1.0], [1.0, 1.0]), factor=1.0 + 1e-7)
    >>> abs(res.b_achieved - res.b_opt) < 1e-6
    True
    """
    factor = positive_number(factor, "factor", SynthesisError)
    if factor < 1.0 + 1e-9:
        raise SynthesisError(f"factor must exceed 1 (gamma = factor gamma_min); got {factor!r}. Use 1.1.")
    if isinstance(G, PartitionedPlant):
        plant = as_partitioned(G, who="ncfsyn")
        Gss = plant.P[plant.nz:, plant.nw:]
    else:
        Gss = as_statespace(G, name="G")
    if Gss.dt not in (0, None):
        return _ncfsyn_sampled(Gss, W1, W2, factor)
    p, m = Gss.noutputs, Gss.ninputs
    W1s, W2s = _weight(W1, m, "W1"), _weight(W2, p, "W2")
    if (W1s.noutputs, W1s.ninputs) != (m, m) or (W2s.noutputs, W2s.ninputs) != (p, p):
        raise SynthesisError(
            f"W1 must be {m}x{m} (at G's inputs) and W2 {p}x{p} (at its outputs); got "
            f"{W1s.noutputs}x{W1s.ninputs} and {W2s.noutputs}x{W2s.ninputs}."
        )
    if W1s.dt not in (0, None) or W2s.dt not in (0, None):
        raise SynthesisError("the weights must be continuous-time systems.")
    Gplain = control.ss(Gss.A, Gss.B, Gss.C, Gss.D)
    Gs = W2s * Gplain * W1s
    A, B, C, D = (np.asarray(x, dtype=float) for x in (Gs.A, Gs.B, Gs.C, Gs.D))
    X, Z = ncf_riccati(A, B, C, D)
    lam = float(np.max(np.linalg.eigvals(X @ Z).real)) if A.size else 0.0
    gamma_min = float(np.sqrt(1.0 + max(lam, 0.0)))
    gamma = factor * gamma_min
    S = np.eye(m) + D.T @ D
    F = -np.linalg.solve(S, D.T @ C + B.T @ X)
    n = A.shape[0]
    Lm = (1.0 - gamma**2) * np.eye(n) + X @ Z
    try:
        LZC = gamma**2 * np.linalg.solve(Lm.T, Z @ C.T)
    except np.linalg.LinAlgError as exc:
        raise SynthesisError("ncfsyn: (1 - gamma^2) I + X Z is singular; raise factor.") from exc
    Ak = A + B @ F + LZC @ (C + D @ F)
    Bk, Ck, Dk = LZC, B.T @ X, -D.T
    b, max_re = _four_block(A, B, C, D, Ak, Bk, Ck, Dk)
    if not b > 0:
        raise SynthesisError(
            f"ncfsyn: the loop closed by the central controller is not stable (max Re(pole) {max_re:.3g}); "
            "raise factor."
        )
    if b < (1.0 / gamma) * (1 - 1e-6):
        raise SynthesisError(
            f"ncfsyn: the achieved margin {b:.6g} is below 1/gamma = {1 / gamma:.6g}: the Riccati solutions "
            "are ill-conditioned; raise factor or rescale the weights."
        )
    Ks = control.ss(Ak, Bk, Ck, Dk, name="Ks")
    Kfull = W1s * Ks * W2s
    K = control.ss(Kfull.A, Kfull.B, Kfull.C, Kfull.D, inputs=list(Gss.output_labels),
                   outputs=list(Gss.input_labels), states=[f"xK{i + 1}" for i in range(Kfull.nstates)],
                   name="K")
    info = {
        "gamma_min": gamma_min,
        "factor": factor,
        "hankel_norm": float(np.sqrt(max(lam, 0.0) / (1.0 + max(lam, 0.0)))),
        "closed_loop_max_real_pole": max_re,
    }
    return LoopShapingResult(K=K, Ks=Ks, shaped=Gs, b_opt=1.0 / gamma_min, b_achieved=b, gamma=gamma,
                             plant=Gss, info=info)


def _ncfsyn_sampled(Gd: Any, W1: Any, W2: Any, factor: float) -> LoopShapingResult:
    """:func:`ncfsyn` of a sampled plant through the bilinear (Tustin) map.

    ``s = (2/T)(z - 1)/(z + 1)`` maps the unit circle onto the imaginary axis and the unit
    disc onto the left half plane, so a sampled system and its Tustin original
    (:func:`~robustctl.robust.continuous_equivalent.d2c`, ``method="tustin"``) take the same
    values, frequency warped: stability, H-infinity norms and the normalisation of coprime
    factors are the same, hence ``b_opt``, ``gamma`` and the achieved margin of the loop are
    those of the continuous design (Zhou, Doyle & Glover 1996, sec. 21.3). The plant and its
    weights are mapped to continuous time, designed there, and the controllers and the
    shaped plant mapped back with ``control.c2d(method="tustin")``.
    """
    dt = Gd.dt
    if dt is True or not float(dt) > 0:
        raise SynthesisError(f"ncfsyn needs G's numeric sample time for a sampled plant; got dt={dt!r}.")
    dt = float(dt)

    def continuous(W: Any, what: str) -> Any:
        if W is None or isinstance(W, (int, float, np.number, np.ndarray, list, tuple)):
            return W
        Ws = as_statespace(W, name=what)
        if Ws.dt in (0, None) or Ws.dt is True or not np.isclose(float(Ws.dt), dt, rtol=1e-12, atol=0.0):
            raise SynthesisError(
                f"G is sampled (dt={dt:g} s) but {what} has dt={Ws.dt!r}: give {what} sampled at the same "
                f"rate (control.c2d({what}, {dt:g}, method='tustin')) or as a constant.")
        return _d2c(Ws, what)

    res = ncfsyn(_d2c(Gd, "G"), continuous(W1, "W1"), continuous(W2, "W2"), factor=factor)

    def sampled(S: Any) -> Any:
        Sd = control.c2d(S, dt, method="tustin")
        return control.ss(Sd.A, Sd.B, Sd.C, Sd.D, dt, inputs=list(S.input_labels),
                          outputs=list(S.output_labels), states=list(S.state_labels), name=S.name)

    return LoopShapingResult(K=sampled(res.K), Ks=sampled(res.Ks), shaped=sampled(res.shaped),
                             b_opt=res.b_opt, b_achieved=res.b_achieved, gamma=res.gamma, plant=Gd,
                             info={**res.info, "sampled": f"designed through the Tustin map at dt={dt:g} s"})


def _d2c(S: Any, what: str) -> Any:
    """``d2c(S, "tustin")`` with its refusal worded for ncfsyn."""
    try:
        return d2c(S, method="tustin")
    except ModelError as exc:
        raise SynthesisError(f"ncfsyn designs a sampled plant through the Tustin map; {what}: {exc}") from exc
