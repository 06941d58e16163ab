"""Structured singular value (mu) bounds over frequency: ``rc.mu`` and :class:`MuResult`.

``mu(M) = 1 / min{ ||Delta|| : det(I - M Delta) = 0, Delta in the block structure }``
(Packard & Doyle 1993, "The complex structured singular value", Automatica 29(1), eq. 3.1;
Zhou, Doyle & Glover 1996, ch. 10). ``rc.mu`` returns at every frequency

* an upper bound with D-scales (and G-scales for repeated real blocks: Fan, Tits & Doyle
  1991; Young, Newlin & Doyle 1995), computed for all frequencies at once by
  :mod:`robustctl.robust.mu_upper` (balancing start, then Newton refinement to the LMI
  optimum), or per frequency through the LMI in cvxpy + Clarabel (``method="lmi"``,
  :mod:`robustctl.robust.mu_lmi`);
* a lower bound by power iteration (Packard & Doyle 1993 sec. 9.2; Young & Doyle 1997),
  :mod:`robustctl.robust.mu_lower`, with the destabilising perturbation it certifies.
"""

from __future__ import annotations

import html
import time
from concurrent.futures import Executor
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import RobustctlError, SynthesisError
from ..frd import FrequencyData
from ..table import Table
from ..threads import limit_blas
from .blocks import BlockStructure, as_block_structure
from .mu_layout import Layout, layout_of
from .mu_lmi import lmi_upper_bound
from .mu_lower import lower_bound
from .mu_upper import upper_bound

__all__ = ["MuResult", "mu", "as_frequency_array"]

_METHODS = ("auto", "lmi")


