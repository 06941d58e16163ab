"""Controller order reduction that looks at the loop: frequency-weighted balanced truncation with
closed-loop weights (Enns) and coprime-factor reduction for unstable controllers.

* **Frequency-weighted balanced truncation** (Enns 1984, "Model reduction with balanced
  realizations: an error bound and a frequency weighted generalization", Proc. 23rd IEEE
  CDC; Zhou, Doyle & Glover 1996, ch. 7, frequency-weighted balanced model reduction):
  the controller's Gramians are taken from the cascades ``K Wi`` (controllability) and
  ``Wo K`` (observability), their ``(1, 1)`` blocks balanced and truncated (square-root
  method). With the closed-loop weight ``Wi = (I - G K)^-1 G`` (positive feedback ``u = K y``),
  the reduced controller ``Kr`` stabilises the plant whenever
  ``||(K - Kr) (I - G K)^-1 G||_inf < 1`` (small gain around ``K - Kr``; Anderson & Liu
  1989, "Controller reduction: concepts and approaches", IEEE TAC 34(8)); the weighted error
  is computed after the reduction (Enns' method has no a-priori bound) and reported. ``K``
  must be stable.
* **Coprime-factor reduction** (Liu, Anderson & Ly 1990; ZDG ch. 19 "controller order
  reduction"): ``K = Mt^-1 Nt`` with normalized left coprime factors
  (:func:`robustctl.robust.analysis.coprime.left_ncf`), the stable ``[Nt, Mt]`` balanced and
  truncated to ``[Ntr, Mtr]`` (a-priori bound ``||[Nt - Ntr, Mt - Mtr]||_inf <= 2 sum_{i>r}
  sigma_i``), ``Kr = Mtr^-1 Ntr``. It applies to unstable controllers; the loop stays stable
  when the factor error is below the loop's normalized-coprime-factor stability margin
  ``b(G, K)`` (McFarlane & Glover 1990; ``b(G, K) = b(K, G)``).

Every reduced controller is re-checked on the loop (internal stability) when the plant is given.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import control
import numpy as np
import scipy.linalg

from ...checks import integer
from ...errors import SynthesisError
from ...interconnect import PartitionedPlant, PicklesStateSpaces
from ...lti import as_statespace, is_stable, roundoff_margin
from ...plots import label_axes, single_axes
from ...table import Table, result_html
from ..analysis.coprime import left_ncf
from ..analysis.loop_shaping import stability_margin
from ..hinf.norm import hinfnorm_matrices

__all__ = [
    "ControllerReduction",
    "weighted_balanced_truncation",
    "coprime_reduction",
    "reduce_controller",
]

#: Hankel singular values below this fraction of the largest are numerically zero.
HSV_RTOL = 1e-12


@dataclass(frozen=True)
class ControllerReduction(PicklesStateSpaces):
    """A reduced controller and its error figures.

    Attributes
    ----------
    K : control.StateSpace
        The reduced controller (same names and time base as the original).
    method : str
        ``"weighted"`` (frequency-weighted balanced truncation) or ``"coprime"``.
    order_before, order_after : int
    hsv : ndarray
        The (weighted, or coprime-factor) Hankel singular values of the full controller.
    error : float
        The achieved error: ``||Wo (K - Kr) Wi||_inf`` (weighted) or ``||[Nt - Ntr, Mt - Mtr]||_inf``
        (coprime), computed after the reduction.
    bound : float
        The a-priori bound ``2 sum_{i > r} sigma_i`` (coprime; NaN for Enns' weighted method,
        which has none).
    stability_radius : float
        Error below which the reduced loop is guaranteed stable: 1 for the closed-loop weight
        (small gain), ``b(G, K)`` for the coprime factors; NaN without a plant.
    closed_loop_stable : bool or None
        The reduced loop checked directly (None without a plant).
    info : dict
    """

    K: Any
    method: str
    order_before: int
    order_after: int
    hsv: np.ndarray
    error: float
    bound: float
    stability_radius: float
    closed_loop_stable: bool | None
    info: dict = field(default_factory=dict)

    @property
    def guaranteed(self) -> bool:
        """True when the achieved error is below the stability radius (stability certified a priori)."""
        return bool(np.isfinite(self.stability_radius) and self.error < self.stability_radius)

    def table(self) -> Table:
        """Key numbers of the reduction."""
        rows = [
            ("method", self.method),
            ("order", f"{self.order_before} -> {self.order_after}"),
            ("achieved error", self.error),
            ("a-priori bound 2 sum sigma_tail", self.bound),
            ("stability radius", self.stability_radius),
            ("stability guaranteed by error < radius", self.guaranteed),
            ("reduced loop stable (checked)", self.closed_loop_stable),
        ]
        return Table(("quantity", "value"), rows, title="Controller reduction", digits=6)

    def summary(self) -> str:
        """A few sentences in plain words."""
        what = {"weighted": "frequency-weighted balanced truncation (closed-loop weight)",
                "coprime": "balanced truncation of the normalized coprime factors"}[self.method]
        stab = {True: "stable", False: "UNSTABLE", None: "not checked (no plant)"}[self.closed_loop_stable]
        bound = (f"a-priori bound {self.bound:.4g}" if np.isfinite(self.bound)
                 else "Enns' method has no a-priori bound")
        return (
            f"Controller reduced from {self.order_before} to {self.order_after} states by {what}.\n"
            f"Achieved error {self.error:.4g} ({bound}); stability radius "
            f"{self.stability_radius:.4g}; the reduced loop is {stab}."
        )

    def plot(self, fig: Any = None) -> Any:
        """The Hankel singular values with the kept ones marked. Returns the Figure."""
        fig, ax = single_axes(fig, 6.0, 3.5)
        k = np.arange(1, self.hsv.size + 1)
        ax.semilogy(k, np.maximum(self.hsv, 1e-300), "o-", ms=3, lw=1)
        ax.axvline(self.order_after + 0.5, color="k", ls="--", lw=1, label=f"kept {self.order_after}")
        label_axes(ax, "state", "Hankel singular value", f"Controller reduction ({self.method})")
        return fig

    def _repr_html_(self) -> str:
        return result_html(self.summary(), self.table())


# ---------------------------------------------------------------------------- kernels
def _mats(sys: Any) -> tuple[np.ndarray, ...]:
    return tuple(np.asarray(x, dtype=float) for x in (sys.A, sys.B, sys.C, sys.D))


def _psd_factor(P: np.ndarray) -> np.ndarray:
    ev, V = np.linalg.eigh((P + P.T) / 2)
    return V * np.sqrt(np.clip(ev, 0.0, None))


def _weighted_gramians(K, Wi, Wo) -> tuple[np.ndarray, np.ndarray]:
    """(1,1) blocks of the Gramians of ``K Wi`` (controllability) and ``Wo K`` (observability) (Enns)."""
    A, B, C, D = K
    n = A.shape[0]
    if Wi is None:
        Ac, Bc = A, B
    else:
        Ai, Bi, Ci, Di = Wi
        ni = Ai.shape[0]
        Ac = np.block([[A, B @ Ci], [np.zeros((ni, n)), Ai]])
        Bc = np.vstack([B @ Di, Bi])
    if Wo is None:
        Ao, Co = A, C
    else:
        Aw, Bw, Cw, Dw = Wo
        no = Aw.shape[0]
        Ao = np.block([[A, np.zeros((n, no))], [Bw @ C, Aw]])
        Co = np.hstack([Dw @ C, Cw])
    P = scipy.linalg.solve_continuous_lyapunov(Ac, -Bc @ Bc.T)[:n, :n]
    Q = scipy.linalg.solve_continuous_lyapunov(Ao.T, -Co.T @ Co)[:n, :n]
    return P, Q


def _square_root(A, B, C, D, P, Q) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Balancing projections from Gramians: ``(hsv, Tl, Tr)`` with ``Tl Tr = I`` on the kept part."""
    Lc, Lo = _psd_factor(P), _psd_factor(Q)
    U, hsv, Vt = np.linalg.svd(Lo.T @ Lc)
    return hsv, U, Vt, (Lc, Lo)


