"""The complex-log cost of identified models: :mod:`robustctl.cost` (one report type for the package)."""

from ..cost import LogCost, channel_cost, cost_report

__all__ = ["LogCost", "channel_cost", "cost_report"]
