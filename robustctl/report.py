"""A self-contained HTML report: headings, text, tables and figures, written under one folder.

Figures are embedded in ``report.html`` as base64 PNG (the page is one self-contained file
that can be mailed on its own) and also saved as PNG files beside it for slides. Nothing
outside the folder is touched, and an existing report is replaced only inside the folder
robustctl created for it.
"""

from __future__ import annotations

import base64
import html
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .errors import RobustctlError
from .table import Table

__all__ = ["Report", "write_report", "join_reports"]

_STYLE = """
body { font-family: system-ui, sans-serif; max-width: 1100px; margin: 2em auto; color: #222; }
h1 { border-bottom: 2px solid #246; } h2 { color: #246; margin-top: 1.6em; }
table { border-collapse: collapse; margin: 0.8em 0; font-size: 0.9em; }
th, td { border: 1px solid #bbb; padding: 3px 8px; text-align: right; }
th { background: #eef; } caption { font-weight: bold; text-align: left; padding: 4px 0; }
img { max-width: 100%; border: 1px solid #ddd; margin: 0.5em 0; }
.note { background: #f6f6e8; border-left: 4px solid #cc9; padding: 0.5em 1em; }
pre { background: #f4f4f4; padding: 0.6em; overflow-x: auto; }
"""

_MARKER = ".robustctl-report"


#: Log axes spanning more decades than this get no minor ticks in report figures.
MINOR_TICK_DECADES = 3.0


def _thin_minor_ticks(fig: Any) -> None:
    """Drop the minor ticks of log-scaled y axes that span more than ``MINOR_TICK_DECADES``.

    Over many decades they are unlabelled clutter, and creating the tick artists is most of
    the drawing time of a multi-channel Bode grid (a 3x3 grid of 2048-point FRFs over six
    decades: 4.4 s -> 2.9 s of CPU to save).
    """
    from matplotlib.ticker import NullLocator

    for ax in fig.axes:
        lo, hi = ax.get_ylim()
        if ax.get_yscale() == "log" and lo > 0 and hi > 0 and abs(np.log10(hi / lo)) > MINOR_TICK_DECADES:
            ax.yaxis.set_minor_locator(NullLocator())


@dataclass
class Report:
    """Collects the sections of a report and writes them to ``folder/report.html``.

    Parameters
    ----------
    folder : str or Path
        Output folder; created when missing. If it exists and holds files, it must be a
        folder robustctl made before (it carries a marker file), so a user's folder is
        never overwritten by mistake.
    title : str
        The report's title.
    """

    folder: Path
    title: str = "robustctl report"
    _parts: list[str] = field(default_factory=list)
    _figures: int = 0
    _summary: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.folder = Path(self.folder)
        if self.folder.exists():
            if not self.folder.is_dir():
                raise RobustctlError(f"{self.folder} exists and is not a folder; choose another --out.")
            if any(self.folder.iterdir()) and not (self.folder / _MARKER).exists():
                raise RobustctlError(
                    f"{self.folder} already holds files that robustctl did not write; "
                    "choose an empty or new folder for the report."
                )
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            (self.folder / _MARKER).write_text("written by robustctl; safe to delete\n")
        except OSError as exc:  # a file on the way, no permission, full disk
            raise RobustctlError(
                f"cannot make the report folder {str(self.folder)!r}: {exc.strerror or exc}; choose another "
                "--out (a new folder in a writable place)."
            ) from None

    def heading(self, text: str) -> None:
        self._parts.append(f"<h2>{html.escape(text)}</h2>")

    def text(self, text: str, note: bool = False) -> None:
        cls = ' class="note"' if note else ""
        self._parts.append(f"<p{cls}>{html.escape(text)}</p>")

    def preformatted(self, text: str) -> None:
        self._parts.append(f"<pre>{html.escape(text)}</pre>")

    def table(self, table: Table) -> None:
        self._parts.append(table._repr_html_())

    def figure(self, fig: Any, name: str, caption: str = "") -> Path:
        """Save a matplotlib figure as PNG in the folder and embed it in the report."""
        self._figures += 1
        path = self.folder / f"{self._figures:02d}_{name}.png"
        _thin_minor_ticks(fig)
        fig.savefig(path, dpi=110)
        encoded = base64.b64encode(path.read_bytes()).decode("ascii")
        cap = f"<p><em>{html.escape(caption)}</em></p>" if caption else ""
        self._parts.append(
            f'<img src="data:image/png;base64,{encoded}" alt="{html.escape(name)}" '
            f'title="{html.escape(path.name)}">{cap}'
        )
        return path

    def record(self, key: str, value: Any) -> None:
        """Keep a headline number; all of them are written to ``summary.json``."""
        self._summary[key] = value

    def write(self) -> Path:
        """Write ``report.html`` and ``summary.json``; return the HTML path."""
        body = "\n".join(self._parts)
        page = (
            f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(self.title)}</title>"
            f"<style>{_STYLE}</style></head><body><h1>{html.escape(self.title)}</h1>\n{body}\n"
            "</body></html>\n"
        )
        path = self.folder / "report.html"
        try:
            path.write_text(page, encoding="utf-8")
            (self.folder / "summary.json").write_text(json.dumps(self._summary, indent=2, default=float))
        except OSError as exc:
            raise RobustctlError(
                f"cannot write the report into {str(self.folder)!r}: {exc.strerror or exc}; free some space "
                "or choose another --out."
            ) from None
        return path


