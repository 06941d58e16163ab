"""The main job end to end: `robustctl demo --example caltech` writes a report holding every section
with numbers, and the report opens in headless Chromium without console messages (one module
per example, so that make test's --dist loadfile runs the two demos on different workers)."""

from _demo_checks import demo_tests

(demo_out, test_demo_report_holds_every_section_with_numbers,
 test_demo_report_opens_in_headless_chromium_without_console_errors) = demo_tests("caltech")
