"""Benchmark: ``rc.diagnose`` with 12 candidate effects on the Caltech truss.

Data: :func:`robustctl.examples.caltech_truss_experiment` (hidden taut-wire tension on the
story-1 longerons, 3 % / 4 % / 5 % parameter errors, 1 % sensor noise), 9 channels x 600
frequencies (0.5 Hz upwards at the 0.049 Hz Welch resolution). Update parameters: the
structural ones (Young's modulus, platform and offset masses, modal damping), as in MACE.
Timed serially and with a two-thread ``ThreadPoolExecutor``; target < 10 s on 2 cores. Also
timed: calibrating the default candidate set (about 285 effects: ``rc.effects.candidates``)
and diagnose with it on 0.5-50 Hz and on the README demo's 0.5-29.8 Hz band, with the rank
of the true taut-wire effect on each, as a user calls it (``workers="auto"``: one worker
process per core) and serially (``workers=1``): wall and CPU time (this process and its
workers), and whether the two results are identical. The machine's load average at the start
is recorded (other jobs on the cores slow the workers). Side
by side: what a user would otherwise do, a full LM fit of every candidate with the update
parameters (8 iterations each), as a time ratio.

Also timed (``corpus_*``): diagnose with the default candidates (now with the test-setup
candidates: swapped cables, sign flips, units slips, sensors and actuators at neighbouring nodes,
and semi-rigid joints on frames) on independently generated data (``tests/verdict_corpus.py``:
numpy modal FRFs, H1 of a periodic measured force), one case per structure with the hidden
effect's rank: a 4-mass chain (added mass), a hub with two arms (grounded spring), a portal frame
(semi-rigid joint) and the chain with two sensor cables swapped. The figures of the library
before the test-setup candidates (292 default candidates on the Caltech truss, 7.9 s on 0.5-50 Hz
and 8.6 s on 0.5-29.8 Hz with workers) are kept in ``before_*`` for comparison.

Run: ``python -m benchmarks.bench_diagnose`` (writes ``benchmarks/results/diagnose.json``).
"""

from __future__ import annotations

import json
import os
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

import robustctl as rc
from robustctl.correlate.diagnosis import PARALLEL_MIN_CANDIDATES
from robustctl.executors import resolve_workers

TARGET_S = 10.0
N_FREQ = 600
UPDATE = ("E_aluminium", "m_platform_1", "m_platform_2", "m_offset", "zeta_modal")


def _candidates(model) -> list:
    fx = rc.effects
    groups = ("longerons_story_1", "longerons_story_2", "diagonals")
    cands = [fx.OutputDelay(), fx.SensorLowPass(order=1), fx.SensorLowPass(order=2), fx.SensorGain("S1")]
    cands += [fx.GroupTension(g) for g in groups] + [fx.GroupStiffness(g) for g in groups]
    cands += [fx.AddedMass("platform_2"), fx.SuspensionSpring("platform_2", direction="x")]
    # the calibrated secant steps of rc.effects.candidates for the same effects
    calibrated = {(c.kind, c.location, getattr(c, "direction", None)): c
                  for c in fx.candidates(model, band=(0.5, 30.0))}
    return [calibrated.get((c.kind, c.location, getattr(c, "direction", None)), c) for c in cands]


def _brute_force(model, data, cands, band) -> tuple[float, str, int]:
    """What a user would otherwise do: a full bounded LM fit of every candidate with the
    update parameters (rc.correlate.levenberg_marquardt, 8 iterations), best cost wins."""
    from robustctl.correlate import Residual, levenberg_marquardt

    t0 = time.perf_counter()
    best, evals = (np.inf, ""), 0
    for c in cands:
        fitted = c.with_values(**{c.param_names[0]: c.typical_size}) if c.kind != "gravity" else c
        res = Residual(fitted.apply(model), data, band=band, point_weights="coherence")
        lm = levenberg_marquardt(res, UPDATE + c.param_names, max_iter=8)
        evals += lm.n_evals
        best = min(best, (lm.cost, c.name))
    return time.perf_counter() - t0, best[1], evals


def _group(diag) -> dict | None:
    """The candidates the band cannot tell from the top one, and where they differ (Hz)."""
    g = diag.indistinguishable
    if g is None:
        return None
    return {"names": list(g.names), "differ_hz": [[round(a, 2), round(b, 2)] for a, b in g.stretches],
            "peak_hz": round(g.peak_hz, 2), "peak_db": round(g.peak_db, 3)}


def _timed(model, data, band, workers="auto") -> tuple:
    """``rc.diagnose`` with the default candidates: the result, its wall time and the CPU time of
    this process and its (finished) worker processes, in s."""
    t0, c0 = time.perf_counter(), os.times()
    diag = rc.diagnose(model, data, band=band, params=UPDATE, workers=workers)
    c1 = os.times()
    cpu = sum(getattr(c1, k) - getattr(c0, k) for k in ("user", "system", "children_user", "children_system"))
    return diag, time.perf_counter() - t0, cpu


