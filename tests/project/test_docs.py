"""The documentation's Python examples run as written, and no document points outside."""

from __future__ import annotations

import json
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
    assert len(blocks) == 10
    env = {**os.environ, "MPLBACKEND": "Agg"}
    # one interpreter, each block in a namespace of its own (a name one block needs and
    # another defines fails): a process per block cost 1 s of imports each
    out = subprocess.run(
        [sys.executable, "-c", _EACH_BLOCK, json.dumps(blocks)],
        cwd=ROOT, env=env, capture_output=True, text=True,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr[-3000:]
    assert out.stdout.splitlines()[-1] == f"ran {len(blocks)}"


#: Runs the blocks given as a JSON list, each with fresh globals, as ``python -c`` would.
_EACH_BLOCK = r"""
import json, sys, traceback
blocks = json.loads(sys.argv[1])
for i, code in enumerate(blocks):
    try:
        exec(compile(code, f"<docs/api.md block {i + 1}>", "exec"), {"__name__": "__main__"})
    except BaseException:
        sys.exit(f"block {i + 1}:\n{code}\n{traceback.format_exc()}")
print(f"ran {len(blocks)}")
"""


def pages():
    """Every Markdown page: README, CHANGELOG and docs/."""
    return [ROOT / "README.md", ROOT / "CHANGELOG.md", *sorted((ROOT / "docs").glob("*.md"))]


def test_docs_and_readme_point_inside_the_repository():
    for path in pages():
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
    for path in pages():
        for target, anchor in re.findall(r"\]\(([^)#\s]*)#([^)\s]+)\)", path.read_text()):
            if "://" in target:
                continue
            to = (path.parent / target) if target else path
            assert anchor in set(anchors(to)), f"{path.name}: no heading for {target}#{anchor}"
            checked += 1
    assert checked >= 20  # README and docs link into each other's sections


def test_anchor_slugs_follow_github():
    doc = ROOT / "docs" / "terrain.md"
    assert "the-resting-pose-mmstabterrainrest" in set(anchors(doc))
    assert "speed-make-bench-terrain" in set(anchors(doc))


def test_help_names_every_exit_status_of_the_cli_doc():
    from mmstab.cli import build_parser

    table = (ROOT / "docs" / "cli.md").read_text().split("## Exit statuses", 1)[1]
    statuses = re.findall(r"^\| (\d+) \|", table.split("\n## ", 1)[0], re.M)
    assert statuses == ["0", "2", "3", "4", "5", "6", "130", "141"]
    epilog = build_parser().epilog or ""
    assert all(re.search(rf"\b{s} [a-z]", epilog) for s in statuses), epilog


#: A quoted number's source: ``<!-- results/X.json: key.path[0].key -->1.23`` (optionally
#: ``@min`` / ``@max`` of a list, and ``* 100`` after the key path, for a percentage or a
#: unit change). The number right after the marker is the quote; it must equal the JSON's
#: value to the quote's decimals.
QUOTE = re.compile(
    r"<!-- (results/[\w./-]+\.json): ([\w.\[\]@]+)(?:\s*\*\s*([0-9.e+-]+))? -->"
    r"\s*(?:\*\*)?(-?\d[\d,]*(?:\.\d+)?)"
)


def json_value(data, path: str):
    """``a.b[0].c`` in nested dicts and lists (``a[1.0]``: a key with a dot); ``a.b@min``
    the least of a list."""
    path, _, reduce = path.partition("@")
    for key, bracket in re.findall(r"([^.\[\]]+)|\[([^\]]+)\]", path):
        if bracket:
            data = data[int(bracket)] if isinstance(data, list) else data[bracket]
        else:
            data = data[key]
    return {"": lambda v: v, "min": min, "max": max}[reduce](data)


def quoted_numbers(path):
    """(marker, quoted text, value from the JSON) of every marked number of a page."""
    import json

    text = path.read_text()
    assert text.count("<!-- results/") == len(QUOTE.findall(text)), f"{path.name}: a bad marker"
    for m in QUOTE.finditer(text):
        source, key, scale, quote = m.groups()
        value = json_value(json.loads((ROOT / source).read_text()), key)
        yield m.group(0), quote, float(value) * (float(scale) if scale else 1.0)


def test_every_marked_number_is_its_source():
    checked: dict[str, int] = {}
    for path in pages():
        if path.name == "CHANGELOG.md":
            continue  # its numbers are those of their day
        for marker, quote, value in quoted_numbers(path):
            decimals = len(quote.split(".")[1]) if "." in quote else 0
            tolerance = 0.5 * 10.0**-decimals + 1e-9
            assert abs(float(quote.replace(",", "")) - value) <= tolerance, (
                f"{path.name}: {marker!r} quotes {quote}, the source says {value:.6g}"
            )
            checked[path.name] = checked.get(path.name, 0) + 1
    assert checked.get("README.md", 0) >= 12, checked  # every feature's number


def test_the_number_check_catches_a_stale_quote(tmp_path, monkeypatch):
    page = tmp_path / "page.md"
    marker = "<!-- results/verdicts/summary.json: models.rigid.agree -->"
    page.write_text(f"agrees in {marker}571 cases")  # the summary says 572
    [(_, quote, value)] = list(quoted_numbers(page))
    assert quote == "571" and value == 572.0


def test_pages_are_short_and_name_no_tracker_issue():
    """The README reads in minutes, a docs page is one topic; history is CHANGELOG.md's."""
    assert len((ROOT / "README.md").read_text().splitlines()) <= 200
    for path in sorted((ROOT / "docs").glob("*.md")):
        assert len(path.read_text().splitlines()) <= 400, f"{path.name}: split it by topic"
    for path in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        hits = re.findall(r"\bissues? \d+", path.read_text(), re.I)
        assert not hits, f"{path.name}: tracker issue numbers {hits}"


def test_the_code_names_no_tracker_issue():
    """A reader of the repository has no tracker: code, tests and problem files say why."""
    folders = ("mmstab", "experiments", "tests", "benchmarks", "examples", "problems")
    hits = []
    for folder in folders:
        for path in sorted((ROOT / folder).rglob("*")):
            if path.suffix in (".py", ".c", ".yaml", ".md") and path.is_file():
                found = re.findall(r"\bissues? #?\d+", path.read_text(errors="ignore"), re.I)
                hits += [f"{path.relative_to(ROOT)}: {h}" for h in found]
    assert not hits, hits
