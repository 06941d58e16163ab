"""One coercion of a generalized plant ``[w; u] -> [z; y]`` for synthesis and analysis.

:func:`as_partitioned` is the single entry through which ``hinfsyn``, ``h2syn``,
``sampled_plant``, ``dksyn`` and the yardstick take their plant: one test of "is a
system" (:func:`robustctl.lti.as_statespace`), one check of ``nmeas``/``ncon``, one wording
of the refusal (:class:`robustctl.errors.PlantError`).
"""

from __future__ import annotations

from typing import Any

from ..checks import integer
from ..errors import ModelError, PlantError
from ..interconnect import PartitionedPlant
from ..lti import as_statespace
from .plant import GeneralizedPlant
from .uncertainty.blocks import as_block_structure

__all__ = ["as_partitioned"]

_FORMS = ("a PartitionedPlant or GeneralizedPlant (rc.generalized_plant, rc.mixed_sensitivity), "
          "or a system (control.StateSpace, transfer function) with nmeas and ncon")


def _carried(P: Any) -> bool:
    """Whether ``P`` carries its partition (a PartitionedPlant, or ``.P``, ``.nmeas``, ``.ncon``)."""
    return isinstance(P, PartitionedPlant) or all(hasattr(P, k) for k in ("P", "nmeas", "ncon"))


def as_partitioned(P: Any, nmeas: Any = None, ncon: Any = None, blocks: Any = None, *,
                   who: str = "hinfsyn", allow_discrete: bool = True,
                   need_blocks: bool = False) -> PartitionedPlant:
    """The plant as a checked :class:`~robustctl.interconnect.PartitionedPlant`.

    Parameters
    ----------
    P : PartitionedPlant, GeneralizedPlant, system, or object with ``.P``, ``.nmeas``, ``.ncon``
        The generalized plant, inputs ``[w..., u...]`` and outputs ``[z..., y...]``. A
        system is anything :func:`robustctl.lti.as_statespace` takes.
    nmeas, ncon : int, optional
        Number of measurements ``y`` and of control inputs ``u``. Required for a bare
        system; for a plant that carries them they may be given only if they agree.
    blocks : BlockStructure, sequence of Block or mussv rows, optional
        Uncertainty/performance blocks (``sum(rows) = nw``, ``sum(cols) = nz``); default:
        the plant's own ``blocks`` when it has them. With blocks the result is a
        :class:`~robustctl.robust.plant.GeneralizedPlant`.
    who : str
        The caller's name, used in the refusals.
    allow_discrete : bool
        Whether a discrete-time plant is accepted (``False`` for continuous-time designs).
    need_blocks : bool
        Refuse a plant without a block structure (D-K synthesis needs one).

    Returns
    -------
    PartitionedPlant
        ``P`` itself when it already is one with the same counts (and blocks), else a new
        PartitionedPlant, or a GeneralizedPlant when there are blocks.

    Raises
    ------
    PlantError
        What was passed cannot be a partitioned plant: not a system, ``nmeas``/``ncon``
        missing, contradicting the plant's, or out of range, an empty signal group, a
        discrete plant where ``allow_discrete`` is False, or blocks that do not fit.

    See Also
    --------
    robustctl.interconnect.PartitionedPlant, robustctl.robust.plant.generalized_plant

    References
    ----------
    K. Zhou, J. C. Doyle, K. Glover, *Robust and Optimal Control*, Prentice Hall, 1996,
    sec. 10.1 (the partitioned plant ``z = P11 w + P12 u``, ``y = P21 w + P22 u``).
    """
    if _carried(P):
        if blocks is None:
            blocks = getattr(P, "blocks", None)
        for name, given, have in (("nmeas", nmeas, P.nmeas), ("ncon", ncon, P.ncon)):
            if given is not None and integer(given, name, PlantError, lo=0) != have:
                raise PlantError(
                    f"{who}: {name}={given!r} contradicts the partitioned plant's {name}={have}; omit {name}."
                )
        base, nmeas, ncon = P.P, P.nmeas, P.ncon
    else:
        if nmeas is None or ncon is None:
            raise PlantError(
                f"{who}(P, nmeas, ncon): give the number of measurements nmeas and of control inputs "
                f"ncon with the {type(P).__name__} passed (got nmeas={nmeas!r}, ncon={ncon!r}), or pass "
                f"a plant that carries them: {_FORMS}."
            )
        base = P
    try:
        ss = as_statespace(base, name="P")
        plant = P if isinstance(P, PartitionedPlant) and P.P is ss else PartitionedPlant(ss, nmeas, ncon)
    except ModelError as exc:
        raise PlantError(f"{who}: {exc} Pass {_FORMS}.") from exc
    if plant.P.dt not in (0, None) and not allow_discrete:
        raise PlantError(
            f"{who} designs continuous-time controllers; the plant is discrete (dt = {plant.P.dt}). "
            "Design on a continuous-time plant and discretise the controller afterwards."
        )
    for what, count in (
        ("nmeas", plant.nmeas),
        ("ncon", plant.ncon),
        ("nw (exogenous inputs)", plant.nw),
        ("nz (regulated outputs)", plant.nz),
    ):
        if count < 1:
            raise PlantError(
                f"{who} needs at least one of each signal group; {what} = {count} for a plant with "
                f"{plant.P.ninputs} inputs and {plant.P.noutputs} outputs "
                f"(nmeas={plant.nmeas}, ncon={plant.ncon})."
            )
    if blocks is None:
        if need_blocks:
            raise PlantError(
                f"{who} needs the uncertainty/performance block structure; got a {type(P).__name__} "
                "without blocks. Pass a GeneralizedPlant (rc.generalized_plant) or a tuple "
                "(P, nmeas, ncon, blocks)."
            )
        return plant
    bs = as_block_structure(blocks)
    if (bs.n_in, bs.n_out) != (plant.nw, plant.nz):
        raise PlantError(
            f"{who}: blocks {bs.mussv().tolist()} need {bs.n_in} w inputs and {bs.n_out} z outputs "
            f"(Delta_i maps block i's z channels to its w channels); the plant has nw={plant.nw}, "
            f"nz={plant.nz}. Put the uncertainty and performance channels first, in block order."
        )
    if isinstance(plant, GeneralizedPlant) and plant.blocks == bs:
        return plant
    return GeneralizedPlant(plant.P, int(plant.nmeas), int(plant.ncon), blocks=bs)
