"""LFT object algebra on raw partitioned realisations, and their structured order reduction.

An uncertain system is kept as one realisation ``(A, [B_w B_u], [C_z; C_y], [[D_zw, D_zu],
[D_yw, D_yu]])`` closed from above by ``w = Delta z`` (Zhou, Doyle & Glover 1996, "Robust
and Optimal Control", sec. 10.1-10.2: every interconnection of LFTs is an LFT of the stacked
perturbation). :func:`connect` is the one interconnection rule: the parts' external signals
``u`` are ``F r + E y`` of the exogenous inputs ``r`` and the parts' outputs ``y``, and the
result's outputs are ``H y + J r``; the algebraic loop is solved once with ``(I - D_yu E)^-1``
(well-posedness). Series, parallel, feedback, concatenation and substitution are that rule
with different ``E, F, H, J``; the inverse is the partial inversion of ZDG lemma 10.3.

:func:`reduce_scalar_blocks` removes repeated copies of scalar blocks that the structure does
not need: the structured Kalman decomposition of Beck & Doyle (1999, "A necessary and
sufficient minimality condition for uncertain systems", IEEE TAC 44(10)) and D'Andrea &
Khatri (1997): a block-diagonal subspace ``V = (+)_j V_j`` with ``range(P_j B) in V_j`` and
``P_j A_big V in V_j`` for every block ``j`` (``A_big = [[A, B_w], [C_z, D_zw]]``) is
invariant under ``A_big Delta`` for every ``Delta = diag(I/s, delta_j I)``, so the LFT
restricted to it is exact; the dual (observability) step follows. The states are the
repeated scalar ``1/s`` and can be reduced alike (``states=True``: a minimal realisation,
which may drop hidden unstable modes); full (dynamics) blocks keep their whole space.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import SynthesisError

__all__ = ["Raw", "connect", "invert", "close_channels", "reduce_scalar_blocks", "permute_delta"]

#: relative singular value below which a direction of the reachable/observable space is dropped
REDUCE_RTOL = 1e-12


@dataclass(frozen=True)
class Raw:
    """A partitioned realisation: inputs ``[w; u]``, outputs ``[z; y]``; ``nw`` w-channels,
    ``nz`` z-channels."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    nw: int
    nz: int

    @property
    def nx(self) -> int:
        return self.A.shape[0]

    @property
    def nu(self) -> int:
        return self.B.shape[1] - self.nw

    @property
    def ny(self) -> int:
        return self.C.shape[0] - self.nz

    def parts(self):
        w, z = self.nw, self.nz
        B, C, D = self.B, self.C, self.D
        return B[:, :w], B[:, w:], C[:z], C[z:], D[:z, :w], D[:z, w:], D[z:, :w], D[z:, w:]


def _dtype(*arrs):
    return complex if any(np.iscomplexobj(a) for a in arrs) else float


def _blkdiag(mats, rows, cols, dtype):
    out = np.zeros((sum(rows), sum(cols)), dtype)
    r = c = 0
    for m, nr, nc in zip(mats, rows, cols):
        out[r:r + nr, c:c + nc] = m
        r, c = r + nr, c + nc
    return out


def connect(parts: list[Raw], E: np.ndarray, F: np.ndarray, H: np.ndarray, J: np.ndarray) -> Raw:
    """Interconnect ``parts`` (their w/z channels stacked in order, passed through).

    ``u = F r + E y``, outputs ``H y + J r`` (``u``, ``y`` the parts' stacked external signals).

    Raises
    ------
    SynthesisError
        The interconnection is not well posed (``I - D_yu E`` singular).
    """
    dt = _dtype(*(p.A for p in parts), *(p.B for p in parts), *(p.C for p in parts), *(p.D for p in parts),
                E, F, H, J)
    sp = [p.parts() for p in parts]
    nx = [p.nx for p in parts]
    nw = [p.nw for p in parts]
    nz = [p.nz for p in parts]
    nu = [p.nu for p in parts]
    ny = [p.ny for p in parts]
    A = _blkdiag([p.A for p in parts], nx, nx, dt)
    Bw = _blkdiag([s[0] for s in sp], nx, nw, dt)
    Bu = _blkdiag([s[1] for s in sp], nx, nu, dt)
    Cz = _blkdiag([s[2] for s in sp], nz, nx, dt)
    Cy = _blkdiag([s[3] for s in sp], ny, nx, dt)
    Dzw = _blkdiag([s[4] for s in sp], nz, nw, dt)
    Dzu = _blkdiag([s[5] for s in sp], nz, nu, dt)
    Dyw = _blkdiag([s[6] for s in sp], ny, nw, dt)
    Dyu = _blkdiag([s[7] for s in sp], ny, nu, dt)
    Iy = np.eye(sum(ny))
    loop = Iy - Dyu @ E
    if sum(ny) and np.linalg.cond(loop) > 1e12:
        raise SynthesisError(
            "the interconnection is not well posed: I - D E is singular (an algebraic loop with "
            "unit gain, e.g. feedback of a static gain -1 with sign -1); change the sign or add dynamics.")
    L = np.linalg.solve(loop, np.eye(sum(ny))) if sum(ny) else np.zeros((0, 0))
    ELCy, ELDyw, G = E @ L @ Cy, E @ L @ Dyw, F + E @ L @ Dyu @ F
    A2 = A + Bu @ ELCy
    Bw2, Br = Bw + Bu @ ELDyw, Bu @ G
    Cz2, Dzw2, Dzr = Cz + Dzu @ ELCy, Dzw + Dzu @ ELDyw, Dzu @ G
    Co, Dow, Dor = H @ L @ Cy, H @ L @ Dyw, H @ L @ Dyu @ F + J
    return Raw(A2, np.hstack([Bw2, Br]), np.vstack([Cz2, Co]),
               np.block([[Dzw2, Dzr], [Dow, Dor]]), sum(nw), sum(nz))


