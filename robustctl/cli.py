"""The ``robustctl`` command.

* ``robustctl demo [--example caltech|mace]`` runs the whole pipeline on an embedded example
  (default: the Caltech truss);
* ``robustctl load DATA`` says what a file holds (channels, band, coherence, the experiment);
* ``robustctl compare MODEL DATA``, ``robustctl diagnose MODEL DATA``,
  ``robustctl update MODEL DATA [--effect NAME | --diagnosis OUT]`` and
  ``robustctl identify DATA`` run one stage on a user's own files: each prints its headline
  (the result's ``summary()``) and writes an HTML report plus ``summary.json`` (the same
  verdict words with their numbers: sizes, standard errors, p-values) into ``--out``;
  ``--inputs``/``--outputs`` select channels of both the model and the data;
* ``robustctl report OUT...`` joins those folders into one page;
* ``robustctl design MODEL [DATA] --fs HZ`` designs a mu-controller (D-K iteration) for the
  model as an update left it (``--update OUT``), covering its error against DATA
  (:mod:`robustctl.cli_design`), prints the D-K summary and mu and writes the controller
  (.json, .h, .mat) and ``summary.json`` into ``--out``;
* ``robustctl export SOURCE TARGET`` writes a controller file as another coefficient file
  (e.g. a continuous ``K.mat`` as a C header at ``--fs``), printing the export checks.

MODEL is ``FILE.py[:NAME]`` or ``package.module[:NAME]`` (see :mod:`robustctl.cli_inputs`);
DATA is any file :func:`robustctl.load_frd` reads (.npz, .csv, .mat, .uff/.unv). A data file
with fewer channels than the model (a one-input impact test of a two-shaker model) is compared
with the model's channels of the same names, and the command says so. Errors are one line on
standard error and exit status 2. On a terminal a progress bar names the running step.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

__all__ = ["main"]

_MODEL_HELP = (
    "the model: FILE.py[:NAME] or package.module[:NAME]; NAME (default 'model') is a model or a "
    "function returning one, e.g. robustctl.examples:caltech_truss"
)
_DATA_HELP = "measured frequency responses: .npz, .csv, .mat or .uff/.unv (robustctl.load_frd)"


def _modes_option(text: str) -> int | str:
    """``--modes``: a positive number of modes or ``auto``."""
    if text.strip().lower() == "auto":
        return "auto"
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"--modes takes a positive number of modes or 'auto'; got {text!r}")
    return value


#: The sub-commands reading DATA: name, summary, description, whether MODEL comes first, and
#: the one option of their own (the band, report folder and experiment options are common).
_DATA_COMMANDS = (
    ("compare", "where does MODEL fail against DATA (channels, bands, modes)?",
     "Compare a model with measured FRFs: per-channel cost (MACE eq. 5), failing bands, "
     "a mode table paired through a measurement model, the error's structure.", True,
     (("--modes",), {"type": _modes_option, "default": None,
                     "help": "fit a measurement model with this many modes ('auto': automatic order) for "
                     "the mode table to pair through and take the data's damping from (default: none; "
                     "peak picking gives frequencies and shapes only)"})),
    ("diagnose", "which physical effect is MODEL missing, judged on DATA?",
     "Rank candidate physical effects (delays, filters, springs, masses, dashpots, taut "
     "wires, ...) by what they explain of the model's error, with a significance test.", True,
     (("--time-budget",), {"type": float, "default": None, "help": "optional wall-clock cap in s "
                           "(default: none; iteration caps bound the work)"})),
    ("update", "update MODEL's parameters (with an effect) so it matches DATA",
     "Update the model's free parameters (MACE eqs. 5-9: sensitivities, alignment and "
     "orthogonality tests, bounded Levenberg-Marquardt), optionally with the effect a diagnosis "
     "proposed (--diagnosis) or one named (--effect).", True,
     (("--effect",), {"default": None, "help": "add this candidate effect first, named as diagnose "
                      "prints it (e.g. 'added mass at node tip')"})),
    ("identify", "fit a measurement model (the yardstick) to DATA",
     "Identify a modal measurement model (vector fitting, SVD mode grouping) of the data.", False,
     (("--modes",), {"type": int, "default": None, "help": "number of modes (default: automatic)"})),
)  # fmt: skip


def _data_command(
    sub: Any, name: str, summary: str, description: str, *, model: bool
) -> argparse.ArgumentParser:
    """A sub-command reading DATA (after MODEL when ``model``); its options are added by the caller."""
    p = sub.add_parser(name, help=summary, description=description)
    if model:
        p.add_argument("model", help=_MODEL_HELP)
    p.add_argument("data", help=_DATA_HELP)
    return p


def _add_common(p: argparse.ArgumentParser, default_out: str) -> None:
    p.add_argument("--band", nargs=2, type=float, metavar=("LO_HZ", "HI_HZ"), help="frequency band in Hz")
    p.add_argument("--out", default=default_out, help=f"report folder (default: {default_out})")
    p.add_argument("--inputs", nargs="+", default=None, metavar="NAME",
                   help="use only these inputs (of the data and of the model)")
    p.add_argument("--outputs", nargs="+", default=None, metavar="NAME",
                   help="use only these outputs (of the data and of the model)")
    _add_experiment(p)


def _add_experiment(p: argparse.ArgumentParser) -> None:
    """How DATA were made, for files that do not say (a stated value must agree)."""
    g = p.add_argument_group(
        "experiment", "how DATA were made, for files that do not say so (robustctl.Experiment); without a "
        "description the model is compared as the plain FRF",
    )
    g.add_argument("--input-kind", choices=("measured", "held"), default=None,
                   help="measured: a measured force or voltage; held: a DAC command (zero-order hold)")
    g.add_argument("--excitation", choices=("random", "periodic", "burst", "impact", "stepped_sine"),
                   default=None, help="the excitation signal")
    g.add_argument("--fs", type=float, default=None, help="sampling frequency of the estimate, Hz")
    g.add_argument("--window", default=None, help="Welch window (a scipy.signal.get_window name)")
    g.add_argument("--nperseg", type=int, default=None, help="Welch segment length, samples")
    g.add_argument("--noverlap", type=int, default=None, help="Welch overlap, samples")
    g.add_argument("--n-averages", type=int, default=None, help="number of averaged segments")
    g.add_argument("--whole-periods", action="store_true", default=None,
                   help="periodic excitation with whole periods per segment")
    g.add_argument("--hold-divided", action="store_true", default=False,
                   help="the estimate was divided by the zero-order hold's response")
    g.add_argument("--exp-window-tau", dest="exp_window_tau_s", type=float, default=None, metavar="TAU_S",
                   help="impact test: time constant of the exponential window from the hit, s")
    g.add_argument("--force-window", dest="force_window_s", type=float, default=None, metavar="SECONDS",
                   help="impact test: force window kept after the end of each force pulse, s")
    g.add_argument("--pretrigger", dest="pretrigger_s", type=float, default=None, metavar="SECONDS",
                   help="impact test: time from the record start to the hit, s")


def _described(data: Any, args: argparse.Namespace) -> Any:
    """``data`` with the experiment options filling what its file does not state."""
    from .cli_inputs import CommandLineError
    from .errors import DataError
    from .frd import Experiment

    given = {
        "input_kind": args.input_kind, "excitation": args.excitation, "fs_hz": args.fs,
        "window": args.window, "nperseg": args.nperseg, "noverlap": args.noverlap,
        "n_averages": args.n_averages, "whole_periods": args.whole_periods,
        "exp_window_tau_s": args.exp_window_tau_s, "force_window_s": args.force_window_s,
        "pretrigger_s": args.pretrigger_s,
    }
    given = {k: v for k, v in given.items() if v is not None}
    if args.hold_divided:
        given["hold_divided"] = True
    if not given:
        return data
    stated = data.experiment.to_dict()
    for key, value in given.items():
        mine = stated[key]
        if mine not in (None, False) and mine != value:
            flag = key.replace("_hz", "").removesuffix("_s").replace("_", "-")
            raise CommandLineError(
                f"--{flag} {value} contradicts the file, which states "
                f"{key} = {mine!r}; drop the option (the file's description is used)."
            )
    try:
        return data.replace(experiment=data.experiment.fill(Experiment(**given)))
    except DataError as exc:
        raise CommandLineError(f"the experiment options cannot describe DATA: {exc}") from None


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="robustctl",
        description="Robust control of flexible structures: measure, model, correlate, identify, design.",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    demo = sub.add_parser("demo", help="run the full pipeline on an embedded example; write a report")
    demo.add_argument("--example", choices=("caltech", "mace"), default="caltech",
                      help="the Caltech truss (default) or the MACE-like bus, with its 0-g prediction")
    demo.add_argument("--out", default="out", help="report folder (default: out)")
    demo.add_argument("--seed", type=int, default=0, help="random seed of the simulated experiment")
    demo.add_argument("--no-design", action="store_true",
                      help="stop after the model update (skip weights, D-K, mu, yardstick and export)")

    for name, summary, description, model, option in _DATA_COMMANDS:
        cmd = _data_command(sub, name, summary, description, model=model)
        cmd.add_argument(*option[0], **option[1])
        _add_common(cmd, f"out-{name}")
        if name == "update":
            cmd.add_argument("--diagnosis", default=None, metavar="OUT",
                             help="a diagnose result (its --out folder or summary.json): add the effect "
                             "it proposed, starting from its fitted size")
            cmd.add_argument("--params", nargs="+", default=None, metavar="NAME",
                             help="parameters to update (default: every free one)")
            cmd.add_argument("--max-iter", type=int, default=20, help="Levenberg-Marquardt iteration cap")

    joined = sub.add_parser("report", help="join the reports of several commands into one page",
                            description="Join the --out folders of compare, diagnose, update and identify "
                            "into one report.html (and one summary.json keyed by folder name).")
    joined.add_argument("folders", nargs="+", help="report folders, in the order to show them")
    joined.add_argument("--out", default="out-report",
                        help="folder of the joined report (default: out-report)")
    joined.add_argument("--title", default="robustctl report", help="title of the page")

    load = sub.add_parser("load", help="say what a measured-FRF file holds",
                          description="Read DATA and print its channels, frequencies, coherence and "
                          "experiment description; write them to summary.json in --out.")
    load.add_argument("data", help=_DATA_HELP)
    load.add_argument("--out", default="out-load", help="report folder (default: out-load)")

    _design_parser(sub)
    _export_parser(sub)
    sub.add_parser("info", help="print the versions robustctl runs with")
    return parser


def _design_parser(sub: Any) -> None:
    des = sub.add_parser(
        "design",
        help="design a mu-controller for MODEL (covering its error against DATA) and export it",
        description="The loop's design step (robustctl.cli_design): the model (as an update left it, "
        "--update), an additive weight covering its error against DATA, 4 %% input and output "
        "multiplicative uncertainty and a band-pass performance weight on the sensors (or a recipe of "
        "your own, --plant), D-K iteration (robustctl.dksyn), then the controller written with "
        "robustctl.export_controller at --fs. Prints the D-K summary and mu.",
    )
    des.add_argument("model", help=_MODEL_HELP)
    des.add_argument("data", nargs="?", default=None,
                     help=_DATA_HELP + "; the additive weight covers the model's error against it")
    des.add_argument("--fs", type=float, required=True, help="sample rate of the exported controller, Hz")
    des.add_argument("--update", default=None, metavar="OUT",
                     help="an update result (its --out folder or summary.json): design on the model as "
                     "updated")
    des.add_argument("--plant", default=None, metavar="FILE.py:NAME",
                     help="your own design recipe: a callable nominal -> GeneralizedPlant (replaces the "
                     "cover, uncertainty and performance options)")
    des.add_argument("--order", type=int, default=None,
                     help="reduce the design model to this many states by balanced truncation first")
    des.add_argument("--band", nargs=2, type=float, metavar=("LO_HZ", "HI_HZ"),
                     help="band of the uncertainty cover, Hz (default: every data point)")
    des.add_argument("--perf-band", nargs=2, type=float, metavar=("LO_HZ", "HI_HZ"), default=None,
                     help="corners of the performance weight, Hz (default: --band, else the data's span)")
    des.add_argument("--level", type=float, default=0.3, help="performance weight gain in its band")
    des.add_argument("--input-mult", type=float, default=0.04, help="input multiplicative uncertainty")
    des.add_argument("--output-mult", type=float, default=0.04, help="output multiplicative uncertainty")
    des.add_argument("--cover-order", type=int, default=4, help="states of the additive weight")
    des.add_argument("--data-sigmas", type=float, default=3.0,
                     help="raise the measured error by this many standard deviations of the H1 estimate's "
                     "random error before covering it (default 3; 0: cover the error as measured)")
    des.add_argument("--max-iter", type=int, default=4, help="D-K iteration cap")
    des.add_argument("--d-order", type=int, default=None,
                     help="order of every D-scale fit (default: chosen per block and iteration)")
    des.add_argument("--no-reduce", action="store_true",
                     help="keep the full-order controller (default: the smallest order that keeps mu)")
    des.add_argument("--inputs", nargs="+", default=None, metavar="NAME",
                     help="control inputs (actuators) to use, of the model and the data")
    des.add_argument("--outputs", nargs="+", default=None, metavar="NAME",
                     help="sensors to use, of the model and the data")
    des.add_argument("--out", default="out-design", help="report and controller folder (default: out-design)")


def _export_parser(sub: Any) -> None:
    exp = sub.add_parser(
        "export",
        help="write a controller file (json/csv/mat/h/sos) as another coefficient file",
        description="Read a controller with robustctl.load_controller (a continuous .mat or .json with "
        "Ts = 0 is discretised at --fs) and write it with robustctl.export_controller; prints the checks "
        "(stability, discretisation error, coefficient dynamic range).",
    )
    exp.add_argument("source", help="controller file: .json, .csv, .mat (A, B, C, D, Ts), .h or .sos")
    exp.add_argument("target", help="file to write: .json, .csv, .h, .mat or .sos")
    exp.add_argument("--fs", type=float, default=None, help="sample rate in Hz (for a continuous source)")
    exp.add_argument("--method", choices=("tustin", "zoh"), default="tustin", help="discretisation method")
    exp.add_argument("--prewarp-hz", type=float, default=None, help="Tustin prewarping frequency in Hz")
    exp.add_argument("--crossover-hz", type=float, default=None, help="where to check the discretisation")
    exp.add_argument(
        "--balance", choices=("none", "diagonal", "balanced"), default="none",
        help="rescale the states for fixed-point use (the transfer function is unchanged)",
    )
    exp.add_argument(
        "--channel", nargs=2, metavar=("OUTPUT", "INPUT"), default=None,
        help="the channel of a MIMO controller to write as second-order sections",
    )
    exp.add_argument("--prefix", default=None, help="C header macro/array prefix (default: the file stem)")
    exp.add_argument("--on-unstable", choices=("warn", "raise", "ignore"), default="warn")
    exp.add_argument("--overwrite", action="store_true", help="replace an existing target file")


def _info() -> int:
    import control
    import numpy
    import scipy

    import robustctl

    print(f"robustctl {robustctl.__version__}")
    print(f"numpy {numpy.__version__}, scipy {scipy.__version__}, python-control {control.__version__}")
    return 0


def _band(args: argparse.Namespace) -> tuple[float, float] | None:
    return None if args.band is None else (args.band[0], args.band[1])


def _report(args: argparse.Namespace, title: str):
    from .report import Report

    return Report(Path(args.out), title=title)


def _run_demo(args: argparse.Namespace) -> Path:
    from .demo import run_demo

    return run_demo(args.out, seed=args.seed, design=not args.no_design, example=args.example)


def _say(text: str) -> None:
    """Print a result's headline (its ``summary()``) on standard output."""
    print(text, flush=True)


