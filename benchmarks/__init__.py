"""robustctl benchmarks: side-by-side timings and accuracy against the tools a user would otherwise use.

Run ``python -m benchmarks [names...]`` (or ``python benchmarks/run.py``). Every
``benchmarks/bench_<name>.py`` module exposes ``run() -> dict`` with keys ``name``,
``description``, ``metrics``, ``targets`` and ``passed``; the runner writes
``benchmarks/results/<name>.json`` (with the BLAS thread setting and machine information)
and the Markdown table ``benchmarks/results/SUMMARY.md``.
"""
