"""What the ``robustctl`` command reads: a model named on the command line.

MODEL convention (``robustctl compare MODEL DATA``):

* ``path/to/file.py`` or ``path/to/file.py:NAME`` — a Python file; ``NAME`` defaults to
  ``model``;
* ``package.module`` or ``package.module:NAME`` — an importable module (e.g.
  ``robustctl.examples:caltech_truss``).

``NAME`` is an attribute that is a model (a ``PhysicalModel`` or anything with
``.statespace()``, a ``control.StateSpace`` or transfer function) or a callable taking no
arguments that returns one. The file is run as Python: only name files you trust.
"""

from __future__ import annotations

import importlib
import importlib.util
import re
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from .errors import RobustctlError

__all__ = ["CommandLineError", "load_model_spec", "match_model_channels", "select_data_channels",
           "effect_from_diagnosis", "updated_model", "load_recipe_spec"]

_DEFAULT_NAME = "model"


class CommandLineError(RobustctlError):
    """A command-line argument cannot be used (missing file, unknown name, bad band)."""


def _split(spec: str) -> tuple[str, str]:
    # "C:\\dir\\m.py:model" keeps its drive letter: split on the last colon after the path part
    match = re.fullmatch(r"(.+?)(?::([A-Za-z_][A-Za-z0-9_]*))?", spec)
    if match is None or not match.group(1):
        raise CommandLineError(f"MODEL {spec!r} is empty; give FILE.py[:NAME] or package.module[:NAME].")
    return match.group(1), match.group(2) or _DEFAULT_NAME


def _module_from_file(path: Path) -> Any:
    if not path.is_file():
        raise CommandLineError(f"MODEL file {str(path)!r} does not exist.")
    spec = importlib.util.spec_from_file_location(f"_robustctl_user_model_{abs(hash(path))}", path)
    if spec is None or spec.loader is None:
        raise CommandLineError(f"MODEL file {str(path)!r} is not a Python file.")
    module = importlib.util.module_from_spec(spec)
    sys.path.insert(0, str(path.parent.resolve()))  # the file may import its neighbours
    try:
        spec.loader.exec_module(module)
    except RobustctlError:
        raise
    except Exception as exc:  # the user's code: report it on one line
        raise CommandLineError(f"running {path.name} failed: {type(exc).__name__}: {exc}") from exc
    finally:
        sys.path.pop(0)
    return module


def _module_from_name(name: str) -> Any:
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as exc:
        raise CommandLineError(
            f"MODEL {name!r} is neither a .py file nor an importable module ({exc}); "
            "give FILE.py[:NAME] or package.module[:NAME]."
        ) from exc
    except Exception as exc:
        raise CommandLineError(f"importing {name} failed: {type(exc).__name__}: {exc}") from exc


def load_model_spec(spec: str) -> Any:
    """The model named by ``spec`` (see the module docstring for the convention).

    Raises
    ------
    CommandLineError
        Missing file or module, unknown attribute (the available names are listed), a
        callable that fails, or an object that is not a model.
    """
    where, name = _split(str(spec))
    module = _module_from_file(Path(where)) if where.endswith(".py") else _module_from_name(where)
    if not hasattr(module, name):
        public = sorted(n for n in vars(module) if not n.startswith("_"))
        raise CommandLineError(
            f"{where} has no {name!r}; name one of its attributes with {where}:NAME "
            f"(it has: {', '.join(public[:15]) or 'nothing public'})."
        )
    obj = getattr(module, name)
    if callable(obj) and not _is_system(obj):
        try:
            obj = obj()
        except RobustctlError:
            raise
        except Exception as exc:
            raise CommandLineError(f"{where}:{name}() failed: {type(exc).__name__}: {exc}") from exc
    if not _is_system(obj):
        raise CommandLineError(
            f"{where}:{name} is a {type(obj).__name__}, not a model; it must be (or return) a "
            "PhysicalModel, an object with .statespace(), or a control.StateSpace."
        )
    return obj


def _is_system(obj: Any) -> bool:
    import control

    return isinstance(obj, control.LTI) or callable(getattr(obj, "statespace", None))



def _names(given: Any, have: Sequence[str], side: str, what: str) -> list[str] | None:
    if given is None:
        return None
    given = [str(g) for g in given]
    unknown = [g for g in given if g not in have]
    if unknown:
        raise CommandLineError(f"--{what} {' '.join(unknown)}: the {side} has no such {what} (it has "
                               f"{', '.join(have)}).")
    return given


def select_data_channels(data: Any, inputs: Sequence[str] | None, outputs: Sequence[str] | None) -> Any:
    """``data`` cut to the named inputs and outputs (``--inputs``/``--outputs``); unchanged when none."""
    ins = _names(inputs, data.inputs, "data", "inputs")
    outs = _names(outputs, data.outputs, "data", "outputs")
    if ins is None and outs is None:
        return data
    return data.select(outputs=outs, inputs=ins)


