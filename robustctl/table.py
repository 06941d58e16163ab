"""A small table type shared by every result object's ``.table()``.

It prints as fixed-width text in a terminal, renders as HTML in Jupyter and as Markdown in
reports, and keeps the raw rows for programmatic use (``table.rows``, ``table.column(name)``).
"""

from __future__ import annotations

import html
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["Table", "result_html"]


def _fmt(value: Any, digits: int) -> str:
    if value is None:
        return ""
    if isinstance(value, (bool, np.bool_)):
        return "yes" if value else "no"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        if not np.isfinite(value):
            return "" if np.isnan(value) else str(value)
        return f"{value:.{digits}g}"
    return str(value)


@dataclass(frozen=True)
class Table:
    """Rows of values under named columns.

    Parameters
    ----------
    columns : sequence of str
        Column headings (with units, e.g. ``"f model (Hz)"``).
    rows : sequence of sequences
        One sequence of values per row, in column order.
    title : str
        A caption.
    digits : int
        Significant digits for floats.
    """

    columns: tuple[str, ...]
    rows: tuple[tuple[Any, ...], ...]
    title: str = ""
    digits: int = 4

    def __post_init__(self) -> None:
        object.__setattr__(self, "columns", tuple(self.columns))
        rows = tuple(tuple(r) for r in self.rows)
        for r in rows:
            if len(r) != len(self.columns):
                raise ValueError(f"a table row has {len(r)} values for {len(self.columns)} columns.")
        object.__setattr__(self, "rows", rows)

    def column(self, name: str) -> list[Any]:
        """The values of column ``name``."""
        k = self.columns.index(name)
        return [r[k] for r in self.rows]

    def _cells(self) -> list[list[str]]:
        return [[_fmt(v, self.digits) for v in r] for r in self.rows]

    def __str__(self) -> str:
        cells = self._cells()
        widths = [len(c) for c in self.columns]
        for r in cells:
            widths = [max(w, len(c)) for w, c in zip(widths, r)]
        line = "  ".join(c.ljust(w) for c, w in zip(self.columns, widths))
        out = [self.title] if self.title else []
        out += [line, "  ".join("-" * w for w in widths)]
        out += ["  ".join(c.ljust(w) for c, w in zip(r, widths)) for r in cells]
        return "\n".join(out)

    def to_markdown(self) -> str:
        """The table as GitHub-flavoured Markdown."""
        out = [f"**{self.title}**", ""] if self.title else []
        out.append("| " + " | ".join(self.columns) + " |")
        out.append("|" + "|".join("---" for _ in self.columns) + "|")
        out += ["| " + " | ".join(r) + " |" for r in self._cells()]
        return "\n".join(out)

    def _repr_html_(self) -> str:
        head = "".join(f"<th>{html.escape(c)}</th>" for c in self.columns)
        body = "".join(
            "<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in r) + "</tr>" for r in self._cells()
        )
        cap = f"<caption>{html.escape(self.title)}</caption>" if self.title else ""
        return f"<table>{cap}<thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"

    def __repr__(self) -> str:
        return str(self)

    @classmethod
    def from_records(cls, records: Sequence[dict[str, Any]], title: str = "", digits: int = 4) -> Table:
        """Build from a list of dicts sharing the same keys."""
        if not records:
            return cls((), (), title, digits)
        columns = tuple(records[0])
        return cls(columns, tuple(tuple(r[c] for c in columns) for r in records), title, digits)


def result_html(summary: str, *tables: Any) -> str:
    """A result's ``_repr_html_``: its summary, one paragraph per line, then its tables (None skipped)."""
    paras = "".join(f"<p>{html.escape(line)}</p>" for line in summary.splitlines())
    return paras + "".join(t._repr_html_() for t in tables if t is not None)