class _Steps:
    """A progress bar over a command's steps, naming the one running, its clock ticking each second
    through a long step such as a diagnosis (tqdm on standard error; off when standard error is not
    a terminal, so logs and pipes stay clean)."""

    def __init__(self, names: Sequence[str]):
        import threading

        from tqdm import tqdm

        self._bar = tqdm(total=len(names), disable=not sys.stderr.isatty(), leave=False,
                         bar_format="{desc} [{n_fmt}/{total_fmt} steps, {elapsed}]")
        self.show = not self._bar.disable
        self._started = False
        self._stop = threading.Event()
        if self.show:
            threading.Thread(target=self._tick, daemon=True).start()

    def _tick(self) -> None:
        while not self._stop.wait(1.0):  # ends with close()
            self._bar.refresh()

    def __call__(self, name: str) -> None:
        if self._started:
            self._bar.update(1)
        self._started = True
        self._bar.set_description_str(name)

    def close(self) -> None:
        self._stop.set()
        self._bar.close()


def _inputs(args: argparse.Namespace, model: bool = True) -> tuple[Any, Any]:
    """The model (when the command has one) and DATA, described and with matching channels."""
    from .cli_inputs import load_model_spec, match_model_channels
    from .frd_io import load_frd

    data = _described(load_frd(args.data), args)
    if not model:
        return None, _select_data(data, args)
    loaded = load_model_spec(args.model)
    mdl, data, note = match_model_channels(loaded, data, inputs=args.inputs, outputs=args.outputs)
    if note:
        _say(note)
    return mdl, data


