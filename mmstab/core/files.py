"""Loading and validating YAML inputs, and writing results atomically.

Inputs are checked once, here, at the boundary: every later stage trusts what it is
handed. A bad file raises :class:`ConfigError` whose message names the file and the
field; the command line turns it into one line on stderr and exit status 2.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
import zipfile
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import jsonschema
import numpy as np
import yaml

from mmstab.core.hints import (
    DEGREES_LIKELY,
    degrees_given,
    did_you_mean,
    unit_hint,
    unknown_keys,
)


class MmstabError(Exception):
    """An error the user can fix; reported as one line, without a traceback."""


class UnstableError(MmstabError):
    """The physics cannot hold: the best plan or the tracked robot tips (exit status 3)."""

    exit_status = 3


class PlanningError(MmstabError):
    """The planner gave up or no plan exists: not bad input, not a verdict (exit status 6)."""

    exit_status = 6


def refuse_degrees(name: str, value: float) -> None:
    """Refuse an option's angle of ``|value| > 2 pi`` given where radians are expected.

    Args:
        name: the option as the user wrote it (``--flipper``, ``--mount: yaw``).
        value: the angle given [rad].

    Raises:
        MmstabError: naming the option, the unit and the value in radians.
    """
    if abs(value) > DEGREES_LIKELY:
        raise MmstabError(
            f"{name}: {value:g} looks like degrees; the unit is radians "
            f"({value:g} deg = {math.radians(value):.4g} rad)"
        )


class ConfigError(MmstabError):
    """A problem or robot file is invalid.

    Args:
        path: the file at fault.
        field: dotted path of the field at fault (``arm.links[2].mass``), or "" for the file.
        message: what is wrong.
    """

    def __init__(self, path: str | os.PathLike[str], field: str, message: str):
        self.path = str(path)
        self.field = field
        self.message = message
        where = f"{self.path}: {field}" if field else self.path
        super().__init__(f"{where}: {message}")


def _field_path(parts: Iterator[Any] | list[Any]) -> str:
    out = ""
    for p in parts:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out


#: Most YAML nodes a file may expand to, aliases counted at every use [-]. A "billion
#: laughs" file (aliases of aliases) is small on disk but expands exponentially when its
#: data is walked; it is refused while still a node graph.
MAX_YAML_NODES = 1_000_000


def _expanded_size(node: yaml.Node, memo: dict[int, int]) -> int:
    """Nodes of ``node``'s tree with every alias expanded (linear time: shared nodes memoised)."""
    key = id(node)
    if key not in memo:
        memo[key] = 1  # a recursive alias counts once (the constructor refuses it anyway)
        if isinstance(node, yaml.SequenceNode):
            memo[key] = 1 + sum(_expanded_size(n, memo) for n in node.value)
        elif isinstance(node, yaml.MappingNode):
            memo[key] = 1 + sum(
                _expanded_size(k, memo) + _expanded_size(v, memo) for k, v in node.value
            )
    return memo[key]


class _DuplicateKey(ValueError):
    """A key given twice in one mapping (PyYAML would keep the last silently)."""

    def __init__(self, key: str, first: int, again: int):
        self.key = key
        super().__init__(f"given twice in one mapping (lines {first} and {again})")


def _check_unique_keys(node: yaml.Node, seen: set[int]) -> None:
    """Raise :class:`_DuplicateKey` at the first mapping of ``node`` that repeats a key."""
    if id(node) in seen:  # an alias: checked where it was anchored
        return
    seen.add(id(node))
    if isinstance(node, yaml.MappingNode):
        lines: dict[str, int] = {}
        for k, _ in node.value:
            if isinstance(k, yaml.ScalarNode) and k.value != "<<":  # merge keys may repeat
                line = k.start_mark.line + 1
                if k.value in lines:
                    raise _DuplicateKey(k.value, lines[k.value], line)
                lines[k.value] = line
    if isinstance(node, (yaml.MappingNode, yaml.SequenceNode)):
        for child in node.value:
            for n in child if isinstance(child, tuple) else (child,):
                _check_unique_keys(n, seen)


def _safe_load_bounded(text: str) -> Any:
    """``yaml.safe_load`` that refuses documents expanding past :data:`MAX_YAML_NODES`."""
    loader = yaml.SafeLoader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        size = _expanded_size(node, {})
        if size > MAX_YAML_NODES:
            raise ValueError(
                f"expands to more than {MAX_YAML_NODES:,} YAML nodes through its aliases "
                f"({size:.3g})"
            )
        _check_unique_keys(node, set())
        return loader.construct_document(node)
    finally:
        loader.dispose()