def _truncate(A, B, C, D, svd, order: int):
    hsv, U, Vt, (Lc, Lo) = svd
    if hsv[order - 1] <= HSV_RTOL * max(hsv[0], 1e-300):
        raise SynthesisError(
            f"only {int(np.count_nonzero(hsv > HSV_RTOL * hsv[0]))} Hankel singular values are numerically "
            f"nonzero; ask for at most that many states (got {order})."
        )
    root = 1.0 / np.sqrt(hsv[:order])
    Tl = root[:, None] * (U[:, :order].T @ Lo.T)
    Tr = (Lc @ Vt[:order].T) * root[None, :]
    return Tl @ A @ Tr, Tl @ B, C @ Tr, D


def _named(K0: Any, mats: tuple):
    A, B, C, D = mats
    return control.ss(A, B, C, D, K0.dt, inputs=list(K0.input_labels), outputs=list(K0.output_labels),
                      states=[f"xK{i + 1}" for i in range(A.shape[0])], name="Kr")


def _check_controller(K: Any, order: Any) -> tuple[Any, int]:
    Kss = as_statespace(K, name="K")
    if Kss.dt not in (0, None):
        raise SynthesisError(
            "controller reduction works in continuous time; reduce before discretising (or map with d2c)."
        )
    order = integer(order, "order", SynthesisError, lo=1)
    if order >= Kss.nstates:
        raise SynthesisError(f"order must be below the controller's {Kss.nstates} states; got {order}.")
    return Kss, order