def _select_data(data: Any, args: argparse.Namespace) -> Any:
    from .cli_inputs import select_data_channels

    return select_data_channels(data, args.inputs, args.outputs)


def _run_load(args: argparse.Namespace) -> Path:
    from .cli_results import data_record
    from .frd_io import load_frd

    data = load_frd(args.data)
    record = data_record(data)
    _say(
        f"{Path(args.data).name}: {data.n_out} outputs {list(data.outputs)} x {data.n_in} inputs "
        f"{list(data.inputs)}, {data.f_hz.size} frequencies {data.f_hz[0]:.4g}-{data.f_hz[-1]:.4g} Hz, "
        f"{'with' if data.coherence is not None else 'without'} coherence."
    )
    stated = {k: v for k, v in record["experiment"].items() if v not in (None, False)}
    _say("Experiment: " + (", ".join(f"{k} = {v}" for k, v in stated.items()) or "not described "
                           "(give --excitation, --input-kind ... to the commands)") + ".")
    report = _report(args, f"robustctl load: {Path(args.data).name}")
    report.heading("The data")
    report.figure(data.plot(), "data", "Measured frequency responses.")
    for key, value in record.items():
        report.record(key, value)
    return report.write()


def _run_report(args: argparse.Namespace) -> Path:
    from .report import join_reports

    path = join_reports(args.folders, args.out, title=args.title)
    _say(f"Joined {len(args.folders)} reports: {', '.join(Path(f).name for f in args.folders)}.")
    return path


