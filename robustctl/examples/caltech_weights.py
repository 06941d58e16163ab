"""The Caltech seed's uncertainty weights, reproduced on the embedded truss.

The seed (Balas-Doyle, "Selection of Uncertainty Weights") covers the variation between
the measured FRFs and its six-mode MIMO model with an additive weight (eq. 14) -- small
at low frequency, rising through the 0.5-5.5 Hz design band to hold the unmodelled local
modes above it -- plus 4 % input and output multiplicative uncertainty. The weights there
were "determined from engineering judgment"; here they are computed:

* the seed's procedure: a six-mode measurement model identified on 0.5-5.5 Hz is the
  nominal, and an additive weight covers its residual against the data;
* the updated physical model: a weight covering the measured residual of ``rc.update``'s
  model plus the spread of its parameters (``UpdateResult.sample_models``).

Both are drawn side by side with eq. 14 by :meth:`CaltechWeights.plot`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..correlate import update
from ..lti import freqresp, freqresp_array
from ..plots import new_figure
from ..robust.uncertainty.cover import cover_additive
from ..robust.uncertainty.weights import caltech_additive_weight

__all__ = ["CaltechWeights", "caltech_truss_weights", "caltech_additive_weight"]


@dataclass(frozen=True, eq=False)
class CaltechWeights:
    """Result of :func:`caltech_truss_weights`.

    Attributes
    ----------
    data : FrequencyData
        The simulated measurement.
    truth : PhysicalModel
        The model the data came from (for checking only).
    update : UpdateResult
        The physical model's update.
    updated : UncertaintyCover
        Additive cover of the updated model's residual and parameter spread.
    measurement : UncertaintyCover or None
        Additive cover of the six-mode measurement model's residual (the seed's procedure).
    seed_weight : control.StateSpace
        The seed's eq. 14.
    truth_margin : float
        ``min_f |W_updated| / sigma_max(G_truth - G_updated)``: >= 1 when the cover holds the
        true plant.
    """

    data: Any
    truth: Any
    update: Any
    updated: Any
    measurement: Any
    seed_weight: Any
    truth_margin: float

    def plot(self, fig: Any = None) -> Any:
        """The covers with eq. 14 on one log-log axis per cover."""
        covers = [("updated physical model + parameter spread", self.updated)]
        if self.measurement is not None:
            covers.append(("six-mode measurement model (the seed's procedure)", self.measurement))
        fig = fig or new_figure(6.0 * len(covers), 4.5)
        axes = fig.subplots(1, len(covers), squeeze=False)[0]
        for ax, (title, cov) in zip(axes, covers):
            f = cov.f_hz
            ax.loglog(f, cov.envelope, "k-", lw=0.6, label="error envelope (data and models)")
            ax.loglog(
                f, cov.weight_mag, "C0-", lw=2, label=f"|W| (order {cov.order}), margin {cov.margin:.3g}"
            )
            ax.loglog(
                f, np.abs(freqresp_array(self.seed_weight, f)[:, 0, 0]), "C3-.", lw=1.5, label="seed eq. 14"
            )
            ax.axvspan(0.5, 5.5, color="0.9", lw=0, zorder=0)
            ax.set_xlabel("frequency (Hz)")
            ax.set_ylabel("sigma_max(G - G0)")
            ax.set_title(title, fontsize=9)
            ax.legend(fontsize=7)
        return fig


def caltech_truss_weights(
    seed: int = 0,
    *,
    band: tuple[float, float] = (0.3, 60.0),
    update_band: tuple[float, float] = (0.5, 10.0),
    n_models: int = 20,
    order: int = 4,
    measurement_model: bool = True,
    data: Any = None,
    truth: Any = None,
) -> CaltechWeights:
    """Additive weights for the Caltech truss from its residuals, beside the seed's eq. 14.

    Parameters
    ----------
    seed : int
        Seed of the simulated experiment and of the parameter draws.
    band : (lo_hz, hi_hz)
        Band of the covers (Hz).
    update_band : (lo_hz, hi_hz)
        Band of the physical update (Hz).
    n_models : int
        Parameter sets drawn from the update's covariance.
    order : int
        Order of the weights.
    measurement_model : bool
        Also cover the six-mode measurement model's residual (the seed's procedure).
    data, truth : optional
        A measurement and its truth (default ``caltech_truss_experiment(seed)``).

    Returns
    -------
    CaltechWeights
    """
    from .caltech_truss_model import caltech_truss
    from .experiments import caltech_truss_experiment

    if data is None:
        data, truth = caltech_truss_experiment(seed=seed)
    upd = update(caltech_truss(), data, band=update_band, progress=False)
    cov = cover_additive(upd.model, [data, *upd.sample_models(n_models, seed=seed)], order, band=band)
    mm_cover = None
    if measurement_model:
        from ..identify import fit_measurement_model

        mm = fit_measurement_model(data, n_modes=6, band=(0.5, 5.5), correct_leakage=True)
        mm_cover = cover_additive(mm.sys, data, 3, band=band)
    margin = float("nan")
    if truth is not None:
        g_t = freqresp(truth, cov.f_hz).response
        g_0 = freqresp(upd.model, cov.f_hz).response
        err = np.linalg.svd(g_t - g_0, compute_uv=False)[:, 0]
        margin = float(np.min(cov.weight_mag / err))
    return CaltechWeights(data, truth, upd, cov, mm_cover, caltech_additive_weight(), margin)
