"""Structured singular value (mu) bounds over frequency: ``rc.mu`` and :class:`MuResult`.

``mu(M) = 1 / min{ ||Delta|| : det(I - M Delta) = 0, Delta in the block structure }``
(Packard & Doyle 1993, "The complex structured singular value", Automatica 29(1), eq. 3.1;
Zhou, Doyle & Glover 1996, ch. 10). ``rc.mu`` returns at every frequency

* an upper bound with D-scales (and G-scales for repeated real blocks: Fan, Tits & Doyle
  1991; Young, Newlin & Doyle 1995), computed for all frequencies at once by
  :mod:`robustctl.robust.mu.upper` (balancing start, then Newton refinement to the LMI
  optimum), or per frequency through the LMI in cvxpy + Clarabel (``method="lmi"``,
  :mod:`robustctl.robust.mu.lmi`);
* a lower bound by power iteration (Packard & Doyle 1993 sec. 9.2; Young & Doyle 1997),
  :mod:`robustctl.robust.mu.lower`, with the destabilising perturbation it certifies.
"""

from __future__ import annotations

import time
from concurrent.futures import Executor
from functools import partial
from typing import Any

import numpy as np

from ...budget import Deadline, as_deadline
from ...checks import flag, integer
from ...errors import RobustctlError, SynthesisError
from ...executors import check_executor, parallel_map
from ...frd import FrequencyData, as_frequency_data
from ...interconnect import PartitionedPlant
from ...lti import freqresp_array
from ...threads import limit_blas
from ..uncertainty.blocks import BlockStructure, as_block_structure
from .layout import Layout, layout_of
from .lmi import lmi_upper_bound
from .lower import lower_bound
from .result import MuResult
from .upper import upper_bound

__all__ = ["MuResult", "mu", "as_frequency_array", "validate_mu_input"]

_METHODS = ("auto", "lmi")


# ---------------------------------------------------------------------------- input handling
def _is_system(M: Any) -> bool:
    return not isinstance(M, (np.ndarray, list, tuple, int, float, complex, np.number, FrequencyData))


def as_frequency_array(M: Any, f_hz: Any = None, what: str = "M") -> tuple[np.ndarray, np.ndarray]:
    """``M`` as a complex (nf, n_out, n_in) array and its frequencies (Hz; NaN if unknown).

    Accepts a constant matrix, an (nf, n_out, n_in) array, a FrequencyData, or a system
    (anything :func:`robustctl.lti.as_statespace` accepts) evaluated on ``f_hz``.
    """
    if hasattr(M, "delta_response") and hasattr(M, "block_structure"):  # an uncertain system: its M11
        if f_hz is None:
            raise SynthesisError(f"{what} is an uncertain system: give f_hz (Hz).")
        f = frequencies_hz(f_hz)
        return M.delta_response(f), f
    if hasattr(M, "omega") and (hasattr(M, "frdata") or hasattr(M, "fresp")):  # python-control's FRD
        M = as_frequency_data(M, what)
    if isinstance(M, FrequencyData):
        if f_hz is not None:
            raise SynthesisError(
                f"{what} is a FrequencyData, which carries its own frequencies; do not pass f_hz."
            )
        return np.asarray(M.response, complex), np.asarray(M.f_hz, float)
    if _is_system(M):
        if f_hz is None:
            raise SynthesisError(f"{what} is a system; pass f_hz (frequencies in Hz) to evaluate it on.")
        f = frequencies_hz(f_hz)

        try:
            return np.asarray(freqresp_array(M, f), complex), f
        except RobustctlError as exc:
            raise SynthesisError(f"cannot evaluate {what} as a system: {exc}") from exc
    try:
        arr = np.asarray(M, dtype=complex)
    except (TypeError, ValueError) as exc:
        raise SynthesisError(f"{what} must be a matrix, an (nf, n_out, n_in) array, a FrequencyData or a "
                             f"system; got {type(M).__name__}.") from exc
    if arr.ndim == 0:
        arr = arr.reshape(1, 1, 1)
    elif arr.ndim == 2:
        arr = arr[None]
    if arr.ndim != 3:
        raise SynthesisError(f"{what} must be (n_out, n_in) or (nf, n_out, n_in); got shape {arr.shape}.")
    if f_hz is None:
        return arr, np.full(arr.shape[0], np.nan)
    f = frequencies_hz(f_hz)
    if f.size != arr.shape[0]:
        raise SynthesisError(
            f"f_hz has {f.size} frequencies but {what} has {arr.shape[0]}; give one per matrix."
        )
    return arr, f


def frequencies_hz(f_hz: Any) -> np.ndarray:
    """``f_hz`` as a checked 1-d float array: finite, non-negative (Hz), not empty, else a
    SynthesisError."""
    try:
        f = np.atleast_1d(np.asarray(f_hz, dtype=float)).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise SynthesisError(f"f_hz must be numbers in Hz; got {f_hz!r}.") from exc
    if f.size == 0:
        raise SynthesisError("f_hz is empty; give at least one frequency in Hz.")
    if not np.all(np.isfinite(f)):
        raise SynthesisError("f_hz contains NaN or inf; frequencies must be finite numbers in Hz.")
    if np.any(f < 0):
        raise SynthesisError(f"f_hz must be frequencies >= 0 Hz; got {f[f < 0][0]:g} Hz.")
    return f