def _loop_plant(plant: Any, K: Any):
    """The plant ``G`` seen by the controller (y <- u): a PartitionedPlant's P22 or a system."""
    if plant is None:
        return None
    if isinstance(plant, PartitionedPlant) or all(hasattr(plant, k) for k in ("P", "nmeas", "ncon")):
        pp = plant if isinstance(plant, PartitionedPlant) else PartitionedPlant(
            as_statespace(plant.P, name="plant"), plant.nmeas, plant.ncon)
        G = pp.sub("y", "u")
    else:
        G = as_statespace(plant, name="plant")
    if (G.noutputs, G.ninputs) != (K.ninputs, K.noutputs):
        raise SynthesisError(
            f"the plant ({G.noutputs} outputs x {G.ninputs} inputs) does not fit the controller "
            f"({K.ninputs} inputs x {K.noutputs} outputs)."
        )
    return G


def _closed_loop_weight(G: Any, K: Any):
    """``(I - G K)^-1 G`` (u-disturbance -> y with the loop ``u = K y`` closed); must be stable."""
    M = control.feedback(control.ss(G.A, G.B, G.C, G.D), control.ss(K.A, K.B, K.C, K.D), sign=+1)
    if not is_stable(M, roundoff_margin(M)):
        raise SynthesisError("the full controller does not stabilise the plant: there is no loop to keep.")
    return M


def _loop_stable(G: Any, Kr: Any) -> bool:
    cl = control.feedback(control.ss(G.A, G.B, G.C, G.D), control.ss(Kr.A, Kr.B, Kr.C, Kr.D), sign=+1)
    return is_stable(cl, roundoff_margin(cl))


# ---------------------------------------------------------------------------- surface
def weighted_balanced_truncation(K: Any, order: int, *, Wi: Any = None, Wo: Any = None,
                                 plant: Any = None) -> ControllerReduction:
    """Frequency-weighted balanced truncation (Enns) of a stable controller.

    Parameters
    ----------
    K : system
        A stable continuous-time controller.
    order : int
        States to keep.
    Wi, Wo : system, optional
        Stable input and output weights (``Wo (K - Kr) Wi`` is made small). With ``plant`` and
        neither weight, ``Wi`` is the closed-loop weight ``(I - G K)^-1 G``.
    plant : system or PartitionedPlant, optional
        The plant (``G = P22`` of a partitioned plant), for the closed-loop weight and the check.

    Returns
    -------
    ControllerReduction
        ``error = ||Wo (K - Kr) Wi||_inf``; with the closed-loop weight, ``stability_radius = 1``.

    Raises
    ------
    SynthesisError
        An unstable controller or weight, a discrete controller, a bad order, a plant that does
        not fit or is not stabilised by ``K``.

    References
    ----------
    Enns (1984), Proc. 23rd IEEE CDC, 127-132. Anderson & Liu (1989), IEEE TAC 34(8), 802-812.
    """
    Kss, order = _check_controller(K, order)
    A, B, C, D = _mats(Kss)
    if not is_stable(A, roundoff_margin(A)):
        raise SynthesisError(
            "frequency-weighted balanced truncation needs a stable controller; use coprime_reduction "
            "(method='coprime') for an unstable one."
        )
    G = _loop_plant(plant, Kss)
    closed_loop_weight = G is not None and Wi is None and Wo is None
    if closed_loop_weight:
        Wi = _closed_loop_weight(G, Kss)
    wi = None if Wi is None else _mats(as_statespace(Wi, name="Wi"))
    wo = None if Wo is None else _mats(as_statespace(Wo, name="Wo"))
    for w, what in ((wi, "Wi"), (wo, "Wo")):
        if w is not None and not is_stable(w[0], roundoff_margin(w[0])):
            raise SynthesisError(f"the weight {what} must be stable.")
    P, Q = _weighted_gramians((A, B, C, D), wi, wo)
    svd = _square_root(A, B, C, D, P, Q)
    Kr = _named(Kss, _truncate(A, B, C, D, svd, order))
    error = _weighted_error(Kss, Kr, wi, wo)
    return ControllerReduction(
        K=Kr, method="weighted", order_before=Kss.nstates, order_after=order, hsv=svd[0], error=error,
        bound=float("nan"), stability_radius=1.0 if closed_loop_weight else float("nan"),
        closed_loop_stable=None if G is None else _loop_stable(G, Kr),
        info={"closed_loop_weight": closed_loop_weight},
    )


def _weighted_error(K, Kr, wi, wo) -> float:
    E = control.ss(*_mats(K)) - control.ss(*_mats(Kr))
    if wi is not None:
        E = E * control.ss(*wi)
    if wo is not None:
        E = control.ss(*wo) * E
    return float(hinfnorm_matrices(*_mats(E), 1e-9)[0])


