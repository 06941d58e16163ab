"""Benchmark runner: discover ``bench_*.py``, run them, write JSON results and a Markdown summary.

Usage::

    python -m benchmarks                 # every benchmark
    python -m benchmarks freqresp        # only bench_freqresp.py
    python benchmarks/run.py --list      # names only

Each result JSON gets ``machine`` (platform, CPU, versions, load average) and
``blas_threads`` (robustctl's setting and the BLAS pools seen by threadpoolctl), so that
numbers from different machines or loads can be told apart. ``SUMMARY.md`` has one row per
metric of every result file present (value, target, met?), and the machine's speed on two fixed
workloads when the result was made (:func:`speed_reference`).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import importlib
import json
import math
import os
import platform
import re
import sys
import time
import traceback
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
MAX_CELL = 60  # characters of a value shown in the summary table
_TARGET = re.compile(r"^\s*(<=|>=|==|!=|<|>)\s*([-+0-9.eE]+|inf|nan)\s*$")
_RANGE = re.compile(r"^\s*([-+0-9.eE]+)\s*\.\.\s*([-+0-9.eE]+)\s*$")
_BOOL = re.compile(r"^\s*(==|!=)\s*(True|False)\s*$")


def discover() -> list[str]:
    """Names of the benchmarks (``bench_<name>.py`` in this folder), sorted."""
    return sorted(p.stem[len("bench_"):] for p in HERE.glob("bench_*.py"))


def _import(name: str):
    if __package__ in (None, ""):  # run as a script: make the package importable
        sys.path.insert(0, str(HERE.parent))
    return importlib.import_module(f"benchmarks.bench_{name}")


def machine_info() -> dict[str, Any]:
    """Where and with what the numbers were measured."""
    import numpy
    import scipy

    info: dict[str, Any] = {
        "timestamp_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "cpu_count": os.cpu_count(),
        "cpu_model": _cpu_model(),
        "numpy": numpy.__version__,
        "scipy": scipy.__version__,
    }
    try:
        import control

        info["control"] = control.__version__
    except ImportError:  # pragma: no cover - a dependency
        pass
    if hasattr(os, "getloadavg"):
        info["load_average_1_5_15"] = [round(x, 2) for x in os.getloadavg()]
    info["speed_reference_ms"] = speed_reference()
    return info


def speed_reference(repeats: int = 5) -> dict[str, float]:
    """CPU milliseconds of two fixed workloads, the least of ``repeats`` runs: a 300 x 300 symmetric
    eigenproblem (LAPACK ``dsyevd``, one BLAS thread) and 200,000 turns of a Python loop. They tell two
    machines apart; they do not scale a figure: on 2026-11-30 this machine ran the diagnose benchmark's
    reference case 1.47x slower at 06:35 than at 03:11 while these read the same (a slowdown of memory-
    bound work that two small workloads do not see)."""
    import numpy as np
    import scipy.linalg as sla
    from threadpoolctl import threadpool_limits

    a = np.random.default_rng(0).standard_normal((300, 300))
    a = a + a.T

    def loop() -> float:
        total = 0.0
        for i in range(200_000):
            total += i * 0.5
        return total

    best = {"eigh_300": math.inf, "python_loop_200k": math.inf}
    with threadpool_limits(1, user_api="blas"):
        for _ in range(repeats):
            for key, work in (("eigh_300", lambda: sla.eigh(a)), ("python_loop_200k", loop)):
                t0 = time.process_time()
                work()
                best[key] = min(best[key], 1e3 * (time.process_time() - t0))
    return {k: round(v, 2) for k, v in best.items()}


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def blas_info() -> dict[str, Any]:
    """robustctl's BLAS thread setting and the pools threadpoolctl sees (with each OpenBLAS pool's
    kernel, ``architecture``: the one it chose for this CPU or the one ``OPENBLAS_CORETYPE`` forced)."""
    from threadpoolctl import threadpool_info

    from robustctl.threads import get_blas_threads

    pools = [
        {k: p.get(k) for k in ("internal_api", "num_threads", "version", "threading_layer", "architecture")}
        for p in threadpool_info()
        if p.get("user_api") == "blas"
    ]
    return {"robustctl_setting": get_blas_threads(), "pools": pools}


def blas_kernel(result: dict[str, Any]) -> str:
    """The BLAS kernel(s) a result was measured with ("Haswell"; "" when not recorded)."""
    pools = (result.get("blas_threads") or {}).get("pools") or []
    return "/".join(sorted({p["architecture"] for p in pools if p.get("architecture")}))


def target_met(value: Any, target: Any) -> bool | None:
    """Whether ``value`` meets ``target``: ``"< 1e-9"``, ``">= 50"``, a closed range ``"0.85 .. 1.15"``,
    ``"== True"`` / ``"== False"``, or a value to equal."""
    if target is None:
        return None
    if isinstance(target, str):
        if (r := _RANGE.match(target)) and isinstance(value, (int, float)) and not isinstance(value, bool):
            return float(r.group(1)) <= value <= float(r.group(2))
        if b := _BOOL.match(target):
            wanted = b.group(2) == "True"
            return (value is wanted) if b.group(1) == "==" else (value is not wanted)
        m = _TARGET.match(target)
        if m:
            if not isinstance(value, (int, float)) or isinstance(value, bool):
                return False
            op, ref = m.group(1), float(m.group(2))
            return {
                "<": value < ref, "<=": value <= ref, ">": value > ref, ">=": value >= ref,
                "==": value == ref, "!=": value != ref,
            }[op]
    return value == target


def _cell(value: Any) -> str:
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return f"{value:.4g}" if math.isfinite(value) else str(value)
    text = json.dumps(value) if isinstance(value, (list, dict)) else str(value)
    text = text.replace("|", "\\|").replace("\n", " ")
    return text if len(text) <= MAX_CELL else text[: MAX_CELL - 1] + "…"


def summary_markdown(results: list[dict[str, Any]]) -> str:
    """The Markdown summary: one row per metric of every result."""
    lines = [
        "# Benchmark summary",
        "",
        "Generated by `python -m benchmarks` from `benchmarks/results/*.json`.",
        "",
        "| Benchmark | Passed | Run at (UTC) | BLAS threads | BLAS kernel | Load (1 min) | CPUs "
        "| Speed reference (ms) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        mach = r.get("machine", {})
        load = mach.get("load_average_1_5_15", [""])[0]
        blas = r.get("blas_threads", {}).get("robustctl_setting", "")
        speed = mach.get("speed_reference_ms") or {}
        cells = [r.get("name"), r.get("passed"), mach.get("timestamp_utc", ""), blas, blas_kernel(r), load,
                 mach.get("cpu_count", ""), " / ".join(f"{v:g}" for v in speed.values())]
        lines.append("| " + " | ".join(_cell(c) for c in cells) + " |")
    lines += ["", "| Benchmark | Metric | Value | Target | Met? |", "|---|---|---|---|---|"]
    for r in results:
        targets = r.get("targets", {}) or {}
        for metric, value in (r.get("metrics", {}) or {}).items():
            target = targets.get(metric)
            met = target_met(value, target)
            met_text = "" if met is None else ("yes" if met else "**no**")
            lines.append(
                f"| {r.get('name')} | {metric} | {_cell(value)} | "
                f"{'' if target is None else _cell(target)} | {met_text} |"
            )
    return "\n".join(lines) + "\n"


README = HERE.parent / "README.md"
README_START, README_END = "<!-- BENCHMARKS:START -->", "<!-- BENCHMARKS:END -->"


def _headline_metrics(result: dict[str, Any]) -> list[str]:
    """Metrics with a target, then side-by-side ratios (names with "speedup" or "ratio")."""
    targets = result.get("targets", {}) or {}
    metrics = result.get("metrics", {}) or {}
    ratios = [
        m for m, v in metrics.items()
        if re.search(r"speedup|(^|_)ratio(_|$)", m) and isinstance(v, (int, float))
    ]
    return list(targets) + [m for m in ratios if m not in targets]


def headline_markdown(results: list[dict[str, Any]]) -> str:
    """The README's table: metrics that carry a target and side-by-side ratios, with the load."""
    lines = ["| Benchmark | Metric | Value | Target | Met? |", "|---|---|---|---|---|"]
    for r in results:
        targets = r.get("targets", {}) or {}
        for metric in _headline_metrics(r):
            value = (r.get("metrics", {}) or {}).get(metric)
            target = targets.get(metric)
            met = target_met(value, target)
            met_text = "" if met is None else ("yes" if met else "**no**")
            target_text = "" if target is None else _cell(target)
            lines.append(f"| {r.get('name')} | {metric} | {_cell(value)} | {target_text} | {met_text} |")
    seen = [r.get("machine", {}).get("load_average_1_5_15") for r in results]
    loads = [_cell(v) for v in sorted({x[0] for x in seen if x})]
    cpus = sorted({f"{m.get('cpu_model', 'unknown CPU')}, {m.get('cpu_count', '?')} cores"
                   for m in (r.get("machine") or {} for r in results) if m})
    kernels = sorted({k for k in (blas_kernel(r) for r in results) if k})
    lines += [
        "",
        f"Measured on {'; '.join(cpus) or 'an unrecorded machine'}, OpenBLAS kernel "
        f"{', '.join(kernels) or 'not recorded'}, 1 BLAS thread; 1-minute load averages during the runs: "
        f"{', '.join(loads)}. Every metric, with the side-by-side tools' own figures, is in "
        "`benchmarks/results/SUMMARY.md`.",
    ]
    return "\n".join(lines)


