"""The C sources compiled at run time ship with the installed package."""

from __future__ import annotations

from pathlib import Path

import pytest

tomllib = pytest.importorskip("tomllib")  # Python 3.11+

ROOT = Path(__file__).parents[2]


def test_every_c_source_in_the_package_is_package_data() -> None:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    data = config["tool"]["setuptools"]["package-data"]
    listed = {
        (ROOT / package.replace(".", "/") / name).resolve()
        for package, names in data.items()
        for name in names
    }
    sources = {p.resolve() for p in (ROOT / "mmstab").rglob("*.c")}
    assert sources, "no C sources found under mmstab/"
    assert sources <= listed, sorted(str(p.relative_to(ROOT)) for p in sources - listed)
    assert all(p.is_file() for p in listed), "package-data names a file that does not exist"
