"""A physical model with real uncertain parameters as a linear fractional transformation.

The parameters ``theta`` of a :class:`~robustctl.physical.model.PhysicalModel` known to
``theta_0 +- `` a covariance ``Sigma = S R S`` (standard deviations ``S``, correlations ``R``;
e.g. an update's fit) are written along the principal axes of ``R`` (unit-free):
``theta = theta_0 + sum_k delta_k a_k`` with ``a_k = n_sigma sqrt(l_k) S v_k`` (``R = sum_k
l_k v_k v_k^T``) and real ``delta_k`` in [-1, 1], so that the box ``|delta_k| <= 1`` holds the
``n_sigma`` ellipsoid of the fit (correlations included; ``a Sigma^-1 a^T = n_sigma^2 I``). The
state-space matrices ``S(delta) = [[A, B], [C, D]]`` then give an LFT (Zhou, Doyle & Glover
1996, sec. 10.2; Packard & Doyle 1993, sec. 2 for the repeated real scalar blocks)

    S(delta) = S_0 + sum_k delta_k S_k,    S_k = L_k R_k  (rank r_k),
    G(delta) = Fu(M, diag(delta_k I_{r_k})),

``M`` having the extra inputs ``w_k`` (entering through ``L_k``) and outputs
``z_k = R_k [x; u]``. This is exact when ``S`` is affine in ``theta`` in a fixed state basis
(stiffness and mass-inverse groups, tension; checked with second differences); otherwise it
is the first-order LFT (``S_k`` from central differences) and its error against models
sampled in the box is stated (:attr:`UncertainModel.max_error`, relative to the nominal's
peak response). A model whose state basis moves with the parameters (modal models re-solved
per parameter value) shows that as a large error: use a physical-coordinates model, or
cover the rest with a complex weight.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import ModelError
from ..lti import freqresp_array

__all__ = ["UncertainModel", "parametric_lft"]

#: relative second difference below which S is taken as affine in an axis
AFFINE_RTOL = 1e-8
#: relative singular value below which a direction of S_k is dropped
RANK_RTOL = 1e-10


@dataclass(frozen=True)
class UncertainModel:
    """``G(delta) = Fu(M, diag(delta_k I_{r_k}))`` with named real parameters ``delta_k`` in [-1, 1].

    Attributes
    ----------
    M : control.StateSpace
        Inputs ``[w (sum r_k); u]``, outputs ``[z (sum r_k); y]`` (``u``, ``y`` the model's).
    names : tuple of str
        One name per real block (``"axis1"``, ...; the parameter's own name for one parameter).
    multiplicity : tuple of int
        ``r_k`` per block.
    parameters : tuple of str
        The model parameters that vary.
    center : ndarray (n_par,)
        ``theta_0`` (parameter units).
    axes : ndarray (n_blocks, n_par)
        ``a_k``: ``theta = theta_0 + sum_k delta_k a_k``.
    exact : bool
        True when ``S`` is affine in the parameters (the LFT is exact).
    max_error : float
        Largest ``|G_sample - Fu(M, Delta_sample)|`` over the check models and frequencies,
        relative to ``max |G_0|`` (0 for an exact LFT up to rounding).
    check_f_hz : ndarray
        Frequencies (Hz) of that check.
    nominal : control.StateSpace
        ``G(0)``.
    form : {"state space", "modal"}
        The coordinates of the LFT: the model's own state-space matrices, or (when that is
        not exact and this is closer to the sampled models) the nominal's real modal
        coordinates with each mode's eigenvalue (frequency and damping) moving to first order
        and its shape held.
    """

    M: Any
    names: tuple[str, ...]
    multiplicity: tuple[int, ...]
    parameters: tuple[str, ...]
    center: np.ndarray
    axes: np.ndarray
    exact: bool
    max_error: float
    check_f_hz: np.ndarray = field(repr=False)
    nominal: Any = field(repr=False)
    form: str = "state space"

    @property
    def n_delta(self) -> int:
        return int(sum(self.multiplicity))

    def mussv(self) -> list[list[int]]:
        """The blocks in MATLAB's mussv rows: ``[-r_k, 0]``."""
        return [[-r, 0] for r in self.multiplicity]

    def statespace(self, delta: Any = None):
        """``Fu(M, diag(delta_k I))`` (default ``delta = 0``: the nominal).

        ``M``'s ``w -> z`` feedthrough is zero, so the loop ``w = Delta z`` closes without an
        inverse: ``A + B_w Delta C_z``, ``B_u + B_w Delta D_zu``, ``C_y + D_yw Delta C_z``,
        ``D_yu + D_yw Delta D_zu``.
        """
        import control

        if delta is None:
            return self.nominal
        d = np.asarray(delta, dtype=float).reshape(-1)
        if d.size != len(self.names):
            raise ModelError(f"delta needs one value per real block ({len(self.names)}); got {d.size}.")
        Dl = np.diag(np.repeat(d, self.multiplicity))
        k = self.n_delta
        A, B, C, D = (np.asarray(x, dtype=float) for x in (self.M.A, self.M.B, self.M.C, self.M.D))
        Bw, Bu, Cz, Cy = B[:, :k], B[:, k:], C[:k], C[k:]
        Dzu, Dyw, Dyu = D[:k, k:], D[k:, :k], D[k:, k:]
        return control.ss(A + Bw @ Dl @ Cz, Bu + Bw @ Dl @ Dzu, Cy + Dyw @ Dl @ Cz, Dyu + Dyw @ Dl @ Dzu,
                          inputs=list(self.nominal.input_labels), outputs=list(self.nominal.output_labels))

    def parameter_values(self, delta: Any) -> dict[str, float]:
        """``theta_0 + sum_k delta_k a_k`` as a dict."""
        d = np.asarray(delta, dtype=float).reshape(-1)
        return dict(zip(self.parameters, map(float, self.center + d @ self.axes)))

    def summary(self) -> str:
        kind = "exact (affine in the parameters)" if self.exact else f"first-order ({self.form})"
        return (f"UncertainModel: {len(self.names)} real blocks {list(self.multiplicity)} over "
                f"{list(self.parameters)}; {kind} LFT, error {100 * self.max_error:.3g} % of the peak "
                f"response on {len(self.check_f_hz)} frequencies.")


def _matrices(model: Any, values: dict[str, float]) -> tuple[np.ndarray, tuple[int, int, int], Any]:
    sys = model.statespace(**values)
    A, B, C, D = (np.asarray(x, dtype=float) for x in (sys.A, sys.B, sys.C, sys.D))
    S = np.block([[A, B], [C, D]])
    return S, (A.shape[0], B.shape[1], C.shape[0]), sys


def parametric_lft(model: Any, parameters: Any, center: Any, covariance: Any, *, n_sigma: float = 2.0,
                   f_hz: Any = None, n_check: int = 8, seed: int = 0) -> UncertainModel:
    """The LFT of ``model`` over the ``n_sigma`` box of its parameters' covariance.

    Parameters
    ----------
    model : PhysicalModel
        Anything with ``.statespace(**values)``.
    parameters : sequence of str
        The parameters that vary.
    center : array_like (n_par,)
        Their nominal values (parameter units).
    covariance : array_like (n_par, n_par)
        Their covariance (parameter units squared); axes with zero variance are dropped.
    n_sigma : float
        Half-width of the box along each principal axis, in standard deviations.
    f_hz : array_like, optional
        Frequencies (Hz) of the error check (default: 200 log-spaced over the nominal's poles).
    n_check : int
        Sampled corners and interior points for the error check (the ``2 n_axes`` axis ends are
        always checked).
    seed : int
        Seed of the sampled points.

    Returns
    -------
    UncertainModel

    Raises
    ------
    ModelError
        Mismatched sizes, a non-positive ``n_sigma``, or state dimensions that change with the
        parameters.
    """

    names = tuple(str(p) for p in parameters)
    c = np.asarray(center, dtype=float).reshape(-1)
    cov = np.atleast_2d(np.asarray(covariance, dtype=float))
    if c.size != len(names) or cov.shape != (len(names), len(names)):
        raise ModelError(f"center needs {len(names)} values and covariance {len(names)}x{len(names)}; "
                         f"got {c.size} and {cov.shape}.")
    if not np.isfinite(n_sigma) or n_sigma <= 0:
        raise ModelError(f"n_sigma must be a positive number of standard deviations; got {n_sigma!r}.")
    cov = 0.5 * (cov + cov.T)
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    if not np.any(sd > 0):
        raise ModelError("the covariance is zero: there is no parametric uncertainty to model.")
    # principal axes of the correlation matrix (unit-free: parameters in different units
    # are not ranked by their numbers), mapped back with the standard deviations
    live = sd > 0
    corr = cov[np.ix_(live, live)] / np.outer(sd[live], sd[live])
    lam, vec = np.linalg.eigh(corr)
    keep = lam > 1e-10 * lam.max()
    order = np.argsort(-lam[keep])
    axes = np.zeros((int(keep.sum()), len(names)))
    axes[:, live] = (n_sigma * np.sqrt(lam[keep]) * (sd[live][:, None] * vec[:, keep])).T[order]

    def at(delta: np.ndarray):
        return _matrices(model, dict(zip(names, map(float, c + delta @ axes))))

    S0, dims, G0 = at(np.zeros(len(axes)))
    n, nu, ny = dims
    scale = max(np.abs(S0).max(), 1e-300)
    Sk, exact = [], True
    for k in range(len(axes)):
        e = np.zeros(len(axes))
        e[k] = 1.0
        Sp, dp, _ = at(e)
        Sm, dm, _ = at(-e)
        if dp != dims or dm != dims:
            raise ModelError("the model's state dimension changes with the parameters; no LFT in them.")
        Sk.append(0.5 * (Sp - Sm))
        if np.abs(Sp + Sm - 2 * S0).max() > AFFINE_RTOL * scale:
            exact = False
    if exact and len(axes) > 1:  # cross terms of an affine map vanish
        e = np.ones(len(axes))
        Sc, _, _ = at(e)
        exact = np.abs(Sc - S0 - sum(Sk)).max() <= AFFINE_RTOL * scale * len(axes)
    A0 = S0[:n, :n]
    if f_hz is None:
        wn = np.abs(np.linalg.eigvals(A0)) if n else np.array([1.0])
        wn = wn[wn > 0] if np.any(wn > 0) else np.array([1.0])
        f = np.logspace(np.log10(wn.min() / 10 / (2 * np.pi)), np.log10(wn.max() * 10 / (2 * np.pi)), 200)
    else:
        f = np.asarray(f_hz, dtype=float).reshape(-1)
    rng = np.random.default_rng(seed)
    pts = [s * np.eye(len(axes))[k] for k in range(len(axes)) for s in (-1.0, 1.0)]
    pts += list(rng.uniform(-1.0, 1.0, (n_check, len(axes))))
    H0 = freqresp_array(G0, f)
    peak = max(np.abs(H0).max(), 1e-300)
    truth = [freqresp_array(at(p)[2], f) for p in pts]

    def build(S0x: np.ndarray, Skx: list[np.ndarray], form: str) -> UncertainModel:
        M, bnames, mult, kept = _lft(S0x, Skx, n, names, axes, G0, scale)
        um = UncertainModel(M, bnames, mult, names, c, axes[kept], bool(exact), 0.0, f, G0, form)
        err = 0.0
        for p, Hs in zip(pts, truth):
            err = max(err, float(np.abs(Hs - freqresp_array(um.statespace(p[kept]), f)).max()) / peak)
        return UncertainModel(M, bnames, mult, names, c, axes[kept], bool(exact), err, f, G0, form)

    um = build(S0, Sk, "state space")
    if not exact and n:
        unit = np.eye(len(axes))
        modal = _modal_form(S0, n, [at(e)[0] for e in unit], [at(-e)[0] for e in unit])
        if modal is not None:
            alt = build(*modal, "modal")
            if alt.max_error < um.max_error:
                um = alt
    return um


def _lft(S0: np.ndarray, Sk: list[np.ndarray], n: int, names: tuple[str, ...], axes: np.ndarray, G0: Any,
         scale: float) -> tuple[Any, tuple[str, ...], tuple[int, ...], list[int]]:
    """``M`` of ``S0 + sum_k delta_k S_k`` (``S_k = L_k R_k`` by SVD), its block names, multiplicities
    and the axes kept (those that change ``S``)."""
    import control

    Ls, Rs, mult, block_names, kept = [], [], [], [], []
    for k, S in enumerate(Sk):
        U, sv, Vt = np.linalg.svd(S)
        r = int(np.count_nonzero(sv > RANK_RTOL * scale))
        if r == 0:
            continue
        kept.append(k)
        Ls.append(U[:, :r] * np.sqrt(sv[:r]))
        Rs.append(np.sqrt(sv[:r])[:, None] * Vt[:r])
        mult.append(r)
        block_names.append(names[int(np.argmax(np.abs(axes[k])))] if len(names) == 1 else f"axis{k + 1}")
    if not mult:
        raise ModelError("the model does not change with these parameters over their spread.")
    L, R = np.hstack(Ls), np.vstack(Rs)
    nd = L.shape[1]
    A0, B0, C0, D0 = S0[:n, :n], S0[:n, n:], S0[n:, :n], S0[n:, n:]
    Bm = np.hstack([L[:n], B0])
    Cm = np.vstack([R[:, :n], C0])
    Dm = np.block([[np.zeros((nd, nd)), R[:, n:]], [L[n:], D0]])
    w_names = [f"{nm}:w[{j}]" for nm, r in zip(block_names, mult) for j in range(r)]
    z_names = [f"{nm}:z[{j}]" for nm, r in zip(block_names, mult) for j in range(r)]
    M = control.ss(A0, Bm, Cm, Dm, inputs=w_names + list(G0.input_labels),
                   outputs=z_names + list(G0.output_labels))
    return M, tuple(block_names), tuple(mult), kept


def _real_modal_basis(A: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """``T`` with ``T^-1 A T`` block diagonal (``[[s, w], [-w, s]]`` per complex pair ``s +- j w``,
    ``[l]`` per real eigenvalue) and the eigenvalues in that order (upper ones of each pair)."""
    lam, V = np.linalg.eig(A)
    cols, order, used = [], [], np.zeros(lam.size, bool)
    for i in np.argsort(np.abs(lam), kind="stable"):
        if used[i]:
            continue
        if abs(lam[i].imag) > 1e-12 * max(abs(lam[i]), 1e-300):
            taken = used | (np.arange(lam.size) == i)
            j = int(np.argmin(np.where(taken, np.inf, np.abs(lam - lam[i].conjugate()))))
            v = V[:, i] if lam[i].imag > 0 else V[:, j]
            cols += [v.real, v.imag]
            order.append(lam[i] if lam[i].imag > 0 else lam[j])
            used[i] = used[j] = True
        else:
            cols.append(V[:, i].real)
            order.append(complex(lam[i].real, 0.0))
            used[i] = True
    T = np.array(cols).T
    if np.linalg.cond(T) > 1e12:
        return None
    return T, np.array(order)


def _modal_form(S0: np.ndarray, n: int, plus: list[np.ndarray], minus: list[np.ndarray]):
    """The LFT data in the nominal's real modal coordinates with the eigenvalues' first-order
    changes only (each mode's frequency and damping; its shape held at the nominal): ``S0`` in
    modal coordinates and one ``S_k`` per axis, or None when the modes cannot be matched."""
    from scipy.optimize import linear_sum_assignment

    A0 = S0[:n, :n]
    basis = _real_modal_basis(A0)
    if basis is None:
        return None
    T, lam0 = basis
    Ti = np.linalg.inv(T)
    S0m = np.block([[Ti @ A0 @ T, Ti @ S0[:n, n:]], [S0[n:, :n] @ T, S0[n:, n:]]])
    Skm = []
    for Sp, Sm in zip(plus, minus):
        moved = []
        for S in (Sp, Sm):
            lam = np.linalg.eigvals(S[:n, :n])
            lam = lam[lam.imag >= -1e-12 * np.maximum(np.abs(lam), 1e-300)]
            if lam.size != lam0.size:
                return None
            cost = np.abs(lam0[:, None] - lam[None, :])
            r, cidx = linear_sum_assignment(cost)
            moved.append(lam[cidx[np.argsort(r)]])
        dl = 0.5 * (moved[0] - moved[1])
        dA = np.zeros((n, n))
        pos = 0
        for d, l0 in zip(dl, lam0):
            if abs(l0.imag) > 0:
                dA[pos:pos + 2, pos:pos + 2] = [[d.real, d.imag], [-d.imag, d.real]]
                pos += 2
            else:
                dA[pos, pos] = d.real
                pos += 1
        S = np.zeros_like(S0m)
        S[:n, :n] = dA
        Skm.append(S)
    return S0m, Skm
