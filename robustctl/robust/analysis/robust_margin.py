"""Robust-stability margin and worst-case gain of an uncertain system (MATLAB ``robstab``,
``wcgain``).

The margin is the largest factor ``k`` such that the system is stable for every element
within ``k`` times its range (about the range's centre): ``k = 1 / max_w mu_Delta(M11(j w))``
with ``M11`` the ``w -> z`` channels of the LFT (Zhou, Doyle & Glover 1996, thm 11.8;
Packard & Doyle 1993), real parameters as real blocks (mixed mu: Young, Newlin & Doyle 1995
for the D-G upper bound, Young & Doyle 1997 for the lower bound). The upper bound of mu gives
the guaranteed margin (``lower``), a destabilising perturbation the other bound (``upper``):
``det(I - M11(j w0) Delta) = 0`` puts a pole at ``j w0`` (``det(sI - A(Delta)) =
det(sI - A) det(I - M11(s) Delta)`` for a well-posed LFT with ``D_zw = 0``, ZDG sec. 10.3).
That perturbation is returned as values of every element -- real and complex scalars as
numbers, a dynamics block as a stable all-pass realisation ``sigma u(s) v(s)^T`` whose value
at ``j w0`` is the constant block (ZDG sec. 9.2, the construction behind the small-gain
theorem's necessity) -- and checked by substitution.

With real blocks only, mu is discontinuous in frequency: besides mu's power-iteration
bound, every vertex ``Q`` of the real blocks (``delta_j = +-1``, up to :data:`MAX_VERTICES`)
is followed along the grid, and where an eigenvalue of ``M11(j w) Q`` crosses the real axis
the crossing frequency is found by bisection, which gives ``Delta = Q / lambda`` exactly at
the crossing. The grid is refined near the peak of the upper bound.
"""

from __future__ import annotations

import html
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...checks import integer
from ...errors import SynthesisError
from ...table import Table
from ..mu.bounds import MuResult, mu
from ..mu.robust_analysis import worst_case_gain
from ..uncertainty.blocks import Block, BlockStructure
from ..uncertainty.elements import UncertainComplex, UncertainDynamics, UncertainReal
from ..uncertainty.system import UncertainSystem, as_uncertain, raw_response

__all__ = ["RobustStabilityMargin", "robstab", "WorstCaseResult", "wcgain", "destabilizing_system"]

#: vertices of the real blocks followed for crossings (2^k for k real blocks, at most this)
MAX_VERTICES = 256
#: bisection steps of a crossing frequency (relative width 2^-60 of its grid interval)
CROSSING_STEPS = 60
#: relative distance of the substituted pole from the stability boundary that confirms the values
VERIFY_TOL = 1e-6
#: refinement passes and points per pass near the peak
REFINE_PASSES, REFINE_POINTS = 3, 25


