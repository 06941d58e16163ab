"""Truth generators: measured-like data from a model with a hidden effect and parameter errors.

A *truth* is the nominal model plus one physical effect it lacks (with values) plus a few
per cent of error on some of its physical parameters. :func:`make_experiment` runs the
Caltech identification experiment on the truth -- one white-noise single-input
experiment per actuator (200 Hz, 81,920 samples), sensor noise (1 % of each response, above
each sensor's floor: :func:`sensor_noise_levels`), H1 Welch estimates with 4096-point
Hamming windows, the SIMO columns joined into the MIMO FRF -- so the data carry
the same estimation errors as a real test. The truth is returned for checking and is
described in ``data.meta["truth"]``, but a demo should reveal it only at the end.

The D/A converter holds each sample (zero-order hold), which the simulation reproduces
exactly; a hold adds a half-sample delay and a sinc droop that no structural model has.
Unless ``hold_correction=False``, the estimate is divided by the hold's response
``(1 - exp(-s T)) / (s T)`` (``T = 1 / fs``), as a test engineer does before comparing
with a continuous model.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..checks import flag, integer, positive_number
from ..correlate.residual import physical_model
from ..errors import DataError, ModelError
from ..frd import FrequencyData
from ..measure.estimate import combine_experiments, estimate_frf, simulate_experiment
from ..measure.estimator import hold_response
from ..physical.effects import GroupTension
from ..threads import limit_blas

__all__ = ["make_experiment", "sensor_noise_levels", "caltech_truss_experiment", "mace_beam_experiment",
           "hold_response"]




def _truth(model: Any, hidden: Any, param_errors: Mapping[str, float]) -> Any:
    for name, err in param_errors.items():
        if name not in model.param_names:
            raise ModelError(
                f"param_errors names unknown parameter {name!r}; the model has {list(model.param_names)}."
            )
        if not np.isfinite(err) or err <= -1:
            raise ModelError(f"relative error of {name!r} must be finite and > -1; got {err!r}.")
    truth = model.with_values(**{n: model.param(n).value * (1.0 + float(e)) for n, e in param_errors.items()})
    if hidden is not None:
        if hidden.is_neutral:
            raise ModelError(
                f"the hidden effect {hidden.name} is at its neutral value (it changes nothing); give it "
                "values, e.g. effect.with_values(...)."
            )
        truth = truth.with_effect(hidden)
    return truth


def sensor_noise_levels(records: Sequence[np.ndarray], noise_rms: float,
                        noise_floor: float = 1e-4) -> np.ndarray:
    """Noise standard deviation of each output in each experiment: 1 % of its RMS, above a floor.

    Output ``j`` of experiment ``k`` gets ``sigma_kj = max(noise_rms * rms_kj, noise_floor * M_j)``
    with ``rms_kj`` the RMS of its noise-free record and ``M_j = max_k rms_kj`` the sensor's
    largest RMS response over all the experiments. The floor is the sensor's own: its noise
    does not fall with the response of the input that happens to be driven. 1e-4 (80 dB below
    the largest response) is the usable dynamic range of a 16-bit acquisition whose range is
    set for the sensor's largest response. Above the floor (``rms_kj >= noise_floor / noise_rms
    * M_j``, 1 % of ``M_j`` by default) the level is ``noise_rms * rms_kj`` as before; below it,
    a channel whose input hardly reaches the sensor is measured as the sensor's floor noise.

    The floor matters where symmetry decouples a channel: its simulated response is round-off
    (MACE's bus: 1e-8 to 3e-6 of the sensor's largest response, different under each BLAS
    kernel), and a level of 1 % of that round-off measured the round-off almost noise-free, at
    high coherence, so a fit followed it. Above the floor, round-off moves the data by at most
    round-off / floor (2.5 % of that channel's noise on MACE, its worst channel).

    Parameters
    ----------
    records : sequence of ndarray, each of shape (n_samples, n_out)
        The noise-free outputs of each experiment, in output units (the same outputs, in the
        same order, in every record).
    noise_rms : float
        The noise as a fraction of each output's own RMS (0.01: 1 %; 0: no noise, no floor).
    noise_floor : float
        Each sensor's floor as a fraction of its largest RMS over the records (1e-4: 80 dB; 0:
        no floor, the noise of each experiment follows its own response).

    Returns
    -------
    ndarray, shape (n_experiments, n_out)
        Noise standard deviation of each output in each experiment, in output units.

    Raises
    ------
    DataError
        No records, records with different outputs, or a negative or non-finite ``noise_rms``
        or ``noise_floor``.
    """
    noise_rms = positive_number(noise_rms, "noise_rms (a fraction of the output RMS)", allow_zero=True)
    noise_floor = positive_number(noise_floor, "noise_floor (a fraction of the sensor's largest RMS)",
                                  allow_zero=True)
    arrays = [np.asarray(y, dtype=float) for y in records]
    if not arrays or any(y.ndim != 2 for y in arrays) or len({y.shape[1] for y in arrays}) != 1:
        raise DataError(
            "records must be one or more (n_samples, n_out) arrays with the same outputs; got shapes "
            f"{[y.shape for y in arrays]}."
        )
    rms = np.array([np.sqrt(np.mean(y**2, axis=0)) for y in arrays])
    if noise_rms == 0:
        return np.zeros_like(rms)
    return np.maximum(noise_rms * rms, noise_floor * rms.max(axis=0))


@limit_blas
def make_experiment(
    model: Any,
    hidden: Any = None,
    param_errors: Mapping[str, float] | None = None,
    noise_rms: float = 0.01,
    seed: int = 0,
    fs: float = 200.0,
    n_samples: int = 81920,
    nperseg: int = 4096,
    band: tuple[float, float] | None = None,
    *,
    simultaneous: bool = False,
    hold_correction: bool = True,
    noise_floor: float = 1e-4,
) -> tuple[FrequencyData, Any]:
    """Simulated test data of ``model`` with a hidden effect and parameter errors.

    Parameters
    ----------
    model : PhysicalModel
        The nominal model.
    hidden : Effect, optional
        The effect the truth has and the model lacks, with its values
        (``rc.effects.GroupTension("longerons_story_1", tension=12.0)``).
    param_errors : mapping, optional
        Relative errors of the truth's parameters, ``{"E_aluminium": 0.03}`` (+3 %).
    noise_rms : float
        White sensor noise as a fraction of each output's RMS response in each experiment
        (0.01: 1 %), above the sensor's floor (``noise_floor``; :func:`sensor_noise_levels`).
    seed : int
        Seed of the excitation and noise (each SIMO experiment uses ``seed + k``).
    fs : float
        Sampling frequency in Hz.
    n_samples : int
        Samples per experiment (Caltech: 81,920 = 409.6 s at 200 Hz).
    nperseg : int
        Welch segment length (Caltech: 4096, 50 % overlap, Hamming; 39 averages).
    band : (float, float), optional
        Keep only this band (Hz) of the estimate.
    simultaneous : bool
        Excite all inputs at once (one MIMO experiment) instead of one SIMO experiment per
        input (Caltech).
    hold_correction : bool
        Divide the estimate by the zero-order hold's response (see the module notes).
    noise_floor : float
        Each sensor's noise floor as a fraction of its largest RMS response over all the
        experiments (1e-4: 80 dB; 0: none). A channel whose RMS is below
        ``noise_floor / noise_rms`` of that (1 %) is measured with the floor's noise.

    Returns
    -------
    data : FrequencyData
        The estimated FRF with coherence; ``meta["truth"]`` describes the truth.
    truth : PhysicalModel
        The model the data were simulated from.

    Notes
    -----
    ``meta["truth"]["noise_std"]`` holds the noise standard deviation of each output in each
    experiment (keyed by the excited inputs, then the output), in the output's units. A
    channel that an input does not reach (decoupled by symmetry: its simulated response is
    round-off) is measured as the sensor's floor noise, as in a laboratory, not as round-off
    plus 1 % of round-off.
    """
    model = physical_model(model, "make_experiment")
    if param_errors is not None and not isinstance(param_errors, Mapping):
        raise ModelError(f"param_errors must map parameter names to relative errors; got {param_errors!r}.")
    errors = dict(param_errors or {})
    noise_rms = positive_number(noise_rms, "noise_rms (a fraction of the output RMS)", allow_zero=True)
    noise_floor = positive_number(noise_floor, "noise_floor (a fraction of the sensor's largest RMS)",
                                  allow_zero=True)
    seed = integer(seed, "seed", lo=0)
    simultaneous = flag(simultaneous, "simultaneous")
    hold_correction = flag(hold_correction, "hold_correction")
    truth = _truth(model, hidden, errors)
    sys = truth.statespace()
    inputs = list(sys.input_labels)
    outputs = list(sys.output_labels)
    groups = [inputs] if simultaneous else [[name] for name in inputs]
    records = [simulate_experiment(sys, fs=fs, n_samples=n_samples, seed=seed + k, inputs=group)
               for k, group in enumerate(groups)]
    noise_std = sensor_noise_levels([y for _, y in records], noise_rms, noise_floor)
    exps = []
    for k, (group, (u, y)) in enumerate(zip(groups, records)):
        if noise_rms > 0:
            rng = np.random.default_rng([int(seed), k, 1])
            y = y + rng.standard_normal(y.shape) * noise_std[k]
        exps.append(estimate_frf(u, y, fs, nperseg=nperseg, inputs=group, outputs=outputs))
    data = exps[0] if len(exps) == 1 else combine_experiments(exps)
    if hold_correction:
        data = data.replace(
            response=data.response / hold_response(data.f_hz, fs)[:, None, None],
            meta={**data.meta, "hold_divided": True},
            experiment=data.experiment.replace(hold_divided=True),
        )
    if band is not None:
        data = data.band(*band)
    meta = dict(data.meta)
    meta["truth"] = {
        "hidden_effect": None
        if hidden is None
        else {
            "name": hidden.name,
            "kind": hidden.kind,
            "location": hidden.location,
            "values": dict(hidden.values),
            "description": hidden.description,
        },
        "param_errors": errors,
        "noise_rms_fraction": float(noise_rms),
        "noise_floor_fraction": float(noise_floor),
        "noise_std": {"+".join(group): {name: float(v) for name, v in zip(outputs, row)}
                      for group, row in zip(groups, noise_std)},
        "seed": int(seed),
        "experiments": "simultaneous" if simultaneous else "one SIMO experiment per input",
        "hold_correction": bool(hold_correction),
    }
    return data.replace(meta=meta), truth


#: The hidden truth of :func:`caltech_truss_experiment` (revealed, e.g., at a demo's end).
CALTECH_TRUTH = {
    "hidden": ("GroupTension", "longerons_story_1", {"tension": 15.0}),
    "param_errors": {"E_aluminium": 0.03, "m_platform_1": -0.04, "m_offset": 0.05},
    "noise_rms": 0.01,
}


def caltech_truss_experiment(seed: int = 0, **kwargs: Any) -> tuple[FrequencyData, Any]:
    """The demo's measured data of the Caltech truss (``rc.examples.caltech_truss()``).

    The truth follows the seed's own explanation of its FEM error: the accelerometer wires
    were "tightly fixed to the columns and pulled taut, thereby adding stiffness to the
    longerons". Spoiler, for the end of a demo: the truth is the nominal truss plus a
    15 N tension along ``longerons_story_1`` (:class:`~robustctl.physical.effects.GroupTension`),
    Young's modulus +3 %, platform-1 mass -4 %, offset mass +5 %, and 1 % sensor noise;
    one white-noise experiment per actuator as in the seed (200 Hz, 409.6 s, 4096-point
    Hamming windows). ``data.meta["truth"]`` holds the same.

    Parameters
    ----------
    seed : int
        Seed of excitation and noise.
    **kwargs
        Passed to :func:`make_experiment` (``noise_rms``, ``n_samples`` ...).

    Returns
    -------
    data : FrequencyData
        Inputs A1-A3, outputs S1-S3 (units V: actuator and sensor volts), 0.049-100 Hz.
    truth : PhysicalModel
    """
    from .caltech_truss_model import caltech_truss

    _, group, values = CALTECH_TRUTH["hidden"]
    hidden = GroupTension(group, **values)
    kw = dict(param_errors=CALTECH_TRUTH["param_errors"], noise_rms=CALTECH_TRUTH["noise_rms"], seed=seed)
    kw.update(kwargs)
    data, truth = make_experiment(caltech_truss(), hidden, **kw)
    volts = {name: "V" for name in data.inputs + data.outputs}  # actuator and sensor volts (caltech_truss)
    return data.replace(units=volts), truth


#: The hidden truth of :func:`mace_beam_experiment`.
MACE_TRUTH = {
    "hidden": ("GroupTension", "bus_struts", {"tension": 50.0}),
    "param_errors": {"E_polycarbonate": 0.03, "E_active_strut": -0.04, "m_rwa": 0.03},
    "noise_rms": 0.01,
}


def mace_beam_experiment(seed: int = 0, **kwargs: Any) -> tuple[FrequencyData, Any]:
    """Measured-like data of ``rc.examples.mace_beam()`` (1 g, servo loops closed).

    MACE sets 1 % damping "for structures with articulation and significant wiring"; here
    the wiring is also taut. Spoiler: the truth is the nominal bus plus a 50 N tension along
    ``bus_struts`` (a cable harness pulled taut along the bus,
    :class:`~robustctl.physical.effects.GroupTension`), polycarbonate modulus +3 %, active
    strut modulus -4 %, reaction-wheel mass +3 %, 1 % sensor noise (above each gyro's floor,
    1e-4 of its largest RMS: the channels symmetry decouples are that noise); one white-noise
    experiment per input, 200 Hz, 204.8 s, 1024-point Hamming windows (0.2 Hz
    resolution; the suspension modes near 0.2 Hz are below it -- analyse from 0.3 Hz).
    ``data.meta["truth"]`` holds the same.

    Parameters
    ----------
    seed : int
    **kwargs
        Passed to :func:`make_experiment`.

    Returns
    -------
    data : FrequencyData
        Inputs ``primary gimbal x/y command``, ``RWA x/y/z``; outputs ``primary gyro x/y``,
        ``RWA gyro x/y/z``.
    truth : PhysicalModel
    """
    from .mace_beam_model import mace_beam

    _, group, values = MACE_TRUTH["hidden"]
    kw = dict(
        param_errors=MACE_TRUTH["param_errors"],
        noise_rms=MACE_TRUTH["noise_rms"],
        seed=seed,
        n_samples=40960,
        nperseg=1024,
    )
    kw.update(kwargs)
    return make_experiment(mace_beam(), GroupTension(group, **values), **kw)
