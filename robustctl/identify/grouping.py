"""SIMO-to-MIMO combination and the Caltech SVD reduction of modes (Balas & Doyle, eqs. 5-10).

``combine_simo`` stacks SIMO fits (one per input) into a MIMO model whose state count is the
sum of theirs (the seed's 12-mode model from three 4-mode fits). ``group_modes`` then groups the
modes by natural frequency and replaces each group by the number of modes the physics allows:
the group's residue matrices are summed and split by an SVD (eq. 10) into the kept rank,
``C = U_k sqrt(S_k)``, ``B = sqrt(S_k) V_k^*`` (eq. 9 generalised to k modes).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..errors import FitError
from ..frd import FrequencyData
from ..threads import limit_blas
from .rational_fit import RationalFit
from .realization import residue_rank
from .refine import refine_residues

__all__ = ["combine_simo", "group_modes", "cluster_modes"]


def _combined_data(fits: Sequence[RationalFit]) -> FrequencyData | None:
    datas = [f.data for f in fits]
    if any(d is None for d in datas) or any(d.f_hz.shape != datas[0].f_hz.shape for d in datas):
        return None
    if any(not np.allclose(d.f_hz, datas[0].f_hz) for d in datas):
        return None
    g = np.concatenate([d.response for d in datas], axis=2)
    coh = None
    if all(d.coherence is not None for d in datas):
        coh = np.concatenate([d.coherence for d in datas], axis=2)
    inputs = [name for d in datas for name in d.inputs]
    return FrequencyData(datas[0].f_hz, g, inputs=inputs, outputs=datas[0].outputs, coherence=coh)


def combine_simo(fits: Sequence[RationalFit]) -> RationalFit:
    """Join fits of disjoint input sets (typically one SIMO fit per input) into one MIMO model.

    The MIMO model keeps every pole of every fit, each acting on its own input(s) only, so its
    state count is the sum of the fits' (Caltech: three 4-mode SIMO fits -> 12 modes).

    Parameters
    ----------
    fits : sequence of RationalFit
        Fits sharing the same outputs (same names, same order) with distinct input names.

    Returns
    -------
    RationalFit
        ``method="combined"``; inputs in the order of ``fits``.
    """
    fits = list(fits)
    if not fits or not all(isinstance(f, RationalFit) for f in fits):
        raise FitError("combine_simo needs a non-empty sequence of RationalFit (one per input).")
    outputs = fits[0].outputs
    if any(f.outputs != outputs for f in fits):
        raise FitError("combine_simo: all fits must have the same outputs in the same order.")
    inputs = tuple(name for f in fits for name in f.inputs)
    if len(set(inputs)) != len(inputs):
        raise FitError(
            f"combine_simo: input names repeat across fits ({list(inputs)}); each fit must "
            "cover its own inputs."
        )
    n_in = len(inputs)
    poles, residues, ranks, col = [], [], [], 0
    for f in fits:
        m = len(f.inputs)
        r = np.zeros((len(f.poles), len(outputs), n_in), dtype=complex)
        r[:, :, col : col + m] = f.residues
        poles.append(f.poles)
        residues.append(r)
        ranks.append(f.ranks)
        col += m
    d = np.concatenate([f.d for f in fits], axis=1)
    band = (min(f.band_hz[0] for f in fits), max(f.band_hz[1] for f in fits))
    return RationalFit(
        np.concatenate(poles),
        np.concatenate(residues),
        d,
        np.concatenate(ranks),
        inputs,
        outputs,
        band,
        "combined",
        max(f.iterations for f in fits),
        all(f.converged for f in fits),
        _combined_data(fits),
    )


def cluster_modes(f_hz: np.ndarray, n_groups: int | None = None, tol: float = 0.05) -> list[np.ndarray]:
    """Group natural frequencies (Hz) into clusters of neighbours.

    With ``n_groups`` the sorted frequencies are cut at the ``n_groups - 1`` largest relative
    gaps; otherwise neighbours closer than ``tol`` (relative) share a cluster. Returns index
    arrays into ``f_hz``, ordered by frequency.
    """
    f = np.asarray(f_hz, dtype=float)
    order = np.argsort(f)
    gaps = np.diff(np.log(f[order]))
    if n_groups is not None:
        if not 1 <= n_groups <= f.size:
            raise FitError(f"cannot make {n_groups} groups from {f.size} modes; give 1..{f.size} groups.")
        cuts = np.sort(np.argsort(gaps)[::-1][: n_groups - 1]) if n_groups > 1 else np.array([], int)
    else:
        cuts = np.flatnonzero(gaps > np.log1p(tol))
    return [np.asarray(c) for c in np.split(order, cuts + 1)]


def _explicit_groups(
    model: RationalFit, groups: Sequence[Any], cand: np.ndarray
) -> list[tuple[np.ndarray, int]]:
    f = model.f_hz
    out = []
    for item in groups:
        try:
            (lo, hi), count = item
            lo, hi, count = float(lo), float(hi), int(count)
        except (TypeError, ValueError) as exc:
            raise FitError(
                f"a group must be ((f_lo_hz, f_hi_hz), n_modes) or an int mode count; got {item!r}."
            ) from exc
        idx = cand[(f[cand] >= lo) & (f[cand] <= hi)]
        if idx.size == 0:
            raise FitError(
                f"group ({lo:g}-{hi:g} Hz) holds no mode of the model; modes are at "
                f"{np.array2string(f[cand], precision=4)} Hz."
            )
        out.append((idx, count))
    return out


def _resolve_groups(
    model: RationalFit, groups: Any, tol: float, rank_tol: float
) -> list[tuple[np.ndarray, int]]:
    cand = np.flatnonzero(model.poles.imag != 0)
    if cand.size == 0:
        raise FitError("the model has no complex (modal) poles to group.")
    if groups is None or isinstance(groups, (float, np.floating)):
        tol = tol if groups is None else float(groups)
        clusters = [cand[c] for c in cluster_modes(model.f_hz[cand], tol=tol)]
        return [(c, residue_rank(model.residues[c].sum(axis=0), rank_tol)) for c in clusters]
    groups = list(groups)
    if all(isinstance(g, (int, np.integer)) for g in groups):
        clusters = [cand[c] for c in cluster_modes(model.f_hz[cand], n_groups=len(groups))]
        return list(zip(clusters, (int(g) for g in groups)))
    return _explicit_groups(model, groups, cand)


def _merge_one(poles: np.ndarray, residues: np.ndarray, keep: int) -> tuple[complex, np.ndarray]:
    """Residue-weighted mean pole and rank-``keep`` SVD truncation of the summed residue (eq. 10)."""
    w = np.array([np.linalg.norm(r) for r in residues])
    w = w / w.sum() if w.sum() > 0 else np.full(w.size, 1.0 / w.size)
    pole = complex(np.sum(w * poles))
    u, sv, vh = np.linalg.svd(residues.sum(axis=0), full_matrices=False)
    return pole, (u[:, :keep] * sv[:keep]) @ vh[:keep]


def _merge(poles: np.ndarray, residues: np.ndarray, keep: int) -> list[tuple[complex, np.ndarray, int]]:
    """Replace a group by ``keep`` modes: ``keep`` frequency sub-clusters of its members, each a
    rank-1 mode (eq. 9); with fewer members than ``keep`` the modes share one rank-``keep`` pole."""
    if keep == 1 or poles.size < keep:
        pole, res = _merge_one(poles, residues, keep)
        return [(pole, res, keep)]
    subs = cluster_modes(np.abs(poles), n_groups=keep)
    return [(*_merge_one(poles[c], residues[c], 1), 1) for c in subs]


@limit_blas
def group_modes(
    model: RationalFit,
    groups: Any = None,
    tol: float = 0.05,
    rank_tol: float = 0.1,
    refine: bool = True,
) -> RationalFit:
    """The Caltech SVD reduction: group modes by frequency and keep a set number per group.

    A group kept at one mode becomes one pole (the residue-weighted mean of its members) whose
    residue is the rank-1 SVD truncation of the group's summed residue matrices (eqs. 9-10).
    A group kept at ``k > 1`` modes (two near-coincident bending modes) is split into ``k``
    frequency sub-clusters of its members, each becoming such a rank-1 mode; if the group has
    fewer members than ``k``, the ``k`` modes share one pole with a rank-``k`` residue. The
    factors are then refined by least squares (``refine``). Real poles and complex poles
    outside every explicit group are kept unchanged.

    Parameters
    ----------
    model : RationalFit
        Typically :func:`combine_simo` of SIMO fits.
    groups : None, float, sequence of int, or sequence of ((f_lo_hz, f_hi_hz), n_modes)
        ``None`` or a float: automatic clustering of neighbours within relative tolerance
        (``tol`` or the float) with the kept count set by the rank of the summed residue
        (singular values above ``rank_tol * sigma_1``). A sequence of ints: that many groups
        cut at the largest frequency gaps, with these mode counts, e.g. ``(2, 1, 2, 1)``.
        A sequence of ``((f_lo, f_hi), n)``: explicit bands in Hz with mode counts.
    tol : float
        Relative frequency tolerance of automatic clustering.
    rank_tol : float
        Relative singular-value threshold of automatic mode counts.
    refine : bool
        After the SVD split, refit the rank-``k`` factors ``C B`` of every group (poles fixed)
        to the model's data by alternating least squares (:func:`refine_residues`); needs
        ``model.data`` (kept by :func:`fit_rational` and :func:`combine_simo`).

    Returns
    -------
    RationalFit
        ``method="grouped"``, one pole per group with ``ranks`` = kept mode counts.
    """
    if not isinstance(model, RationalFit):
        raise FitError(
            f"group_modes needs a RationalFit (e.g. from combine_simo); got {type(model).__name__}."
        )
    resolved = _resolve_groups(model, groups, tol, rank_tol)
    used = np.zeros(len(model.poles), dtype=bool)
    poles, residues, ranks = [], [], []
    max_rank = min(len(model.outputs), len(model.inputs))
    for idx, keep in resolved:
        if not 1 <= keep <= max_rank:
            raise FitError(
                f"a group near {model.f_hz[idx].mean():.4g} Hz asks for {keep} modes; with "
                f"{len(model.outputs)} outputs and {len(model.inputs)} inputs keep 1..{max_rank}."
            )
        for pole, res, rank in _merge(model.poles[idx], model.residues[idx], keep):
            poles.append(pole)
            residues.append(res)
            ranks.append(rank)
        used[idx] = True
    for k in np.flatnonzero(~used):
        poles.append(model.poles[k])
        residues.append(model.residues[k])
        ranks.append(model.ranks[k])
    order = np.argsort(np.abs(poles), kind="stable")
    grouped = RationalFit(
        np.array(poles)[order],
        np.array(residues)[order],
        model.d.copy(),
        np.array(ranks, dtype=int)[order],
        model.inputs,
        model.outputs,
        model.band_hz,
        "grouped",
        model.iterations,
        model.converged,
        model.data,
    )
    return refine_residues(grouped) if refine else grouped