def invert(p: Raw) -> Raw:
    """The LFT of ``G^-1`` (inputs ``y``, outputs ``u``; ZDG lemma 10.3): needs ``D_yu``
    square and invertible."""
    Bw, Bu, Cz, Cy, Dzw, Dzu, Dyw, Dyu = p.parts()
    if Dyu.shape[0] != Dyu.shape[1] or Dyu.size == 0 or np.linalg.cond(Dyu) > 1e12:
        raise SynthesisError(
            "the inverse of an uncertain system needs a square, invertible feedthrough D (a proper "
            f"system with a proper inverse); D is {Dyu.shape[0]}x{Dyu.shape[1]}"
            f"{' and singular' if Dyu.shape[0] == Dyu.shape[1] and Dyu.size else ''}. Invert a "
            "biproper factor, or write the loop with feedback().")
    Di = np.linalg.inv(Dyu)
    A = p.A - Bu @ Di @ Cy
    Bw2, Br = Bw - Bu @ Di @ Dyw, Bu @ Di
    Cz2, Dzw2, Dzr = Cz - Dzu @ Di @ Cy, Dzw - Dzu @ Di @ Dyw, Dzu @ Di
    Co, Dow, Dor = -Di @ Cy, -Di @ Dyw, Di
    return Raw(A, np.hstack([Bw2, Br]), np.vstack([Cz2, Co]), np.block([[Dzw2, Dzr], [Dow, Dor]]), p.nw, p.nz)


def permute_delta(p: Raw, w_order: np.ndarray, z_order: np.ndarray) -> Raw:
    """Reorder the w and z channels."""
    nu, ny = p.nu, p.ny
    cols = np.concatenate([w_order, p.nw + np.arange(nu)]).astype(int)
    rows = np.concatenate([z_order, p.nz + np.arange(ny)]).astype(int)
    return Raw(p.A, p.B[:, cols], p.C[rows], p.D[np.ix_(rows, cols)], p.nw, p.nz)


def close_channels(p: Raw, nw_close: int, nz_close: int, delta: Raw) -> Raw:
    """Close the first ``nw_close`` w- and ``nz_close`` z-channels with ``delta`` (a realisation
    without w/z channels, inputs z, outputs w): the partial upper LFT (star product)."""
    # move the closed channels into the u/y group of a part and feed them through delta
    w_rest = p.nw - nw_close
    z_rest = p.nz - nz_close
    cols = np.concatenate([np.arange(nw_close, p.nw), np.arange(nw_close), p.nw + np.arange(p.nu)])
    rows = np.concatenate([np.arange(nz_close, p.nz), np.arange(nz_close), p.nz + np.arange(p.ny)])
    q = Raw(p.A, p.B[:, cols], p.C[rows], p.D[np.ix_(rows, cols)], w_rest, z_rest)
    nu, ny = p.nu, p.ny
    # parts: [q (u = [w_c; u]), delta (u = z_c)], y = [z_c; y; w_c]
    n_in_q, n_out_q = nw_close + nu, nz_close + ny
    E = np.zeros((n_in_q + nz_close, n_out_q + nw_close))
    E[:nw_close, n_out_q:] = np.eye(nw_close)  # w_c = delta output
    E[n_in_q:, :nz_close] = np.eye(nz_close)  # delta input = z_c
    F = np.zeros((n_in_q + nz_close, nu))
    F[nw_close:n_in_q] = np.eye(nu)
    H = np.zeros((ny, n_out_q + nw_close))
    H[:, nz_close:n_out_q] = np.eye(ny)
    return connect([q, delta], E, F, H, np.zeros((ny, nu)))


def _basis(M: np.ndarray, tol: float) -> np.ndarray:
    if M.size == 0:
        return np.zeros((M.shape[0], 0), M.dtype)
    U, s, _ = np.linalg.svd(M, full_matrices=False)
    return U[:, s > tol]


