"""Session totals of the bad-input property suites, summed over pytest-xdist workers.

A property test records ``record_property("reliability_outcomes", {outcome: count})``; the
reports of every worker reach the controlling process, which prints the totals per module at
the end of the run (``make test`` runs with ``-n 2``, so no single worker sees every case).
"""

from __future__ import annotations

from collections import Counter, defaultdict

_TOTALS: defaultdict[str, Counter] = defaultdict(Counter)


def pytest_runtest_logreport(report):
    if report.when != "call":
        return
    for name, value in report.user_properties:
        if name == "reliability_outcomes" and isinstance(value, dict):
            _TOTALS[report.nodeid.split("::")[0]].update(value)


def pytest_terminal_summary(terminalreporter):
    for module, counts in sorted(_TOTALS.items()):
        terminalreporter.write_line(
            f"{module}: {sum(counts.values())} generated bad-argument cases, by outcome {dict(counts)}"
        )
