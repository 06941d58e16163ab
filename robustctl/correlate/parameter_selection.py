"""Which parameters to update: MACE test 1 alignment of each parameter's sensitivity with the
initial cost vector and superparameters of near-collinear pairs (:func:`select_parameters`)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..errors import FitError
from .residual import (
    alignment,
    normalized,
    orthogonality,
)


# ---------------------------------------------------------------------------- selection
def superparameter(name_a: str, name_b: str, da: np.ndarray, db: np.ndarray) -> str:
    """The combination of two parameters with parallel relative sensitivities the data fix.

    If ``dJ_a ~ c dJ_b`` (relative sensitivities, MACE eq. 7) the residual depends on
    ``c ln a + ln b``, i.e. on ``a^c * b``; returned as a readable expression
    (``"a * b"``, ``"b / a"``, ``"a^0.5 * b"``).
    """
    c = float(da @ db) / max(float(db @ db), 1e-300)
    if abs(abs(c) - 1.0) < 0.1:
        return f"{name_a} * {name_b}" if c > 0 else f"{name_b} / {name_a}"
    if c > 0:
        return f"{name_a}^{c:.2g} * {name_b}"
    return f"{name_b} / {name_a}^{-c:.2g}"


def select_parameters(
    names: Sequence[str],
    j0: np.ndarray,
    dJ: np.ndarray,
    *,
    min_alignment: float = 0.01,
    max_orthogonality: float = 0.95,
    min_singular: float = 0.02,
    keep: Sequence[str] = (),
) -> tuple[tuple[str, ...], list[str], list[str]]:
    """MACE's two tests (eqs. 8-9) as an automatic selection.

    Parameters
    ----------
    names : sequence of str
        Candidate parameters, in the column order of ``dJ``.
    j0, dJ : ndarray
        Initial residual (n,) and sensitivities (n, p) (relative, MACE eq. 7).
    min_alignment : float
        Drop a parameter whose ``|j0^T dJ_i|`` is below this fraction of the largest.
    max_orthogonality : float
        Of a pair with ``|dJn_i^T dJn_k|`` above this, keep the better-aligned.
    min_singular : float
        After the pairwise test, while the smallest singular value of the kept normalised
        sensitivities is below this (a rank loss among three or more), drop the
        least-aligned parameter of the near-null combination.
    keep : sequence of str
        Parameters exempt from test 1 and considered first in test 2 (they win ties): the
        parameters of an effect added after ``rc.diagnose``, which already fitted them, so
        the remaining error is nearly orthogonal to them by construction.

    Returns
    -------
    selected : tuple of str
        Kept parameters, by decreasing alignment.
    notes : list of str
        Why each parameter was dropped, in words.
    suggestions : list of str
        Superparameter suggestions.
    """
    names = list(names)
    a = alignment(j0, dJ)
    amax = float(a.max()) if a.size else 0.0
    if amax <= 0:
        raise FitError(
            "no candidate parameter changes the residual (all sensitivities are zero); check that "
            "the parameters enter the model and that the band holds the modes they move."
        )
    O = orthogonality(dJ)
    notes, suggestions, kept = [], [], []
    order = sorted(range(len(names)), key=lambda i: (names[i] not in keep, -a[i]))
    for i in order:
        name = names[i]
        if a[i] < min_alignment * amax and name not in keep:
            notes.append(
                f"{name}: dropped by the alignment test (|j0^T dJ| = {a[i] / amax:.2%} of the largest): "
                "the initial error is insensitive to it."
            )
            continue
        clash = [k for k in kept if O[i, names.index(k)] > max_orthogonality]
        if clash:
            other = clash[0]
            k = names.index(other)
            combo = superparameter(other, name, dJ[:, k], dJ[:, i])
            notes.append(
                f"{name}: dropped by the orthogonality test ({O[i, k]:.3f} with {other}, which is better "
                "aligned with the initial error)."
            )
            suggestions.append(
                f"{other} and {name} move the residual the same way (orthogonality {O[i, k]:.3f}); the data "
                f"fix only the combination {combo}. {other} was kept; to update both, tie them into the "
                f"superparameter {combo}."
            )
            continue
        kept.append(name)
    while len(kept) > 1:
        cols = [names.index(k) for k in kept]
        _, s, vt = np.linalg.svd(normalized(dJ[:, cols]), full_matrices=False)
        if s[-1] >= min_singular * np.sqrt(len(kept)):
            break
        involved = [kept[m] for m in np.flatnonzero(np.abs(vt[-1]) > 0.3)]
        drop = min(involved, key=lambda n: (n in keep, a[names.index(n)]))
        kept.remove(drop)
        notes.append(
            f"{drop}: dropped because {', '.join(involved)} together move the residual in only "
            f"{len(involved) - 1} independent direction(s) (smallest singular value {s[-1]:.2g}); a "
            "superparameter of this group may be what the data determine."
        )
    return tuple(kept), notes, suggestions