def _run_compare(args: argparse.Namespace) -> Path:
    from .cli_results import comparison_record
    from .correlate import compare
    from .identify import fit_measurement_model

    steps = _Steps(["load", "measurement model", "compare", "report"])
    try:
        steps("load model and data")
        model, data = _inputs(args)
        band = _band(args)
        steps("fit the measurement model")
        n_modes = None if args.modes == "auto" else args.modes
        mm = None if args.modes is None else fit_measurement_model(data, n_modes=n_modes, band=band,
                                                                   progress=steps.show)
        steps("compare")
        cmp = compare(model, data, band=band, measurement_model=mm)
        _say(cmp.summary())
        steps("write the report")
        report = _report(args, f"robustctl compare: {args.model} against {Path(args.data).name}")
        report.heading("Where the model fails")
        report.text(cmp.summary())
        report.table(cmp.table())
        report.table(cmp.mode_table())
        report.figure(cmp.plot(), "compare", "Data against model; failing bands shaded.")
        report.figure(cmp.plot_error_map(), "error_map",
                      "Error per channel and band; grey: within the noise.")
        for key, value in comparison_record(cmp).items():
            report.record(key, value)
        report.record("experiment", data.experiment.to_dict())
        return report.write()
    finally:
        steps.close()


def _run_diagnose(args: argparse.Namespace) -> Path:
    from .cli_results import diagnosis_record
    from .correlate import diagnose

    steps = _Steps(["load", "diagnose", "report"])
    try:
        steps("load model and data")
        model, data = _inputs(args)
        steps("diagnose: rank the candidate effects")
        diag = diagnose(model, data, band=_band(args), time_budget_s=args.time_budget)
        _say(diag.summary())
        steps("write the report")
        report = _report(args, f"robustctl diagnose: {args.model} against {Path(args.data).name}")
        report.heading("Which physical effect is missing?")
        report.text(diag.summary())
        report.table(diag.table())
        report.figure(diag.plot(), "diagnose",
                      "Candidate effects ranked by the share of the error they explain.")
        if diag.chain:
            report.heading(f"Verdict: {diag.verdict}")
            report.table(diag.chain_table())
            _error_before_and_after(report, model, data, diag, _band(args))
        for key, value in diagnosis_record(diag).items():
            report.record(key, value)
        return report.write()
    finally:
        steps.close()


