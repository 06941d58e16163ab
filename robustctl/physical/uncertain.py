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

``form="modes"`` parametrises the modes instead of the parameters (a large model, or one
reduced to its design modes with ``order=``): each retained mode ``i`` is written in its
companion coordinates ``q'' = -p_i q - q_i q'`` (``p_i = w_i^2``, ``q_i = 2 zeta_i w_i``,
affine in both: one rank-1 real scalar per direction), its shape held at the nominal. The
mode's first-order movement ``J_i (theta - theta_0)`` over the ``n_sigma`` ellipsoid spans
``n_sigma^2 J_i Sigma J_i^T`` (Gelb 1974, sec. 4.4 for the linearised covariance), one real
scalar per principal direction of that 2 x 2 matrix: a frequency (and, when the parameters
move it, a damping) scalar per mode. The modes move independently in the LFT (the
correlations between modes are dropped, which covers more than the ellipsoid), and what the
parametrisation misses -- shape changes, higher-order terms, the truncated modes -- is left
to a complex remainder cover (:func:`robustctl.robust.uncertainty.cover.cover_remainder`, kept in
:attr:`UncertainModel.remainder`; ``rc.generalized_plant`` puts both into ``.blocks``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import control
import numpy as np

from ..balanced import balanced_truncation
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
    form : {"state space", "modal", "modes"}
        The coordinates of the LFT: the model's own state-space matrices, or (when that is
        not exact and this is closer to the sampled models) the nominal's real modal
        coordinates with each mode's eigenvalue (frequency and damping) moving to first order
        and its shape held; ``"modes"``: one real scalar per mode and direction of its
        movement (module docstring).
    remainder : UncertaintyCover or None
        A complex weight covering what the LFT misses against sampled models and data
        (:func:`robustctl.robust.uncertainty.cover.cover_remainder`); ``rc.generalized_plant`` adds its
        block after the real ones.
    modes : tuple or None
        ``form="modes"``: per block ``(nominal eigenvalue, direction (2,) in (p, q), half-range)``,
        what :meth:`delta_of` projects a model's eigenvalues on.
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
    remainder: Any = field(default=None, repr=False)
    modes: tuple | None = field(default=None, repr=False)

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

    def with_remainder(self, cover: Any) -> UncertainModel:
        """This LFT with ``cover`` (a complex weight of what it misses) as its remainder.

        Parameters
        ----------
        cover : UncertaintyCover
            Additive or multiplicative, e.g. from :func:`robustctl.robust.uncertainty.cover.cover_remainder`.

        Returns
        -------
        UncertainModel
        """
        from dataclasses import replace

        if cover is not None and not hasattr(cover, "weight"):
            raise ModelError(
                f"the remainder must be a cover with .weight and .kind; got {type(cover).__name__}.")
        return replace(self, remainder=cover)

    def without(self, blocks: Any) -> UncertainModel:
        """This LFT with the named real blocks removed (held at ``delta = 0``).

        Their ``w`` and ``z`` channels are dropped from ``M`` (an exact LFT of the rest); the
        remainder is dropped too (it covered the LFT with those blocks: refit it).

        Parameters
        ----------
        blocks : sequence of str
            Names among :attr:`names` (all of them: an LFT without real blocks, ``G_0`` itself).

        Returns
        -------
        UncertainModel
        """
        from dataclasses import replace


        drop = set(blocks)
        unknown = drop - set(self.names)
        if unknown:
            raise ModelError(f"no real block named {sorted(unknown)}; the blocks are {list(self.names)}.")
        keep = [k for k, nm in enumerate(self.names) if nm not in drop]
        starts = np.concatenate([[0], np.cumsum(self.multiplicity)]).astype(int)
        ch = np.concatenate([np.arange(starts[k], starts[k + 1]) for k in keep] + [np.zeros(0, int)])
        nd = self.n_delta
        cols = np.concatenate([ch, np.arange(nd, nd + self.nominal.ninputs)])
        rows = np.concatenate([ch, np.arange(nd, nd + self.nominal.noutputs)])
        A, B, C, D = (np.asarray(x, dtype=float) for x in (self.M.A, self.M.B, self.M.C, self.M.D))
        M = control.ss(A, B[:, cols], C[rows], D[np.ix_(rows, cols)],
                       inputs=[self.M.input_labels[i] for i in cols],
                       outputs=[self.M.output_labels[i] for i in rows])
        modes = None if self.modes is None else tuple(self.modes[k] for k in keep)
        return replace(self, M=M, names=tuple(self.names[k] for k in keep),
                       multiplicity=tuple(self.multiplicity[k] for k in keep), axes=self.axes[keep],
                       remainder=None, modes=modes)

    def block_effect(self, f_hz: Any) -> np.ndarray:
        """``max_{delta_k = +-1} sigma_max(Fu(M, delta_k e_k) - G_0)`` per block and frequency.

        Parameters
        ----------
        f_hz : array_like
            Frequencies (Hz).

        Returns
        -------
        ndarray (n_blocks, nf)
        """
        f = np.asarray(f_hz, dtype=float).reshape(-1)
        H0 = freqresp_array(self.nominal, f)
        out = np.zeros((len(self.names), f.size))
        for k in range(len(self.names)):
            for sgn in (-1.0, 1.0):
                e = np.zeros(len(self.names))
                e[k] = sgn
                gap = freqresp_array(self.statespace(e), f) - H0
                out[k] = np.maximum(out[k], np.linalg.norm(gap, ord=2, axis=(1, 2)))
        return out

    def delta_of(self, model: Any, clip: bool = True) -> np.ndarray:
        """The real parameters ``delta`` (one per block) that stand for ``model`` in this LFT.

        Parameter forms: the least-squares solution of ``theta - theta_0 = delta @ axes`` from
        ``model``'s parameter values. ``form="modes"``: each retained mode's ``(p, q) = (|l|^2,
        -2 Re l)`` of the eigenvalue ``l`` of ``model`` nearest the nominal's, projected on the
        block's direction and divided by its half-range.

        Parameters
        ----------
        model : PhysicalModel, dict or system
            A model with ``.values`` (parameter units), a dict of parameter values, or (modes
            form) any system ``rc.as_statespace`` accepts.
        clip : bool
            Clip ``delta`` to [-1, 1] (the LFT's set; what lies outside is left to the remainder).

        Returns
        -------
        ndarray (n_blocks,)
        """
        if not self.names:
            return np.zeros(0)
        if self.modes is not None and not isinstance(model, dict):
            from ..lti import as_statespace

            lam = np.linalg.eigvals(np.asarray(as_statespace(model).A, dtype=float))
            d = np.empty(len(self.modes))
            for k, (l0, direction, half) in enumerate(self.modes):
                li = lam[int(np.argmin(np.abs(lam - l0)))]
                dpq = np.array([abs(li) ** 2 - abs(l0) ** 2, -2.0 * (li.real - l0.real)])
                d[k] = float(direction @ dpq) / half
        else:
            values = model if isinstance(model, dict) else dict(model.values)
            missing = [p for p in self.parameters if p not in values]
            if missing:
                raise ModelError(
                    f"the model has no values for {missing}; the LFT varies {list(self.parameters)}.")
            dth = np.array([values[p] for p in self.parameters], dtype=float) - self.center
            d = np.linalg.lstsq(self.axes.T, dth, rcond=None)[0]
        return np.clip(d, -1.0, 1.0) if clip else d

    def __repr__(self) -> str:
        kind = "exact" if self.exact else f"first order ({self.form}), error {100 * self.max_error:.3g} %"
        blocks = ", ".join(f"{n} x{r}" for n, r in zip(self.names, self.multiplicity))
        rem = "" if self.remainder is None else f", {self.remainder.kind} remainder"
        nom = self.nominal
        return (f"UncertainModel({nom.noutputs}x{nom.ninputs}, {nom.nstates} states; "
                f"real blocks [{blocks}] over {list(self.parameters)}; {kind}{rem})")

    def summary(self) -> str:
        kind = "exact (affine in the parameters)" if self.exact else f"first-order ({self.form})"
        text = (f"UncertainModel: {len(self.names)} real blocks {list(self.multiplicity)} over "
                f"{list(self.parameters)}; {kind} LFT, error {100 * self.max_error:.3g} % of the peak "
                f"response on {len(self.check_f_hz)} frequencies.")
        if self.remainder is not None:
            text += (f" Remainder: {self.remainder.kind} complex weight of order {self.remainder.order} "
                     f"(margin {self.remainder.margin:.3g} on its sources).")
        return text


