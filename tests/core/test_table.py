import pytest

from robustctl.table import Table


def test_table_renders_text_markdown_and_html():
    t = Table(("mode", "f (Hz)", "ok"), [(1, 1.23456789, True), (2, 2.5, False)], title="Modes")
    text = str(t)
    assert "1.235" in text and "Modes" in text
    assert t.to_markdown().splitlines()[2] == "| mode | f (Hz) | ok |"
    assert "<td>yes</td>" in t._repr_html_()
    assert t.column("f (Hz)") == [1.23456789, 2.5]


def test_table_rejects_ragged_rows():
    with pytest.raises(ValueError, match="2 values for 3 columns"):
        Table(("a", "b", "c"), [(1, 2)])


def test_result_html_is_summary_paragraphs_then_tables():
    from robustctl.table import Table, result_html

    page = result_html("a < b\nsecond", Table(("x",), [(1.5,)]), None)
    assert page.startswith("<p>a &lt; b</p><p>second</p><table>") and "<td>1.5</td>" in page