def _error_before_and_after(report: Any, model: Any, data: Any, diag: Any, band: Any) -> None:
    """The error map of the parameters-only fit, then of the model with each effect of the diagnosis's
    chain added in turn (its jointly fitted size, the parameters fitted with it): where each effect
    brings the misfit within the noise (grey) and where misfit is left."""
    from .correlate import compare

    current = model.with_values(**diag.update_values) if diag.update_values else model
    cmp = compare(current, data, band=band)
    report.figure(cmp.plot_error_map(), "error_parameters_only",
                  f"Error with the parameters alone updated (cost {cmp.cost:.4g}); grey: within the noise.")
    current = model
    for k, step in enumerate(diag.chain, start=1):
        current = current.with_effect(step.effect)
        values = {n: v for n, v in step.update_values.items() if n in current.param_names}
        cmp = compare(current.with_values(**values) if values else current, data, band=band)
        report.figure(cmp.plot_error_map(), f"error_with_effect_{k}",
                      f"Error with effect {k}, {step.effect.name} = {step.effect.describe_value()}, and the "
                      f"parameters re-fitted (cost {cmp.cost:.4g}); grey: within the noise.")


def _run_update(args: argparse.Namespace) -> Path:
    from .cli_inputs import effect_from_diagnosis
    from .cli_results import comparison_record, update_record
    from .correlate import compare, update

    steps = _Steps(["load", "effect", "update", "compare", "report"])
    try:
        steps("load model and data")
        model, data = _inputs(args)
        steps("add the effect")
        name, values = effect_from_diagnosis(args.diagnosis, args.effect)
        if name is not None:
            model = model.with_effect(name)
            known = {k: v for k, v in values.items() if k in model.param_names}
            model = model.with_values(**known) if known else model
            start = f", starting from {known}" if known else " (at its neutral value)"
            _say(f"Effect added: {name}{start}.")
        band = _band(args)
        steps("update the parameters")
        upd = update(model, data, params=args.params, band=band, max_iter=args.max_iter, progress=steps.show)
        _say(upd.summary())
        steps("compare the updated model")
        after = compare(upd.model, data, band=band)
        steps("write the report")
        report = _report(args, f"robustctl update: {args.model} against {Path(args.data).name}")
        report.heading("The updated model")
        report.text(upd.summary())
        report.table(upd.table())
        report.figure(upd.plot(), "update", "Cost per iteration; MACE's alignment and orthogonality tests.")
        report.heading("The updated model against the data")
        report.text(after.summary())
        report.figure(after.plot(), "compare_updated", "Data against the updated model.")
        report.record("effect", name)
        for key, value in update_record(upd).items():
            report.record(key, value)
        report.record("compare_after", comparison_record(after))
        return report.write()
    finally:
        steps.close()