def _matrices(model: Any, values: dict[str, float], order: int | None = None
              ) -> tuple[np.ndarray, tuple[int, int, int], Any]:
    sys = model.statespace(**values)
    if order is not None and sys.nstates > order:
        sys = _reduced(sys, order)
    A, B, C, D = (np.asarray(x, dtype=float) for x in (sys.A, sys.B, sys.C, sys.D))
    S = np.block([[A, B], [C, D]])
    return S, (A.shape[0], B.shape[1], C.shape[0]), sys


def _reduced(sys: Any, order: int):
    """``sys`` by balanced truncation to ``order`` states, its signal names kept."""
    red = balanced_truncation(sys, order).sys
    return control.ss(red.A, red.B, red.C, red.D, inputs=list(sys.input_labels),
                      outputs=list(sys.output_labels))


def parametric_lft(model: Any, parameters: Any, center: Any, covariance: Any, *, n_sigma: float = 2.0,
                   f_hz: Any = None, n_check: int = 8, seed: int = 0, form: str = "auto",
                   order: int | None = None) -> UncertainModel:
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
    form : {"auto", "modes"}
        ``"auto"``: the state-space LFT (exact when affine), else the modal one when it is
        closer to the sampled models; ``"modes"``: one real scalar per retained mode and
        direction of its movement (module docstring), for large or reduced models.
    order : int, optional
        Reduce the model to this many states by balanced truncation first (at every
        parameter value; 12 for six modes, the Caltech design model). With ``form="auto"``
        the basis of the reduction moves with the parameters, so use ``form="modes"``.

    Returns
    -------
    UncertainModel

    Raises
    ------
    ModelError
        Mismatched sizes, a non-positive ``n_sigma``, an unknown ``form``, or state dimensions
        that change with the parameters.
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
    rank = np.argsort(-lam[keep])
    axes = np.zeros((int(keep.sum()), len(names)))
    axes[:, live] = (n_sigma * np.sqrt(lam[keep]) * (sd[live][:, None] * vec[:, keep])).T[rank]

    if form not in ("auto", "modes"):
        raise ModelError(f'form must be "auto" or "modes"; got {form!r}.')
    if order is not None and (isinstance(order, bool) or not isinstance(order, (int, np.integer))
                              or order < 1):
        raise ModelError(f"order must be a positive number of states; got {order!r}.")

    def at(delta: np.ndarray):
        return _matrices(model, dict(zip(names, map(float, c + delta @ axes))), order)

    if form == "modes":
        return _modes_lft(model, names, c, axes, at, f_hz=f_hz, n_check=n_check, seed=seed)

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
         scale: float, block_names: Any = None) -> tuple[Any, tuple[str, ...], tuple[int, ...], list[int]]:
    """``M`` of ``S0 + sum_k delta_k S_k`` (``S_k = L_k R_k`` by SVD), its block names, multiplicities
    and the axes kept (those that change ``S``)."""
    given = block_names
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
        if given is not None:
            block_names.append(given[k])
        else:
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


