"""The main job end to end: `robustctl demo --example mace` writes a report holding every section
with numbers, and the report opens in headless Chromium without console messages."""

import pytest
from _demo_checks import check_report_in_chromium, check_report_sections, run_demo


@pytest.fixture(scope="module")
def demo_out(tmp_path_factory):
    return run_demo("mace", tmp_path_factory)


@pytest.mark.slow
def test_demo_report_holds_every_section_with_numbers(demo_out):
    check_report_sections(demo_out)


@pytest.mark.slow
def test_demo_report_opens_in_headless_chromium_without_console_errors(demo_out):
    check_report_in_chromium(demo_out)
