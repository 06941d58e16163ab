"""The G-scales of mixed-mu synthesis (D-G-K iteration): targets, rational fits, loop transformation.

For a block structure with real scalar blocks the mixed-mu upper bound at one frequency is
(Fan, Tits & Doyle 1991, IEEE TAC 36(1), Thm 2.1; Young 1996, "Controller design for mixed
uncertainties", Automatica 32(8))

    mu(M) <= beta   if   M^H X M + j (G M - M^H G^H) - beta^2 X <= 0,

``X = D^H D`` commuting with ``Delta`` and ``G`` Hermitian on the real blocks. The K step
of D-G-K needs this as an H-infinity condition on a *stable* rational plant. With
``Y = D M D^-1 / beta`` and, on each real channel, a stable real-rational ``r(s)`` with
``|r| < 1`` on the imaginary axis, the matrix

    Z = (Y + R_1) (I + R_2 Y)^-1,     R_1 = r on (z_i, w_i),  R_2 = r on (w_i, z_i),

satisfies ``sigma_max(Z) <= 1`` exactly when ``[Y; I]^H Pi [Y; I] <= 0`` for the multiplier
``Pi = Psi^H J Psi``, ``Psi = [[I, R_1], [R_2, I]]``, ``J = diag(I, -I)``: on a real channel
``Pi = [[1 - |r|^2, 2 j Im r], [-2 j Im r, |r|^2 - 1]]`` (a J-spectral factor of the D-G
multiplier with stable, stably invertible factors; the 2 x 2 symmetric form ``[[1, r], [r, 1]]``
keeps ``Pi``'s off-diagonal purely imaginary, as the real blocks' multipliers must be). Back
in ``M`` this is the LMI above with

    X_i = d_i^2 (1 - |r_i|^2),   G_i = -2 beta d_i^2 Im r_i,

so a mu analysis' optimal ``(X, G)`` at level ``beta`` is reproduced by
``Im r / (1 - |r|^2) = -g / (2 beta d^2)`` and ``d_fit = d / sqrt(1 - |r|^2)``. ``Z`` is a
star product ``Theta * Y`` with ``Theta = [[R_1, I - R_1 R_2], [I, -R_2]]`` (all stable),
so ``Z = Fl(Theta * (D P D^-1 / beta), K)``: the K step is an ordinary H-infinity synthesis
on the transformed plant, and ``||Z||_inf < 1`` certifies ``mu < beta`` at every frequency
(internal stability: the loop closed through ``-R_2`` is one stable perturbation of norm < 1
covered by the small-gain argument). The ``w`` the plant sees is ``w' - R_2 z`` and the
output ``z' = z + R_1 w``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..uncertainty.blocks import BlockStructure

__all__ = ["g_targets", "blended_scales", "transformed_norm", "fit_g_filter", "scaled_d_targets",
           "g_transform", "real_block_indices"]

#: largest |r| on the axis a G fit may reach (the transformation's loop gain)
R_MAX = 0.95
#: weight of |r| itself in the G fit: of the many r with the same Im r / (1 - |r|^2) (the real
#: part is free) the fit prefers small ones (a loop transformation near the identity)
R_WEIGHT = 0.02


def real_block_indices(blocks: BlockStructure) -> list[int]:
    """Indices of the real scalar blocks."""
    return [i for i, b in enumerate(blocks) if b.kind == "real"]


def g_targets(m: Any, blocks: BlockStructure, level: float) -> np.ndarray:
    """``gamma_i(f) = -g_i / (2 level d_i^2)`` per real block (nf, n_real), from a MuResult.

    ``g_i`` and ``d_i`` are the analysis' LMI scales (:class:`~robustctl.robust.mu.result.MuResult`
    ``g_matrices``, ``d_matrices``); a repeated real block uses ``tr(D^-H G D^-1) / r``.
    """
    out = []
    for i in real_block_indices(blocks):
        D = np.asarray(m.d_matrices[i])
        G = np.asarray(m.g_matrices[i])
        Di = np.linalg.inv(D)
        gh = np.trace(np.swapaxes(Di, 1, 2).conj() @ G @ Di, axis1=1, axis2=2).real / D.shape[-1]
        out.append(-gh / (2.0 * level))
    return np.stack(out, axis=1) if out else np.zeros((len(m.f_hz), 0))


def _lmi_max_eig(H: np.ndarray, blocks: BlockStructure, x: np.ndarray, g: np.ndarray,
                 level: np.ndarray) -> np.ndarray:
    """``lambda_max(M^H X M + j (G M - M^H G) - level^2 X)`` per frequency, relative to
    ``level^2 max(x)``, for scalar scales ``x`` (nf, n_blocks) and ``g`` (nf, n_blocks)."""
    zs, ws = blocks.row_slices(), blocks.col_slices()
    xl = np.zeros((H.shape[0], blocks.n_out))
    xr = np.zeros((H.shape[0], blocks.n_in))
    gd = np.zeros((H.shape[0], blocks.n_in))
    for i, (z, w) in enumerate(zip(zs, ws)):
        xl[:, z], xr[:, w] = x[:, [i]], x[:, [i]]
        if blocks.blocks[i].kind == "real":
            gd[:, w] = g[:, [i]]  # real blocks are square: G_i = g_i I on (w_i, z_i)
    MH = np.swapaxes(H, 1, 2).conj()
    L = MH @ (xl[:, :, None] * H)
    if np.any(gd):
        GM = np.zeros_like(L)
        for i, (z, w) in enumerate(zip(zs, ws)):
            if blocks.blocks[i].kind == "real":
                GM[:, w, :] = g[:, i, None, None] * H[:, z, :]
        X = 1j * GM
        L = L + X + np.swapaxes(X, 1, 2).conj()
    L = L - (level**2)[:, None, None] * np.eye(blocks.n_in) * xr[:, None, :]
    return np.linalg.eigvalsh(L)[:, -1] / (level**2 * x.max(axis=1))


def blended_scales(H: np.ndarray, m: Any, mc: Any, blocks: BlockStructure,
                   level: float) -> tuple[np.ndarray, np.ndarray]:
    """Scales for the D-G-K step: as close to the complex analysis' as the mixed bound allows.

    Where the real blocks hold mu down the optimal mixed scales are often extreme (the LMI
    optimum lies towards infinite scales) and jump from point to point, which no low-order
    D fit follows. The LMI is convex in ``(X, G)``: with the mixed optimum ``(X_m, G_m)``
    (feasible at ``mu_m(f)``) and the complex one ``(X_c, 0)`` (feasible at ``mu_c(f)``),
    ``(1 - lambda) (X_m, G_m) + lambda (X_c, 0)`` is feasible at ``b(f) = max(mu_m (1 + 1e-3),
    min(mu_c, level))`` for the largest ``lambda`` in [0, 1] found by bisection: the complex
    scales wherever mu_c <= level, the mixed ones only where the real blocks matter.
    Scalar scales per block (a repeated block's ``|det D|^(1/r)`` and mean G).

    Returns
    -------
    d : ndarray (nf, n_blocks)
        D-scales (last block 1).
    gamma : ndarray (nf, n_real)
        ``-g / (2 level d^2)`` per real block (:func:`fit_g_filter`'s targets).
    """
    nf = H.shape[0]
    dm = np.asarray(m.d_scales, dtype=float)
    dm = dm / dm[:, [-1]]
    dc = np.asarray(mc.d_scales, dtype=float)
    dc = dc / dc[:, [-1]]
    xm, xc = dm**2, dc**2
    gm = np.zeros_like(xm)
    gam_m = g_targets(m, blocks, 1.0)  # -g^ / 2 with g^ = g / d^2 (level 1)
    for k, i in enumerate(real_block_indices(blocks)):
        gm[:, i] = -2.0 * gam_m[:, k] * xm[:, i]
    b = np.maximum(np.asarray(m.upper) * (1 + 1e-3), np.minimum(np.asarray(mc.upper), level))
    lo, hi = np.zeros(nf), np.ones(nf)

    def feasible(lam: np.ndarray) -> np.ndarray:
        x = (1 - lam)[:, None] * xm + lam[:, None] * xc
        g = (1 - lam)[:, None] * gm
        return _lmi_max_eig(H, blocks, x, g, b) <= 1e-9

    ok1 = feasible(hi)
    lo[ok1] = 1.0
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        f = feasible(mid)
        lo, hi = np.where(f, mid, lo), np.where(f, hi, mid)
    lam = lo
    x = (1 - lam)[:, None] * xm + lam[:, None] * xc
    g = (1 - lam)[:, None] * gm
    d = np.sqrt(x)
    gamma = np.stack([-g[:, i] / (2.0 * level * x[:, i]) for i in real_block_indices(blocks)], axis=1)
    return d / d[:, [-1]], gamma


def transformed_norm(H: np.ndarray, blocks: BlockStructure, d: np.ndarray, r: np.ndarray,
                     level: float) -> np.ndarray:
    """``sigma_max(Z)`` per frequency, ``Z = (Y + R_1)(I + R_2 Y)^-1``, ``Y = D H D^-1 / level``.

    ``d`` (nf, n_blocks) positive scalar D-scales, ``r`` (nf, n_real) the G filters' values.
    ``sigma_max(Z) <= 1`` certifies ``mu(H) <= level`` (module docstring).
    """
    zs, ws = blocks.row_slices(), blocks.col_slices()
    nf = H.shape[0]
    dl, dr = np.zeros((nf, blocks.n_out)), np.zeros((nf, blocks.n_in))
    for i, (z, w) in enumerate(zip(zs, ws)):
        dl[:, z], dr[:, w] = d[:, [i]], d[:, [i]]
    Y = dl[:, :, None] * H / dr[:, None, :] / level
    R1 = np.zeros((nf, blocks.n_out, blocks.n_in), complex)
    R2 = np.zeros((nf, blocks.n_in, blocks.n_out), complex)
    for k, i in enumerate(real_block_indices(blocks)):
        for j in range(blocks.blocks[i].rows):
            R1[:, zs[i].start + j, ws[i].start + j] = r[:, k]
            R2[:, ws[i].start + j, zs[i].start + j] = r[:, k]
    Z = np.linalg.solve(np.swapaxes(np.eye(blocks.n_in) + R2 @ Y, 1, 2), np.swapaxes(Y + R1, 1, 2))
    return np.linalg.norm(Z, ord=2, axis=(1, 2))


def _basis(w: np.ndarray, poles: np.ndarray) -> np.ndarray:
    """``[p_k / (s + p_k), s / (s + p_k)]`` at ``s = j w``, shape (nf, 2 n)."""
    s = 1j * w[:, None]
    return np.concatenate([poles / (s + poles), s / (s + poles)], axis=1)


def fit_g_filter(f_hz: np.ndarray, gamma: np.ndarray, weight: np.ndarray, n_poles: int | None = None):
    """A stable real-rational ``r(s)`` with ``Im r / (1 - |r|^2) ~ gamma`` and ``|r| <= R_MAX``.

    ``r(s) = sum_k a_k p_k / (s + p_k) + b_k s / (s + p_k)`` with real poles ``p_k`` spread
    (two per decade, 2 to 6) over the band where ``weight * |gamma|`` matters, coefficients
    by nonlinear least squares (scipy's trust-region reflective) on
    ``weight (Im r / (1 - |r|^2) - gamma) / (1 + |gamma|)``, with a penalty above ``R_MAX``
    and a small one (``R_WEIGHT``) on ``|r|``.

    Parameters
    ----------
    f_hz : ndarray (nf,)
        Frequencies (Hz).
    gamma : ndarray (nf,)
        Targets from :func:`g_targets`.
    weight : ndarray (nf,)
        Non-negative importance per frequency (e.g. ``(mu / peak)^4``).
    n_poles : int, optional
        Number of poles (default: two per decade of the band, 2..6).

    Returns
    -------
    control.StateSpace
        SISO, stable; ``r(j w)`` is returned by :func:`robustctl.lti.freqresp_array`.
    """
    import control
    from scipy.optimize import least_squares

    w = 2 * np.pi * np.asarray(f_hz, dtype=float)
    gamma = np.asarray(gamma, dtype=float)
    wt = np.asarray(weight, dtype=float)
    size = wt * np.abs(gamma)
    if not np.any(size > 0):
        return control.ss([], [], [], [[0.0]])
    used = size >= 0.05 * size.max()
    lo, hi = w[used].min(), w[used].max()
    if n_poles is None:
        n_poles = int(np.clip(np.ceil(2 * np.log10(hi / lo)) + 1, 2, 6))
    poles = np.geomspace(lo, hi, n_poles) if n_poles > 1 else np.array([np.sqrt(lo * hi)])
    Phi = _basis(w, poles)
    norm = 1.0 + np.abs(gamma)

    def residual(c: np.ndarray) -> np.ndarray:
        r = Phi @ c
        a2 = np.abs(r) ** 2
        val = r.imag / np.maximum(1.0 - a2, 1e-3)
        over = np.maximum(np.sqrt(a2) - R_MAX, 0.0)
        return np.concatenate([wt * (val - gamma) / norm, 10.0 * over * np.sqrt(wt.max()),
                               R_WEIGHT * np.sqrt(wt.max() * a2), 1e-3 * c])

    sol = least_squares(residual, np.zeros(2 * n_poles), method="trf", max_nfev=200 * (2 * n_poles + 1))
    c = sol.x
    r = Phi @ c
    peak = np.abs(r).max()
    if peak > R_MAX:  # the penalty is soft: shrink to the bound
        c = c * (R_MAX / peak)
    a, b = c[:n_poles], c[n_poles:]
    A = -np.diag(poles)
    return control.ss(A, np.ones((n_poles, 1)), (poles * (a - b))[None, :], [[float(b.sum())]])


def scaled_d_targets(d: np.ndarray, blocks: BlockStructure, r_mag: np.ndarray) -> np.ndarray:
    """D-scales that keep the analysis' ``X`` with the G filters: ``d_i / sqrt(1 - |r_i|^2)``
    on the real blocks, renormalised so that the last block's is 1 (nf, n_blocks)."""
    out = np.array(d, dtype=float, copy=True)
    for k, i in enumerate(real_block_indices(blocks)):
        out[:, i] = out[:, i] / np.sqrt(np.maximum(1.0 - r_mag[:, k] ** 2, 1e-6))
    return out / out[:, [-1]]


def g_transform(P: Any, blocks: BlockStructure, g_fits: tuple, level: float):
    """``Theta * (P with z / level)``: the plant on which ``||Fl(., K)||_inf < 1`` certifies
    ``mu < level`` with the G filters ``g_fits`` (one SISO per real block, in block order).

    ``P``'s inputs are ``[w; u]`` and outputs ``[z; y]`` with ``w``, ``z`` in block order
    (rows of block ``i`` are its ``w`` channels, columns its ``z`` channels). Each channel of a
    real block gets two copies of its filter: ``q = r z_j`` (fed back, ``w_j = w'_j - q``)
    and ``z'_j = z_j + r w_j``. Returns a control.StateSpace with ``P``'s names.
    """
    import control

    A0, B0, C0, D0 = (np.asarray(x, dtype=float) for x in (P.A, P.B, P.C, P.D))
    nz, nw = blocks.n_out, blocks.n_in
    scale = np.ones(C0.shape[0])
    scale[:nz] = 1.0 / level
    C0, D0 = C0 * scale[:, None], D0 * scale[:, None]
    # the filter of every real channel (z index, w index, filter)
    chans = []
    rows, cols = blocks.col_slices(), blocks.row_slices()  # w slices, z slices
    for k, i in enumerate(real_block_indices(blocks)):
        r = g_fits[k]
        for j in range(blocks.blocks[i].rows):
            chans.append((cols[i].start + j, rows[i].start + j, r))
    n_p = A0.shape[0]
    nin, nout = B0.shape[1], C0.shape[0]
    # states: plant, then per channel [x_a (on z), x_b (on w)]
    sizes = [np.asarray(r.A).shape[0] for _, _, r in chans]
    n = n_p + 2 * sum(sizes)
    # build the open map from [w'; u; q] and closing: w = w' - q, q = r z, z' = z + r w
    # algebraic part: z depends on w through D0[:nz, :nw]; q depends on z through dr
    # Write the combined system with w eliminated: unknown vector v = w (nw), solve
    # w = w' - Q_x x_a - Dr_z z,  z = C0z x + D0zw w + D0zu u
    Dr = np.zeros((nw, nz))
    Qx = np.zeros((nw, n))
    Ar_blocks, off = [], n_p
    for (zi, wi, r), m in zip(chans, sizes):
        ar, br, cr, dr = (np.asarray(x, dtype=float) for x in (r.A, r.B, r.C, r.D))
        Dr[wi, zi] = dr[0, 0]
        Qx[wi, off:off + m] = cr[0]
        Ar_blocks.append((off, m, ar, br, cr, dr, zi, wi))
        off += 2 * m
    Czx = np.zeros((nz, n))
    Czx[:, :n_p] = C0[:nz]
    Dzw, Dzu = D0[:nz, :nw], D0[:nz, nw:]
    # w = w' - Qx x - Dr (Czx x + Dzw w + Dzu u)  =>  (I + Dr Dzw) w = w' - (Qx + Dr Czx) x - Dr Dzu u
    L = np.linalg.inv(np.eye(nw) + Dr @ Dzw)
    # w = Wx x + Ww w' + Wu u
    Wx, Ww, Wu = -L @ (Qx + Dr @ Czx), L, -L @ Dr @ Dzu
    nu = nin - nw
    # z = Zx x + Zw w' + Zu u
    Zx, Zw, Zu = Czx + Dzw @ Wx, Dzw @ Ww, Dzu + Dzw @ Wu
    A = np.zeros((n, n))
    B = np.zeros((n, nw + nu))
    A[:n_p, :n_p] = A0
    A[:n_p] += B0[:, :nw] @ Wx
    B[:n_p, :nw] = B0[:, :nw] @ Ww
    B[:n_p, nw:] = B0[:, nw:] + B0[:, :nw] @ Wu
    # outputs: z' = z + r w on real channels, y = C0y x + D0yw w + D0yu u
    C = np.zeros((nout, n))
    D = np.zeros((nout, nw + nu))
    C[:nz], D[:nz, :nw], D[:nz, nw:] = Zx, Zw, Zu
    Cyx = np.zeros((nout - nz, n))
    Cyx[:, :n_p] = C0[nz:]
    Dyw, Dyu = D0[nz:, :nw], D0[nz:, nw:]
    C[nz:] = Cyx + Dyw @ Wx
    D[nz:, :nw] = Dyw @ Ww
    D[nz:, nw:] = Dyu + Dyw @ Wu
    for off, m, ar, br, cr, dr, zi, wi in Ar_blocks:
        a, b = slice(off, off + m), slice(off + m, off + 2 * m)
        # x_a' = ar x_a + br z_zi
        A[a, :] += br @ Zx[zi:zi + 1]
        A[a, a] += ar
        B[a, :nw] += br @ Zw[zi:zi + 1]
        B[a, nw:] += br @ Zu[zi:zi + 1]
        # x_b' = ar x_b + br w_wi
        A[b, :] += br @ Wx[wi:wi + 1]
        A[b, b] += ar
        B[b, :nw] += br @ Ww[wi:wi + 1]
        B[b, nw:] += br @ Wu[wi:wi + 1]
        # z'_zi = z_zi + cr x_b + dr w_wi
        C[zi, b] += cr[0]
        C[zi] += dr[0, 0] * Wx[wi]
        D[zi, :nw] += dr[0, 0] * Ww[wi]
        D[zi, nw:] += dr[0, 0] * Wu[wi]
    return control.ss(A, B, C, D, inputs=list(P.input_labels), outputs=list(P.output_labels))