#: Section heading and figure caption of each result kind :func:`write_report` takes.
_SECTIONS = {
    "compare": ("Where the model fails", "Data against model; failing bands shaded; grey heat-map cells "
                "are within the noise."),
    "diagnose": ("Which physical effect is missing?", "Candidate effects ranked by the share of the "
                 "error they explain."),
    "update": ("The updated model", "Cost per iteration; MACE's alignment and orthogonality tests."),
    "identify": ("Measurement model", "Measurement model against the data."),
}


def write_report(folder: Any, *results: Any, title: str = "robustctl report") -> Path:
    """One self-contained page of results, in the order given, and their numbers in ``summary.json``.

    Each result (``rc.compare``, ``rc.diagnose``, ``rc.update``, ``rc.fit_measurement_model``)
    gets a section with its ``summary()``, its ``table()`` and its ``plot()``; ``summary.json``
    holds, under ``compare``, ``diagnose``, ``update`` or ``identify`` (numbered when a kind
    repeats), the same verdict words and numbers the command line writes
    (:mod:`robustctl.cli_results`: sizes, standard errors, p-values).

    Parameters
    ----------
    folder : str or Path
        A new or empty folder, or one robustctl wrote before (:class:`Report`).
    *results : Comparison, Diagnosis, UpdateResult or MeasurementModel
    title : str

    Returns
    -------
    Path
        ``folder/report.html``.

    Raises
    ------
    RobustctlError
        No result, or one of another kind (the message names it).
    """
    from .cli_results import record_of, result_kind

    if not results:
        raise RobustctlError(
            "write_report needs at least one result (rc.compare, rc.diagnose, rc.update ...)."
        )
    kinds = [result_kind(r) for r in results]
    report = Report(Path(folder), title=title)
    seen: dict[str, int] = {}
    for result, kind in zip(results, kinds):
        seen[kind] = seen.get(kind, 0) + 1
        key = kind if seen[kind] == 1 else f"{kind}_{seen[kind]}"
        heading, caption = _SECTIONS[kind]
        report.heading(heading)
        report.preformatted(result.summary())
        report.table(result.table())
        report.figure(result.plot(), key, caption)
        report.record(key, record_of(result))
    return report.write()


def join_reports(folders: Any, out: Any, title: str = "robustctl report") -> Path:
    """One page from reports robustctl wrote (``robustctl compare/diagnose/update ... --out``), in order.

    Each folder's ``report.html`` becomes a section under its own title, and its
    ``summary.json`` goes into the joined ``summary.json`` under the folder's name.

    Parameters
    ----------
    folders : sequence of str or Path
        Report folders (each holds ``report.html`` and ``summary.json``).
    out : str or Path
        The folder of the joined report (new, empty, or written by robustctl before).
    title : str

    Returns
    -------
    Path
        ``out/report.html``.

    Raises
    ------
    RobustctlError
        No folder, or one without a robustctl report.
    """
    folders = [Path(f) for f in folders]
    if not folders:
        raise RobustctlError("join_reports needs at least one report folder.")
    sections = []
    for folder in folders:
        page, numbers = folder / "report.html", folder / "summary.json"
        if not page.is_file() or not numbers.is_file():
            raise RobustctlError(
                f"{folder} holds no robustctl report (report.html and summary.json); give the --out "
                "folders of robustctl compare, diagnose, update or identify."
            )
        text = page.read_text(encoding="utf-8")
        head, body = text.split("<h1>", 1) if "<h1>" in text else ("", text)
        heading, body = body.split("</h1>", 1) if "</h1>" in body else (folder.name, body)
        body = body.rsplit("</body>", 1)[0]
        sections.append((folder.name, heading, body, json.loads(numbers.read_text(encoding="utf-8"))))
    report = Report(Path(out), title=title)
    for name, heading, body, numbers in sections:
        report._parts.append(f"<h2>{heading}</h2>\n{body}")
        report.record(name, numbers)
    return report.write()