def _same(a, b) -> bool:
    """Whether two diagnoses rank the same candidates with the same costs, shares and values."""
    return len(a.ranking) == len(b.ranking) and all(
        (x.name, x.cost, x.fraction, x.values) == (y.name, y.cost, y.fraction, y.values)
        for x, y in zip(a.ranking, b.ranking)
    )


def _rank(diag, name: str) -> int | None:
    """1-based rank of the effect ``name`` (or of a candidate it is equivalent to)."""
    for k, r in enumerate(diag.ranking, start=1):
        if r.name == name or name in r.equivalent:
            return k
    return None


#: The Caltech figures of the default candidates before the test-setup candidates were added
#: (benchmarks/results/diagnose.json of that library, 2 cores).
BEFORE = {"before_default_candidates_n": 292, "before_default_candidates_0.5_50Hz_time_s": 7.895,
          "before_default_candidates_0.5_29.8Hz_time_s": 8.56}


def _corpus() -> dict:
    """Diagnose with the default candidates on the independent corpus: time, candidates, rank."""
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    import verdict_corpus as vc

    fx = rc.effects
    out = {}
    f_chain, f_hub = np.arange(2.0, 40.0, 0.125), np.arange(1.0, 40.0, 0.125)
    f_frame = np.arange(5.0, 80.0, 0.25)
    chain = vc.chain_model()
    hub = vc.hub_model()[0]
    frame = vc.frame_model()

    def chain_case(**truth):
        M, K, B, C, kinds = vc.chain_matrices(s_k=1.03, **truth)
        return vc.modal_frf(M, K, B, C, kinds, f_chain)

    M, K, T = vc.hub_matrices(k_scale=0.97, spring={5: 600.0})
    B, C, kinds = vc.hub_pointing(T)
    g_hub = vc.modal_frf(M, K, B, C, kinds, f_hub)
    struct = frame.with_effect(fx.JointSpring("t1", group="beam", compliance=2e-5)).build_structure()
    g_frame = vc.modal_frf(*vc.structure_matrices(struct), f_frame)
    cases = {
        "chain_added_mass": (chain, chain_case(added={3: 0.1}), f_chain, "added mass at dof 3"),
        "chain_swapped_cables": (chain, chain_case()[:, [1, 0, 2]], f_chain, "outputs a2 and a3 swapped"),
        "hub_grounded_spring": (hub, g_hub, f_hub, "suspension spring at dof 5"),
        "frame_semi_rigid_joint": (frame, g_frame, f_frame, "semi-rigid joint of beam at node t1"),
    }
    for key, (model, g, f, truth) in cases.items():
        data = vc.periodic_h1(g, n_avg=32, noise=0.05, seed=1, inputs=model.inputs, outputs=model.outputs,
                              f_hz=f)
        t0 = time.perf_counter()
        diag = rc.diagnose(model, data, workers=1)
        out[f"corpus_{key}_time_s"] = round(time.perf_counter() - t0, 3)
        out[f"corpus_{key}_n_candidates"] = len(diag.ranking) + sum(len(r.equivalent) for r in diag.ranking)
        out[f"corpus_{key}_proposed"] = None if diag.best is None else diag.best.name
        rank = _rank(diag, truth)
        if rank is not None and rank > 1 and diag.indistinguishable and truth in diag.indistinguishable.names:
            rank = 1
        out[f"corpus_{key}_rank_of_truth"] = rank
    return out


