"""What ``robustctl design`` builds: a model (and the data it must cover) to a mu-controller.

The loop's design step on a user's own files, by the demo's D-K route
(:mod:`robustctl.demo_design`) with one generic recipe in place of an example's:

1. the design model ``G0``: MODEL, with an update's effect and parameter values
   (``--update OUT``, :func:`robustctl.cli_inputs.updated_model`), reduced to ``--order``
   states by balanced truncation when asked (:func:`robustctl.balanced_truncation`);
2. an additive uncertainty weight covering ``sigma_max(data - G0)`` over the band
   (:func:`robustctl.robust.cover_additive`, Caltech seed eqs. 1-2) when DATA is given;
3. ``input_mult`` and ``output_mult`` multiplicative uncertainty (4 % by default, the seed's),
   unit input disturbances, and on the sensors the band-pass performance weight
   ``level w2 s / ((s + w1)(s + w2))`` with corners ``perf_band_hz`` (gain ``level`` in the band);
4. :func:`robustctl.dksyn` on that generalized plant (:func:`robustctl.generalized_plant`).

A recipe of the user's own replaces 2-3: ``--plant FILE.py:NAME``, a callable ``nominal ->
GeneralizedPlant`` (the same convention as :class:`robustctl.demo_design.DesignSpec.plant`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["DesignRecipe", "band_pass_weight"]


def band_pass_weight(level: float, band_hz: tuple[float, float]) -> Any:
    """``level w2 s / ((s + w1)(s + w2))`` with corners ``band_hz`` (Hz): gain ``level`` in the band.

    Returns
    -------
    control.StateSpace
        SISO, two states.
    """
    import control

    w1, w2 = 2 * np.pi * float(band_hz[0]), 2 * np.pi * float(band_hz[1])
    return control.ss(control.tf([level * w2, 0.0], np.polymul([1.0, w1], [1.0, w2])))


@dataclass(frozen=True)
class DesignRecipe:
    """The command's generic design plant (see the module docstring).

    Attributes
    ----------
    data : FrequencyData or None
        Measured FRFs the additive weight covers (None: no additive uncertainty).
    perf_band_hz : (float, float)
        Corners of the performance weight, Hz.
    level : float
        Gain of the performance weight in its band.
    input_mult, output_mult : float
        Multiplicative uncertainty at the plant input and output (0.04 = 4 %).
    cover_order : int
        States of the additive weight.
    cover_band_hz : (float, float) or None
        Band of the cover, Hz (None: every data point).
    data_sigmas : float
        The measured error is raised by this many standard deviations of the H1 estimate's random
        error before it is covered (:func:`~robustctl.robust.cover_additive`; 0: as measured).
    """

    data: Any = None
    perf_band_hz: tuple[float, float] = (0.3, 8.0)
    level: float = 0.3
    input_mult: float = 0.04
    output_mult: float = 0.04
    cover_order: int = 4
    cover_band_hz: tuple[float, float] | None = None
    data_sigmas: float = 3.0

    def __post_init__(self) -> None:
        from .checks import integer, positive_number
        from .errors import DataError

        lo, hi = (positive_number(f, "the performance band", unit="Hz") for f in self.perf_band_hz)
        if not lo < hi:
            raise DataError(
                f"the performance band must be (low, high) in Hz with low < high; got {self.perf_band_hz}."
            )
        positive_number(self.level, "level")
        positive_number(self.input_mult, "input_mult", allow_zero=True)
        positive_number(self.output_mult, "output_mult", allow_zero=True)
        integer(self.cover_order, "cover_order", lo=0)
        positive_number(self.data_sigmas, "data_sigmas", allow_zero=True)

    def cover(self, nominal: Any) -> Any:
        """The additive :class:`~robustctl.robust.uncertainty.UncertaintyCover` of ``nominal`` against
        the data (as their estimator sees the model, :meth:`seen_data`), or None without data."""
        from .robust import cover_additive

        if self.data is None:
            return None
        seen = self.seen_data(nominal)
        return cover_additive(
            nominal,
            seen,
            order=self.cover_order,
            band=self.cover_band_hz,
            smooth_octaves=0.5,
            data_sigmas=self.data_sigmas,
        )

    def seen_data(self, nominal: Any) -> Any:
        """The data the cover covers: ``data - E[H1 of G0] + G0`` when the data's experiment description
        establishes their estimator (:func:`robustctl.measure.estimator.resolve_view`, the rule of
        :func:`robustctl.compare`), so the weight covers the model's error and not the estimate's
        window leakage (a 1 %-damped mode's peak, which leakage lowers several-fold, would otherwise
        count as model error); the data unchanged otherwise."""
        from .lti import as_statespace, freqresp_array
        from .measure.estimator import model_view, resolve_view, split_hold

        settings, _ = resolve_view("auto", self.data, nominal)
        if settings is None:
            return self.data
        bare, hold = split_hold(nominal)
        sys = as_statespace(bare)
        outs, ins = [str(n) for n in sys.output_labels], [str(n) for n in sys.input_labels]
        rows = [outs.index(o) for o in self.data.outputs]
        cols = [ins.index(i) for i in self.data.inputs]
        f = self.data.f_hz
        leak = model_view(sys, hold, f, settings) - freqresp_array(sys, f)
        return self.data.replace(response=self.data.response - leak[:, rows][:, :, cols])

    def __call__(self, nominal: Any, cover: Any = None) -> Any:
        """The generalized plant of ``nominal`` (``cover``: its additive cover, computed when None)."""
        from .robust import generalized_plant

        cover = self.cover(nominal) if cover is None else cover
        return generalized_plant(
            nominal,
            additive=None if cover is None else cover.weight,
            input_mult=self.input_mult or None,
            output_mult=self.output_mult or None,
            performance=band_pass_weight(self.level, self.perf_band_hz),
            disturbances=1.0,
        )