@dataclass(frozen=True)
class RobustStabilityMargin:
    """The robust-stability margin of an uncertain system.

    Attributes
    ----------
    lower, upper : float
        Stable for every element within ``lower`` times its range (guaranteed, from mu's upper
        bound on the grid); unstable for the :attr:`destabilizing` values, which lie at
        ``upper`` times the ranges and were substituted to confirm it (``inf`` when the
        substitution did not put a pole within :data:`VERIFY_TOL` of the boundary, e.g. for
        a dynamics element used twice, whose copies mu treats as independent).
        ``lower > 1``: robustly stable over the given ranges.
    f_critical_hz : float
        Frequency (Hz) where the destabilising values put a pole (0: a real pole through 0).
    destabilizing : dict
        ``{name: value}`` in the elements' units (a ``control.StateSpace`` for dynamics).
    normalized : dict
        The same in the unit ball (``|delta| = upper`` for the worst elements).
    pole : complex
        The pole of the system at :attr:`destabilizing` nearest ``j 2 pi f_critical_hz``.
    pole_offset : float
        ``|Re(pole)| / max(|pole|, 1)`` (continuous) or ``||pole| - 1|`` (discrete): how far the
        check found it from the stability boundary.
    nominal_stable : bool
    mu : MuResult
        mu of ``M11`` on the refined grid.
    f_peak_hz : float
        Frequency of mu's upper-bound peak.
    """

    lower: float
    upper: float
    f_critical_hz: float
    destabilizing: dict
    normalized: dict
    pole: complex
    pole_offset: float
    nominal_stable: bool
    mu: MuResult = field(repr=False)
    f_peak_hz: float = float("nan")

    @property
    def robustly_stable(self) -> bool:
        """True when the guaranteed margin exceeds 1 (stable over the whole given ranges)."""
        return self.lower > 1.0

    def table(self) -> Table:
        rows = [(k, _fmt(v), _fmt(self.normalized[k])) for k, v in self.destabilizing.items()]
        return Table(("element", "destabilising value", "normalised"), rows,
                     title=f"robust stability margin in [{self.lower:.4g}, {self.upper:.4g}]")

    def summary(self) -> str:
        if not self.nominal_stable:
            return "The nominal system is unstable: robust-stability margin 0."
        verdict = ("robustly stable over the given ranges" if self.robustly_stable else
                   "not robustly stable over the given ranges" if self.upper < 1 else
                   "robust stability over the given ranges undecided (the bounds straddle 1)")
        return (f"Robust-stability margin between {self.lower:.4g} and {self.upper:.4g} "
                f"(times the ranges): {verdict}; destabilising values at {self.upper:.4g} x the ranges "
                f"put a pole at {self.pole:.4g} (f = {self.f_critical_hz:.4g} Hz).")

    def __repr__(self) -> str:
        return (f"RobustStabilityMargin(lower={self.lower:.4g}, upper={self.upper:.4g}, "
                f"f_critical_hz={self.f_critical_hz:.4g})")

    def _repr_html_(self) -> str:
        return f"<p>{html.escape(self.summary())}</p>" + self.table()._repr_html_()

    def plot(self, fig: Any = None) -> Any:
        """mu's bounds over frequency (the margin is ``1 / peak``)."""
        return self.mu.plot(fig, title="robust stability: mu of the uncertainty channels")


def _fmt(v: Any) -> str:
    if isinstance(v, (float, int, np.floating)):
        return f"{float(v):.6g}"
    if isinstance(v, complex):
        return f"{v:.6g}"
    return f"{type(v).__name__} ({getattr(v, 'nstates', 0)} states)"


# ---------------------------------------------------------------------------- helpers
def _stable(A: np.ndarray, dt: float) -> tuple[bool, np.ndarray]:
    lam = np.linalg.eigvals(A) if A.size else np.zeros(0)
    ok = bool(np.all(np.abs(lam) < 1)) if dt else bool(np.all(lam.real < 0))
    return ok, lam


def _grid(usys: UncertainSystem, n: int) -> np.ndarray:
    lam = np.linalg.eigvals(usys.raw.A) if usys.nstates else np.zeros(0)
    if usys.dt:
        lam = np.log(lam[lam != 0].astype(complex)) / usys.dt
    wn = np.abs(lam[np.abs(lam) > 0])
    if wn.size == 0:
        return np.zeros(1)
    lo, hi = wn.min() / 20 / (2 * np.pi), wn.max() * 20 / (2 * np.pi)
    if usys.dt:
        hi = min(hi, 0.5 / usys.dt)
    return np.concatenate([[0.0], np.geomspace(lo, hi, n)])


def _refine(f: np.ndarray, score: np.ndarray, dt: float) -> np.ndarray:
    k = int(np.argmax(score))
    a = f[max(k - 1, 0)]
    b = f[min(k + 1, f.size - 1)]
    if dt:
        b = min(b, 0.5 / dt)
    return np.linspace(a, b, REFINE_POINTS)


