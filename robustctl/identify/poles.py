"""Pole bookkeeping shared by the fitting methods: the real partial-fraction basis,
conjugate-pair splitting, stability reflection and the linear residue identification.

A pole set is stored as *one pole per complex-conjugate pair* (``Im p > 0``) plus the real
poles, in rad/s. A model with poles ``p`` and residue matrices ``R`` is

    G(s) = D + sum_real R_k / (s - p_k) + sum_pairs [R_k / (s - p_k) + conj(R_k) / (s - conj(p_k))].
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "TIE_MARGIN",
    "first_lowest",
    "split_poles",
    "reflect_unstable",
    "partial_fraction_basis",
    "fit_residues",
    "evaluate",
    "n_states",
    "pole_change",
    "weighted_cost",
    "BestPoles",
    "lstsq_normal",
    "basis_gram",
    "GramWeights",
]

#: |Im p| below this fraction of |p| counts as a real pole.
REAL_TOL = 1e-9


def split_poles(z: np.ndarray) -> np.ndarray:
    """Reduce a conjugate-symmetric set of roots to one pole per pair plus the real poles.

    Returns the poles sorted by natural frequency |p|; real poles get an exactly zero
    imaginary part.
    """
    z = np.asarray(z, dtype=complex).reshape(-1)
    scale = np.maximum(np.abs(z), np.finfo(float).tiny)
    real = np.abs(z.imag) <= REAL_TOL * scale
    poles = np.concatenate([z[real].real.astype(complex), z[~real & (z.imag > 0)]])
    return poles[np.argsort(np.abs(poles), kind="stable")]


def n_states(poles: np.ndarray) -> int:
    """Order of the pole set counting conjugates (two per complex pole, one per real pole)."""
    poles = np.asarray(poles)
    return int(np.sum(np.where(poles.imag != 0, 2, 1)))


def reflect_unstable(poles: np.ndarray) -> tuple[np.ndarray, int]:
    """Reflect poles with ``Re p > 0`` into the left half plane (Gustavsen's pole flipping).

    Returns the new poles and how many were reflected. Poles exactly on the imaginary axis
    are moved to a tiny negative real part (1e-9 |p|).
    """
    p = np.array(poles, dtype=complex)
    flip = p.real > 0
    p[flip] = -p[flip].real + 1j * p[flip].imag
    on_axis = p.real == 0
    p[on_axis] = -1e-9 * np.maximum(np.abs(p[on_axis]), 1.0) + 1j * p[on_axis].imag
    return p, int(np.count_nonzero(flip))


def partial_fraction_basis(s: np.ndarray, poles: np.ndarray) -> np.ndarray:
    """Real-coefficient partial-fraction basis, complex array of shape (K, n_states(poles)).

    A real pole ``a`` gives the column ``1/(s-a)``; a pair ``p, conj(p)`` gives the two columns
    ``1/(s-p) + 1/(s-conj p)`` and ``j/(s-p) - j/(s-conj p)``, whose real coefficients
    ``(x1, x2)`` are the residue ``x1 + j x2`` of ``p``.
    """
    s = np.asarray(s)
    q, idx, _ = _atoms(np.asarray(poles, dtype=complex))
    return _basis_from_atoms(1.0 / (s[:, None] - q[None, :]), idx)


def _basis_from_atoms(atoms: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """:func:`partial_fraction_basis` from the atoms ``1/(s - q)`` of :func:`_atoms` (K, M) and their
    index pairs: ``a + b`` and ``j (a - b)`` per pair, ``a`` per real pole, written block by block
    (a scattered column assignment is several times slower than the divisions)."""
    k = atoms.shape[0]
    pair = idx[:, 0] != idx[:, 1]
    if np.all(pair):  # every pole complex: the atoms come as (p, conj p) side by side
        a, b = atoms[:, 0::2], atoms[:, 1::2]
        out = np.empty((k, a.shape[1], 2), dtype=complex)
        np.add(a, b, out=out[:, :, 0])
        out[:, :, 1] = 1j * (a - b)
        return out.reshape(k, -1)
    out = np.empty((k, idx.shape[0]), dtype=complex)
    real = np.flatnonzero(~pair)
    out[:, real] = atoms[:, idx[real, 0]]
    first = np.flatnonzero(pair)[0::2]  # each complex pole's first column
    a, b = atoms[:, idx[first, 0]], atoms[:, idx[first, 1]]
    out[:, first] = a + b
    out[:, first + 1] = 1j * (a - b)
    return out


def _atoms(poles: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The columns of :func:`partial_fraction_basis` as combinations of the atoms ``1/(s - q)``
    over the poles and their conjugates: column ``j`` is ``coef[j, 0] / (s - q[idx[j, 0]]) +
    coef[j, 1] / (s - q[idx[j, 1]])`` (a real pole's second coefficient is 0). Returns (q, idx, coef)."""
    q, idx, coef = [], [], []
    for p in poles:
        if p.imag == 0:
            q.append(complex(p.real))
            idx.append((len(q) - 1, len(q) - 1))
            coef.append((1.0, 0.0))
        else:
            q += [complex(p), complex(np.conj(p))]
            k = len(q) - 2
            idx += [(k, k + 1), (k, k + 1)]
            coef += [(1.0, 1.0), (1j, -1j)]
    return np.array(q, dtype=complex), np.array(idx, dtype=int).reshape(-1, 2), np.array(coef).reshape(-1, 2)


def _re_products(
    a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray], out: np.ndarray | None = None
) -> np.ndarray:
    """``out[x, w, y] = Re(a0[w, x] b0[x, y] + a1[w, x] b1[x, y])`` as one batched real product
    (into ``out``, shape (n, n_w, n), when given)."""
    left = np.stack([a[0].real.T, a[1].real.T, -a[0].imag.T, -a[1].imag.T], axis=-1)  # (n, n_w, 4)
    right = np.stack([b[0].real, b[1].real, b[0].imag, b[1].imag], axis=1)  # (n, 4, n)
    return np.matmul(left, right, out=out)


