"""What the ``robustctl`` command writes to ``summary.json``: each result's headline as numbers.

One function per result kind turns it into plain JSON values (floats, ints, strings, lists,
dicts; NaN as ``null``): the verdict words the result's ``summary()`` prints, the numbers behind
them (costs, sizes, standard errors, p-values) and the noise test's cells. A script reading the
file gets what the terminal showed, without parsing sentences.
"""

from __future__ import annotations

import math
from typing import Any

__all__ = ["record_of", "result_kind", "json_value", "noise_record", "comparison_record", "diagnosis_record",
           "update_record",
           "identify_record", "data_record", "design_record"]


def json_value(x: Any) -> Any:
    """``x`` as plain JSON: numpy scalars and arrays as numbers and lists, NaN and inf as None."""
    import numpy as np

    if isinstance(x, dict):
        return {str(k): json_value(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [json_value(v) for v in x]
    if isinstance(x, np.ndarray):
        return json_value(x.tolist())
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        v = float(x)
        return v if math.isfinite(v) else None
    return x if x is None or isinstance(x, str) else str(x)


def noise_record(test: Any) -> dict[str, Any]:
    """A :class:`~robustctl.correlate.verdict.NoiseTest` (or None) as ``verdict``, ``alpha``, cells."""
    if test is None:
        return {"verdict": "no noise estimate", "source": None}
    failing = test.failing
    return json_value({
        "verdict": "within the noise" if test.within else "beyond the noise",
        "source": test.source,
        "alpha": test.alpha,
        "n_cells": len(test.cells),
        "n_failing": len(failing),
        "mean_normalised_squared_error": test.overall_ratio,
        "smallest_p": min((c.p_value for c in test.cells), default=None),
        "failing": [
            {"output": c.output, "input": c.input, "lo_hz": c.lo_hz, "hi_hz": c.hi_hz, "ratio": c.ratio,
             "p_value": c.p_value}
            for c in failing
        ],
    })


def data_record(data: Any) -> dict[str, Any]:
    """What a measured-FRF file holds: channels, frequencies, coherence, the experiment."""
    f = data.f_hz
    return json_value({
        "outputs": list(data.outputs),
        "inputs": list(data.inputs),
        "n_freq": int(f.size),
        "f_hz": [float(f[0]), float(f[-1])],
        "coherence": data.coherence is not None,
        "experiment": data.experiment.to_dict(),
    })


def comparison_record(cmp: Any) -> dict[str, Any]:
    """A :class:`~robustctl.correlate.comparison.Comparison`: cost, per-channel share, bands, modes."""
    share = cmp.channel_cost / max(float(cmp.cost), 1e-300)
    return json_value({
        "cost": cmp.cost,
        "cost_per_point": cmp.cost_per_point,
        "rms_magnitude_error_db": float((cmp.mag_error_db**2).mean() ** 0.5),
        "rms_phase_error_deg": float((cmp.phase_error_deg**2).mean() ** 0.5),
        "noise": noise_record(cmp.noise_test),
        "within_noise": cmp.within_noise,
        "channels": [
            {"output": o, "input": i, "share_of_cost": share[a, b]}
            for a, o in enumerate(cmp.outputs) for b, i in enumerate(cmp.inputs)
        ],
        "failing_bands_hz": [
            {"lo_hz": b.lo_hz, "hi_hz": b.hi_hz, "share_of_cost": b.share, "peak_error_db": b.peak_error_db,
             "peak_hz": b.peak_hz}
            for b in cmp.bands
        ],
        "modes": [
            {"f_model_hz": m.f_model, "f_data_hz": m.f_data, "zeta_model": m.zeta_model,
             "zeta_data": m.zeta_data, "mac": m.mac}
            for m in cmp.modes
        ],
        "view": cmp.estimator_note,
    })


def _candidate(r: Any) -> dict[str, Any]:
    return {
        "name": r.name,
        "size": r.effect.describe_value(),
        "values": dict(r.values),
        "fitted": r.fitted,
        "share_first_order": r.fraction,
        "cost_reduction": r.reduction if r.fitted else None,
        "explains": r.gain if r.fitted else None,
        "p_value": r.p_value,
        "p_raw": r.p_raw,
        "significant": r.significant,
        "at_bound": r.at_bound,
        "where": r.where,
        "sentence": r.sentence,
    }


def diagnosis_record(diag: Any, n: int = 10) -> dict[str, Any]:
    """A :class:`~robustctl.correlate.diagnosis.Diagnosis`: the proposal with its size and p-value,
    the next candidates, the costs and the null fit's verdict."""
    best = diag.best_result
    effects = getattr(diag, "effects", ())
    closest = getattr(diag, "closest", None)
    verdict = (
        "proposed: " + " + ".join(e.name for e in effects) if len(effects) > 1
        else f"proposed: {best.name}" if best is not None
        else f"closest, incomplete: {closest.name}" if closest is not None
        else "no candidate is significant" if diag.noise_source
        else "no noise estimate: no candidate proposed"
    )
    return json_value({
        "verdict": verdict,
        "verdict_word": getattr(diag, "verdict", ""),
        "chain": [{"effect": s.name, "size": s.effect.describe_value(), "values": dict(s.effect.values),
                   "explains": s.gain, "p_value": s.p_value, "misfit_before": s.dispersion_before,
                   "misfit_after": s.dispersion_after, "tentative": s.tentative}
                  for s in getattr(diag, "chain", ())],
        "misfit_left": [{"lo_hz": b.lo_hz, "hi_hz": b.hi_hz, "share": b.share, "x_noise": b.dispersion,
                         "modes_hz": [f for f, _, _ in b.modes]} for b in getattr(diag, "left", ())],
        "dispersion_left": getattr(diag, "dispersion_left", None),
        "best": None if best is None else _candidate(best),
        "ranking": [_candidate(r) for r in diag.ranking[:n]],
        "cost_nominal": diag.cost_nominal,
        "cost_update": diag.cost_update,
        "update_params": list(diag.update_params),
        "update_values": dict(diag.update_values),
        "family_alpha": diag.family_alpha,
        "noise_source": diag.noise_source or None,
        "model_error": diag.model_error,
        "dispersion": diag.dispersion,
        "p_null": diag.p_null,
        "channel_verdict": diag.channel_verdict or None,
        "n_candidates": len(diag.ranking),
        "time_s": diag.time_s,
    })


def update_record(upd: Any) -> dict[str, Any]:
    """An :class:`~robustctl.correlate.update_result.UpdateResult`: every updated parameter's values,
    change and standard error, the costs, the move test and the noise verdicts."""
    params = []
    moves = upd.moves_se
    for name in upd.selected:
        before, after = upd.initial_model.param(name).value, upd.model.param(name).value
        params.append({
            "name": name,
            "unit": upd.model.param(name).unit,
            "before": before,
            "after": after,
            "change_pct": 100 * (after - before) / before if before else None,
            "std_error": upd.std_errors.get(name),
            "move_in_se": moves.get(name),
        })
    test = upd.move_test
    move = None
    if test is not None:
        t, dof, p = test
        move = {"statistic": t, "dof": dof, "p_value": p, "alpha": upd_alpha(upd),
                "verdict": "moved beyond the noise" if p < upd_alpha(upd) else "not moved beyond the noise"}
    return json_value({
        "cost_before": upd.cost_before,
        "cost_after": upd.cost_after,
        "reduction": upd.reduction,
        "iterations": upd.n_iter,
        "parameters": params,
        "move_test": move,
        "noise_before": noise_record(upd.noise_before),
        "noise_after": noise_record(upd.noise_after),
        "stop_reason": upd.fit.stop_reason,
        "warnings": list(upd.warnings),
    })


def upd_alpha(upd: Any) -> float:
    """The level the update's tests use (its noise test's, else the default)."""
    from .correlate.verdict import ALPHA

    test = upd.noise_after or upd.noise_before
    return float(test.alpha) if test is not None else ALPHA


def identify_record(mm: Any) -> dict[str, Any]:
    """A :class:`~robustctl.identify.MeasurementModel`: its physical modes and fillers."""
    return json_value({
        "n_modes": int(mm.n_modes),
        "modes": [{"f_hz": m.f_hz, "zeta": m.zeta} for m in mm.modes],
        "n_fillers": len(getattr(mm, "fillers", ())),
    })


def design_record(dk: Any, cover: Any, files: list[str], fs_hz: float) -> dict[str, Any]:
    """A :class:`~robustctl.robust.dk.iteration.DKResult` as ``robustctl design`` made it: the verdict,
    mu (upper and lower bound, where), the controller, the iteration history, the cover and the files."""
    return json_value({
        "verdict": "robust performance certified (mu < 1)" if dk.mu_peak < 1 else "not certified (mu >= 1)",
        "mu_peak": dk.mu_peak,
        "mu_lower_peak": dk.mu.lower_peak,
        "mu_f_peak_hz": dk.mu.f_peak_hz,
        "controller_states": int(dk.K.nstates),
        "controller_inputs": [str(n) for n in dk.K.input_labels],
        "controller_outputs": [str(n) for n in dk.K.output_labels],
        "best_iteration": dk.best_iteration,
        "history_mu": [h.mu_peak for h in dk.history],
        "stop_reason": dk.stop_reason,
        "cover_margin": None if cover is None else cover.margin,
        "cover_order": None if cover is None else cover.order,
        "fs_hz": fs_hz,
        "files": list(files),
    })


def result_kind(result: Any) -> str:
    """``"compare"``, ``"diagnose"``, ``"update"`` or ``"identify"`` for a result (RobustctlError
    for anything else)."""
    from .correlate import Comparison, Diagnosis, UpdateResult
    from .errors import RobustctlError
    from .identify import MeasurementModel

    for kind, cls in (("compare", Comparison), ("diagnose", Diagnosis), ("update", UpdateResult),
                      ("identify", MeasurementModel)):
        if isinstance(result, cls):
            return kind
    raise RobustctlError(
        f"a report takes results of rc.compare, rc.diagnose, rc.update or rc.fit_measurement_model; got "
        f"{type(result).__name__}."
    )


def record_of(result: Any) -> dict[str, Any]:
    """The JSON record of any result :func:`result_kind` knows."""
    return {"compare": comparison_record, "diagnose": diagnosis_record, "update": update_record,
            "identify": identify_record}[result_kind(result)](result)
