"""Room sizes: a review prompt at 400 lines a module and 80 a function, a limit at 1.5 times.

Modules split by concept, not by a line count: a module or function past the prompt is
listed as a warning (a reviewer's question: is this still one concept?), and only one past
the hard limit fails.
"""

from __future__ import annotations

import ast
import warnings

from conftest import ROOT

PACKAGE = ROOT / "mmstab"
#: Past these, a warning; past 1.5 times these, a failure.
PROMPT_MODULE_LINES, PROMPT_FUNCTION_LINES = 400, 80
LIMIT = 1.5


def measure(module_bar: int, function_bar: int) -> tuple[dict[str, int], dict[str, int]]:
    """Modules over ``module_bar`` lines and functions over ``function_bar`` lines."""
    modules, functions = {}, {}
    for path in sorted(PACKAGE.rglob("*.py")):
        name = path.relative_to(PACKAGE).as_posix()
        text = path.read_text()
        if len(text.splitlines()) > module_bar:
            modules[name] = len(text.splitlines())
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                lines = (node.end_lineno or node.lineno) - node.lineno + 1
                if lines > function_bar:
                    functions[f"{name}:{node.name}"] = lines
    return modules, functions


def test_no_module_or_function_past_the_limit():
    modules, functions = measure(PROMPT_MODULE_LINES, PROMPT_FUNCTION_LINES)
    for name, lines in {**modules, **functions}.items():
        warnings.warn(f"{name}: {lines} lines (review: one concept?)", stacklevel=1)
    hard = int(LIMIT * PROMPT_MODULE_LINES), int(LIMIT * PROMPT_FUNCTION_LINES)
    assert measure(*hard) == ({}, {})


def test_the_measure_counts_lines():
    modules, _ = measure(0, 10**9)
    assert modules["__init__.py"] == len((PACKAGE / "__init__.py").read_text().splitlines())