#: A mode's second direction of movement (in (p, q) = (w^2, 2 zeta w)) gets its own real
#: scalar when its half-range is at least this fraction of the first's; smaller ones are left
#: to the remainder cover.
MODE_DIRECTION_RTOL = 0.05


def _companion_basis(A0: np.ndarray):
    """``Tc`` with ``Tc^-1 A0 Tc`` block diagonal, ``[[0, 1], [-p, -q]]`` per complex pair
    (``p = |l|^2``, ``q = -2 Re l``) and ``[l]`` per real eigenvalue; the pairs' upper
    eigenvalues and their first state index (None when the modes cannot be separated)."""
    basis = _real_modal_basis(A0)
    if basis is None:
        return None
    T, lam = basis
    n = A0.shape[0]
    P = np.eye(n)
    pos, pairs = 0, []
    for li in lam:
        if abs(li.imag) > 0:
            P[pos + 1, pos:pos + 2] = [li.real, li.imag]  # y' = s y1 + w y2 in the [[s, w], [-w, s]] block
            pairs.append((li, pos))
            pos += 2
        else:
            pos += 1
    return T @ np.linalg.inv(P), pairs


def _upper_eigs(A: np.ndarray) -> np.ndarray:
    lam = np.linalg.eigvals(A)
    return lam[lam.imag > 0]


