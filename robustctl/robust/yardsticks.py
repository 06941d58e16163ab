"""The measurement-model yardstick: score controllers designed on different models on the data.

MACE (Glaese & Miller, seed paper, "General Modeling Approach" and "Closed-loop
updating"): "because the measurement model is the most accurate representation of the
experimental data, [controllers designed on it] should achieve the highest performance.
The performance achieved using the measurement model is compared with that achieved using
the FEM. When these performances are comparable, the FEM updating has converged."

:func:`yardstick` designs one mu-controller per model with :func:`~robustctl.robust.dk.iteration.dksyn`
(the same weights and objectives for each, from one ``recipe``) and scores each controller
on the *measured* frequency responses:

* **attenuation** -- the loop is closed on the measured plant frequency by frequency: an
  input disturbance ``d`` (at the actuators) reaches the sensors through
  ``T(jw) = (I - s G(jw) K(jw))^-1 G(jw)`` where ``u = K y`` and the plant's measurement
  is ``y = s G u`` (``s = +-1``, read from the generalized plant). The score is
  ``20 log10(rms ||G||_F / rms ||T||_F)`` over the band (dB; the RMS response to a white
  disturbance, open over closed loop);
* **stability** -- the generalized Nyquist criterion on the data: the closed loop is stable
  iff ``det(I - s G K)`` encircles the origin counter-clockwise as many times as ``G K`` has
  open-loop unstable poles (Maciejowski 1989, sec. 2.8; Skogestad & Postlethwaite 2005,
  Theorem 4.9), counted from the plant model's and the controller's poles. Between the
  measured points the data are interpolated with the measurement model (data = model +
  interpolated residual), which resolves modes narrower than the frequency spacing. Outside the
  measured band the model's loop continues the curve, trusted only where it agrees with
  the data at the band edge and has no crossover (gain below 1, or quasi-static below the
  band); otherwise the verdict is "cannot tell";
* **robustness** -- mu of each controller against each model's uncertainty set.
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Callable, Mapping
from concurrent.futures import Executor
from dataclasses import dataclass, field, replace
from typing import Any

import control
import numpy as np

from ..checks import check_band, flag, match_channels
from ..errors import DataError, RobustctlWarning, SynthesisError
from ..executors import check_executor, parallel_map
from ..frd import FrequencyData
from ..identify._problem import as_frequency_data
from ..lti import as_statespace, freqresp_array, is_stable
from ..plots import new_figure
from ..table import Table
from .dk.iteration import DKResult, as_plant, check_dk_options, closed_loop, default_grid, dksyn, mu_of
from .dk.verify import verified_mu

__all__ = ["NyquistVerdict", "Yardstick", "YardstickWarning", "nyquist_stability", "yardstick"]

#: The loop gain must be below this at the band edges (and the model's outside) to count encirclements.
EDGE_LOOP_GAIN = 0.9
#: Points added to the fine grid around each lightly damped pole (uniform in the pole's phase).
POLE_POINTS = 48
#: Poles up to this damping ratio get them (better damped ones are followed by the log grid).
POLE_ZETA = 0.05


# ---------------------------------------------------------------------------- Nyquist on data
@dataclass(frozen=True)
class NyquistVerdict:
    """Generalized Nyquist test of one loop on measured data.

    Attributes
    ----------
    stable : bool or None
        None when the data cannot tell.
    encirclements : float
        Counter-clockwise encirclements of the origin by ``det(I - L)`` over the whole
        imaginary axis (NaN when not countable).
    open_loop_unstable : int
        Open-loop unstable poles of the loop (plant model + controller).
    reason : str
        Why the data cannot tell, or a short verdict.
    """

    stable: bool | None
    encirclements: float
    open_loop_unstable: int
    reason: str

    @property
    def label(self) -> str:
        """"stable", "unstable" or "cannot tell"."""
        return {True: "stable", False: "unstable", None: "cannot tell"}[self.stable]


def _eig_arg_sum(L: np.ndarray) -> float:
    """Sum of principal arguments of the eigenvalues of ``I - L``."""
    return float(np.sum(np.angle(np.linalg.eigvals(np.eye(L.shape[0]) - L))))


def _det_phase(L: np.ndarray) -> np.ndarray:
    """Unwrapped argument of ``det(I - L)`` along the first axis."""
    return np.unwrap(np.angle(np.linalg.det(np.eye(L.shape[-1])[None] - L)))


def _coarse(phase: np.ndarray, f: np.ndarray, max_step: float) -> str:
    steps = np.abs(np.diff(phase))
    if steps.size and steps.max() > max_step:
        k = int(np.argmax(steps))
        return (f"det(I - GK) turns by {steps[k]:.2g} rad between {f[k]:.4g} and {f[k + 1]:.4g} Hz: "
                "the frequency points are too coarse to follow it")
    return ""


def _outside(model_loop: Callable[[np.ndarray], np.ndarray], f_edge: float, L_edge: np.ndarray,
             side: str, max_step: float, poles: np.ndarray | None = None) -> tuple[float, str]:
    """Argument change of ``det(I - L)`` outside the data, from the model loop.

    ``side="low"``: from 0 to the first data point (including the step from the model's
    determinant to the data's there); ``"high"``: from the last one to infinity. Trusted
    when the model loop joins the data at the band edge (:func:`_junction`) and, out
    there, stays below unit gain (no crossover outside the data) or, below the band, is
    quasi-static (its determinant turns by less than pi/4). The log grid gets
    :func:`_pole_points` around the lightly damped ``poles``. Returns (change, "") or
    (NaN, reason).
    """
    if side == "low":
        lo, hi = f_edge * 1e-6, f_edge
        f = np.concatenate([[0.0], np.logspace(np.log10(lo), np.log10(hi), 600)])
    else:
        lo, hi = f_edge, f_edge * 1e6
        f = np.concatenate([np.logspace(np.log10(lo), np.log10(hi), 900), [1e12 * f_edge]])
    if poles is not None and poles.size:
        f = np.union1d(f, _pole_points(poles, lo, hi))
    L = np.asarray(model_loop(f), dtype=complex)
    L_model_edge = L[-1] if side == "low" else L[0]
    jump = _junction(L_model_edge, L_edge)
    if jump is None:
        return np.nan, (f"the plant model and the data disagree at the {side} band edge ({f_edge:.3g} Hz), "
                        "so the loop outside the measured band is unknown")
    phase = _det_phase(L)
    why = _coarse(phase, f, max_step)
    if why:
        return np.nan, why
    gain = float(np.linalg.norm(L, ord=2, axis=(1, 2)).max())
    if gain >= 1.0 and not (side == "low" and np.ptp(phase) < np.pi / 4):
        where = "below" if side == "low" else "above"
        return np.nan, (f"the loop gain reaches {gain:.2g} {where} the measured band: the data do not "
                        "cover the crossover band")
    return float(phase[-1] - phase[0]) + (jump if side == "low" else -jump), ""


def _junction(L_model: np.ndarray, L_data: np.ndarray) -> float | None:
    """Argument step of ``det(I - L)`` from the model's loop to the data's at a band edge.

    Exact when both loop gains are below 1 (every eigenvalue of ``I - L`` in the right half
    plane: the step is the change of the sum of principal arguments); otherwise accepted
    only when the two determinants differ by less than 30 %. None when they disagree.
    """
    gains = np.linalg.norm(np.stack([L_model, L_data]), ord=2, axis=(1, 2))
    if gains.max() < 1.0:
        return _eig_arg_sum(L_data) - _eig_arg_sum(L_model)
    eye = np.eye(L_data.shape[0])
    d_model, d_data = np.linalg.det(eye - L_model), np.linalg.det(eye - L_data)
    if abs(d_model - d_data) > 0.3 * abs(d_data):
        return None
    return float(np.angle(d_data / d_model))


def _unresolved(model_loop: Callable[[np.ndarray], np.ndarray], f: np.ndarray, n_fine: int = 20000) -> str:
    """A reason when the data's points miss turns of the model's ``det(I - L)`` (sharp resonances).

    The model loop's winding on the data's points is compared with its winding on a dense
    log grid (``n_fine`` points, a ratio of 1.0006 between neighbours over five decades).
    """
    fine = np.union1d(f, np.geomspace(f[0], f[-1], n_fine))
    turn_fine = np.diff(_det_phase(np.asarray(model_loop(fine), dtype=complex))[[0, -1]])[0]
    turn_data = np.diff(_det_phase(np.asarray(model_loop(f), dtype=complex))[[0, -1]])[0]
    if abs(turn_fine - turn_data) > np.pi / 2:
        return ("the frequency points are too coarse: between them the model's det(I - GK) turns "
                f"{(turn_fine - turn_data) / np.pi:+.1f} pi rad more than point by point")
    return ""


def nyquist_stability(
    f_hz: np.ndarray,
    loop: np.ndarray,
    open_loop_unstable: int,
    model_loop: Callable[[np.ndarray], np.ndarray] | None = None,
    *,
    max_step_rad: float = 0.75 * np.pi,
    poles: Any = None,
) -> NyquistVerdict:
    """Closed-loop stability of ``det(I - L)`` from ``L(j 2 pi f)`` measured on ``f_hz``.

    Parameters
    ----------
    f_hz : ndarray, shape (nf,)
        Increasing positive frequencies (Hz).
    loop : ndarray, shape (nf, n, n)
        Loop transfer matrix ``L = s G K`` on the data (positive feedback: ``det(I - L)``).
    open_loop_unstable : int
        Number of open-loop poles of ``L`` in the open right half plane.
    model_loop : callable, optional
        ``f_hz -> L`` of a model of the loop (``f = 0`` allowed), used only outside the
        measured band (see :func:`_outside`). Without it the loop gain must be below 0.9 at
        both band edges and is assumed to stay below 1 outside.
    max_step_rad : float
        Largest phase step of ``det(I - L)`` between neighbouring points still followed
        (unwrapping is unambiguous below pi; with a model loop, :func:`_unresolved` also
        checks that the points miss no turn of the model's determinant).
    poles : array_like, optional
        Poles (rad/s) of the model loop, its controller and its closed loop: the model's
        continuation outside the band is also sampled around the lightly damped ones
        (:func:`_pole_points`), so that a sharp resonance there is followed, not missed.

    Returns
    -------
    NyquistVerdict

    Notes
    -----
    Generalized Nyquist criterion (Maciejowski 1989, Theorem 2.8.1; Skogestad &
    Postlethwaite 2005, Theorem 4.9): the closed loop is stable iff ``det(I - L(s))``
    encircles the origin counter-clockwise ``open_loop_unstable`` times as ``s`` runs up the
    imaginary axis -- for a real-rational loop, twice the argument change over ``[0, inf)``
    divided by ``2 pi``. Where ``sigma_max(L) < 1`` every eigenvalue of ``I - L`` lies in
    the right half plane, so there the change is that of the sum of the eigenvalues'
    principal arguments (0 at ``f = 0`` and ``f = inf``).
    """
    f = np.asarray(f_hz, dtype=float)
    L = np.asarray(loop, dtype=complex)
    phase = _det_phase(L)
    why = _coarse(phase, f, max_step_rad)
    if why:
        return NyquistVerdict(None, np.nan, open_loop_unstable, why)
    if model_loop is None:
        gain = np.linalg.norm(L[[0, -1]], ord=2, axis=(1, 2))
        if gain.max() >= EDGE_LOOP_GAIN:
            edge = "low" if gain[0] >= EDGE_LOOP_GAIN else "high"
            return NyquistVerdict(None, np.nan, open_loop_unstable,
                                  f"the loop gain is {gain.max():.2g} at the {edge} end of the data "
                                  f"({f[0]:.3g}-{f[-1]:.3g} Hz): the data do not cover the crossover band")
        low, high = _eig_arg_sum(L[0]), -_eig_arg_sum(L[-1])
    else:
        why = _unresolved(model_loop, f)
        if why:
            return NyquistVerdict(None, np.nan, open_loop_unstable, why)
        poles = None if poles is None else np.asarray(poles, dtype=complex).ravel()
        low, why_low = _outside(model_loop, f[0], L[0], "low", max_step_rad, poles)
        high, why_high = _outside(model_loop, f[-1], L[-1], "high", max_step_rad, poles)
        if why_low or why_high:
            return NyquistVerdict(None, np.nan, open_loop_unstable, why_low or why_high)
    n_ccw = (low + (phase[-1] - phase[0]) + high) / np.pi
    rounded = int(np.round(n_ccw))
    if abs(n_ccw - rounded) > 0.1:
        return NyquistVerdict(None, n_ccw, open_loop_unstable,
                              f"the winding number {n_ccw:.2f} is not close to an integer")
    unstable_cl = open_loop_unstable - rounded
    if unstable_cl == 0:
        return NyquistVerdict(True, float(rounded), open_loop_unstable, "stable")
    return NyquistVerdict(False, float(rounded), open_loop_unstable,
                          f"{unstable_cl} closed-loop pole(s) in the right half plane")


def _n_unstable(sys1: Any, what: str) -> int:
    if sys1.nstates == 0:
        return 0
    p = np.linalg.eigvals(np.asarray(sys1.A, dtype=float))
    scale = max(1.0, float(np.abs(p).max()))
    if np.any(np.abs(p.real) <= 1e-9 * scale):
        raise SynthesisError(
            f"the {what} has poles on the imaginary axis; the Nyquist count on data needs them moved off "
            "(e.g. a pole at -1e-6 instead of an integrator)."
        )
    return int(np.sum(p.real > 0))


# ---------------------------------------------------------------------------- helpers
def measurement_sign(gp: Any, G: Any) -> float:
    """``s`` with ``P_yu ~ s G``: the recipe measures +-the plant's outputs.

    The recipe may reduce the model (e.g. to its six modes), so ``P_yu`` need only be
    correlated with ``+-G`` (|correlation| > 0.5 over the model's band).
    """
    Pyu = gp.sub("y", "u") if hasattr(gp, "sub") else None
    if Pyu is None or Pyu.noutputs != G.noutputs or Pyu.ninputs != G.ninputs:
        raise SynthesisError(
            f"the recipe's plant must measure the model's {G.noutputs} outputs with its "
            f"{G.ninputs} inputs as controls; got y x u = {getattr(gp, 'nmeas', '?')} x "
            f"{getattr(gp, 'ncon', '?')}."
        )
    f = default_grid(G, per_decade=10, max_points=200)
    a, b = freqresp_array(Pyu, f).ravel(), freqresp_array(G, f).ravel()
    corr = float(np.real(np.vdot(b, a)) / max(np.linalg.norm(a) * np.linalg.norm(b), 1e-300))
    if abs(corr) < 0.5:
        raise SynthesisError(
            f"the recipe's u -> y channel is not +-the model (correlation {corr:.2f}); yardstick closes "
            "the loop on the measured G, so the measurements must be the plant's outputs."
        )
    return float(np.sign(corr))


def _pole_points(poles: np.ndarray, f_lo: float, f_hi: float, n: int = POLE_POINTS,
                 zeta_max: float = POLE_ZETA) -> np.ndarray:
    """Frequencies (Hz) ``(w_d + sigma t) / (2 pi)`` around each lightly damped pole
    ``p = -sigma + j w_d`` (damping ratio below ``zeta_max``, ``w_d`` in the band).

    ``t = tan(theta)`` with ``theta`` uniform in ``(-pi/2, pi/2)`` (``n`` points): the mode's
    term ``1 / (j w - p)`` turns its phase by ``pi / n`` from point to point however narrow
    the resonance (a mode of 1e-6 damping at 17 Hz is 1e-4 rad/s wide, far below a log
    grid's spacing); then ``n`` points a side in geometric steps out to ``|t| = |p| / sigma``,
    where the term's magnitude falls by a constant factor per step and the log grid takes over.
    """
    p = np.asarray(poles, dtype=complex).ravel()
    p = p[(p.imag > 0) & (p.real < 0)]
    sigma, wd = -p.real, p.imag
    keep = (sigma < zeta_max * np.abs(p)) & (wd >= 2 * np.pi * f_lo) & (wd <= 2 * np.pi * f_hi)
    sigma, wd, wn = sigma[keep], wd[keep], np.abs(p[keep])
    if not sigma.size:
        return np.zeros(0)
    t_core = np.tan(np.linspace(-np.pi / 2, np.pi / 2, n + 2)[1:-1])
    t0 = t_core[-1]
    reach = np.maximum(wn / sigma / t0, 1.0)  # tail from t0 to |p| / sigma
    t_tail = t0 * reach[:, None] ** np.linspace(0.0, 1.0, n + 1)[None, 1:]
    t = np.concatenate([np.broadcast_to(t_core, (sigma.size, n)), t_tail, -t_tail], axis=1)
    f = (wd[:, None] + sigma[:, None] * t).ravel() / (2 * np.pi)
    return f[(f >= f_lo) & (f <= f_hi)]


def _loop_poles(systems: dict, designs: dict, signs: dict, reference: str) -> np.ndarray:
    """Poles that shape ``det(I - s G K)`` on the axis: every model's and controller's, and
    those of each controller's loop closed on its own model and on the reference model."""
    poles = [np.linalg.eigvals(np.asarray(sys1.A, dtype=float)) for sys1 in systems.values() if sys1.nstates]
    for lab, design in designs.items():
        K = design.K
        k = control.ss(K.A, K.B, K.C, K.D)
        if K.nstates:
            poles.append(np.linalg.eigvals(np.asarray(K.A, dtype=float)))
        for G in {lab: systems[lab], reference: systems[reference]}.values():
            g = control.ss(G.A, G.B, signs[lab] * np.asarray(G.C), signs[lab] * np.asarray(G.D))
            try:
                poles.append(control.feedback(g, k, sign=+1).poles())
            except (ValueError, np.linalg.LinAlgError):  # an ill-posed loop (I - D_G D_K singular)
                continue
    return np.concatenate(poles) if poles else np.zeros(0, complex)


def _interpolated(data: FrequencyData, systems: dict, reference: str, f: np.ndarray,
                  n_fine: int = 20000, poles: np.ndarray | None = None) -> tuple[np.ndarray, dict]:
    """The measured plant between its points: the reference (measurement) model plus the
    linearly interpolated residual ``G_data - G_ref``.

    Lightly damped modes are narrower than a Welch estimate's resolution (1.5 % damping at
    1.1 Hz: half-power width 0.033 Hz, data spacing 0.049 Hz), so ``det(I - G K)`` can turn
    by more than pi between measured points; the measurement model fits the data to within
    the noise and carries the resonance shape between them. The grid is a log grid of
    ``n_fine`` points plus :func:`_pole_points` around the lightly damped ``poles``.
    """
    fine = np.union1d(f, np.geomspace(f[0], f[-1], n_fine))
    if poles is not None and poles.size:
        fine = np.union1d(fine, _pole_points(poles, f[0], f[-1]))
    ref = systems[reference]
    base = freqresp_array(ref, fine)
    out = {}
    for lab, G in systems.items():
        resid = _aligned_response(data, G) - freqresp_array(ref, f)
        flat = resid.reshape(f.size, -1)
        inter = np.stack([np.interp(fine, f, c.real) + 1j * np.interp(fine, f, c.imag)
                          for c in flat.T], axis=1)
        out[lab] = base + inter.reshape(fine.size, *resid.shape[1:])
    return fine, out


def _design(gp: Any, options: dict) -> DKResult:
    """One D-K design (module level so a process executor can pickle it)."""
    return dksyn(gp, progress=False, **options)


def _band_of(data: FrequencyData, band: tuple[float, float] | None) -> tuple:
    """The data's frequencies, the band (Hz) and its mask; refuses a band with fewer than 2 points."""
    f_all = np.asarray(data.f_hz, dtype=float)
    lo, hi = (f_all[0], f_all[-1]) if band is None else band
    in_band = (f_all >= lo) & (f_all <= hi)
    if in_band.sum() < 2:
        raise DataError(f"band ({lo:g}, {hi:g}) Hz holds fewer than 2 data points; the data span "
                        f"{f_all[0]:g}-{f_all[-1]:g} Hz.")
    return f_all, lo, hi, in_band


def _recipe_plant(recipe: Callable[[Any], Any], model: Any, label: str) -> Any:
    """``recipe(model)``, refused unless it is a plant :func:`dksyn` takes."""
    plant = recipe(model)
    try:
        as_plant(plant)
    except SynthesisError as exc:
        raise SynthesisError(f"recipe(models[{label!r}]) must return a GeneralizedPlant: {exc}") from exc
    return plant


def _fit_band(model: Any) -> tuple[float, float] | None:
    """The band (Hz) a measurement model was fitted on; None for other models."""
    band = getattr(model, "band_hz", None) if hasattr(model, "fit") else None
    return None if band is None else (float(band[0]), float(band[1]))


def _system_of(model: Any) -> Any:
    """The model as a system: a MeasurementModel (``.sys``, no ``.statespace()``) gives its ``sys``."""
    if not hasattr(model, "statespace") and hasattr(model, "sys"):
        return model.sys
    return model


def _aligned_response(data: FrequencyData, G: Any, values: np.ndarray | None = None) -> np.ndarray:
    """The data's response (or ``values`` of the data's shape, e.g. its coherence) with channels in
    the model's order (:func:`robustctl.checks.match_channels`: by name, by position only when one
    side has python-control's default names)."""
    if data.shape[1:] != (G.noutputs, G.ninputs):
        raise DataError(
            f"the data have {data.n_out} outputs x {data.n_in} inputs but the models have "
            f"{G.noutputs} x {G.ninputs}; select matching channels (data.select(...))."
        )
    out_idx = match_channels(data.outputs, G.output_labels, "outputs", ("data", "model"))
    in_idx = match_channels(data.inputs, G.input_labels, "inputs", ("data", "model"))
    arr = np.asarray(data.response, dtype=complex) if values is None else np.asarray(values)
    return arr[:, out_idx][:, :, in_idx]


def _windings(f_hz: np.ndarray, L: np.ndarray) -> list[tuple[int, int, int]]:
    """Where ``det(I - L)`` winds around the origin: ``(first, last, turns)`` per stretch of points
    with loop gain ``sigma_max(L) >= 1`` that turns it (counter-clockwise positive).

    Where ``sigma_max(L) < 1`` every eigenvalue of ``I - L`` lies in the right half plane, so the
    sum of their principal arguments is the determinant's argument without ambiguity: between two
    such points the unwrapped argument's change minus that of the sums is ``2 pi`` times the
    encirclements made in between. A stretch at an end of the data is closed by the end point.
    """
    gain = np.linalg.norm(L, ord=2, axis=(1, 2))
    phase = _det_phase(L)
    quiet = np.flatnonzero(gain < 1.0)
    out = []
    k = 0
    while k < f_hz.size:
        if gain[k] < 1.0:
            k += 1
            continue
        first = k
        while k < f_hz.size and gain[k] >= 1.0:
            k += 1
        last = k - 1
        before = quiet[quiet < first]
        after = quiet[quiet > last]
        a = int(before[-1]) if before.size else first
        b = int(after[0]) if after.size else last
        direct = _eig_arg_sum(L[b]) - _eig_arg_sum(L[a]) if before.size and after.size else 0.0
        turns = int(np.round((phase[b] - phase[a] - direct) / (2 * np.pi)))
        if turns:
            out.append((first, last, turns))
    return out


def _loop_detail(f_hz: np.ndarray, L: np.ndarray, coherence: np.ndarray | None, G: np.ndarray | None = None,
                 K: np.ndarray | None = None, fit_band: tuple[float, float] | None = None,
                 fine: tuple[np.ndarray, np.ndarray] | None = None) -> str:
    """Where the loop on the data decides its verdict, in words.

    The generalized Nyquist count changes only where ``det(I - s G K)`` winds around the
    origin, which needs a loop gain of at least 1: the stretches of frequency where it winds
    (:func:`_windings`) are named first, each with its peak loop gain and the data's coherence
    there, then the largest loop gain. The coherence that matters is the one of the channels
    carrying the loop: a channel counts by its share of ``||L||_F^2``,
    ``|G_ij|^2 sum_k |K_jk|^2`` (a decoupled channel has coherence near 0 because its
    response is near 0, and carries nothing of the loop); without ``G`` and ``K`` the lowest
    channel's coherence is given. A winding outside ``fit_band`` (the band the controller's
    design model was fitted on) is said to be there: outside it that model is the extrapolation
    of its fillers, not a fit to the data.

    Parameters
    ----------
    f_hz : ndarray, shape (nf,)
        Measured frequencies (Hz).
    L : ndarray, shape (nf, n, n)
        Loop ``s G K`` on the data.
    coherence : ndarray, shape (nf, n, m) or None
        The data's coherence per channel, in the model's channel order.
    G : ndarray, shape (nf, n, m), optional
        The measured plant (weights the coherence with ``K``).
    K : ndarray, shape (nf, m, n), optional
        The controller's response on ``f_hz``.
    fit_band : (f_lo_hz, f_hi_hz), optional
        Band the design model was fitted on (a measurement model's ``band_hz``).
    fine : (f_fine_hz, L_fine), optional
        The loop on a finer grid (the yardstick's interpolated data) to locate the windings;
        default: the measured points.

    Returns
    -------
    str
    """
    gain = np.linalg.norm(L, ord=2, axis=(1, 2))

    def coh(k: int) -> str:
        if coherence is None:
            return "the data carry no coherence"
        c = np.asarray(coherence[k], dtype=float)
        w = None if G is None or K is None else np.abs(G[k]) ** 2 * np.sum(np.abs(K[k]) ** 2, axis=1)[None, :]
        if w is None or not np.sum(w) > 0:
            return f"the data's coherence is {float(np.min(c)):.2f} (lowest channel)"
        weighted = float(np.sum(w * c) / np.sum(w))
        return (f"the data's coherence is {weighted:.2f} on the channels carrying the loop, "
                f"{float(np.min(c)):.2f} on the lowest")

    f_w, L_w = (f_hz, L) if fine is None else fine
    g_w = np.linalg.norm(L_w, ord=2, axis=(1, 2))
    parts = []
    for first, last, turns in _windings(f_w, L_w):
        peak = first + int(np.argmax(g_w[first:last + 1]))
        k = int(np.argmin(np.abs(f_hz - f_w[peak])))
        where = (f"det(I - GK) winds {abs(turns)} time(s) {'counter-' if turns > 0 else ''}clockwise around "
                 f"the origin in {f_w[first]:.4g}-{f_w[last]:.4g} Hz (loop gain up to {g_w[peak]:.3g} at "
                 f"{f_w[peak]:.4g} Hz; {coh(k)})")
        if fit_band is not None and not fit_band[0] <= f_w[peak] <= fit_band[1]:
            where += (f", outside the {fit_band[0]:.4g}-{fit_band[1]:.4g} Hz band the controller's design "
                      "model was fitted on (there that model extrapolates its fillers)")
        parts.append(where)
    top = int(np.argmax(gain))
    parts.append(f"largest loop gain sigma_max(GK) = {gain[top]:.3g} at {f_hz[top]:.4g} Hz ({coh(top)})")
    return "; ".join(parts)


class YardstickWarning(RobustctlWarning):
    """A yardstick controller whose stability on the data is not established (not ranked)."""


def _rms_frobenius(X: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum(np.abs(X) ** 2, axis=(1, 2)))))


def _model_loop(G: Any, K: Any, sign: float) -> Callable[[np.ndarray], np.ndarray]:
    """``f_hz -> s G(j 2 pi f) K(j 2 pi f)`` of a model (``f = 0`` allowed)."""
    def loop(f: np.ndarray) -> np.ndarray:
        return sign * freqresp_array(G, f) @ freqresp_array(K, f)

    return loop


# ---------------------------------------------------------------------------- result
@dataclass(frozen=True)
class Yardstick:
    """Controllers designed on several models, scored on the measured data.

    Attributes
    ----------
    labels : tuple of str
        Model labels, in the order given.
    reference : str
        The measurement model's label (the yardstick).
    designs : dict
        label -> :class:`~robustctl.robust.dk.iteration.DKResult`.
    attenuation_db : dict
        label -> disturbance attenuation on the data over the band (dB, larger is better).
    stability : dict
        label -> :class:`NyquistVerdict` of the loop closed on the measured plant.
    mu_cross : ndarray, shape (n, n)
        Peak mu of controller ``i`` (row) against model ``j``'s uncertainty set (column);
        inf when that loop is unstable. Against a set with real blocks (mixed mu, which can
        rise in a narrow spike between grid points) the peak is verified as ``dksyn``
        verifies its own (:func:`~robustctl.robust.dk.verify.verification_grid`).
    band_hz : tuple of float
    f_hz : ndarray
        The data's frequencies in the band.
    open_loop : ndarray
        ``sigma_max(G_data)`` over ``f_hz``.
    closed_loop : dict
        label -> ``sigma_max(T)`` over ``f_hz`` with the measured ``G``.
    """

    labels: tuple[str, ...]
    reference: str
    designs: dict[str, DKResult] = field(repr=False)
    attenuation_db: dict[str, float]
    stability: dict[str, NyquistVerdict] = field(repr=False)
    mu_cross: np.ndarray = field(repr=False)
    band_hz: tuple[float, float]
    f_hz: np.ndarray = field(repr=False)
    open_loop: np.ndarray = field(repr=False)
    closed_loop: dict[str, np.ndarray] = field(repr=False)

    @property
    def ranked(self) -> tuple[str, ...]:
        """Labels whose loop on the data is stable, best attenuation first: only these are ranked.
        A controller whose stability on the data is unstable or cannot be told is not ranked on
        its attenuation (that number assumes a stable loop)."""
        ok = [lab for lab in self.labels if self.stability[lab].stable is True]
        return tuple(sorted(ok, key=lambda lab: -self.attenuation_db[lab]))

    @property
    def unverified(self) -> tuple[str, ...]:
        """Labels whose stability on the data is not established ("unstable" or "cannot tell")."""
        return tuple(lab for lab in self.labels if self.stability[lab].stable is not True)

    def gap_db(self, label: str) -> float:
        """How many dB less than the reference controller ``label``'s controller attenuates."""
        return float(self.attenuation_db[self.reference] - self.attenuation_db[label])

    def ratio(self, label: str) -> float:
        """``label``'s attenuation (dB) as a fraction of the reference's (1 = as good)."""
        ref = self.attenuation_db[self.reference]
        return float(self.attenuation_db[label] / ref) if ref != 0 else float("nan")

    def table(self) -> Table:
        """One row per model: design mu, attenuation on the data, gap to the yardstick, stability."""
        rows = []
        ranked = self.ranked
        for i, lab in enumerate(self.labels):
            dk = self.designs[lab]
            verdict = self.stability[lab].label
            rank = str(ranked.index(lab) + 1) if lab in ranked else f"not ranked ({verdict})"
            rows.append((
                lab + (" (yardstick)" if lab == self.reference else ""),
                dk.K.nstates, dk.mu_peak, float(np.max(self.mu_cross[i])),
                self.attenuation_db[lab], self.gap_db(lab), self.ratio(lab), self.stability[lab].label, rank,
            ))
        cols = ("controller designed on", "K order", "mu (own set)", "mu (worst set)",
                "attenuation (dB)", "gap (dB)", "ratio", "on the data", "rank")
        return Table(cols, rows, title=f"Yardstick on the data, {self.band_hz[0]:g}-{self.band_hz[1]:g} Hz")

    def mu_table(self) -> Table:
        """Peak mu of each controller (rows) against each model's uncertainty set (columns)."""
        rows = [(lab, *self.mu_cross[i]) for i, lab in enumerate(self.labels)]
        return Table(("controller \\ model set", *self.labels), rows, title="Peak mu across models")

    def summary(self) -> str:
        """MACE's convergence test in one paragraph."""
        ref = self.reference
        band = f"{self.band_hz[0]:g}-{self.band_hz[1]:g} Hz"
        if self.stability[ref].stable is True:
            parts = [f"The {ref}-model controller attenuates the disturbance by "
                     f"{self.attenuation_db[ref]:.1f} dB on the data ({band}), stable on the data."]
        else:
            parts = [f"NOT RANKED: the {ref}-model controller's stability on the data is "
                     f"{self.stability[ref].label} ({self.stability[ref].reason}); its "
                     f"{self.attenuation_db[ref]:.1f} dB attenuation ({band}) assumes a stable loop, so "
                     "the gaps below are measured from an unverified reference."]
        for lab in self.labels:
            if lab == ref:
                continue
            verdict = self.stability[lab]
            if verdict.stable is True:
                parts.append(f"{lab}: {self.attenuation_db[lab]:.1f} dB (gap {self.gap_db(lab):.1f} dB, "
                             f"ratio {self.ratio(lab):.2f}; stable on the data).")
            else:
                parts.append(f"{lab}: NOT RANKED, {verdict.label} on the data ({verdict.reason}); its "
                             f"{self.attenuation_db[lab]:.1f} dB would hold only for a stable loop.")
        if self.ranked:
            parts.append("Ranking of the controllers stable on the data: " + ", ".join(self.ranked) + ".")
        return " ".join(parts)

    def plot(self):
        """Disturbance response on the data (open loop and each controller) and the scores."""
        fig = new_figure(10.0, 4.5)
        ax1, ax2 = fig.subplots(1, 2, width_ratios=(2, 1))
        ax1.loglog(self.f_hz, self.open_loop, "k", lw=1.0, label="open loop (data)")
        for lab in self.labels:
            ax1.loglog(self.f_hz, self.closed_loop[lab], lw=1.2, label=f"K from {lab}")
        ax1.set(xlabel="frequency (Hz)", ylabel="sigma_max, disturbance -> sensors",
                title="Loops closed on the measured plant")
        ax1.legend(fontsize=8)
        ax2.bar(range(len(self.labels)), [self.attenuation_db[lab] for lab in self.labels])
        ax2.set_xticks(range(len(self.labels)), self.labels, rotation=20)
        ax2.set(ylabel="attenuation on the data (dB)", title="Yardstick")
        return fig

    def _repr_html_(self) -> str:
        import html

        return f"<p>{html.escape(self.summary())}</p>" + self.table()._repr_html_()


# ---------------------------------------------------------------------------- the function
def _check_inputs(data: Any, models: Any, recipe: Any, reference: str | None) -> tuple:
    data = as_frequency_data(data)
    if not isinstance(models, Mapping) or len(models) < 2:
        raise SynthesisError(
            "models must map at least two labels to systems, e.g. {'nominal': model, 'measurement': mm}; "
            f"got {type(models).__name__}."
        )
    if not callable(recipe):
        raise SynthesisError(f"recipe must be a callable nominal -> GeneralizedPlant; got {recipe!r}.")
    labels = tuple(str(k) for k in models)
    if reference is None:
        reference = "measurement" if "measurement" in labels else labels[-1]
    if reference not in labels:
        raise SynthesisError(f"reference {reference!r} is not one of the model labels {list(labels)}.")
    return data, labels, reference


def yardstick(
    data: Any,
    models: Mapping[str, Any],
    recipe: Callable[[Any], Any],
    *,
    reference: str | None = None,
    band: tuple[float, float] | None = None,
    executor: Executor | None = None,
    progress: bool | None = None,
    **dk_options: Any,
) -> Yardstick:
    """Design one mu-controller per model and score each on the measured data (MACE's yardstick).

    Parameters
    ----------
    data : FrequencyData
        Measured plant responses (actuators -> sensors).
    models : mapping of str to system
        Labels -> models (anything ``rc.as_statespace`` accepts, or a MeasurementModel), e.g.
        ``{"nominal": model, "updated": upd.model, "measurement": mm}``.
    recipe : callable
        ``nominal -> GeneralizedPlant`` (the same weights and objectives for every model);
        its measurements must be +-the model's outputs, its controls the model's inputs. It
        receives each model as given (a MeasurementModel as its ``.sys``).
    reference : str, optional
        The yardstick's label (default ``"measurement"`` if present, else the last one).
    band : (f_lo_hz, f_hi_hz), optional
        Band of the attenuation score (default: the whole data).
    executor : concurrent.futures.Executor, optional
        Runs the designs in parallel.
    progress : bool, optional
        tqdm bar over the designs (only when stderr is a terminal; False switches it off).
    **dk_options
        Passed to :func:`~robustctl.robust.dk.iteration.dksyn` (``max_iter``, ``order_d`` ...).

    Returns
    -------
    Yardstick
    """
    data, labels, reference = _check_inputs(data, models, recipe, reference)
    f_all, lo, hi, in_band = _band_of(data, check_band(band))
    if progress is not None:
        flag(progress, "progress", SynthesisError)
    check_executor(executor)
    check_dk_options(dk_options, "yardstick")
    given = {lab: _system_of(models[lab]) for lab in labels}
    systems = {lab: as_statespace(given[lab], name=f"models[{lab!r}]") for lab in labels}
    plants = {lab: _recipe_plant(recipe, given[lab], lab) for lab in labels}
    signs = {lab: measurement_sign(plants[lab], systems[lab]) for lab in labels}
    results = parallel_map(functools.partial(_design, options=dk_options), [plants[lab] for lab in labels],
                           executor, desc="yardstick designs", progress=progress is None or bool(progress))
    designs = dict(zip(labels, results))
    attenuation, stability, closed = {}, {}, {}
    G_ref = _aligned_response(data, systems[reference])
    poles = _loop_poles(systems, designs, signs, reference)
    f_fine, G_fine = _interpolated(data, systems, reference, f_all, poles=poles)
    open_rms = _rms_frobenius(G_ref[in_band])
    for lab in labels:
        K, s = designs[lab].K, signs[lab]
        G_all = _aligned_response(data, systems[lab])
        Kf = freqresp_array(K, f_all)
        L = s * G_all @ Kf
        T = np.linalg.solve(np.eye(L.shape[1])[None] - L, G_all)
        attenuation[lab] = float(20 * np.log10(open_rms / _rms_frobenius(T[in_band])))
        closed[lab] = np.linalg.norm(T[in_band], ord=2, axis=(1, 2))
        n_ol = _n_unstable(systems[lab], f"model {lab!r}") + _n_unstable(K, f"controller for {lab!r}")
        L_fine = s * G_fine[lab] @ freqresp_array(K, f_fine)
        verdict = nyquist_stability(f_fine, L_fine, n_ol, _model_loop(systems[lab], K, s), poles=poles)
        if verdict.stable is not True:
            coh = None if data.coherence is None else _aligned_response(data, systems[lab], data.coherence)
            detail = _loop_detail(f_all, L, coh, G_all, Kf, _fit_band(models[lab]), (f_fine, L_fine))
            verdict = replace(verdict, reason=f"{verdict.reason}; {detail}")
            warnings.warn(
                f"the controller designed on {lab!r} is {verdict.label} on the data: {verdict.reason}. "
                "It is not ranked on its attenuation (Yardstick.ranked).",
                YardstickWarning,
                stacklevel=2,
            )
        stability[lab] = verdict
    mu_cross = np.full((len(labels), len(labels)), np.inf)
    for i, lab_k in enumerate(labels):
        for j, lab_m in enumerate(labels):
            gp = plants[lab_m]
            cl = closed_loop(gp.P, designs[lab_k].K, gp.nmeas, gp.ncon)
            if cl.nstates and is_stable(cl, margin=0.0):
                blocks = designs[lab_m].blocks
                m = mu_of(cl, blocks, default_grid(gp.P), refine=True)[0]
                if blocks.has_real:  # mixed mu can spike between grid points: verify it
                    m = verified_mu(cl, blocks, m.f_hz)
                mu_cross[i, j] = m.peak
    return Yardstick(labels=labels, reference=reference, designs=designs, attenuation_db=attenuation,
                     stability=stability, mu_cross=mu_cross, band_hz=(lo, hi), f_hz=f_all[in_band],
                     open_loop=np.linalg.norm(G_ref[in_band], ord=2, axis=(1, 2)), closed_loop=closed)
