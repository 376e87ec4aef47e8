"""The documentation's Python examples run as written, and no document points outside."""

from __future__ import annotations

import os
import re
import subprocess
import sys

import pytest
from conftest import ROOT

BLOCK = re.compile(r"```python\n(.*?)```", re.S)


@pytest.mark.slow
def test_api_examples_run():
    blocks = BLOCK.findall((ROOT / "docs" / "api.md").read_text())
    assert len(blocks) == 5
    env = {**os.environ, "MPLBACKEND": "Agg"}
    for code in blocks:
        out = subprocess.run(
            [sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True
        )
        assert out.returncode == 0, f"{code}\n{out.stderr}"


def test_docs_and_readme_point_inside_the_repository():
    for path in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        text = path.read_text()
        assert "../shared" not in text and "DESIGN.md" not in text, path
        for target in re.findall(r"\]\(([^)#]+)\)", text):
            if "://" in target:
                continue
            assert (path.parent / target).exists(), f"{path.name}: dead link {target}"


def anchors(path):
    """The ``#anchors`` GitHub gives a Markdown file's headings (its slug rules, repeats -1, -2)."""
    text = re.sub(r"```.*?```", "", path.read_text(), flags=re.S)
    seen: dict[str, int] = {}
    for heading in re.findall(r"^#{1,6}\s+(.+?)\s*#*\s*$", text, re.M):
        slug = re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")
        seen[slug] = seen.get(slug, -1) + 1
        yield slug if seen[slug] == 0 else f"{slug}-{seen[slug]}"


def test_every_anchor_a_link_names_exists():
    checked = 0
    for path in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        for target, anchor in re.findall(r"\]\(([^)#\s]*)#([^)\s]+)\)", path.read_text()):
            if "://" in target:
                continue
            to = (path.parent / target) if target else path
            assert anchor in set(anchors(to)), f"{path.name}: no heading for {target}#{anchor}"
            checked += 1
    assert checked >= 20  # README and docs link into each other's sections


def test_anchor_slugs_follow_github():
    doc = ROOT / "docs" / "terrain.md"
    assert "the-resting-pose-mmstabterrainrestpy" in set(anchors(doc))
    assert "speed-make-bench-terrain" in set(anchors(doc))


def test_help_names_every_exit_status_of_the_cli_doc():
    from mmstab.cli import build_parser

    table = (ROOT / "docs" / "cli.md").read_text().split("## Exit statuses", 1)[1]
    statuses = re.findall(r"^\| (\d+) \|", table.split("\n## ", 1)[0], re.M)
    assert statuses == ["0", "2", "3", "4", "5", "6", "130", "141"]
    epilog = build_parser().epilog or ""
    assert all(re.search(rf"\b{s} [a-z]", epilog) for s in statuses), epilog