def validate_mu_input(M: np.ndarray, bs: BlockStructure) -> None:
    """Refuse an empty ``M``, one whose shape does not fit ``bs``, or one with NaN/inf (SynthesisError)."""
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
def _bounds_chunk(item: tuple[np.ndarray, int], bs: BlockStructure, lower: bool, method: str, seed: int,
                  time_budget_s: Deadline | float | None = None) -> dict:
    """Bounds on one chunk ``(M, index of its first frequency)`` (top level, so executors can pickle it)."""
    M, start = item
    deadline = as_deadline(time_budget_s, SynthesisError)
    lay = layout_of(bs)
    t0 = time.perf_counter()
    size = np.abs(M).max(axis=(1, 2))
    size = np.where(size > 0, size, 1.0)  # mu(c M) = c mu(M): work at unit size (no over/underflow)
    M = M / size[:, None, None]
    ub = upper_bound(M, lay, time_budget_s=deadline)
    t1 = time.perf_counter()
    out = {"upper": ub.upper * size, "d": ub.dblocks, "g": [g * size[:, None, None] for g in ub.gblocks],
           "newton": ub.iterations, "t_upper": t1 - t0, "stopped_by_budget": deadline.hit}
    if lower:
        lb = lower_bound(M, lay, ub.a0, ub.w0, ub.upper, seed=seed, index=start + np.arange(M.shape[0]))
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
        "stopped_by_budget": any(p["stopped_by_budget"] for p in parts),
    }
    if "t_lmi" in parts[0]:
        out["info"]["t_lmi_s"] = sum(p["t_lmi"] for p in parts)
    return out


def _scalar_of(d: np.ndarray) -> np.ndarray:
    """|det D|^(1/m) of (nf, m, m) scales (the scale itself when m = 1)."""
    return np.abs(np.linalg.det(d)) ** (1.0 / d.shape[-1])


def mu(M: Any, blocks: Any = None, f_hz: Any = None, *, lower: bool = True, method: str = "auto",
       executor: Executor | None = None, chunk: int | None = None, seed: int = 0,
       time_budget_s: float | None = None) -> MuResult:
    """Upper and lower bounds of the structured singular value, over frequency.

    Parameters
    ----------
    M : array_like, FrequencyData or system
        A constant matrix (n_out, n_in) or scalar, an array (nf, n_out, n_in), a FrequencyData
        (response (nf, n_out, n_in)) or python-control FrequencyResponseData, or a system
        (control.StateSpace, TransferFunction, anything with ``.statespace()``) evaluated at
        ``f_hz``, or an uncertain system (``rc.ureal(...) * G``: mu of its ``w -> z`` channels
        ``M11`` with its own blocks, real parameters as real blocks), or a partitioned plant
        (``rc.generalized_plant``, ``rc.as_partitioned``): mu of its open-loop ``w -> z``
        channels ``P11`` (the loop with ``K = 0``), with its own blocks. ``Delta`` closes the loop
        from the outputs of ``M`` back to its inputs: ``det(I - M Delta)``.
    blocks : BlockStructure, list of Block, MATLAB mussv rows, or None (an uncertain system's own)
        ``[[-r, 0]]`` repeated real scalar, ``[[r, 0]]`` repeated complex scalar, ``[[r, c]]``
        full ``r x c`` block (``M`` is then ``(sum c) x (sum r)``).
    f_hz : array_like, optional
        Frequencies in Hz: required for a system, optional labels for an array.
    lower : bool
        Also compute the power-iteration lower bound and the worst-case perturbation.
    method : {"auto", "lmi"}
        ``"auto"``: the batched D-(G-)scaling bound (balancing start + Newton refinement, to
        within 0.2 % of the LMI optimum, with real blocks too); ``"lmi"``: solve the LMI with cvxpy + Clarabel
        at every frequency (slow, tenths of a second per frequency; the reference).
    executor : concurrent.futures.Executor, optional
        Split the frequency grid into chunks and compute them on this executor (anything with
        ``.submit``: thread or process pools, a dask ``Client.get_executor()``).
    chunk : int, optional
        Frequencies per chunk (default: about an eighth of the grid with an executor).
    seed : int
        Seed of the lower bound's random start.
    time_budget_s : float or None
        Optional wall-clock limit (s) of the upper bound's Newton refinement over the whole
        grid, by :mod:`robustctl.budget`'s policy: None (default) caps it by its iteration
        count only. When a budget stops it, the bound stays valid (only less tight),
        ``info["stopped_by_budget"]`` is True and a BudgetWarning is issued.

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
    if not isinstance(method, str) or method not in _METHODS:
        raise SynthesisError(f"method must be one of {_METHODS}; got {method!r}.")
    deadline = Deadline(time_budget_s, error=SynthesisError)
    lower = flag(lower, "lower", SynthesisError)
    seed = integer(seed, "seed", SynthesisError, lo=0)
    if isinstance(M, PartitionedPlant):
        if blocks is None:
            blocks = getattr(M, "blocks", None)
        M = M.P[:M.nz, :M.nw]
    if blocks is None and hasattr(M, "block_structure"):
        blocks = M.block_structure()
    bs = as_block_structure(blocks)
    arr, f = as_frequency_array(M, f_hz)
    validate_mu_input(arr, bs)
    check_executor(executor)
    if chunk is not None:
        chunk = integer(chunk, "chunk", SynthesisError, lo=1)
    t0 = time.perf_counter()
    slices = _chunks(arr.shape[0], executor, chunk)
    work = partial(_bounds_chunk, bs=bs, lower=lower, method=method, seed=seed, time_budget_s=deadline)
    parts = parallel_map(work, [(arr[s], s.start) for s in slices], executor, desc="mu",
                         progress=len(slices) > 1)
    out = _merge(parts)
    if out["info"]["stopped_by_budget"]:
        deadline.warn("mu's upper-bound refinement")
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
