"""The `progress(done, total)` adapter over tqdm used by the long `islands` commands."""

from __future__ import annotations

import io

from island_mapping.cli.progress import ProgressBar


def test_bar_reaches_100_percent_once_and_ends_its_line() -> None:
    out = io.StringIO()  # not a terminal
    bar = ProgressBar("confidence map", out)
    for done in range(0, 101, 7):
        bar(done, 100)
    bar(100, 100)
    bar(100, 100)  # a caller's final report after the loop already reached the end
    text = out.getvalue()
    assert text.count("confidence map: 100%") == 1
    assert "100/100" in text
    assert text.endswith("\n")


def test_a_new_total_starts_a_new_bar() -> None:
    out = io.StringIO()
    bar = ProgressBar("phase", out)
    bar(5, 10)
    bar(3, 4)
    bar(4, 4)
    text = out.getvalue()
    assert "5/10" in text
    assert "phase: 100%" in text and "4/4" in text
    assert text.count("\n") == 2  # the unfinished first bar is closed on its own line