class GramWeights:
    """Weight columns prepared once for many :func:`basis_gram` calls on the same data (the
    transposed columns, their conjugates and their sums), e.g. every relocation of a vector fit.

    Parameters
    ----------
    v : ndarray, complex or real, shape (K, n_w)
        Weight columns, as :func:`basis_gram` takes them.
    reuse : bool
        Keep :func:`basis_gram`'s working arrays, and the Gram blocks it returns, for its next
        call with as many poles (the caller is done with the blocks before that call): a large
        problem's arrays are then not allocated and first touched again at every call.
    """

    def __init__(self, v: np.ndarray, reuse: bool = False):
        self.vt = np.ascontiguousarray(np.asarray(v, dtype=complex).T)
        self.vt_conj = np.conj(self.vt)
        self.sums = self.vt.sum(axis=1).real
        self._work: dict | None = {} if reuse else None

    def buffer(self, key: str, shape: tuple[int, ...]) -> np.ndarray:
        """An uninitialised float array of ``shape``: the one kept under ``key`` when reused."""
        if self._work is None:
            return np.empty(shape)
        buf = self._work.get(key)
        if buf is None or buf.shape != shape:
            buf = self._work[key] = np.empty(shape)
        return buf


def basis_gram(s: np.ndarray, poles: np.ndarray, v, with_basis: bool = False):
    """``Re(B^H diag(v_c) B)`` for every weight column ``v_c``, with ``B = [partial_fraction_basis(s,
    poles), 1]`` and ``s`` on the imaginary axis, in O(K n) per column instead of O(K n^2).

    On ``s = j w``, ``conj(1/(s - q_a)) = -1/(s + conj q_a)``, and the partial fractions

        conj(phi_a) phi_b = [1/(s + conj q_a) - 1/(s - q_b)] / (q_b + conj q_a)

    turn every Gram entry into a difference of two first moments, ``E_a = sum_k v_k/(s_k + conj
    q_a)`` and ``F_b = sum_k v_k/(s_k - q_b)`` (one matrix product each), times fixed factors. The
    rounding error of an entry stays of the order of eps times the geometric mean of its two
    diagonal entries, because ``|q_b + conj q_a| >= |Re q_a| + |Re q_b|`` for stable poles.

    Parameters
    ----------
    s : ndarray, complex, shape (K,)
        Laplace variable ``j w`` (purely imaginary).
    poles : ndarray, complex
        One pole per conjugate pair plus real poles, all with ``Re p < 0``.
    v : ndarray, complex or real, shape (K, n_w), or GramWeights
        Weight columns (or the same prepared by :class:`GramWeights`).
    with_basis : bool
        Also return :func:`partial_fraction_basis` ``(s, poles)``, made from the same atoms
        ``1/(s - q)`` (one set of divisions for both).

    Returns
    -------
    ndarray, shape (n_w, n + 1, n + 1)
        Real Gram matrices, basis order of :func:`partial_fraction_basis` then the constant; with
        ``with_basis``, the tuple (Gram matrices, basis (K, n)).
    """
    q, idx, coef = _atoms(poles)
    if not isinstance(v, GramWeights):
        v = GramWeights(v)
    vt = v.vt
    atoms = 1.0 / (s[:, None] - q[None, :])
    # on s = j w, 1/(s + conj q) = -conj(1/(s - q)): E = -conj(conj(v)^T atoms), no second division
    mirror = -np.conj(v.vt_conj @ atoms)  # E (n_w, M)
    first = vt @ atoms  # F
    r = 1.0 / (q[None, :] + np.conj(q)[:, None])  # r[a, b] = 1/(q_b + conj q_a)
    # P[a, y] = sum_{b in y} t_yb r[a, b];  Q[x, b] = sum_{a in x} conj(t_xa) r[a, b]
    p_ay = r[:, idx[:, 0]] * coef[:, 0] + r[:, idx[:, 1]] * coef[:, 1]
    q_xb = np.conj(coef[:, :1]) * r[idx[:, 0]] + np.conj(coef[:, 1:]) * r[idx[:, 1]]
    n = idx.shape[0]
    e = [np.conj(coef[:, j]) * mirror[:, idx[:, j]] for j in range(2)]  # conj(t_xa) E_a, (n_w, n)
    f = [coef[:, j] * first[:, idx[:, j]] for j in range(2)]  # t_yb F_b
    n_w = vt.shape[0]
    # (x, w, y) and (y, w, x)
    term_e = _re_products(e, [p_ay[idx[:, j]] for j in range(2)], v.buffer("e", (n, n_w, n)))
    term_f = _re_products(f, [q_xb[:, idx[:, j]].T for j in range(2)], v.buffer("f", (n, n_w, n)))
    gram = v.buffer("gram", (n_w, n + 1, n + 1))
    np.subtract(np.swapaxes(term_e, 0, 1), np.transpose(term_f, (1, 2, 0)), out=gram[:, :n, :n])
    gram[:, :n, n] = -(e[0] + e[1]).real  # sum v conj(B_x) = -sum conj(t_xa) E_a
    gram[:, n, :n] = (f[0] + f[1]).real
    gram[:, n, n] = v.sums
    return (gram, _basis_from_atoms(atoms, idx)) if with_basis else gram