def _run_identify(args: argparse.Namespace) -> Path:
    from .cli_results import identify_record
    from .identify import fit_measurement_model

    steps = _Steps(["load", "identify", "report"])
    try:
        steps("load data")
        _, data = _inputs(args, model=False)
        steps("identify the measurement model")
        mm = fit_measurement_model(data, n_modes=args.modes, band=_band(args), progress=steps.show)
        _say(mm.summary())
        steps("write the report")
        report = _report(args, f"robustctl identify: {Path(args.data).name}")
        report.heading("Measurement model")
        report.text(mm.summary())
        report.table(mm.table())
        report.figure(mm.plot(), "measurement_model", "Measurement model against the data.")
        for key, value in identify_record(mm).items():
            report.record(key, value)
        return report.write()
    finally:
        steps.close()


def _design_inputs(args: argparse.Namespace) -> tuple[Any, Any, Any]:
    """The design model (updated, selected, reduced), the data (or None) and the recipe."""
    from .balanced import balanced_truncation
    from .cli_design import DesignRecipe
    from .cli_inputs import (
        CommandLineError,
        load_model_spec,
        load_recipe_spec,
        match_model_channels,
        updated_model,
    )
    from .frd_io import load_frd

    model, note = updated_model(load_model_spec(args.model), args.update)
    if note:
        _say(note)
    data = None if args.data is None else load_frd(args.data)
    if data is not None:
        model, data, note = match_model_channels(model, data, inputs=args.inputs, outputs=args.outputs)
    elif args.inputs or args.outputs:
        model = model.select(inputs=args.inputs, outputs=args.outputs)
        note = f"Model channels selected: inputs {args.inputs or 'all'}, outputs {args.outputs or 'all'}."
    if note:
        _say(note)
    if args.order is not None:
        bt = balanced_truncation(model, args.order)
        _say(f"Design model reduced to {args.order} states by balanced truncation "
             f"(||G - G_r||_inf <= {bt.bound:.3g}).")
        model = bt.sys
    if args.plant is not None:
        return model, data, load_recipe_spec(args.plant)
    span = None if data is None else (float(data.f_hz[0]), float(data.f_hz[-1]))
    perf = args.perf_band or args.band or span
    if perf is None:
        raise CommandLineError("give --perf-band LO_HZ HI_HZ (or DATA, whose span is the default).")
    return model, data, DesignRecipe(data, tuple(perf), args.level, args.input_mult, args.output_mult,
                                     args.cover_order, _band(args), args.data_sigmas)


