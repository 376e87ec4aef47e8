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