def _modes_lft(model: Any, names: tuple[str, ...], c: np.ndarray, axes: np.ndarray, at: Any, *,
               f_hz: Any, n_check: int, seed: int) -> UncertainModel:
    """The ``form="modes"`` LFT (module docstring): one rank-1 real scalar per mode and direction."""
    S0, dims, G0 = at(np.zeros(len(axes)))
    n = dims[0]
    if n == 0:
        raise ModelError("the model has no states: there are no modes to make uncertain.")
    A0 = S0[:n, :n]
    found = _companion_basis(A0)
    if found is None:
        raise ModelError("the model's modes cannot be separated (a defective or repeated eigenvalue); "
                         'use form="auto".')
    Tc, pairs = found
    if not pairs:
        raise ModelError("the model has no oscillatory mode to make uncertain; use form=\"auto\".")
    Ti = np.linalg.inv(Tc)
    S0c = np.block([[Ti @ A0 @ Tc, Ti @ S0[:n, n:]], [S0[n:, :n] @ Tc, S0[n:, n:]]])
    lam0 = np.array([li for li, _ in pairs])
    pq0 = np.stack([np.abs(lam0) ** 2, -2.0 * lam0.real], axis=1)

    def pq(A: np.ndarray) -> np.ndarray:
        lam = _upper_eigs(A)
        idx = [int(np.argmin(np.abs(lam - l0))) for l0 in lam0]
        lam = lam[idx]
        return np.stack([np.abs(lam) ** 2, -2.0 * lam.real], axis=1)

    # each mode's (p, q) per unit delta along the principal axes (the n_sigma ellipsoid is the unit ball)
    D = np.zeros((len(lam0), 2, len(axes)))
    for k in range(len(axes)):
        e = np.eye(len(axes))[k]
        Sp, dp, _ = at(e)
        Sm, dm, _ = at(-e)
        if dp != dims or dm != dims:
            raise ModelError("the model's state dimension changes with the parameters; no LFT in them.")
        D[:, :, k] = 0.5 * (pq(Sp[:n, :n]) - pq(Sm[:n, :n]))
    Sk, block_names, info, par_axes = [], [], [], []
    for i, ((l0, pos), Di) in enumerate(zip(pairs, D)):
        mu, U = np.linalg.eigh(Di @ Di.T)
        half = np.sqrt(np.clip(mu[::-1], 0.0, None))
        U = U[:, ::-1]
        if half[0] <= 1e-12 * pq0[i, 0]:
            continue
        for j in range(2):
            if half[j] < MODE_DIRECTION_RTOL * half[0]:
                continue
            u = U[:, j] * (1.0 if U[np.argmax(np.abs(U[:, j])), j] > 0 else -1.0)
            S = np.zeros_like(S0c)
            S[pos + 1, pos:pos + 2] = -half[j] * u
            Sk.append(S)
            f0 = abs(l0) / (2 * np.pi)
            block_names.append(f"mode{i + 1}_{f0:.4g}Hz".replace(".", "p") + ("" if j == 0 else "_damping"))
            info.append((complex(l0), u, float(half[j])))
            par_axes.append((Di.T @ u / half[j]) @ axes)  # the ellipsoid's point that moves it most
    if not Sk:
        raise ModelError("no mode moves with these parameters over their spread.")
    scale = max(np.abs(S0c).max(), 1e-300)
    M, bnames, mult, kept = _lft(S0c, Sk, n, names, axes, G0, scale, block_names)
    info = tuple(info[k] for k in kept)
    par_axes = np.array([par_axes[k] for k in kept])
    if f_hz is None:
        wn = np.abs(np.linalg.eigvals(A0))
        wn = wn[wn > 0] if np.any(wn > 0) else np.array([1.0])
        f = np.logspace(np.log10(wn.min() / 10 / (2 * np.pi)), np.log10(wn.max() * 10 / (2 * np.pi)), 200)
    else:
        f = np.asarray(f_hz, dtype=float).reshape(-1)
    um = UncertainModel(M, bnames, mult, names, c, par_axes, False, 0.0, f, G0, "modes", None, info)
    # the error check: the axis ends and points drawn in the n_sigma ellipsoid (the unit ball)
    rng = np.random.default_rng(seed)
    pts = [s * np.eye(len(axes))[k] for k in range(len(axes)) for s in (-1.0, 1.0)]
    for x in rng.standard_normal((n_check, len(axes))):
        pts.append(x / np.linalg.norm(x) * rng.uniform() ** (1.0 / len(axes)))
    peak = max(np.abs(freqresp_array(G0, f)).max(), 1e-300)
    err = 0.0
    for pt in pts:
        Gs = at(np.asarray(pt))[2]
        gap = freqresp_array(Gs, f) - freqresp_array(um.statespace(um.delta_of(Gs)), f)
        err = max(err, float(np.abs(gap).max()) / peak)
    from dataclasses import replace

    return replace(um, max_error=err)