def read_yaml(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read a YAML mapping from ``path``, or raise :class:`ConfigError`."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise ConfigError(p, "", f"cannot read file ({exc.strerror})") from None
    except UnicodeDecodeError as exc:  # binary bytes, or another encoding: YAML is UTF-8 here
        raise ConfigError(p, "", f"not UTF-8 text (byte {exc.start}): not a YAML file") from None
    try:
        data = _safe_load_bounded(text)
    except _DuplicateKey as exc:
        raise ConfigError(p, exc.key, str(exc)) from None
    except ValueError as exc:
        raise ConfigError(p, "", str(exc)) from None
    except yaml.reader.ReaderError as exc:  # a control character (NUL, ...) in the text
        c = exc.character if isinstance(exc.character, int) else ord(exc.character)
        msg = f"character {exc.position}: U+{c:04X} is not allowed in YAML"
        raise ConfigError(p, "", msg) from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}" if mark is not None else "YAML"
        raise ConfigError(p, "", f"{where}: not valid YAML") from None
    if not isinstance(data, dict):
        raise ConfigError(p, "", "expected a mapping at the top level")
    return data


#: Largest integer a file may hold: NumPy's 64-bit integers hold it (seeds, counts), and a
#: float too (a YAML integer of 400 digits would overflow both).
MAX_INTEGER = 2**63 - 1


def _check_finite(path: Path, node: Any, trail: list[Any]) -> None:
    if isinstance(node, float) and not math.isfinite(node):
        raise ConfigError(path, _field_path(trail), f"must be a finite number, got {node}")
    if isinstance(node, int) and abs(node) > MAX_INTEGER:
        msg = f"integer of {len(str(abs(node)))} digits; at most 2**63 - 1"
        raise ConfigError(path, _field_path(trail), msg)
    if isinstance(node, dict):
        for k, v in node.items():
            _check_finite(path, v, [*trail, k])
    elif isinstance(node, list):
        for i, v in enumerate(node):
            _check_finite(path, v, [*trail, i])


def _branch_errors(err: Any) -> list[Any]:
    """A ``oneOf`` error of a mapping whose ``type`` names one branch: that branch's errors.

    Without it jsonschema may report another branch's complaint (a capsule with a typo
    read as "'box' was expected").
    """
    kinds = _kinds(err)
    chosen = [i for i, k in enumerate(kinds) if k == err.instance.get("type")]
    if len(chosen) != 1:
        return [err]
    sub = [e for e in err.context if e.relative_schema_path[0] == chosen[0]]
    return [b for e in sub for b in _branch_errors(e)] or [err]


def validate(path: str | os.PathLike[str], data: dict[str, Any], schema: dict[str, Any]) -> None:
    """Validate ``data`` (read from ``path``) against a JSON schema; NaN/inf are rejected.

    Raises:
        ConfigError: naming the first offending field (the deepest error jsonschema reports).
    """
    p = Path(path)
    _check_finite(p, data, [])
    angle = degrees_given(data, schema, [])
    if angle is not None:
        raise ConfigError(p, _field_path(angle[0]), angle[1])
    validator = jsonschema.Draft202012Validator(schema)
    found = [b for e in validator.iter_errors(data) for b in _branch_errors(e)]
    errors = sorted(found, key=lambda e: (-len(e.absolute_path), str(e.absolute_path)))
    if not errors:
        return
    err = jsonschema.exceptions.best_match(errors) or errors[0]
    field = _field_path(list(err.absolute_path))
    unknown = unknown_keys(err)
    if unknown and err.validator in ("additionalProperties", "required"):
        # a misspelt key is both unknown and missing: name the key the file has, and the
        # closest valid one (``waypionts``, not "path.center: missing required key")
        known = list(err.schema.get("properties", {}))
        field = _field_path([*err.absolute_path, unknown[0]])
        msg = "unknown key" + did_you_mean(unknown[0], known)
    elif err.validator == "required":
        missing = [r for r in err.validator_value if r not in err.instance]
        field = _field_path([*err.absolute_path, missing[0]])
        what = err.schema.get("properties", {}).get(missing[0], {}).get("description")
        msg = "missing required key" + (f": {what}" if what else "")  # what it is, its unit
    elif _kinds(err):  # a mapping of no known ``type``: name the kinds, not the mapping
        field = _field_path([*err.absolute_path, "type"])
        msg = f"must be one of {', '.join(_kinds(err))}"
    else:
        msg = err.message + unit_hint(err.schema)
    raise ConfigError(p, field, msg)


def check_known_keys(
    path: str | os.PathLike[str], field: str, mapping: Any, known: Sequence[str]
) -> None:
    """Refuse a key of ``mapping`` that none of the section's forms knows, naming the closest.

    For sections told apart by their keys (``path``: a circle or a route; ``terrain``): a
    misspelt key that selects the wrong form would otherwise be reported as another form's
    missing key.

    Raises:
        ConfigError: ``field.key: unknown key; did you mean 'X'?``.
    """
    if not isinstance(mapping, dict):
        return
    for key in sorted(str(k) for k in mapping):
        if key not in known:
            raise ConfigError(path, f"{field}.{key}", "unknown key" + did_you_mean(key, known))


