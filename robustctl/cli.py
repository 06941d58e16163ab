"""The ``robustctl`` command: ``robustctl demo --out out`` runs the whole pipeline on the
embedded default example and writes an HTML report."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence

__all__ = ["main"]


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="robustctl", description="Robust control of flexible structures: measure, model, correlate."
    )
    sub = parser.add_subparsers(dest="command", required=True)
    demo = sub.add_parser(
        "demo", help="run the full pipeline on the embedded Caltech truss and write a report"
    )
    demo.add_argument("--out", default="out", help="report folder (default: out)")
    demo.add_argument("--seed", type=int, default=0, help="random seed of the simulated experiment")
    sub.add_parser("info", help="print the versions robustctl runs with")
    return parser


def _info() -> int:
    import control
    import numpy
    import scipy

    import robustctl

    print(f"robustctl {robustctl.__version__}")
    print(f"numpy {numpy.__version__}, scipy {scipy.__version__}, python-control {control.__version__}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``robustctl`` command; returns the exit status."""
    args = _parser().parse_args(argv)
    if args.command == "info":
        return _info()
    from .demo import run_demo
    from .errors import RobustctlError

    start = time.perf_counter()
    try:
        path = run_demo(args.out, seed=args.seed)
    except RobustctlError as exc:
        print(f"robustctl: {exc}", file=sys.stderr)
        return 2
    print(f"report written to {path} in {time.perf_counter() - start:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
