"""Session totals of the bad-input property suites, and the order in which files are handed out.

A property test records ``record_property("reliability_outcomes", {outcome: count})``; the
reports of every worker reach the controlling process, which prints the totals per module at
the end of the run (``make test`` runs with ``-n 2``, so no single worker sees every case).

``make test`` distributes whole files (``--dist loadfile --no-loadscope-reorder``) in
collection order. The files holding the most slow cases (a notebook counts as one) are
collected first -- longest work first, Graham's LPT rule for parallel machines -- so that no
long file starts while the other worker runs out of work; inside a file the order is
unchanged, and the order depends only on the collected tests (the same on every worker).
"""

from __future__ import annotations

from collections import Counter, defaultdict

_TOTALS: defaultdict[str, Counter] = defaultdict(Counter)


def pytest_collection_modifyitems(session, config, items):
    weight: Counter = Counter()
    first_seen: dict[str, int] = {}
    for index, item in enumerate(items):
        path = str(item.path)
        if path not in first_seen:
            first_seen[path] = index
            weight[path] += path.endswith(".ipynb")  # a notebook runs a whole session
        weight[path] += item.get_closest_marker("slow") is not None
    items.sort(key=lambda item: (-weight[str(item.path)], first_seen[str(item.path)]))


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