def _merge_mu(a: MuResult, b: MuResult) -> MuResult:
    """Two mu results on disjoint grids as one, sorted by frequency."""
    from dataclasses import replace

    f = np.concatenate([a.f_hz, b.f_hz])
    order = np.argsort(f, kind="stable")
    cat = lambda x, y: np.concatenate([x, y])[order]  # noqa: E731
    upper, lower = cat(a.upper, b.upper), cat(a.lower, b.lower)
    k = int(np.argmax(upper))
    best = a if a.lower_peak >= b.lower_peak else b
    g = None if a.g_scales is None else cat(a.g_scales, b.g_scales)
    gm = None if a.g_matrices is None else tuple(cat(x, y) for x, y in zip(a.g_matrices, b.g_matrices))
    return replace(a, f_hz=f[order], upper=upper, lower=lower, peak=float(upper[k]),
                   f_peak_hz=float(f[order][k]), d_scales=cat(a.d_scales, b.d_scales),
                   d_matrices=tuple(cat(x, y) for x, y in zip(a.d_matrices, b.d_matrices)),
                   g_scales=g, g_matrices=gm, worst_perturbation=best.worst_perturbation,
                   f_worst_hz=best.f_worst_hz)


def _mu_on(M11, bs: BlockStructure, res: MuResult, extra: np.ndarray, seed: int) -> MuResult:
    """``res`` extended by the frequencies of ``extra`` it does not hold yet."""
    new = np.setdiff1d(np.unique(extra), res.f_hz)
    if new.size == 0:
        return res
    return _merge_mu(res, mu(M11(new), bs, new, seed=seed))


