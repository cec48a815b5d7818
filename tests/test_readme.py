"""README.md and docs/*.md carry no unreplaced placeholder (e.g. ``SPEEDUP_LINE``, ``TODO``)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

_WORDS = "TODO|TBD|FIXME|XXX+|TKTK|PLACEHOLDER"
_SUFFIXES = "LINE|HERE|TODO|TBD|FIXME|PLACEHOLDER|FIGURE|NUMBER|VALUE|RESULTS?|TEXT"
_PREFIXES = "INSERT|FILL|PLACEHOLDER|REPLACE"
PLACEHOLDER = re.compile(
    rf"\b(?:{_WORDS})\b"  # an editor's marker word on its own
    rf"|\b[A-Z][A-Z0-9]*(?:_[A-Z0-9]+)*_(?:{_SUFFIXES})\b"  # FOO_LINE, RAY_SPEEDUP_HERE
    rf"|\b(?:{_PREFIXES})_[A-Z0-9_]+\b"  # INSERT_NUMBER, FILL_ME
    r"|\{\{\s*[A-Za-z_]+\s*\}\}"  # {{ template_slot }}
)
"""What an unreplaced placeholder looks like: upper case only, so prose and code names pass."""


def placeholders(text: str) -> list[tuple[int, str]]:
    """(line number, token) of every placeholder in `text`."""
    return [
        (n, m.group(0))
        for n, line in enumerate(text.splitlines(), start=1)
        for m in PLACEHOLDER.finditer(line)
    ]


def test_the_documents_exist():
    assert DOCS[0].is_file()
    assert len(DOCS) > 1, "no docs/*.md found"


@pytest.mark.parametrize("path", DOCS, ids=lambda p: str(p.relative_to(ROOT)))
def test_no_placeholder_left(path: Path):
    found = placeholders(path.read_text(encoding="utf-8"))
    shown = ", ".join(f"line {n}: {token}" for n, token in found)
    assert not found, f"{path.relative_to(ROOT)} has unreplaced placeholders: {shown}"


@pytest.mark.parametrize(
    "text",
    [
        "- Measured: SPEEDUP_LINE. What limits 100 nodes",
        "Speed-up: RAY_SPEEDUP_HERE",
        "TODO: measure",
        "the result (TBD)",
        "FIXME",
        "see XXX",
        "INSERT_NUMBER episodes",
        "{{ speedup }}",
    ],
)
def test_placeholders_are_caught(text: str):
    assert placeholders(text), text


@pytest.mark.parametrize(
    "text",
    [
        "`RAY_AUTH_TOKEN` and `RAY_AUTH_MODE=token`",
        "python scripts/metrics.py DATA_DIR [--json]",
        "its module name in `TASK_MODULES`",
        "move_tcp(ctx, side, X_WT)",
        "`$BICOORD_CACHE`, SMP, STI, TL, HDF5, JSON, MP4",
        "a todo list, tbd in lower case, Todo",
        "a line here, the LINE_WIDTH constant",
    ],
)
def test_ordinary_text_passes(text: str):
    assert not placeholders(text), text
