"""The main job end to end: `robustctl demo` writes a report holding every section with numbers."""

import json
import re
import shutil
import subprocess

import pytest

from robustctl.cli import main

SECTIONS = [
    "1. Measurements",
    "2. Measurement model",
    "3. Nominal physical model",
    "4. Which physical effect is missing?",
    "5. Updating the physical parameters",
    "6. Updated physical model",
    "7. The truth, revealed",
    "8. Uncertainty weights",
    "9. Generalized plant and D-K iteration",
    "10. mu over frequency",
    "11. The yardstick",
    "12. Exported controller",
]


@pytest.fixture(scope="module")
def demo_out(tmp_path_factory):
    out = tmp_path_factory.mktemp("demo") / "out"
    assert main(["demo", "--out", str(out)]) == 0
    return out


@pytest.mark.slow
def test_demo_report_holds_every_section_with_numbers(demo_out):
    page = (demo_out / "report.html").read_text()
    headings = re.findall(r"<h2>(.*?)</h2>", page)
    for section in SECTIONS:
        assert any(h.startswith(section.replace(">", "&gt;")) for h in headings), (section, headings)
    # every section has a table or a figure with numbers in it
    bodies = re.split(r"<h2>.*?</h2>", page)[1:]
    for heading, body in zip(headings, bodies):
        assert re.search(r"<td>[^<]*\d", body) or "data:image/png;base64," in body, heading
    figures = {h.split(" ")[0]: b.count("data:image/png;base64,") for h, b in zip(headings, bodies)}
    assert figures["1."] >= 1 and figures["4."] >= 1  # measured FRFs; the diagnosis figure
    summary = json.loads((demo_out / "summary.json").read_text())
    assert summary["cost_reduction_percent"] > 90
    assert summary["robust_stability_peak_mu"] < 1  # robust stability certified for the seed's weights
    assert summary["stabilises_truth"] is True
    gap = summary["yardstick_gap_db"]
    # gap (dB) = measurement-model controller minus this one: it closes as the model improves
    assert gap["measurement"] == 0 and gap["updated"] < gap["nominal"]
    for name in ("controller.h", "controller.json", "controller.mat", "controller.csv"):
        assert (demo_out / name).stat().st_size > 100


@pytest.mark.slow
def test_demo_report_opens_in_headless_chromium_without_console_errors(demo_out):
    browser = next((shutil.which(b) for b in ("chromium", "chromium-browser", "google-chrome")
                    if shutil.which(b)), None)
    if browser is None:
        pytest.skip("no Chromium on this machine: `apt-get install chromium` to run the browser check")
    run = subprocess.run(
        [browser, "--headless", "--no-sandbox", "--disable-gpu", "--enable-logging=stderr", "--v=0",
         "--dump-dom", (demo_out / "report.html").as_uri()],
        capture_output=True, text=True, timeout=120,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    assert "12. Exported controller" in run.stdout
    console_errors = [ln for ln in run.stderr.splitlines() if "CONSOLE" in ln and "ERROR" in ln.upper()]
    assert not console_errors, console_errors
