"""Small rooms: no module over 400 lines, no function over 80 (issue 27).

The offenders still left are listed with their current length; the test fails on any new
one and on a listed one that grows (a listed one that shrinks under the bar must leave the
list, so the list only ever gets shorter).
"""

from __future__ import annotations

import ast

from conftest import ROOT

PACKAGE = ROOT / "mmstab"
MAX_MODULE_LINES, MAX_FUNCTION_LINES = 400, 80

#: Modules still over the bar: path -> lines.
LONG_MODULES: dict[str, int] = {}
#: Functions still over the bar: "path:function" -> lines.
LONG_FUNCTIONS: dict[str, int] = {}


def measure() -> tuple[dict[str, int], dict[str, int]]:
    modules, functions = {}, {}
    for path in sorted(PACKAGE.rglob("*.py")):
        name = path.relative_to(PACKAGE).as_posix()
        text = path.read_text()
        if len(text.splitlines()) > MAX_MODULE_LINES:
            modules[name] = len(text.splitlines())
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                lines = (node.end_lineno or node.lineno) - node.lineno + 1
                if lines > MAX_FUNCTION_LINES:
                    functions[f"{name}:{node.name}"] = lines
    return modules, functions


def test_no_new_long_module_or_function_and_none_grows():
    modules, functions = measure()
    assert set(modules) == set(LONG_MODULES), "update LONG_MODULES: only ever remove entries"
    assert set(functions) == set(LONG_FUNCTIONS), "update LONG_FUNCTIONS: only ever remove"
    assert all(modules[m] <= LONG_MODULES[m] for m in modules)
    assert all(functions[f] <= LONG_FUNCTIONS[f] for f in functions)