def _kinds(err: Any) -> list[str]:
    """The ``type`` names of a ``oneOf`` over mappings told apart by ``type`` (else [])."""
    if err.validator not in ("oneOf", "anyOf") or not isinstance(err.instance, dict):
        return []
    kinds = [
        b.get("properties", {}).get("type", {}).get("const") if isinstance(b, dict) else None
        for b in err.validator_value
    ]
    return [str(k) for k in kinds] if all(isinstance(k, str) for k in kinds) else []


def check_order(path: Path, field: str, lower: float, upper: float) -> None:
    """Raise :class:`ConfigError` unless ``lower < upper`` (an inverted or empty limit)."""
    if not lower < upper:
        raise ConfigError(path, field, f"lower limit {lower} must be below upper limit {upper}")


# ---------------------------------------------------------------------------- writing results
def writable_dir_problem(path: str | os.PathLike[str]) -> str | None:
    """Why files cannot be written in folder ``path`` (created if missing), or None.

    Looks at the nearest existing folder on the way up: it must be a folder and accept a
    new file (a probe file is created and removed there). Nothing else is created.
    """
    p = Path(path)
    probe = p
    while not probe.exists() and not probe.is_symlink() and probe.parent != probe:
        probe = probe.parent
    if not probe.is_dir():
        return f"{probe} is not a folder"
    try:
        fd, tmp = tempfile.mkstemp(dir=probe, prefix=".mmstab-probe-")
    except OSError as exc:
        return f"cannot write in {probe} ({exc.strerror or exc})"
    os.close(fd)
    os.unlink(tmp)
    return None


def check_output_dir(path: str | os.PathLike[str], what: str = "output folder") -> Path:
    """Refuse, before any work, an output folder that cannot be created or written.

    Raises:
        MmstabError: one line naming the folder and why.
    """
    why = writable_dir_problem(path)
    if why is not None:
        raise MmstabError(f"{what} {path}: {why}")
    return Path(path)


def _atomic(path: Path, write: Callable[[Path], None]) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    umask = os.umask(0)
    os.umask(umask)
    tmp = ""
    try:
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=path.suffix)
        os.close(fd)
        write(Path(tmp))
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; results are ordinary files
        os.replace(tmp, path)
    except BaseException:  # KeyboardInterrupt too: never a half-written file
        if tmp:
            Path(tmp).unlink(missing_ok=True)
        raise
    return path


def _write_text(path: Path, text: str) -> None:
    path.write_text(text)


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serialisable: {type(obj)}")


def write_text(path: str | os.PathLike[str], text: str) -> Path:
    """Write ``text`` to ``path``, atomically (temp file + rename)."""
    return _atomic(Path(path), lambda t: _write_text(t, text))


def write_json(path: str | os.PathLike[str], data: Any) -> Path:
    """Write ``data`` as indented JSON, atomically (temp file + rename)."""
    text = json.dumps(data, indent=2, default=_jsonable, allow_nan=False) + "\n"
    return _atomic(Path(path), lambda t: _write_text(t, text))


#: zlib level of :func:`write_npz`: level 1 writes a roadmap's arrays 4 times as fast as
#: NumPy's level 6 (0.22 s against 0.95 s) for a file 3 % larger (8.2 MB against 8.0 MB).
NPZ_LEVEL = 1


def write_npz(path: str | os.PathLike[str], **arrays: Any) -> Path:
    """Write arrays to a compressed ``.npz`` (what ``np.load`` reads), atomically."""

    def _w(t: Path) -> None:
        with zipfile.ZipFile(t, "w", zipfile.ZIP_DEFLATED, compresslevel=NPZ_LEVEL) as z:
            for name, value in arrays.items():
                with z.open(f"{name}.npy", "w", force_zip64=True) as fh:
                    np.lib.format.write_array(fh, np.asanyarray(value), allow_pickle=True)

    return _atomic(Path(path), _w)


def write_npy(path: str | os.PathLike[str], array: Any) -> Path:
    """Write one array to an uncompressed ``.npy`` (memory-mappable), atomically."""

    def _w(t: Path) -> None:
        with open(t, "wb") as fh:
            np.save(fh, np.asarray(array))

    return _atomic(Path(path), _w)


def write_figure(path: str | os.PathLike[str], fig: Any, dpi: int = 110) -> Path:
    """Save a matplotlib figure as PNG, atomically, and close it."""
    import matplotlib.pyplot as plt

    def _w(t: Path) -> None:
        fig.savefig(t, dpi=dpi, format="png", bbox_inches="tight")

    try:
        return _atomic(Path(path), _w)
    finally:
        plt.close(fig)


def write_yaml(path: str | os.PathLike[str], data: Any) -> Path:
    """Write ``data`` as YAML, atomically (used to save the settings beside results)."""
    text = yaml.safe_dump(data, sort_keys=False)
    return _atomic(Path(path), lambda t: _write_text(t, text))