def run() -> dict:
    """Time diagnose serially and with 2 threads; check that the hidden effect ranks first."""
    with rc.blas_threads(1):
        model = rc.examples.caltech_truss()
        data, _ = rc.examples.caltech_truss_experiment(seed=0)
        f = data.f_hz
        band = (0.5, float(f[np.searchsorted(f, 0.5) + N_FREQ - 1]))
        cands = _candidates(model)
        t0 = time.perf_counter()
        serial = rc.diagnose(model, data, cands, band=band, params=UPDATE)
        t_serial = time.perf_counter() - t0
        with ThreadPoolExecutor(max_workers=2) as pool:
            t0 = time.perf_counter()
            par = rc.diagnose(model, data, cands, band=band, params=UPDATE, executor=pool)
            t_par = time.perf_counter() - t0
        t_brute, brute_top, brute_evals = _brute_force(model, data, cands, band)
        t0 = time.perf_counter()  # the default candidate set alone (calibrated on the model)
        default_cands = rc.effects.candidates(model, band=(0.5, 50.0))
        t_cands = time.perf_counter() - t0
        load = os.getloadavg()[0] if hasattr(os, "getloadavg") else None
        # a user's default call (worker processes, workers="auto"), 0.5-50 Hz and the README demo's
        # band, 0.5-29.8 Hz; then the same serially (workers=1) for the ratio and the equality
        full, t_full, cpu_full = _timed(model, data, (0.5, 50.0))
        low, t_low, cpu_low = _timed(model, data, (0.5, 29.8))
        full_1, t_full_1, cpu_full_1 = _timed(model, data, (0.5, 50.0), workers=1)
        low_1, t_low_1, cpu_low_1 = _timed(model, data, (0.5, 29.8), workers=1)
    top = serial.ranking[0]
    names = [r.name for r in serial.ranking]
    true_name = "taut wires (tension) along longerons_story_1"
    n_freq = int(np.count_nonzero((f >= band[0]) & (f <= band[1])))
    metrics = {
        "n_candidates": len(cands),
        "n_channels": data.n_out * data.n_in,
        "n_frequencies": n_freq,
        "time_serial_s": round(t_serial, 3),
        "time_2_threads_s": round(t_par, 3),
        "speedup_2_threads": round(t_serial / t_par, 3),
        "model_evaluations": serial.n_evals,
        "ms_per_evaluation_serial": round(1e3 * t_serial / serial.n_evals, 2),
        "top_effect": top.name,
        "top_effect_value": top.effect.describe_value(),
        "top_effect_significant": bool(top.significant),
        "same_ranking_with_executor": [r.name for r in serial.ranking] == [r.name for r in par.ranking],
        "cost_reduction_top_pct": round(100 * top.reduction, 2),
        "rank_of_true_effect": names.index(true_name) + 1 if true_name in names else None,
        "true_effect_significant": any(r.significant for r in serial.ranking if r.name == true_name),
        "brute_force_lm_every_candidate_s": round(t_brute, 3),
        "brute_force_evaluations": brute_evals,
        "brute_force_top_effect": brute_top,
        "speedup_vs_brute_force": round(t_brute / t_serial, 2),
        "default_candidates_0.5_50Hz_n": len(full.ranking) + sum(len(r.equivalent) for r in full.ranking),
        "default_candidates_0.5_50Hz_time_s": round(t_full, 3),
        "default_candidates_0.5_50Hz_cpu_s": round(cpu_full, 3),
        "default_candidates_0.5_50Hz_serial_time_s": round(t_full_1, 3),
        "default_candidates_0.5_50Hz_serial_cpu_s": round(cpu_full_1, 3),
        "default_candidates_0.5_50Hz_speedup_workers": round(t_full_1 / t_full, 3),
        "default_candidates_0.5_50Hz_same_as_serial": _same(full, full_1),
        "default_candidates_0.5_50Hz_evaluations": full.n_evals,
        "default_candidates_0.5_50Hz_top_effect": full.ranking[0].name,
        "default_candidates_0.5_50Hz_top_value": full.ranking[0].effect.describe_value(),
        "default_candidates_calibration_s": round(t_cands, 3),
        "default_candidates_n": len(default_cands),
        "default_candidates_0.5_29.8Hz_time_s": round(t_low, 3),
        "default_candidates_0.5_29.8Hz_cpu_s": round(cpu_low, 3),
        "default_candidates_0.5_29.8Hz_serial_time_s": round(t_low_1, 3),
        "default_candidates_0.5_29.8Hz_serial_cpu_s": round(cpu_low_1, 3),
        "default_candidates_0.5_29.8Hz_speedup_workers": round(t_low_1 / t_low, 3),
        "default_candidates_0.5_29.8Hz_same_as_serial": _same(low, low_1),
        "default_candidates_0.5_29.8Hz_evaluations": low.n_evals,
        "default_candidates_workers": resolve_workers("auto", len(default_cands), PARALLEL_MIN_CANDIDATES),
        "load_average_1min_at_start": None if load is None else round(load, 2),
        "default_candidates_0.5_29.8Hz_indistinguishable": _group(low),
        "default_candidates_0.5_29.8Hz_top_effect": low.ranking[0].name,
        "default_candidates_0.5_29.8Hz_rank_of_true_effect": _rank(low, true_name),
        "default_candidates_0.5_50Hz_rank_of_true_effect": _rank(full, true_name),
        "cpu_count": os.cpu_count(),
        "default_candidates_test_setup_n": sum(1 for c in default_cands if getattr(c, "switch", False)),
        **BEFORE,
        **_corpus(),
    }
    # Below 30 Hz the local fits (update sensitivities frozen at the null fit) left the true
    # taut wires at half their tension, behind stiffer diagonals; diagnose now polishes the
    # contenders with a full LM fit, which ranks them first at 15 N. Tension along the
    # diagonals fits as well within the noise (Vuong's test): the result names them as one
    # group and where their fitted models differ (the local modes at about 33-45 Hz);
    # tests/test_indistinguishable.py checks it.
    targets = {"time_serial_s": f"< {TARGET_S}", "time_2_threads_s": f"< {TARGET_S}",
               "default_candidates_0.5_50Hz_time_s": f"< {TARGET_S}",
               "default_candidates_0.5_29.8Hz_time_s": f"< {TARGET_S}"}
    passed = bool(t_par < TARGET_S and t_serial < TARGET_S and t_full < TARGET_S and t_low < TARGET_S)
    return {
        "name": "diagnose",
        "description": "rc.diagnose, 12 candidates, Caltech truss, 9 channels x 600 frequencies "
                       "(serial and 2-thread executor)",
        "metrics": metrics,
        "targets": targets,
        "passed": passed,
    }


def main() -> None:
    result = run()
    out = Path(__file__).parent / "results" / "diagnose.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
