"""Every relative link in the docs and the README points at a file that exists (the
docs follow the code's stage folders, so a move that forgets a link fails here)."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")


def broken_links(root=ROOT):
    """``"page: target"`` for every relative link whose target does not exist."""
    found = []
    for page in sorted([*root.glob("docs/**/*.md"), root / "README.md"]):
        for target in LINK.findall(page.read_text()):
            if "://" in target or target.startswith("mailto:"):
                continue
            if not (page.parent / target).exists():
                found.append(f"{page.relative_to(root)}: {target}")
    return found


def test_every_relative_link_resolves():
    found = broken_links()
    assert not found, "broken links:\n" + "\n".join(found)


def test_a_broken_link_is_named(tmp_path):
    (tmp_path / "docs").mkdir()
    (tmp_path / "README.md").write_text("[ok](docs/a.md) [web](https://x.org/y)")
    (tmp_path / "docs" / "a.md").write_text("[up](../README.md) [gone](pose/b.md#top)")
    assert broken_links(tmp_path) == ["docs/a.md: pose/b.md"]