# ---------------------------------------------------------------------------- result
@dataclass(frozen=True)
class MuResult:
    """Bounds of the structured singular value over frequency.

    Attributes
    ----------
    f_hz : ndarray, (nf,)
        Frequencies in Hz (NaN when ``M`` was given without frequencies).
    upper, lower : ndarray, (nf,)
        Upper and lower bounds of mu (``lower <= mu <= upper``).
    peak : float
        ``max(upper)``: robust stability against ``||Delta|| < 1 / peak`` is guaranteed.
    f_peak_hz : float
        Frequency of ``peak`` (Hz).
    d_scales : ndarray, (nf, n_blocks)
        Positive scalar D-scale of every block, last block normalised to 1; applied as
        ``M -> D_L M D_R^{-1}`` with block ``i`` scaled by ``d_i`` on its rows and columns.
        For a repeated scalar block with a full ``D_i`` it is ``|det D_i|^(1/r)``.
    d_matrices : tuple of ndarray
        Per block, the D-scale matrices (nf, m, m) (``m = r`` for a repeated scalar block of
        multiplicity ``r > 1``, else 1), same normalisation.
    g_scales : ndarray (nf, n_blocks) or None
        G-scales of the LMI ``M^H X_L M + j(G M - M^H G^H) - upper^2 X_R <= 0`` (``X = D^H D``)
        on the real blocks (mean eigenvalue of ``G_i``; 0 on complex blocks); None without real
        blocks.
    g_matrices : tuple of ndarray or None
        Per block the Hermitian ``G_i`` (nf, r, r) (zero on complex blocks).
    worst_perturbation : ndarray, (n_in, n_out)
        A structured ``Delta`` with ``det(I - M Delta) = 0`` and ``||Delta|| = 1 / lower`` at
        ``f_worst_hz`` (the frequency of the largest lower bound); zeros if no lower bound was
        found.
    f_worst_hz : float
        Frequency of ``worst_perturbation``.
    blocks : BlockStructure
    method : str
        ``"auto"`` (batched D/G-scaling) or ``"lmi"``.
    info : dict
        Timings (s), iteration counts.
    """

    f_hz: np.ndarray
    upper: np.ndarray
    lower: np.ndarray
    peak: float
    f_peak_hz: float
    d_scales: np.ndarray
    d_matrices: tuple[np.ndarray, ...]
    g_scales: np.ndarray | None
    g_matrices: tuple[np.ndarray, ...] | None
    worst_perturbation: np.ndarray
    f_worst_hz: float
    blocks: BlockStructure
    method: str = "auto"
    info: dict = field(default_factory=dict)

    # ------------------------------------------------------------------ derived numbers
    @property
    def lower_peak(self) -> float:
        """``max(lower)``: some ``Delta`` with ``||Delta|| = 1 / lower_peak`` destabilises."""
        return float(np.max(self.lower))

    @property
    def stability_margin(self) -> float:
        """``1 / peak``: the guaranteed robust stability margin when ``blocks`` are the
        (normalised) uncertainty blocks: stable for all ``||Delta|| < 1 / peak``."""
        return float(np.inf) if self.peak == 0 else 1.0 / self.peak

    @property
    def stability_margin_bounds(self) -> tuple[float, float]:
        """(guaranteed margin ``1/peak``, margin that is certainly exceeded ``1/lower_peak``)."""
        lp = self.lower_peak
        return self.stability_margin, (float(np.inf) if lp == 0 else 1.0 / lp)

    @property
    def gap(self) -> np.ndarray:
        """Relative gap ``upper / lower - 1`` per frequency (inf where ``lower == 0``)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self.lower > 0, self.upper / np.where(self.lower > 0, self.lower, 1) - 1, np.inf)

    # ------------------------------------------------------------------ presentation
    def _peaks(self, count: int) -> list[int]:
        u = self.upper
        if u.size < 3:
            return list(np.argsort(-u)[:count])
        inner = np.flatnonzero((u[1:-1] >= u[:-2]) & (u[1:-1] >= u[2:])) + 1
        ends = [i for i in (0, u.size - 1) if u[i] == u.max()]
        cand = np.unique(np.concatenate([inner, ends]).astype(int))
        return list(cand[np.argsort(-u[cand])][:count])

    def table(self, count: int = 8) -> Table:
        """The largest local peaks of the upper bound: frequency, bounds, gap and D-scales."""
        names = [b.name or f"{b.kind} {b.rows}x{b.cols}" for b in self.blocks]
        cols = ("f (Hz)", "mu upper", "mu lower", "gap (%)") + tuple(f"d [{n}]" for n in names)
        rows = []
        for k in self._peaks(count):
            gap = 100 * self.gap[k] if np.isfinite(self.gap[k]) else float("inf")
            rows.append((float(self.f_hz[k]), float(self.upper[k]), float(self.lower[k]), gap)
                        + tuple(float(d) for d in self.d_scales[k]))
        return Table(cols, rows, title=f"mu peaks, blocks {self.blocks.mussv().tolist()}")

    def summary(self) -> str:
        """A few sentences in plain words."""
        nf = self.f_hz.size
        where = f" at {self.f_peak_hz:.4g} Hz" if np.isfinite(self.f_peak_hz) else ""
        lines = [
            f"mu over {nf} frequenc{'y' if nf == 1 else 'ies'}, blocks {self.blocks.mussv().tolist()} "
            f"({self.method}): peak upper bound {self.peak:.4g}{where}, "
            f"peak lower bound {self.lower_peak:.4g}.",
        ]
        lo, hi = self.stability_margin_bounds
        lines.append(
            f"As an uncertainty structure: stable for every ||Delta|| < {lo:.4g}; a perturbation of size "
            f"{hi:.4g} destabilises."
            + (" Robust stability holds for the unit ball (peak < 1)." if self.peak < 1 else
               " Robust stability for the unit ball is not guaranteed (peak >= 1).")
        )
        finite = np.isfinite(self.gap)
        if finite.any():
            lines.append(f"Largest gap between the bounds: {100 * np.max(self.gap[finite]):.3g} %.")
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        summary = "".join(f"<p>{html.escape(s)}</p>" for s in self.summary().splitlines())
        return summary + self.table()._repr_html_()

    def __repr__(self) -> str:
        return (f"MuResult(peak={self.peak:.4g}, f_peak_hz={self.f_peak_hz:.4g}, "
                f"lower_peak={self.lower_peak:.4g}, n_freq={self.f_hz.size}, "
                f"blocks={self.blocks.mussv().tolist()})")

    def plot(self, fig: Any = None, *, title: str = "") -> Any:
        """Upper and lower bound against frequency (log axis); returns the matplotlib Figure."""
        from ..plots import new_figure

        fig = fig or new_figure(7.0, 4.0)
        ax = fig.add_subplot(1, 1, 1)
        f = self.f_hz
        x = f if np.all(np.isfinite(f)) else np.arange(f.size)
        ax.plot(x, self.upper, "C0-", lw=1.5, label="mu upper bound")
        ax.plot(x, self.lower, "C1--", lw=1.2, label="mu lower bound")
        if np.all(np.isfinite(f)) and np.all(f > 0) and f.size > 1:
            ax.set_xscale("log")
            ax.set_xlabel("frequency (Hz)")
        else:
            ax.set_xlabel("frequency (Hz)" if np.all(np.isfinite(f)) else "frequency index")
        if self.peak > 0:
            ax.axhline(1.0, color="0.5", lw=0.8, ls=":")
        ax.plot([x[int(np.argmax(self.upper))]], [self.peak], "C0o", ms=5)
        ax.set_ylabel("mu")
        ax.set_title(title or f"mu, peak {self.peak:.4g}" + (f" at {self.f_peak_hz:.4g} Hz"
                                                               if np.isfinite(self.f_peak_hz) else ""))
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
        return fig


# ---------------------------------------------------------------------------- input handling
def _is_system(M: Any) -> bool:
    return not isinstance(M, (np.ndarray, list, tuple, int, float, complex, np.number, FrequencyData))


def as_frequency_array(M: Any, f_hz: Any = None, what: str = "M") -> tuple[np.ndarray, np.ndarray]:
    """``M`` as a complex (nf, n_out, n_in) array and its frequencies (Hz; NaN if unknown).

    Accepts a constant matrix, an (nf, n_out, n_in) array, a FrequencyData, or a system
    (anything :func:`robustctl.lti.as_statespace` accepts) evaluated on ``f_hz``.
    """
    if isinstance(M, FrequencyData):
        if f_hz is not None:
            raise SynthesisError(
                f"{what} is a FrequencyData, which carries its own frequencies; do not pass f_hz."
            )
        return np.asarray(M.response, complex), np.asarray(M.f_hz, float)
    if _is_system(M):
        if f_hz is None:
            raise SynthesisError(f"{what} is a system; pass f_hz (frequencies in Hz) to evaluate it on.")
        f = _frequencies(f_hz)
        from ..lti import freqresp_array

        try:
            return np.asarray(freqresp_array(M, f), complex), f
        except RobustctlError as exc:
            raise SynthesisError(f"cannot evaluate {what} as a system: {exc}") from exc
    try:
        arr = np.asarray(M, dtype=complex)
    except (TypeError, ValueError) as exc:
        raise SynthesisError(f"{what} must be a matrix, an (nf, n_out, n_in) array, a FrequencyData or a "
                             f"system; got {type(M).__name__}.") from exc
    if arr.ndim == 2:
        arr = arr[None]
    if arr.ndim != 3:
        raise SynthesisError(f"{what} must be (n_out, n_in) or (nf, n_out, n_in); got shape {arr.shape}.")
    if f_hz is None:
        return arr, np.full(arr.shape[0], np.nan)
    f = _frequencies(f_hz)
    if f.size != arr.shape[0]:
        raise SynthesisError(
            f"f_hz has {f.size} frequencies but {what} has {arr.shape[0]}; give one per matrix."
        )
    return arr, f


def _frequencies(f_hz: Any) -> np.ndarray:
    try:
        f = np.atleast_1d(np.asarray(f_hz, dtype=float)).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise SynthesisError(f"f_hz must be numbers in Hz; got {f_hz!r}.") from exc
    if f.size == 0:
        raise SynthesisError("f_hz is empty; give at least one frequency in Hz.")
    if not np.all(np.isfinite(f)):
        raise SynthesisError("f_hz contains NaN or inf; frequencies must be finite numbers in Hz.")
    return f


def _check(M: np.ndarray, bs: BlockStructure) -> None:
    if M.shape[0] == 0 or M.shape[1] == 0 or M.shape[2] == 0:
        raise SynthesisError(
            f"M is empty (shape {M.shape}); mu needs at least one frequency and one channel."
        )
    bs.check_matrix_shape(M.shape)
    bad = ~np.isfinite(M).all(axis=(1, 2))
    if bad.any():
        raise SynthesisError(f"M contains NaN or inf at {int(bad.sum())} of {M.shape[0]} frequencies "
                             f"(first at index {int(np.argmax(bad))}); mu needs finite values.")


# ---------------------------------------------------------------------------- computation
@limit_blas
def _bounds_chunk(M: np.ndarray, bs: BlockStructure, lower: bool, method: str, seed: int) -> dict:
    """Bounds on one chunk of frequencies (top level, so executors can pickle it)."""
    lay = layout_of(bs)
    t0 = time.perf_counter()
    size = np.abs(M).max(axis=(1, 2))
    size = np.where(size > 0, size, 1.0)  # mu(c M) = c mu(M): work at unit size (no over/underflow)
    M = M / size[:, None, None]
    ub = upper_bound(M, lay)
    t1 = time.perf_counter()
    out = {"upper": ub.upper * size, "d": ub.dblocks, "g": [g * size[:, None, None] for g in ub.gblocks],
           "newton": ub.iterations, "t_upper": t1 - t0}
    if lower:
        lb = lower_bound(M, lay, ub.a0, ub.w0, ub.upper, seed=seed)
        out.update(lower=lb.lower * size, delta=lb.delta / size[:, None, None], power=lb.iterations)
    else:
        nf = M.shape[0]
        out.update(lower=np.zeros(nf), delta=np.zeros((nf, lay.n_in, lay.n_out), complex), power=0)
    out["t_lower"] = time.perf_counter() - t1
    if method == "lmi":
        _lmi_replace(M * size[:, None, None], lay, out)
    return out


def _lmi_replace(M: np.ndarray, lay: Layout, out: dict) -> None:
    """Replace the upper bound and scales by the LMI route's, frequency by frequency."""
    t0 = time.perf_counter()
    for f in range(M.shape[0]):
        beta, xb, gb = lmi_upper_bound(M[f], lay, bracket=(float(out["lower"][f]), float(out["upper"][f])))
        out["upper"][f] = beta
        for i, (x, g) in enumerate(zip(xb, gb)):
            ev, V = np.linalg.eigh(0.5 * (x + x.conj().T))
            out["d"][i][f] = (V * np.sqrt(np.maximum(ev, 0.0))) @ V.conj().T
            if g is not None:
                out["g"][i][f] = g
    last = out["d"][-1]
    c = np.abs(np.linalg.det(last)) ** (1.0 / last.shape[-1])
    c = np.where(c > 0, c, 1.0)
    out["d"] = [d / c[:, None, None] for d in out["d"]]
    out["g"] = [g / (c**2)[:, None, None] for g in out["g"]]
    out["t_lmi"] = time.perf_counter() - t0


