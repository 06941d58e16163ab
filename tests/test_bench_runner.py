"""The benchmark runner's tables and README update (the numbers themselves are never asserted)."""

from benchmarks.run import README_END, README_START, headline_markdown, target_met, update_readme

RESULTS = [
    {"name": "fast", "metrics": {"speedup": 55.8, "n": 3, "speedup_threads": 0.8, "iterations": 7},
     "targets": {"speedup": ">= 50"}, "machine": {"load_average_1_5_15": [1.5, 1, 1]}},
    {"name": "slow", "metrics": {"time_s": 12.0}, "targets": {"time_s": "< 10"}},
]


def test_target_met_reads_comparisons():
    assert target_met(55.8, ">= 50") is True
    assert target_met(12.0, "< 10") is False
    assert target_met("x", "x") is True and target_met(1, None) is None


def test_headline_table_lists_targeted_metrics_and_ratios():
    table = headline_markdown(RESULTS)
    assert "| fast | speedup | 55.8 | >= 50 | yes |" in table
    assert "| slow | time_s | 12 | < 10 | **no** |" in table
    assert "| fast | n |" not in table and "| fast | iterations |" not in table
    assert "| fast | speedup_threads | 0.8 |  |  |" in table  # side-by-side ratios are shown too


def test_update_readme_replaces_only_between_markers(tmp_path):
    readme = tmp_path / "README.md"
    readme.write_text(f"head\n{README_START}\nold\n{README_END}\ntail\n")
    assert update_readme("new table", readme)
    assert readme.read_text() == f"head\n{README_START}\nnew table\n{README_END}\ntail\n"
    (tmp_path / "other.md").write_text("no markers")
    assert not update_readme("x", tmp_path / "other.md")


def test_target_met_reads_ranges_and_booleans():
    assert target_met(1.02, "0.85 .. 1.15") is True
    assert target_met(0.84, "0.85 .. 1.15") is False
    assert target_met(True, "== True") is True and target_met(False, "== True") is False
    assert target_met(False, "== False") is True and target_met(1, "== True") is False


def test_speed_reference_is_timed_and_shown_in_the_summary():
    """The two reference workloads are timed (CPU ms) and the summary shows them beside the load."""
    from benchmarks.run import speed_reference, summary_markdown

    ref = speed_reference(repeats=3)
    assert set(ref) == {"eigh_300", "python_loop_200k"} and all(v > 0 for v in ref.values())
    row = summary_markdown([{"name": "x", "passed": True, "machine": {"speed_reference_ms": ref}}])
    assert f"{ref['eigh_300']:g} / {ref['python_loop_200k']:g}" in row


def test_the_blas_kernel_is_recorded_and_shown():
    """Each OpenBLAS pool's kernel is kept (``architecture``) and both tables name it."""
    from benchmarks.run import blas_info, blas_kernel, headline_markdown, summary_markdown

    info = blas_info()
    kernels = {p.get("architecture") for p in info["pools"] if p["internal_api"] == "openblas"}
    assert kernels and None not in kernels
    r = {"name": "x", "passed": True, "blas_threads": info,
         "machine": {"cpu_model": "CPU A", "cpu_count": 2, "load_average_1_5_15": [1.0, 1.0, 1.0]}}
    kernel = blas_kernel(r)
    assert kernel == "/".join(sorted(kernels))
    assert f"| 1 | {kernel} |" in summary_markdown([r])
    assert f"CPU A, 2 cores, OpenBLAS kernel {kernel}" in headline_markdown([r])
    assert blas_kernel({"name": "old"}) == ""
