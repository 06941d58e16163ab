"""``python -m benchmarks [names...]``: run the benchmarks and write results/SUMMARY.md."""

from .run import main

raise SystemExit(main())