def _structured_space(Abig: np.ndarray, Bbig: np.ndarray, groups: list[np.ndarray], reducible: list[bool],
                      tol: float) -> list[np.ndarray]:
    """Per group an orthonormal basis of the smallest block-diagonal ``A_big``-invariant space
    holding ``range(B_big)`` (whole space for groups that are not reducible)."""
    bases = []
    for g, red in zip(groups, reducible):
        bases.append(_basis(Bbig[g], tol) if red else np.eye(g.size, dtype=Abig.dtype))
    for _ in range(sum(g.size for g in groups) + 1):
        grown = False
        cols = np.concatenate([np.zeros(0, int), *groups])
        V = np.zeros((Abig.shape[1], sum(b.shape[1] for b in bases)), Abig.dtype)
        c = 0
        for g, b in zip(groups, bases):
            V[g, c:c + b.shape[1]] = b
            c += b.shape[1]
        AV = Abig[:, cols] @ V[cols] if cols.size else V
        for j, (g, red) in enumerate(zip(groups, reducible)):
            if not red:
                continue
            new = _basis(np.hstack([bases[j], AV[g]]), tol)
            if new.shape[1] > bases[j].shape[1]:
                bases[j], grown = new, True
        if not grown:
            break
    return bases


def reduce_scalar_blocks(p: Raw, widths: list[int], scalar: list[bool],
                         states: bool = False) -> tuple[Raw, list[int]]:
    """Structured Kalman reduction of the repeated scalar blocks (module docstring).

    Parameters
    ----------
    p : Raw
        Its w/z channels grouped per block (``widths[j]`` each; a scalar block's w- and
        z-widths are equal).
    widths : list of int
        w-channels per block (for dynamics blocks the w-width; their z-width follows from
        ``p.nz - sum of the others``).
    scalar : list of bool
        Which blocks may be reduced (repeated real or complex scalars).
    states : bool
        Reduce the states too (the repeated scalar ``1/s``): removes hidden modes, stable or
        not, so it is off inside interconnections (internal stability needs every mode).

    Returns
    -------
    (Raw, list of int)
        The reduced realisation and the new widths.
    """
    if p.nz != p.nw:  # a non-square dynamics block: keep the realisation
        return p, widths
    Bw, Bu, Cz, Cy, Dzw, Dzu, Dyw, Dyu = p.parts()
    Abig = np.block([[p.A, Bw], [Cz, Dzw]])
    Bbig = np.vstack([Bu, Dzu])
    Cbig = np.hstack([Cy, Dyw])
    scale = max(np.abs(Abig).max(initial=0), np.abs(Bbig).max(initial=0), np.abs(Cbig).max(initial=0), 1e-300)
    tol = REDUCE_RTOL * scale * max(Abig.shape[0], 1)
    nx = p.nx
    # z-widths equal the w-widths for scalar blocks; full blocks take their own (in order)
    out_groups = [np.arange(nx)] + _ranges(nx, widths)
    red = [bool(states)] + list(scalar)
    # reachability (output space of A_big = [x'; z]); scalar groups share in/out coordinates
    Vb = _structured_space(Abig, Bbig, out_groups, red, tol)
    T = _blkdiag(Vb, [g.size for g in out_groups], [b.shape[1] for b in Vb], Abig.dtype)
    Abig, Bbig, Cbig = T.conj().T @ Abig @ T, T.conj().T @ Bbig, Cbig @ T
    sizes = [b.shape[1] for b in Vb]
    groups = _ranges(0, sizes)
    # observability: the same on the transposed system
    Wb = _structured_space(Abig.conj().T, Cbig.conj().T, groups, red, tol)
    T = _blkdiag(Wb, sizes, [b.shape[1] for b in Wb], Abig.dtype)
    Abig, Bbig, Cbig = T.conj().T @ Abig @ T, T.conj().T @ Bbig, Cbig @ T
    sizes = [b.shape[1] for b in Wb]
    nx, nw_new = sizes[0], sum(sizes[1:])
    A, Bw, Cz, Dzw = Abig[:nx, :nx], Abig[:nx, nx:], Abig[nx:, :nx], Abig[nx:, nx:]
    Bu, Dzu = Bbig[:nx], Bbig[nx:]
    Cy, Dyw = Cbig[:, :nx], Cbig[:, nx:]
    out = Raw(A, np.hstack([Bw, Bu]), np.vstack([Cz, Cy]), np.block([[Dzw, Dzu], [Dyw, Dyu]]), nw_new, nw_new)
    return out, sizes[1:]


def _ranges(start: int, sizes: list[int]) -> list[np.ndarray]:
    out, s = [], start
    for n in sizes:
        out.append(np.arange(s, s + n))
        s += n
    return out
