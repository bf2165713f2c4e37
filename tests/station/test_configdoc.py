"""README's configuration reference is the schema's own (`station.configdoc`): it cannot drift."""

from pathlib import Path

from station.config import SCHEMA
from station.configdoc import BEGIN, END, markdown_reference

README = Path(__file__).resolve().parents[2] / "README.md"


def test_readme_holds_the_generated_reference():
    text = README.read_text()
    start, stop = text.index(BEGIN), text.index(END) + len(END)
    assert text[start:stop] == markdown_reference(), \
        "README.md's configuration reference is stale: paste `python -m station.configdoc`"


def test_every_key_has_a_row_with_its_default():
    rows = markdown_reference().splitlines()
    for section, keys in SCHEMA.items():
        for name in keys:
            assert sum(row.startswith(f"| `{section}.{name}` |") for row in rows) == 1
