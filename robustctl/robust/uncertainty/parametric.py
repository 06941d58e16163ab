"""Uncertain reals from an update, and a physical model with uncertain parameters as an
uncertain system.

* :func:`uncertain_parameters` (also ``UpdateResult.uncertain_parameters``, registered here):
  each updated parameter as a named :func:`~.elements.ureal` ``theta_hat +- n_sigma s``
  (``s`` its standard error, from the noise model when the update had one). Independent
  intervals drop the fit's correlations; the principal-axes LFT that keeps them is
  ``UpdateResult.uncertain()`` (:func:`robustctl.physical.uncertain.parametric_lft`).
* :func:`physical_uncertain` -- ``PhysicalModel`` + uncertain reals -> :class:`.system.
  UncertainSystem`, through ``parametric_lft`` with a diagonal covariance (one axis per
  parameter, ``n_sigma = 1`` so the box is the elements' ranges): exact when the state-space
  matrices are affine in the parameters (Zhou, Doyle & Glover 1996, sec. 10.2), else the
  first-order LFT with its error stated (an :class:`LFTAccuracyWarning`).
* :func:`from_uncertain_model` -- any ``UncertainModel`` as an uncertain system (its blocks
  as normalised reals named after its axes).
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from ...correlate.update_result import UpdateResult
from ...errors import ModelError, RobustctlWarning, SynthesisError
from ...physical.uncertain import UncertainModel, parametric_lft
from .elements import UncertainReal, ureal
from .lft_algebra import Raw
from .system import UncertainSystem, _merged, as_uncertain

__all__ = ["uncertain_parameters", "physical_uncertain", "from_uncertain_model", "LFTAccuracyWarning"]

#: relative LFT error against sampled models above which a first-order LFT is reported
LFT_ERROR_WARN = 1e-6


class LFTAccuracyWarning(RobustctlWarning):
    """The model is not affine in its uncertain parameters: the LFT is first order."""


def uncertain_parameters(upd: Any, n_sigma: float = 2.0, params: Any = None) -> dict[str, UncertainReal]:
    """The updated parameters as named uncertain reals ``theta_hat +- n_sigma * s``.

    Parameters
    ----------
    upd : UpdateResult
    n_sigma : float
        Half-width in standard errors (2: about 95 % for a Gaussian estimate).
    params : sequence of str, optional
        A subset of the updated parameters (default: all).

    Returns
    -------
    dict of str to UncertainReal
        In the order of the update's parameters; correlations are dropped (use
        ``upd.uncertain()`` for the principal-axes LFT that keeps them).

    Raises
    ------
    SynthesisError
        A non-positive ``n_sigma``, an unknown name, or a parameter without a finite positive
        standard error.
    """
    if not (isinstance(n_sigma, (int, float)) and np.isfinite(n_sigma) and n_sigma > 0):
        raise SynthesisError(f"n_sigma must be a positive number; got {n_sigma!r}.")
    names = tuple(upd.fit.names)
    chosen = names if params is None else tuple(params)
    unknown = [p for p in chosen if p not in names]
    if unknown:
        raise SynthesisError(f"params must be among the updated parameters {list(names)}; got {unknown}.")
    values = np.asarray(upd.fit.x_array, dtype=float)
    cov = np.asarray(upd.fit.covariance, dtype=float)
    out = {}
    for p in chosen:
        i = names.index(p)
        se = float(upd.std_errors.get(p, np.sqrt(max(cov[i, i], 0.0)))) if upd.std_errors else float(
            np.sqrt(max(cov[i, i], 0.0)))
        if not np.isfinite(se) or se <= 0:
            raise SynthesisError(f"the update gives {p} no finite positive standard error ({se!r}); "
                                 "it cannot be an uncertain parameter.")
        out[p] = ureal(p, float(values[i]), plusminus=n_sigma * se)
    return out


def from_uncertain_model(um: UncertainModel) -> UncertainSystem:
    """An ``UncertainModel`` (a parametric LFT) as an uncertain system; its blocks become
    reals ``0 +- 1`` named after the axes (``upd.uncertain()``'s principal axes).

    Parameters
    ----------
    um : UncertainModel

    Returns
    -------
    UncertainSystem
    """
    return as_uncertain(um)


def physical_uncertain(model: Any, uncertain: Any, *, f_hz: Any = None, n_check: int = 8,
                       seed: int = 0) -> UncertainSystem:
    """A physical model whose parameters are uncertain reals, as an uncertain system.

    Parameters
    ----------
    model : PhysicalModel
        Anything with ``.statespace(**values)``.
    uncertain : dict of str to UncertainReal, or sequence of UncertainReal
        The uncertain parameters, named as the model's (e.g. ``upd.uncertain_parameters()``).
    f_hz : array_like, optional
        Frequencies (Hz) of the LFT's error check.
    n_check : int
        Sampled points of that check.
    seed : int
        Seed of those points.

    Returns
    -------
    UncertainSystem
        One real block per parameter (multiplicity = the rank of its matrix change).

    Raises
    ------
    SynthesisError
        An element that is not an uncertain real.
    """
    els = list(uncertain.values()) if isinstance(uncertain, dict) else list(uncertain)
    if not els or not all(isinstance(e, UncertainReal) for e in els):
        raise SynthesisError("uncertain must hold rc.ureal elements named after the model's parameters.")
    names = [e.name for e in els]
    center = np.array([e.center for e in els])
    cov = np.diag([e.half_range ** 2 for e in els])
    try:
        um = parametric_lft(model, names, center, cov, n_sigma=1.0, f_hz=f_hz, n_check=n_check, seed=seed)
    except ModelError as exc:
        raise SynthesisError(f"cannot write the model as an LFT in {names}: {exc}") from exc
    if um.form != "state space":
        raise SynthesisError(f"the model's LFT in {names} is not in state-space form ({um.form!r}); its "
                             "blocks do not map to the parameters. Use a physical-coordinates model.")
    if not um.exact and um.max_error > LFT_ERROR_WARN:
        warnings.warn(
            f"the model is not affine in {names}: its LFT is first order, off by {100 * um.max_error:.3g} % "
            "of the peak response at sampled values; cover the rest with a complex weight.",
            LFTAccuracyWarning, stacklevel=2)
    sysu = from_uncertain_model(um)
    # each axis is +-half_k e_k (a diagonal covariance): map it to its parameter and sign
    A, B, C, D = sysu.raw.A, sysu.raw.B.copy(), sysu.raw.C, sysu.raw.D.copy()
    blocks, start = [], 0
    for k, r in enumerate(um.multiplicity):
        axis = um.axes[k]
        j = int(np.argmax(np.abs(axis)))
        off = np.delete(axis, j)
        tol = 1e-9 * abs(axis[j])
        if np.any(np.abs(off) > tol) or abs(abs(axis[j]) - els[j].half_range) > tol:
            raise SynthesisError(f"the LFT's axis {um.names[k]} mixes parameters; cannot name it.")
        if axis[j] < 0:  # delta_axis = -delta_parameter: flip the block's w channels
            B[:, start:start + r] *= -1
            D[:, start:start + r] *= -1
        blocks.append((els[j], r))
        start += r
    raw = Raw(A, B, C, D, sysu.raw.nw, sysu.raw.nz)
    return _merged(raw, blocks, sysu.inputs, sysu.outputs, 0.0)


def _update_uncertain_parameters(self, n_sigma: float = 2.0, params: Any = None) -> dict[str, UncertainReal]:
    return uncertain_parameters(self, n_sigma, params)


_update_uncertain_parameters.__doc__ = uncertain_parameters.__doc__
UpdateResult.uncertain_parameters = _update_uncertain_parameters