def _from_factors(Ar, Br, Cr, Dr, ny: int):
    """``Kr = Mtr^-1 Ntr`` from ``[Ntr, Mtr]`` (inputs: ny of Nt, then nu of Mt)."""
    Bn, Bm = Br[:, :ny], Br[:, ny:]
    Dn, Dm = Dr[:, :ny], Dr[:, ny:]
    Dmi = np.linalg.inv(Dm)
    return Ar - Bm @ Dmi @ Cr, Bn - Bm @ Dmi @ Dn, Dmi @ Cr, Dmi @ Dn


def coprime_reduction(K: Any, order: int, *, plant: Any = None) -> ControllerReduction:
    """Reduce a (possibly unstable) controller through its normalized left coprime factors.

    Parameters
    ----------
    K : system
        Continuous-time controller (stabilisable and detectable realisation).
    order : int
        States to keep.
    plant : system or PartitionedPlant, optional
        For the stability radius ``b(G, K)`` and the closed-loop check.

    Returns
    -------
    ControllerReduction
        ``error = ||[Nt - Ntr, Mt - Mtr]||_inf <= bound = 2 sum_{i > order} sigma_i``.

    References
    ----------
    Zhou, Doyle & Glover (1996), ch. 19 (controller order reduction via coprime factors).
    McFarlane & Glover (1990), LNCIS 138.
    """
    Kss, order = _check_controller(K, order)
    A, B, C, D = _mats(Kss)
    F = left_ncf(A, B, C, D)  # [Nt, Mt], stable
    Af, Bf, Cf, Df = F
    P = scipy.linalg.solve_continuous_lyapunov(Af, -Bf @ Bf.T)
    Q = scipy.linalg.solve_continuous_lyapunov(Af.T, -Cf.T @ Cf)
    svd = _square_root(Af, Bf, Cf, Df, P, Q)
    Fr = _truncate(Af, Bf, Cf, Df, svd, order)
    try:
        Kr = _named(Kss, _from_factors(*Fr, Kss.ninputs))
    except np.linalg.LinAlgError as exc:  # pragma: no cover - Mt's feedthrough is Rt^-1/2, invertible
        raise SynthesisError(f"the reduced factor Mtr is singular ({exc}).") from exc
    E = control.ss(*F) - control.ss(*Fr)
    error = float(hinfnorm_matrices(*_mats(E), 1e-9)[0])
    hsv = svd[0]
    G = _loop_plant(plant, Kss)
    radius = float("nan")
    if G is not None:
        radius = stability_margin(G, Kss)
    return ControllerReduction(
        K=Kr, method="coprime", order_before=Kss.nstates, order_after=order, hsv=hsv, error=error,
        bound=float(2.0 * np.sum(hsv[order:])), stability_radius=radius,
        closed_loop_stable=None if G is None else _loop_stable(G, Kr),
    )


def reduce_controller(K: Any, order: int, plant: Any = None, *, method: str = "auto") -> ControllerReduction:
    """Reduce a controller with the loop in view: weighted truncation if stable, coprime factors otherwise.

    Parameters
    ----------
    K : system
        Continuous-time controller ``u = K y``.
    order : int
        States to keep.
    plant : system or PartitionedPlant, optional
        The plant the controller closes (``P22`` of a partitioned plant).
    method : {"auto", "weighted", "coprime"}
        ``"auto"``: ``"weighted"`` (closed-loop weight when ``plant`` is given) for a stable
        ``K``, ``"coprime"`` for an unstable one.

    Returns
    -------
    ControllerReduction

    See Also
    --------
    weighted_balanced_truncation, coprime_reduction
    """
    if not isinstance(method, str) or method not in ("auto", "weighted", "coprime"):
        raise SynthesisError(f"method must be 'auto', 'weighted' or 'coprime'; got {method!r}.")
    if method == "auto":
        Kss = as_statespace(K, name="K")
        method = "weighted" if is_stable(Kss, roundoff_margin(Kss)) else "coprime"
    if method == "weighted":
        return weighted_balanced_truncation(K, order, plant=plant)
    return coprime_reduction(K, order, plant=plant)


def reducer(K: Any, G: Any, method: str) -> tuple[np.ndarray, Any]:
    """``(hsv, reduce_to)`` for :func:`robustctl.robust.dk.iteration.dksyn`'s order search: ``reduce_to(r)``
    is the :class:`ControllerReduction` of ``K`` to ``r`` states by ``method`` ("weighted":
    closed-loop weight with the plant ``G``; "coprime")."""
    full = reduce_controller(K, 1, G, method=method) if K.nstates > 1 else None
    hsv = full.hsv if full is not None else np.ones(1)
    return hsv, lambda r: reduce_controller(K, r, G, method=method)