def _run_design(args: argparse.Namespace) -> Path:
    from .cli_results import design_record
    from .export import export_controller
    from .robust import dksyn

    steps = _Steps(["load", "cover", "D-K", "export", "report"])
    try:
        steps("load the model and data")
        model, data, recipe = _design_inputs(args)
        steps("cover the model's error")
        cover = recipe.cover(model) if hasattr(recipe, "cover") else None
        gp = recipe(model, cover) if cover is not None else recipe(model)
        if cover is not None:
            _say(cover.summary())
        steps("D-K iteration")
        reduce = None if args.no_reduce else "auto"
        dk = dksyn(gp, max_iter=args.max_iter, order_d=args.d_order, reduce=reduce, progress=steps.show)
        _say(dk.summary())
        certified = "certified" if dk.mu_peak < 1 else "NOT certified"
        _say(f"mu: peak {dk.mu.peak:.4g} at {dk.mu.f_peak_hz:.4g} Hz (upper bound; lower bound "
             f"{dk.mu.lower_peak:.4g}): robust performance {certified}.")
        steps("export the controller")
        report = _report(args, f"robustctl design: {args.model}")
        folder = Path(report.folder)
        exported = []
        provenance = {"model": args.model, "data": args.data, "update": args.update}
        for suffix in (".json", ".h", ".mat"):  # diagonal: the exact power-of-two state scaling
            exported.append(export_controller(dk, folder / f"controller{suffix}", fs=args.fs, overwrite=True,
                                              balance="diagonal", provenance=provenance))
        _say(f"Controller ({dk.K.nstates} states) at {args.fs:g} Hz: {exported[0].summary()}")
        steps("write the report")
        report.heading("Design plant")
        report.text(gp.summary())
        if cover is not None:
            report.text(cover.summary())
            report.figure(cover.plot(), "cover", "The model's error against the data and its additive cover.")
        report.heading("D-K iteration")
        report.text(dk.summary())
        report.table(dk.table())
        report.figure(dk.plot(), "dk", "mu upper bound per D-K iteration.")
        report.figure(dk.mu.plot(), "mu", "Robust performance mu of the controller: upper and lower bounds.")
        report.heading("Exported controller")
        report.text(" ".join(f"{r.path.name}: {r.summary()}" for r in exported))
        for key, value in design_record(dk, cover, [r.path.name for r in exported], args.fs).items():
            report.record(key, value)
        return report.write()
    finally:
        steps.close()


