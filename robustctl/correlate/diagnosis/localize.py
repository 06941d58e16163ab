"""Where a misfit sits, in the structure's terms: the frequency bands that hold its excess over the
noise, the model's modes there and the part of the structure they move; and whether its pattern
is a channel's (one output row or input column at every frequency: a cable or a calibration).

The excess of a residual point over the noise is ``z^2 - 2`` (its real and imaginary parts
normalised by the noise model's variance, :func:`robustctl.correlate.diagnosis.significance._null_test`),
counted on the testable points where it is positive. A mode's region is the set of locations
holding most of its kinetic energy ``phi_i (M phi)_i`` (mass-normalised shapes: the shares sum to
one; Ewins, *Modal Testing*, 2nd ed., sec. 4.3 on the modal mass distribution).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ...physical.eigen import solve_modes
from ...physical.reduction import REDUCE_MIN_DOF
from ..residual import Residual

#: A band extends from a peak of the smoothed excess while it stays above this share of the peak.
BAND_LEVEL = 0.2
#: At most this many bands are named ...
N_BANDS = 3
#: ... each holding at least this share of the total excess.
BAND_MIN_SHARE = 0.05
#: Half-width (points along frequency) of the running mean of the excess before the bands are cut.
SMOOTH_HALF_WIDTH = 3
#: Relative widening of a band when looking for the model's modes in it.
MODE_MARGIN = 0.03
#: Locations named per mode: the fewest holding this share of its kinetic energy (at most three).
REGION_SHARE = 0.6
#: Frequency segments of the channel-pattern test (:func:`channel_pattern`).
N_SEGMENTS = 6
#: A channel's pattern is frequency independent when its excess spreads over the segments with a
#: participation ratio ``(sum x)^2 / (K sum x^2)`` of at least this (1: equal in every segment).
CHANNEL_SPREAD = 0.5
_DOF_SUFFIXES = ("ux", "uy", "uz", "rx", "ry", "rz", "x", "y", "z")


def point_excess(res: Residual, vec: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """``(excess, z2)`` per residual point, shape (n_freq, n_out, n_in): the normalised squared
    error ``z^2`` (expectation 2 within the noise) and its positive excess over 2, zero on points
    the noise model does not test; None without a noise model."""
    if res.noise is None:
        return None
    e = res.unstack(vec)
    base = np.broadcast_to(res.point_weights * res.noise.sigma**2, e.shape)
    ok = (res.point_weights > 0) & np.broadcast_to(res.noise.testable, e.shape) & (base > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        z2 = np.where(ok, np.abs(e) ** 2 / np.where(ok, base, 1.0), 0.0)
    return np.where(ok, np.maximum(z2 - 2.0, 0.0), 0.0), np.where(ok, z2, np.nan)


@dataclass(frozen=True)
class MisfitBand:
    """One frequency band holding part of a misfit's excess over the noise.

    Attributes
    ----------
    lo_hz, hi_hz : float
        The band, Hz.
    share : float
        Its share of the total excess (0..1).
    dispersion : float
        Mean ``z^2`` per real residual entry in the band (1 within the noise): "N x the noise".
    modes : tuple of (float, tuple of str, bool)
        The model's natural frequencies in the band (Hz) with the locations holding most of each
        mode's kinetic energy; when none lies in it, the nearest mode (the third item True: the
        data's resonance sits where the model has none, e.g. a mode moved by a missing stiffness).
    """

    lo_hz: float
    hi_hz: float
    share: float
    dispersion: float
    modes: tuple = ()

    def describe(self) -> str:
        head = (f"{self.lo_hz:.3g}-{self.hi_hz:.3g} Hz ({100 * self.share:.0f}% of the excess, "
                f"{self.dispersion:.3g} x the noise)")
        if not self.modes:
            return head + ", no mode of the model there"
        items = [f"{f:.4g} Hz" + (f" ({', '.join(where)})" if where else "") for f, where, _ in self.modes]
        if self.modes[0][2]:
            return head + ": no mode of the model there; the nearest is " + items[0]
        return head + ": mode" + ("s " if len(items) > 1 else " ") + "; ".join(items)


def misfit_bands(res: Residual, vec: np.ndarray, model: Any = None) -> tuple[MisfitBand, ...]:
    """The bands holding most of the excess of the residual ``vec`` over the noise, largest first,
    with the modes of ``model`` (default ``res.model``) in each; empty without a noise model or an
    excess."""
    got = point_excess(res, vec)
    if got is None:
        return ()
    excess, z2 = got
    per_f = excess.sum(axis=(1, 2))
    total = float(per_f.sum())
    if total <= 0:
        return ()
    from scipy.ndimage import uniform_filter1d

    smooth = uniform_filter1d(per_f, 2 * SMOOTH_HALF_WIDTH + 1, mode="nearest")
    f = np.asarray(res.f_hz, dtype=float)
    taken = np.zeros(f.size, dtype=bool)
    out = []
    for _ in range(N_BANDS):
        level = np.where(taken, -1.0, smooth)
        k = int(np.argmax(level))
        if level[k] <= 0:
            break
        lo = hi = k
        while lo > 0 and not taken[lo - 1] and smooth[lo - 1] >= BAND_LEVEL * smooth[k]:
            lo -= 1
        while hi < f.size - 1 and not taken[hi + 1] and smooth[hi + 1] >= BAND_LEVEL * smooth[k]:
            hi += 1
        taken[lo:hi + 1] = True
        share = float(per_f[lo:hi + 1].sum()) / total
        if share < BAND_MIN_SHARE:
            continue
        disp = float(np.nanmean(z2[lo:hi + 1])) / 2.0 if np.any(np.isfinite(z2[lo:hi + 1])) else np.nan
        out.append(MisfitBand(float(f[lo]), float(f[hi]), share, disp))
    if not out:
        return ()
    modes = band_modes(model if model is not None else res.model, [(b.lo_hz, b.hi_hz) for b in out])
    return tuple(MisfitBand(b.lo_hz, b.hi_hz, b.share, b.dispersion, m) for b, m in zip(out, modes))


def band_modes(model: Any, bands: list[tuple[float, float]]) -> list[tuple]:
    """For each band (Hz), the model's natural frequencies in it (widened by :data:`MODE_MARGIN`)
    with each mode's region (:func:`mode_region`); frequencies only for a model without a
    structure (the poles of its state space)."""
    lo = min(b[0] for b in bands) / 2.0
    hi = max(b[1] for b in bands) * 2.0
    shapes = None
    try:
        struct = model.build_structure()
        mats = struct.matrices()
        # a large structure's modes by Lanczos (a dense eigh of 20,000 DOFs needs 20 GB), as the
        # candidates' calibration finds them (effects.catalogue._modes)
        w, phi = solve_modes(mats.mass, mats.stiffness, band_hz=(lo, hi),
                             sparse=True if mats.n_dof >= REDUCE_MIN_DOF else None)
        f_modes = w / (2 * np.pi)
        shapes = (phi, mats.mass, tuple(mats.dof_labels))
    except Exception:  # noqa: BLE001 - a model without a structure: its poles name the modes
        try:
            poles = np.linalg.eigvals(np.asarray(model.statespace().A, dtype=float))
        except Exception:  # noqa: BLE001 - nothing to name: the bands stand alone
            return [() for _ in bands]
        f_modes = np.sort(np.abs(poles[poles.imag > 0]) / (2 * np.pi))
    out = []
    for b_lo, b_hi in bands:
        inside = np.flatnonzero((f_modes >= b_lo * (1 - MODE_MARGIN)) & (f_modes <= b_hi * (1 + MODE_MARGIN)))
        nearest = inside.size == 0 and f_modes.size > 0
        if nearest:  # the nearest on a log scale
            centre = np.sqrt(max(b_lo, 1e-300) * max(b_hi, 1e-300))
            inside = np.array([int(np.argmin(np.abs(np.log(np.maximum(f_modes, 1e-300) / centre))))])
        items = []
        for k in inside[:4]:
            where = () if shapes is None else mode_region(shapes[0][:, k], shapes[1], shapes[2])
            items.append((float(f_modes[k]), where, bool(nearest)))
        out.append(tuple(items))
    return out


def _location(label: str) -> str:
    head, _, tail = label.rpartition(" ")
    return head if head and tail in _DOF_SUFFIXES else label


def mode_region(phi: np.ndarray, mass: Any, labels: tuple[str, ...]) -> tuple[str, ...]:
    """The fewest locations (at most three) holding :data:`REGION_SHARE` of a mode's kinetic
    energy ``|phi_i (M phi)_i|`` summed per location (the DOF label without its direction)."""
    m_phi = np.asarray(mass @ phi).ravel()
    energy = np.abs(phi * m_phi)
    per: dict[str, float] = {}
    for lab, e in zip(labels, energy):
        loc = _location(str(lab))
        per[loc] = per.get(loc, 0.0) + float(e)
    total = sum(per.values())
    if total <= 0:
        return ()
    names, acc = [], 0.0
    for loc, e in sorted(per.items(), key=lambda kv: -kv[1]):
        names.append(loc)
        acc += e / total
        if acc >= REGION_SHARE or len(names) == 3:
            break
    return tuple(names)


def channel_pattern(res: Residual, vec: np.ndarray, share_needed: float) -> tuple[str, int, float] | None:
    """``(side, index, share)`` when the excess of ``vec`` over the noise is a channel's: one output
    row (``side="output"``) or input column holds at least ``share_needed`` of it overall and in
    every frequency segment (of :data:`N_SEGMENTS`) that holds a real part of it, and its own excess
    spreads over the segments (participation ratio at least :data:`CHANNEL_SPREAD`): a cable, sign
    or calibration fault is there at every frequency, a structural fault at its modes. None
    otherwise (or without a noise model)."""
    found = _channel_sets(res, vec, share_needed, size=1)
    return None if found is None else (found[0], found[1][0], found[2])


def channel_pair_pattern(res: Residual, vec: np.ndarray,
                         share_needed: float) -> tuple[str, tuple[int, int], float] | None:
    """``(side, (i, j), share)`` when the excess of ``vec`` is two channels' together: two output
    rows (or input columns) hold at least ``share_needed`` of it overall and in every segment that
    holds a real part of it, and their excess together spreads over the segments as
    :func:`channel_pattern` asks of one channel's. Two cables swapped (or two sensors exchanged) put their
    misfit ``|H_i - H_j|`` in both rows at every frequency, its split between them changing from
    mode to mode, so neither row alone passes :func:`channel_pattern`. Only with at least three
    channels on that side (with two, every misfit is the pair's); None otherwise."""
    return _channel_sets(res, vec, share_needed, size=2)


def _channel_sets(res: Residual, vec: np.ndarray, share_needed: float,
                  size: int) -> tuple[str, tuple[int, ...], float] | None:
    """The ``size`` output rows (else input columns) holding most of the excess, when they hold
    ``share_needed`` of it overall and in every real segment and their excess spreads over them."""
    got = point_excess(res, vec)
    if got is None:
        return None
    excess = got[0]
    total = float(excess.sum())
    if total <= 0:
        return None
    segs = np.array_split(np.arange(excess.shape[0]), min(N_SEGMENTS, excess.shape[0]))
    d = res.data
    for side, axis, n in (("output", (0, 2), d.n_out), ("input", (0, 1), d.n_in)):
        per = excess.sum(axis=axis)
        ks = tuple(int(k) for k in np.argsort(-per, kind="stable")[:size])
        share = float(per[list(ks)].sum()) / total
        if n < size + 1 or share < share_needed or share <= 1.5 * size / n:
            continue
        rows = np.array([excess[s].sum(axis=axis) for s in segs])
        seg_tot = rows.sum(axis=1)
        real = seg_tot > total / (2 * len(segs))
        x = rows[:, list(ks)].sum(axis=1)
        consistent = all(x[i] >= share_needed * seg_tot[i] for i in np.flatnonzero(real))
        spread = float(x.sum() ** 2 / (x.size * float(x @ x))) if x.any() else 0.0
        if consistent and spread >= CHANNEL_SPREAD:
            return side, tuple(sorted(ks)), share
    return None