def _chunks(nf: int, executor: Executor | None, chunk: int | None) -> list[slice]:
    if executor is None and chunk is None:
        return [slice(0, nf)]
    size = chunk or max(16, int(np.ceil(nf / 8)))
    return [slice(s, min(s + size, nf)) for s in range(0, nf, size)]


def _merge(parts: list[dict]) -> dict:
    out = {k: np.concatenate([p[k] for p in parts]) for k in ("upper", "lower", "delta")}
    out["d"] = [np.concatenate([p["d"][i] for p in parts]) for i in range(len(parts[0]["d"]))]
    out["g"] = [np.concatenate([p["g"][i] for p in parts]) for i in range(len(parts[0]["g"]))]
    out["info"] = {
        "newton_iterations": max(p["newton"] for p in parts),
        "power_iterations": max(p["power"] for p in parts),
        "t_upper_s": sum(p["t_upper"] for p in parts),
        "t_lower_s": sum(p["t_lower"] for p in parts),
        "n_chunks": len(parts),
    }
    if "t_lmi" in parts[0]:
        out["info"]["t_lmi_s"] = sum(p["t_lmi"] for p in parts)
    return out


def _scalar_of(d: np.ndarray) -> np.ndarray:
    """|det D|^(1/m) of (nf, m, m) scales (the scale itself when m = 1)."""
    return np.abs(np.linalg.det(d)) ** (1.0 / d.shape[-1])


