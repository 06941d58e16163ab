"""Progress inside rc.diagnose: a bar per stage counting candidates, on a terminal only, never in results."""

import io
import re
import sys
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest

import robustctl as rc
from robustctl.executors import parallel_map_shared
from robustctl.physical import effects as fx

F_HZ = np.linspace(0.5, 40.0, 300)
KC = 1e3 * np.array([[1.0, -1.0, 0.0], [-1.0, 2.0, -1.0], [0.0, -1.0, 1.0]])


class Terminal(io.StringIO):
    """A standard error that says it is a terminal (what tqdm and robustctl check)."""

    def isatty(self):
        return True


def bars(text):
    """``{stage: {(n, total), ...}}`` of the tqdm bars drawn in ``text`` (every update, see
    :func:`every_update_drawn`)."""
    seen = {}
    for m in re.finditer(r"([A-Za-z][A-Za-z \-]*?):\s+\d+%\|[^|]*\|\s*(\d+)/(\d+)", text):
        seen.setdefault(m.group(1).strip(), set()).add((int(m.group(2)), int(m.group(3))))
    return seen


@pytest.fixture(autouse=True)
def every_update_drawn(monkeypatch):
    """Bars that draw at every update, not at most every 0.1 s: what is drawn does not depend on
    how fast the machine runs the stage (a quick screening drew only its 0/N)."""
    import tqdm

    class Eager(tqdm.tqdm):
        def __init__(self, *args, **kwargs):
            kwargs.update(mininterval=0.0, miniters=1)
            super().__init__(*args, **kwargs)

    monkeypatch.setattr(tqdm, "tqdm", Eager)


def run_with_stderr(stream, fn):
    old, sys.stderr = sys.stderr, stream
    try:
        return fn()
    finally:
        sys.stderr = old


@pytest.fixture(scope="module")
def case():
    k_par = rc.Parameter("k_ground", 4e3, "N/m", (1e3, 1e4))
    model = rc.structural_model(
        np.diag([2.0, 1.0, 0.5]),
        lambda th: KC + np.diag([th["k_ground"], 0.0, 0.0]),
        inputs={"F1": "dof 1", "F3": "dof 3"},
        outputs={"a2": ("dof 2", "acceleration"), "a3": ("dof 3", "acceleration")},
        damping=0.02,
        params=[k_par],
        name="3-mass chain",
    )
    truth = model.with_values(k_ground=4.12e3).with_effect(fx.AddedMass("dof 3", mass=0.05))
    g = truth.freqresp(F_HZ).response
    rng = np.random.default_rng(0)
    g = g * np.exp(0.01 * (rng.standard_normal(g.shape) + 1j * rng.standard_normal(g.shape)))
    data = rc.FrequencyData(F_HZ, g, inputs=model.inputs, outputs=model.outputs)
    noise = rc.NoiseModel(F_HZ, np.full((F_HZ.size, 2, 2), 0.01), "synthetic log noise of 0.01 (known)")
    return model, data, noise


def test_diagnose_counts_candidates_on_a_terminal_and_gives_the_same_result(case):
    model, data, noise = case

    def go():
        params = ["k_ground", "zeta_modal"]
        return rc.diagnose(model, data, params=params, noise=noise, workers=1, chain=False)

    quiet_err, tty_err = io.StringIO(), Terminal()
    quiet = run_with_stderr(quiet_err, go)
    shown = run_with_stderr(tty_err, go)
    assert quiet_err.getvalue() == ""  # not a terminal: nothing
    stages = bars(tty_err.getvalue())
    # per candidate, not per step: the screening bar counts its candidates, and moves
    totals = {total for _, total in stages["screening"]}
    assert len(totals) == 1 and totals.pop() >= 20
    total = next(iter(stages["screening"]))[1]
    assert (total, total) in stages["screening"]  # it counts up to every candidate
    assert len(stages["screening"]) >= 2 and {"calibration", "local fits"} <= set(stages)
    # the bars stay out of the result: the ranking is the same to the last bit
    assert quiet.best is not None and quiet.best.name == shown.best.name == "added mass at dof 3"
    key = [(r.name, r.values, r.p_value, r.gain, r.fraction) for r in quiet.ranking]
    assert key == [(r.name, r.values, r.p_value, r.gain, r.fraction) for r in shown.ranking]
    assert quiet.summary() == shown.summary()


def _square(shared, x):
    return shared * x * x


def test_worker_processes_count_items_not_chunks():
    items = list(range(40))  # 2 workers x 8 chunks: 16 chunks of 2-3 items
    err = Terminal()
    with ProcessPoolExecutor(2) as pool:
        out = run_with_stderr(err, lambda: parallel_map_shared(_square, 3, items, pool, desc="squares"))
    assert out == [3 * x * x for x in items]
    drawn = bars(err.getvalue())["squares"]
    assert {total for _, total in drawn} == {40}  # items, not the 16 chunks