def coefficients_to_residues(x: np.ndarray, poles: np.ndarray) -> np.ndarray:
    """Map real basis coefficients (first axis) to one complex residue per pole."""
    out, k = [], 0
    for p in poles:
        if p.imag == 0:
            out.append(x[k] + 0j)
            k += 1
        else:
            out.append(x[k] + 1j * x[k + 1])
            k += 2
    return np.array(out)


def lstsq_normal(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Least squares ``min |a x - b|`` through the column-scaled normal equations (one GEMM and a
    Cholesky factorisation, several times faster than LAPACK's SVD solver on tall problems);
    falls back to ``numpy.linalg.lstsq`` when the scaled Gram matrix is not safely positive
    definite (condition number above about 1e10)."""
    norm = np.linalg.norm(a, axis=0)
    norm[norm == 0] = 1.0
    a_s = a / norm
    gram = a_s.T @ a_s
    try:
        chol = np.linalg.cholesky(gram)
        diag = np.diag(chol)
        if diag.min() < 1e-5 * diag.max():
            raise np.linalg.LinAlgError("ill-conditioned")
        y = np.linalg.solve(chol, a_s.T @ b)
        x = np.linalg.solve(chol.T, y)
    except np.linalg.LinAlgError:
        x = np.linalg.lstsq(a_s, b, rcond=None)[0]
    return x / (norm if x.ndim == 1 else norm[:, None])


def _real_stack(m: np.ndarray) -> np.ndarray:
    return np.concatenate([m.real, m.imag], axis=0)


def fit_residues(
    s: np.ndarray,
    g: np.ndarray,
    row_weight: np.ndarray,
    poles: np.ndarray,
    feedthrough: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """Linear least-squares residues and feedthrough for fixed poles (one solve per channel).

    Minimises ``sum_k row_weight_k^2 |G(s_k) - g_k|^2`` for each channel; with
    ``row_weight = sqrt(w)/|g|`` this is the relative (log-like) error of MACE eq. 5.

    Parameters
    ----------
    s : ndarray, complex, shape (K,)
        Laplace variable on the band, rad/s.
    g : ndarray, complex, shape (K, n_out, n_in)
    row_weight : ndarray, shape (K, n_out, n_in)
        Multiplier of each complex residual.
    poles : ndarray, complex
        One pole per conjugate pair plus real poles, rad/s.
    feedthrough : bool
        Fit a constant ``D`` too.

    Returns
    -------
    residues : ndarray, complex, shape (n_poles, n_out, n_in)
    d : ndarray, shape (n_out, n_in)
    """
    basis = partial_fraction_basis(s, poles)
    if feedthrough:
        basis = np.hstack([basis, np.ones((s.size, 1))])
    _, n_out, n_in = g.shape
    x = np.zeros((basis.shape[1], n_out, n_in))
    for i in range(n_out):
        for j in range(n_in):
            wk = row_weight[:, i, j][:, None]
            a = _real_stack(basis * wk)
            b = _real_stack(g[:, i, j] * row_weight[:, i, j])
            x[:, i, j] = lstsq_normal(a, b)
    n_basis = n_states(poles)
    residues = coefficients_to_residues(x[:n_basis], poles)
    d = x[n_basis] if feedthrough else np.zeros((n_out, n_in))
    return residues.reshape(len(poles), n_out, n_in), d


def evaluate(s: np.ndarray, poles: np.ndarray, residues: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Frequency response of a pole-residue model, shape (K, n_out, n_in)."""
    s = np.asarray(s, dtype=complex).reshape(-1)
    out = np.broadcast_to(np.asarray(d, dtype=complex), (s.size,) + np.shape(d)).copy()
    for p, r in zip(poles, residues):
        if p.imag == 0:
            out += (1.0 / (s - p.real))[:, None, None] * r.real
        else:
            out += (1.0 / (s - p))[:, None, None] * r + (1.0 / (s - np.conj(p)))[:, None, None] * np.conj(r)
    return out


def pole_change(old: np.ndarray | None, new: np.ndarray) -> float:
    """Largest relative change between two pole sets matched by frequency (inf if sizes differ)."""
    if old is None or old.size != new.size:
        return np.inf
    a = old[np.lexsort((old.real, np.abs(old)))]
    b = new[np.lexsort((new.real, np.abs(new)))]
    return float(np.max(np.abs(a - b) / np.maximum(np.abs(a), 1e-300)))


def weighted_cost(s: np.ndarray, g: np.ndarray, rw: np.ndarray, poles: np.ndarray) -> float:
    """``sum |rw (g - G)|^2`` of the best residues for ``poles``; ``g``, ``rw`` of shape (K, n_ch)."""
    res, d = fit_residues(s, g[:, :, None], rw[:, :, None], poles)
    model = evaluate(s, poles, res, d)[:, :, 0]
    return float(np.sum(np.abs(rw * (g - model)) ** 2))


#: relative cost difference below which two candidate fits count as tied and the first one (in a
#: fixed order of candidates, iterates or routes) is kept: converged fits move by 1e-10 - 1e-8
#: under round-off (another BLAS kernel, a 1e-12 change of the data), so a choice between them by
#: a bare ``<`` followed the round-off wherever two were nearly equal
TIE_MARGIN = 1e-6


def first_lowest(costs, margin: float = TIE_MARGIN) -> int:
    """Index of the first of ``costs`` within ``margin`` (relative) of the lowest one.

    Parameters
    ----------
    costs : sequence of float or of (bool, float)
        Costs (dimensionless weighted sums of squares) in the candidates' fixed order; a
        ``(flag, cost)`` pair with the smaller flag wins outright (``False`` before ``True``), the
        margin applies among those with the smallest flag.
    margin : float
        Relative tie margin (default ``TIE_MARGIN``).

    Returns
    -------
    int
        Index of the chosen candidate.
    """
    keys = [c if isinstance(c, tuple) else (0, c) for c in costs]
    flag = min(k[0] for k in keys)
    values = np.array([k[1] if k[0] == flag else np.inf for k in keys], dtype=float)
    best = float(np.min(values))
    return int(np.flatnonzero(values <= best + margin * abs(best))[0])


class BestPoles:
    """Keeps the pole set of lowest weighted cost seen by an iteration and says when to stop.

    Noisy data with spare poles make VF and SK wander instead of converging; the iteration is
    stopped when the best cost has not improved by ``rtol`` (relative) for ``patience`` steps,
    and the best poles (not the last) are returned.
    """

    def __init__(self, s: np.ndarray, g: np.ndarray, rw: np.ndarray, rtol: float = 1e-4, patience: int = 5):
        self.s, self.g, self.rw, self.rtol, self.patience = s, g, rw, rtol, patience
        self.best_cost, self.best, self.stale = np.inf, None, 0

    def update(self, poles: np.ndarray) -> bool:
        """Record ``poles`` (cost computed here); True when the iteration should stop."""
        return self.record(poles, weighted_cost(self.s, self.g, self.rw, poles))

    def record(self, poles: np.ndarray, cost: float) -> bool:
        """Record ``poles`` with a known ``cost``; True after ``patience`` steps without progress."""
        if cost < self.best_cost * (1 - self.rtol):
            self.stale = 0
        else:
            self.stale += 1
        if cost < self.best_cost * (1 - TIE_MARGIN) or self.best is None:  # a near tie keeps the earlier
            self.best_cost, self.best = cost, poles
        return self.stale >= self.patience