def mu(M: Any, blocks: Any, f_hz: Any = None, *, lower: bool = True, method: str = "auto",
       executor: Executor | None = None, chunk: int | None = None, seed: int = 0) -> MuResult:
    """Upper and lower bounds of the structured singular value, over frequency.

    Parameters
    ----------
    M : array_like, FrequencyData or system
        A constant matrix (n_out, n_in), an array (nf, n_out, n_in), a FrequencyData
        (response (nf, n_out, n_in)), or a system (control.StateSpace, TransferFunction,
        anything with ``.statespace()``) evaluated at ``f_hz``. ``Delta`` closes the loop from
        the outputs of ``M`` back to its inputs: ``det(I - M Delta)``.
    blocks : BlockStructure, list of Block, or MATLAB mussv rows
        ``[[-r, 0]]`` repeated real scalar, ``[[r, 0]]`` repeated complex scalar, ``[[r, c]]``
        full ``r x c`` block (``M`` is then ``(sum c) x (sum r)``).
    f_hz : array_like, optional
        Frequencies in Hz: required for a system, optional labels for an array.
    lower : bool
        Also compute the power-iteration lower bound and the worst-case perturbation.
    method : {"auto", "lmi"}
        ``"auto"``: the batched D-(G-)scaling bound (balancing start + Newton refinement, to
        within about 0.2 % of the LMI optimum); ``"lmi"``: solve the LMI with cvxpy + Clarabel
        at every frequency (slow, tenths of a second per frequency; the reference).
    executor : concurrent.futures.Executor, optional
        Split the frequency grid into chunks and compute them on this executor.
    chunk : int, optional
        Frequencies per chunk (default: about an eighth of the grid with an executor).
    seed : int
        Seed of the lower bound's random start.

    Returns
    -------
    MuResult

    Raises
    ------
    SynthesisError
        Shape mismatch with the blocks, NaN/inf, empty input, unknown method.

    Examples
    --------
    >>> import numpy as np, robustctl as rc
    >>> r = rc.mu(np.array([[1.0, 2.0], [0.5, 1.0]]), [[1, 0], [1, 0]])
    >>> round(r.peak, 6)
    2.0
    """
    if method not in _METHODS:
        raise SynthesisError(f"method must be one of {_METHODS}; got {method!r}.")
    bs = as_block_structure(blocks)
    arr, f = as_frequency_array(M, f_hz)
    _check(arr, bs)
    if executor is not None and not isinstance(executor, Executor):
        raise SynthesisError(
            f"executor must be a concurrent.futures.Executor; got {type(executor).__name__}."
        )
    t0 = time.perf_counter()
    slices = _chunks(arr.shape[0], executor, chunk)
    if executor is None:
        parts = [_bounds_chunk(arr[s], bs, lower, method, seed) for s in slices]
    else:
        futures = [executor.submit(_bounds_chunk, arr[s], bs, lower, method, seed) for s in slices]
        parts = [fut.result() for fut in futures]
    out = _merge(parts)
    out["info"]["t_total_s"] = time.perf_counter() - t0
    return _result(out, f, bs, method)


def _result(out: dict, f: np.ndarray, bs: BlockStructure, method: str) -> MuResult:
    upper, lo = out["upper"], np.minimum(out["lower"], out["upper"])
    k = int(np.argmax(upper))
    kw = int(np.argmax(lo))
    d_scales = np.stack([_scalar_of(d) for d in out["d"]], axis=1)
    has_real = bs.has_real
    g_mats = tuple(out["g"]) if has_real else None
    g_scales = (np.stack([np.trace(g, axis1=1, axis2=2).real / g.shape[-1] for g in out["g"]], axis=1)
                if has_real else None)
    return MuResult(
        f_hz=f, upper=upper, lower=lo, peak=float(upper[k]), f_peak_hz=float(f[k]),
        d_scales=d_scales, d_matrices=tuple(out["d"]), g_scales=g_scales, g_matrices=g_mats,
        worst_perturbation=out["delta"][kw], f_worst_hz=float(f[kw]), blocks=bs, method=method,
        info=out["info"],
    )
