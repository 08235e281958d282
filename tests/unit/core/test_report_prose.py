"""A report's prose keeps each command-line option on one line (the browser broke "--all-classes"
after its dashes at a line end) and is still escaped."""

from __future__ import annotations

from calidar.report.html import Report, prose


def test_options_are_unbroken_and_the_rest_escaped():
    html = prose("keep them (--all-classes); a--b, <b> & --method planes --no-all-classes/--all-classes")
    assert '(<span class="opt">--all-classes</span>)' in html
    assert "a--b" in html and "&lt;b&gt; &amp;" in html  # not an option; escaped
    assert html.count('class="opt"') == 4


def test_the_report_styles_them_unbroken(tmp_path):
    rep = Report("t")
    sec = rep.section("s")
    sec.text("every LAS class (--all-classes)")
    sec.warning("give --trajectory-accuracy FILE")
    page = rep.write(tmp_path / "r.html").read_text()
    assert ".opt{white-space:nowrap}" in page
    assert '<span class="opt">--all-classes</span>' in page and '<span class="opt">--trajectory-accuracy</span>' in page