def _run_export(args: argparse.Namespace) -> Path:
    from .cli_inputs import CommandLineError
    from .export import export_controller, load_controller

    source, target = Path(args.source), Path(args.target)
    if source.exists() and target.exists() and source.samefile(target):
        raise CommandLineError(
            f"TARGET {args.target!r} is the SOURCE file; writing it would replace the original (its design "
            "figures and provenance). Write to another file name."
        )
    report = export_controller(
        load_controller(args.source),
        args.target,
        fs=args.fs,
        method=args.method,
        prewarp_hz=args.prewarp_hz,
        crossover_hz=args.crossover_hz,
        balance=False if args.balance == "none" else args.balance,
        channel=None if args.channel is None else tuple(args.channel),
        prefix=args.prefix,
        on_unstable=args.on_unstable,
        overwrite=args.overwrite,
        provenance={"converted_from": str(args.source)},
    )
    print(report.table())
    return report.path


_COMMANDS: dict[str, Callable[[argparse.Namespace], Path]] = {
    "demo": _run_demo,
    "load": _run_load,
    "compare": _run_compare,
    "diagnose": _run_diagnose,
    "update": _run_update,
    "report": _run_report,
    "identify": _run_identify,
    "design": _run_design,
    "export": _run_export,
}


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``robustctl`` command; returns the exit status (2 on bad input)."""
    args = _parser().parse_args(argv)
    if args.command == "info":
        return _info()
    from .errors import RobustctlError

    start = time.perf_counter()
    try:
        path = _COMMANDS[args.command](args)
    except RobustctlError as exc:
        print(f"robustctl {args.command}: {_one_line(exc)}", file=sys.stderr)
        return 2
    what = "controller" if args.command == "export" else "report"
    print(f"{what} written to {path} in {time.perf_counter() - start:.1f} s")
    return 0


def _one_line(exc: Any) -> str:
    return " ".join(str(exc).split())


if __name__ == "__main__":
    raise SystemExit(main())