def _vertices(n_real: int) -> np.ndarray:
    if 2 ** n_real <= MAX_VERTICES:
        grid = np.array(np.meshgrid(*([[-1.0, 1.0]] * n_real), indexing="ij")).reshape(n_real, -1).T
        return grid[: max(1, grid.shape[0] // 2)]  # Q and -Q give the same crossings
    rng = np.random.default_rng(0)
    return rng.choice([-1.0, 1.0], (MAX_VERTICES, n_real))


def _real_crossings(usys: UncertainSystem, bs: BlockStructure, f: np.ndarray):
    """Best vertex crossing: (mu lower bound, frequency, Delta) or None (module docstring)."""
    sizes = [b.rows for b in bs.blocks]
    best = None
    resp = lambda ff: raw_response(usys.raw, np.atleast_1d(ff), usys.dt)[:, : usys.raw.nz, : usys.raw.nw]  # noqa: E731
    M = resp(f)
    for q in _vertices(len(sizes)):
        Q = np.diag(np.repeat(q, sizes))
        lam = np.linalg.eigvals(M @ Q)
        for k in range(f.size):  # exact real eigenvalues on the grid (w = 0, or M real)
            tiny = 1e-12 * max(np.abs(lam[k]).max(), 1e-300)
            re = lam[k][(np.abs(lam[k].imag) <= tiny) & (np.abs(lam[k]) > 0)]
            if re.size and (best is None or np.abs(re).max() > best[0]):
                j = np.argmax(np.abs(re))
                best = (float(np.abs(re[j])), float(f[k]), Q * np.sign(re[j].real) / np.abs(re[j]))
        for k in range(f.size - 1):
            l0, l1 = lam[k], lam[k + 1]
            for a in l0:
                b = l1[np.argmin(np.abs(l1 - a))]
                if a.imag * b.imag >= 0 or max(abs(a), abs(b)) <= (best[0] if best else 0):
                    continue
                lo, hi, sa = f[k], f[k + 1], np.sign(a.imag)
                cur = a
                for _ in range(CROSSING_STEPS):
                    mid = 0.5 * (lo + hi)
                    lm = np.linalg.eigvals(resp(mid)[0] @ Q)
                    cur = lm[np.argmin(np.abs(lm - cur))]
                    if np.sign(cur.imag) == sa:
                        lo = mid
                    else:
                        hi = mid
                    if hi - lo <= 1e-15 * max(hi, 1e-300):
                        break
                fm = 0.5 * (lo + hi)
                lm = np.linalg.eigvals(resp(fm)[0] @ Q)
                cur = lm[np.argmin(np.abs(lm - cur))]
                if abs(cur.imag) > 1e-6 * abs(cur) or (best is not None and abs(cur) <= best[0]):
                    continue
                best = (float(abs(cur)), float(fm), Q * np.sign(cur.real) / abs(cur))
    return best


def _allpass_entry(c: complex, w0: float, dt: float):
    """A stable real first-order all-pass (or constant) with value ``c`` at ``j w0`` (``e^{j w0 dt}``)."""
    mag, phi = abs(c), float(np.angle(c))
    sign = 1.0
    if phi > 0:  # an all-pass lags by (0, pi); a sign adds pi
        sign, phi = -1.0, phi - np.pi
    if abs(phi) < 1e-14 or w0 == 0 or mag == 0:
        return (np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), np.array([[sign * mag * np.cos(phi)]]))
    wc = (2 / dt) * np.tan(w0 * dt / 2) if dt else w0
    a = wc / np.tan(-phi / 2)  # (a - s)/(a + s) has phase -2 atan(w/a) = phi at w
    # (a - s)/(a + s) = -1 + 2a/(s + a)
    A, B = np.array([[-a]]), np.array([[1.0]])
    C, D = np.array([[2 * a * sign * mag]]), np.array([[-sign * mag]])
    if dt:
        import control

        d = control.c2d(control.ss(A, B, C, D), dt, method="bilinear")
        A, B, C, D = (np.asarray(x, float) for x in (d.A, d.B, d.C, d.D))
    return A, B, C, D


def destabilizing_system(delta: np.ndarray, f_hz: float, dt: float = 0.0):
    """A stable real system ``Delta(s)`` with ``Delta(j w0) = delta`` and ``||Delta||_inf =
    ||delta||`` for a rank-one ``delta = sigma u v^H``: ``sigma u(s) v(s)^T`` with all-pass
    entries (ZDG sec. 9.2).

    Parameters
    ----------
    delta : ndarray (ny, nu), complex
    f_hz : float
        ``w0 / (2 pi)`` (Hz).
    dt : float
        Sample time (0: continuous).

    Returns
    -------
    control.StateSpace
    """
    import control

    delta = np.atleast_2d(np.asarray(delta, complex))
    U, s, Vh = np.linalg.svd(delta)
    if s.size > 1 and s[1] > 1e-9 * max(s[0], 1e-300):
        raise SynthesisError("the destabilising block is not rank one; its all-pass realisation "
                             "needs rank one.")
    w0 = 2 * np.pi * float(f_hz)
    u, v = U[:, 0] * s[0], Vh[0].conj()  # delta = u v^H

    def column(vals, transpose):
        parts = [_allpass_entry(x, w0, dt) for x in vals]
        n = sum(p[0].shape[0] for p in parts)
        A = np.zeros((n, n))
        B = np.zeros((n, 1 if not transpose else len(vals)))
        C = np.zeros((len(vals) if not transpose else 1, n))
        D = np.zeros((C.shape[0], B.shape[1]))
        i = 0
        for j, (a, b, c, d) in enumerate(parts):
            m = a.shape[0]
            A[i:i + m, i:i + m] = a
            if transpose:
                B[i:i + m, j:j + 1], C[0:1, i:i + m], D[0, j] = b, c, d[0, 0]
            else:
                B[i:i + m, 0:1], C[j:j + 1, i:i + m], D[j, 0] = b, c, d[0, 0]
            i += m
        return control.ss(A, B, C, D, dt or 0)

    us = column(u, False)  # ny x 1, value u at j w0
    vs = column(v.conj(), True)  # 1 x nu, value v^H at j w0
    return control.series(vs, us)


def _values_of(usys: UncertainSystem, bs: BlockStructure, Delta: np.ndarray, f0: float) -> tuple[dict, dict]:
    """Element values (own units) and normalised values of a structured ``Delta``."""
    vals, norm = {}, {}
    rs, cs = bs.col_slices(), bs.row_slices()
    by_name = usys.elements
    for blk, r, c in zip(bs.blocks, rs, cs):
        name = blk.name.split("#")[0]
        e = by_name[name]
        D = Delta[r, c]
        if name in vals:
            continue
        if isinstance(e, UncertainReal):
            d = float(np.real(np.trace(D)) / D.shape[0])
            vals[name], norm[name] = e.from_normalized(d), d
        elif isinstance(e, UncertainComplex):
            d = complex(np.trace(D) / D.shape[0])
            vals[name], norm[name] = e.from_normalized(d), d
        else:
            norm[name] = float(np.linalg.norm(D, 2))
            if norm[name] == 0:
                import control

                vals[name] = control.ss(np.zeros((e.ny, e.nu)))
            else:
                sysd = destabilizing_system(D, f0, usys.dt)
                vals[name] = sysd * e.bound
    return vals, norm


def _check_pole(usys: UncertainSystem, vals: dict, f0: float) -> tuple[complex, float]:
    out = usys.substitute(vals)
    A = np.asarray(out.raw.A if isinstance(out, UncertainSystem) else out.A)
    lam = np.linalg.eigvals(A) if A.size else np.zeros(1, complex)
    if usys.dt:
        target = np.exp(2j * np.pi * f0 * usys.dt)
        k = int(np.argmin(np.abs(lam - target)))
        return complex(lam[k]), float(abs(abs(lam[k]) - 1))
    target = 2j * np.pi * f0
    k = int(np.argmin(np.abs(lam - target) + np.where(lam.real >= -1e-9 * np.abs(lam), 0, 1e300)))
    k = int(np.argmin(np.abs(lam - target))) if not np.isfinite(np.abs(lam[k] - target)) else k
    return complex(lam[k]), float(abs(lam[k].real) / max(abs(lam[k]), 1.0))


# ---------------------------------------------------------------------------- robust stability
def robstab(usys: Any, f_hz: Any = None, *, n_grid: int = 200, seed: int = 0) -> RobustStabilityMargin:
    """Robust-stability margin of an uncertain system, with the destabilising values.

    Parameters
    ----------
    usys : UncertainSystem
        A closed loop (e.g. ``P.feedback(K)``): stability of its own poles is analysed.
    f_hz : array_like, optional
        Frequency grid (Hz); default 200 points log-spaced a decade and more around the
        nominal poles, plus 0. Refined near the peak either way.
    n_grid : int
        Points of the default grid.
    seed : int
        Seed of mu's lower-bound start.

    Returns
    -------
    RobustStabilityMargin

    Examples
    --------
    >>> import robustctl as rc, control
    >>> c = rc.ureal("c", 1.0, percent=50)            # damping of x'' + c x' + x
    >>> x = rc.as_uncertain(control.tf([1], [1, 0]))  # an integrator
    >>> sys = (x * x.feedback(c)).feedback(1)         # poles: s^2 + c s + 1 = 0
    >>> m = rc.robstab(sys)
    >>> round(m.upper, 6), m.destabilizing["c"]       # c = 0 at 2 x 50 %
    (2.0, 0.0)
    """
    usys = as_uncertain(usys)
    n_grid = integer(n_grid, "n_grid", SynthesisError, lo=2)
    if not usys.blocks:
        raise SynthesisError("robstab needs an uncertain system (with elements); use rc.is_stable "
                             "for a certain one.")
    r = usys.raw
    ok, lam = _stable(r.A, usys.dt)
    bs = usys.block_structure()
    names = list(usys.elements)
    if not ok:
        vals = {n: (e.center if not isinstance(e, UncertainDynamics) else 0 * e.nominal)
                for n, e in usys.elements.items()}
        k = int(np.argmax(np.abs(lam) if usys.dt else lam.real))
        empty = mu(np.zeros((1, bs.n_out, bs.n_in)), bs, lower=False)
        return RobustStabilityMargin(0.0, 0.0, float("nan"), vals, dict.fromkeys(names, 0.0), complex(lam[k]),
                                     0.0, False, empty)
    f = np.atleast_1d(np.asarray(f_hz, float)) if f_hz is not None else _grid(usys, n_grid)
    if f.ndim != 1 or not np.all(np.isfinite(f)) or np.any(f < 0):
        raise SynthesisError("f_hz must be finite non-negative frequencies (Hz).")
    M11 = lambda ff: raw_response(r, ff, usys.dt)[:, : r.nz, : r.nw]  # noqa: E731
    f = np.unique(f)
    res = mu(M11(f), bs, f, seed=seed)
    for _ in range(REFINE_PASSES):
        res = _mu_on(M11, bs, res, _refine(res.f_hz, res.upper, usys.dt), seed)
    crossing = None
    if all(b.kind == "real" for b in bs.blocks):
        crossing = _real_crossings(usys, bs, res.f_hz)
        if crossing is not None:
            res = _mu_on(M11, bs, res, np.array([crossing[1]]), seed)
    lo_mu, f0, Delta = res.lower_peak, res.f_worst_hz, res.worst_perturbation
    if crossing is not None and crossing[0] >= lo_mu:
        lo_mu, f0, Delta = crossing
    peak = max(res.peak, lo_mu)
    lower = float("inf") if peak == 0 else 1.0 / peak
    upper = float("inf") if lo_mu == 0 else 1.0 / lo_mu
    if lo_mu == 0:
        vals = {n: e.nominal for n, e in usys.elements.items()}
        return RobustStabilityMargin(lower, upper, float("nan"), vals, dict.fromkeys(names, 0.0),
                                     complex("nan"), float("nan"), True, res, res.f_peak_hz)
    vals, norm = _values_of(usys, bs, Delta, f0)
    pole, off = _check_pole(usys, vals, f0)
    if not off <= VERIFY_TOL:  # e.g. copies of one dynamics element that mu treats as independent
        upper = float("inf")  # no destabilising values confirmed: claim none
    return RobustStabilityMargin(lower, upper, float(f0), vals, norm, pole, off, True, res, res.f_peak_hz)


# ---------------------------------------------------------------------------- worst-case gain
@dataclass(frozen=True)
class WorstCaseResult:
    """Worst-case gain ``max sigma_max(G(Delta, j w))`` over the elements' ranges.

    Attributes
    ----------
    lower, upper : float
        Bounds of the worst-case peak gain (``upper`` from mu's upper bound on the grid,
        ``lower`` the gain the :attr:`worst_values` achieve, evaluated directly).
    f_hz : float
        Frequency of the worst values (Hz).
    worst_values : dict
        ``{name: value}`` within the ranges (dynamics as a ``control.StateSpace``).
    nominal_gain : float
        Peak gain of the nominal system on the grid.
    gains : WorstCaseGain
        Bounds over frequency (:func:`robustctl.robust.mu.robust_analysis.worst_case_gain`).
    """

    lower: float
    upper: float
    f_hz: float
    worst_values: dict
    nominal_gain: float
    gains: Any = field(repr=False)

    def summary(self) -> str:
        return (f"Worst-case gain between {self.lower:.4g} and {self.upper:.4g} (nominal "
                f"{self.nominal_gain:.4g}); the worst values reach {self.lower:.4g} at {self.f_hz:.4g} Hz.")

    def table(self) -> Table:
        return Table(("element", "worst value"), [(k, _fmt(v)) for k, v in self.worst_values.items()],
                     title=self.summary())

    def __repr__(self) -> str:
        return f"WorstCaseResult(lower={self.lower:.4g}, upper={self.upper:.4g}, f_hz={self.f_hz:.4g})"

    def _repr_html_(self) -> str:
        return f"<p>{html.escape(self.summary())}</p>" + self.table()._repr_html_()

    def plot(self, fig: Any = None) -> Any:
        return self.gains.plot(fig)


def _merge_gain(a: Any, b: Any) -> Any:
    from dataclasses import replace

    f = np.concatenate([a.f_hz, b.f_hz])
    order = np.argsort(f, kind="stable")
    cat = lambda x, y: np.concatenate([x, y])[order]  # noqa: E731
    upper = cat(a.upper, b.upper)
    k = int(np.argmax(upper))
    return replace(a, f_hz=f[order], upper=upper, lower=cat(a.lower, b.lower),
                   nominal=cat(a.nominal, b.nominal),
                   peak=float(upper[k]), f_peak_hz=float(f[order][k]))


def wcgain(usys: Any, f_hz: Any = None, *, n_grid: int = 50, seed: int = 0) -> WorstCaseResult:
    """Worst-case gain of an uncertain system over its elements' ranges (MATLAB ``wcgain``).

    Skewed mu at every frequency (:func:`robustctl.robust.mu.robust_analysis.worst_case_gain`,
    real parameters as real blocks), the grid refined near the peak; the worst values come
    from mu's lower-bound perturbation of the skewed problem at the peak frequency and their
    gain is evaluated directly (so ``lower`` is achieved, not estimated).

    Parameters
    ----------
    usys : UncertainSystem
    f_hz : array_like, optional
        Grid (Hz); default as :func:`robstab`.
    n_grid : int
    seed : int

    Returns
    -------
    WorstCaseResult
    """
    usys = as_uncertain(usys)
    n_grid = integer(n_grid, "n_grid", SynthesisError, lo=2)
    if not usys.blocks:
        raise SynthesisError("wcgain needs an uncertain system (with elements).")
    r = usys.raw
    bs = usys.block_structure()
    f = np.atleast_1d(np.asarray(f_hz, float)) if f_hz is not None else _grid(usys, n_grid)
    N = lambda ff: raw_response(r, ff, usys.dt)  # noqa: E731
    f = np.unique(f)
    wc = worst_case_gain(N(f), bs, f)
    for _ in range(REFINE_PASSES):
        score = np.where(np.isfinite(wc.upper), wc.upper, 1e300)
        new = np.setdiff1d(_refine(wc.f_hz, score, usys.dt), wc.f_hz)
        if new.size:
            wc = _merge_gain(wc, worst_case_gain(N(new), bs, new))
    f = wc.f_hz
    k = int(np.argmax(np.where(np.isfinite(wc.lower), wc.lower, 1e300)))
    f0 = float(f[k])
    Nk = N(np.array([f0]))
    nz = r.nz
    full = BlockStructure(bs.blocks + (Block("full", r.nu, r.ny, "performance"),))
    gamma = float(wc.lower[k]) * (1 - 1e-3) if np.isfinite(wc.lower[k]) else float(wc.nominal[k])
    Ns = Nk.copy()
    Ns[:, nz:, :] /= max(gamma, 1e-300)
    res = mu(Ns, full, np.array([f0]), seed=seed)
    Delta = res.worst_perturbation
    if res.lower_peak > 0:
        Delta = Delta * min(1.0, res.lower_peak)  # inside the unit ball
    Du = Delta[: bs.n_in, : bs.n_out]
    vals, _ = _values_of(usys, bs, Du, f0)
    g = usys.freqresp(np.array([f0]), vals)[0]
    achieved = float(np.linalg.norm(g, 2))
    return WorstCaseResult(achieved, float(np.max(wc.upper)), f0, vals, float(np.max(wc.nominal)), wc)