def match_model_channels(
    model: Any, data: Any, inputs: Sequence[str] | None = None, outputs: Sequence[str] | None = None
) -> tuple[Any, Any, str]:
    """The model and the data on the same channels, and a sentence saying what was selected.

    ``--inputs``/``--outputs`` select those channels of both. Without them, a data file whose
    channel names are a subset of the model's (a one-input impact test of a two-shaker model)
    is matched by ``model.select`` of the data's names; any other mismatch is left to the
    one matching policy (:func:`robustctl.checks.match_channels`), which names the fix.

    Returns
    -------
    (model, data, note) : the note is ``""`` when nothing was selected.
    """
    data = select_data_channels(data, inputs, outputs)
    system = model.statespace() if callable(getattr(model, "statespace", None)) else model
    m_in, m_out = [str(n) for n in system.input_labels], [str(n) for n in system.output_labels]
    ins = _names(inputs, m_in, "model", "inputs") or list(data.inputs)
    outs = _names(outputs, m_out, "model", "outputs") or list(data.outputs)
    if not (set(ins) <= set(m_in) and set(outs) <= set(m_out)) or (ins == m_in and outs == m_out):
        return model, data, ""
    if callable(getattr(model, "select", None)):
        picked = model.select(inputs=ins, outputs=outs)
    else:
        import control

        picked = control.ss(system)[[m_out.index(o) for o in outs], [m_in.index(i) for i in ins]]
    left = [f"{len(m_in) - len(ins)} of {len(m_in)} inputs" if len(ins) < len(m_in) else "",
            f"{len(m_out) - len(outs)} of {len(m_out)} outputs" if len(outs) < len(m_out) else ""]
    note = (f"Model channels selected to match DATA: inputs {ins}, outputs {outs} "
            f"({' and '.join(x for x in left if x)} of the model left out).")
    return picked, data, note


def effect_from_diagnosis(diagnosis: str | None, effect: str | None) -> tuple[str | None, dict[str, float]]:
    """The effect ``robustctl update`` adds: named (``--effect``), or the one a diagnose result
    proposed (``--diagnosis``: its folder or ``summary.json``) with its fitted values.

    Returns
    -------
    (name, values) : ``(None, {})`` when neither is given.

    Raises
    ------
    CommandLineError
        Both given, a missing or unreadable file, or a diagnosis that proposed nothing.
    """
    if diagnosis is not None and effect is not None:
        raise CommandLineError("give --effect or --diagnosis, not both.")
    if diagnosis is None:
        return effect, {}
    record = _summary_record(diagnosis, "--diagnosis", "diagnose")
    best = record.get("best")
    if not isinstance(best, dict) or not best.get("name"):
        raise CommandLineError(
            f"--diagnosis {diagnosis}: the diagnosis proposed no effect "
            f"({record.get('verdict', 'no verdict')}); update without an effect, or name one with --effect."
        )
    return str(best["name"]), {str(k): float(v) for k, v in (best.get("values") or {}).items()}


def _summary_record(folder: str, option: str, command: str) -> dict[str, Any]:
    """The ``summary.json`` of a command's ``--out`` folder (or the file itself)."""
    import json

    path = Path(folder)
    path = path / "summary.json" if path.is_dir() else path
    try:
        record = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise CommandLineError(
            f"{option} {folder}: cannot read {path} ({exc}); give the --out folder of "
            f"'robustctl {command}' or its summary.json."
        ) from None
    if not isinstance(record, dict):
        raise CommandLineError(f"{option} {folder}: {path} is not a robustctl {command} summary.")
    return record


def updated_model(model: Any, update: str | None) -> tuple[Any, str]:
    """``model`` as ``robustctl update`` left it (``--update OUT``): the effect it added and every
    updated parameter at its value after the update, with a sentence saying so.

    Returns
    -------
    (model, note) : ``(model, "")`` when ``update`` is None.

    Raises
    ------
    CommandLineError
        An unreadable summary, one that is not an update's, or a model without the parameters.
    """
    if update is None:
        return model, ""
    record = _summary_record(update, "--update", "update")
    params = record.get("parameters")
    if not isinstance(params, list) or not all(isinstance(p, dict) and "name" in p for p in params):
        raise CommandLineError(f"--update {update}: its summary.json holds no updated parameters "
                               "(is it the --out folder of 'robustctl update'?).")
    if not callable(getattr(model, "with_values", None)):
        raise CommandLineError(f"--update {update}: MODEL is a {type(model).__name__}, which has no "
                               "parameters to set; give the PhysicalModel the update started from.")
    effect = record.get("effect")
    if effect:
        model = model.with_effect(str(effect))
    values = {str(p["name"]): float(p["after"]) for p in params if p.get("after") is not None}
    missing = sorted(set(values) - set(model.param_names))
    if missing:
        raise CommandLineError(f"--update {update}: MODEL has no parameter {', '.join(missing)} (the "
                               "update was made on another model).")
    model = model.with_values(**values)
    added = f"effect {effect!r} added, " if effect else ""
    shown = ", ".join(f"{k} = {v:.6g}" for k, v in values.items())
    return model, f"Model as updated in {update}: {added}{shown}."


def load_recipe_spec(spec: str) -> Any:
    """The design-plant recipe named by ``spec`` (``FILE.py:NAME`` or ``package.module:NAME``): a
    callable ``nominal -> GeneralizedPlant``.

    Raises
    ------
    CommandLineError
        Missing file, module or attribute, or an attribute that is not callable.
    """
    where, name = _split(str(spec))
    module = _module_from_file(Path(where)) if where.endswith(".py") else _module_from_name(where)
    recipe = getattr(module, name, None)
    if not callable(recipe):
        raise CommandLineError(f"--plant {spec}: {where} has no callable {name!r} (a function nominal -> "
                               "GeneralizedPlant, e.g. robustctl.examples:caltech_design_plant).")
    return recipe