def update_readme(table: str, readme: Path = README) -> bool:
    """Replace the text between the README's benchmark markers; False when they are absent."""
    if not readme.exists():
        return False
    text = readme.read_text()
    start, end = text.find(README_START), text.find(README_END)
    if start < 0 or end < start:
        return False
    readme.write_text(text[: start + len(README_START)] + "\n" + table + "\n" + text[end:])
    return True


def load_results() -> list[dict[str, Any]]:
    """Every ``results/*.json`` (unreadable files are reported and skipped)."""
    out = []
    for path in sorted(RESULTS.glob("*.json")):
        try:
            out.append(json.loads(path.read_text()))
        except (OSError, ValueError) as exc:
            print(f"skipping {path.name}: {exc}", file=sys.stderr)
    return out


def run_one(name: str) -> dict[str, Any]:
    """Run ``bench_<name>.run()`` and write ``results/<name>.json``."""
    module = _import(name)
    t0 = time.perf_counter()
    result = dict(module.run())
    result.setdefault("name", name)
    result.setdefault("metrics", {})
    result.setdefault("targets", {})
    if "passed" not in result:
        checks = [target_met(result["metrics"].get(k), t) for k, t in result["targets"].items()]
        result["passed"] = all(c is True for c in checks)
    result["wall_time_s"] = round(time.perf_counter() - t0, 3)
    result["blas_threads"] = blas_info()
    result["machine"] = machine_info()
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / f"{result['name']}.json").write_text(json.dumps(result, indent=2, default=str) + "\n")
    return result


def main(argv: list[str] | None = None) -> int:
    """Command line entry point; returns 0 when every benchmark run passed."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks", description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", help="benchmarks to run (default: all); e.g. freqresp")
    parser.add_argument("--list", action="store_true", help="list the benchmarks and exit")
    args = parser.parse_args(argv)
    available = discover()
    if args.list:
        print("\n".join(available))
        return 0
    names = [n.removeprefix("bench_").removesuffix(".py") for n in args.names] or available
    unknown = [n for n in names if n not in available]
    if unknown:
        parser.error(f"unknown benchmark(s) {unknown}; available: {available}")
    ok = True
    for name in names:
        print(f"== {name}", flush=True)
        try:
            result = run_one(name)
        except Exception:  # one broken benchmark must not hide the others
            traceback.print_exc()
            ok = False
            continue
        ok &= bool(result["passed"])
        print(json.dumps(result["metrics"], indent=2, default=str))
    results = load_results()
    summary = summary_markdown(results)
    (RESULTS / "SUMMARY.md").write_text(summary)
    update_readme(headline_markdown(results))
    print(summary)
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
