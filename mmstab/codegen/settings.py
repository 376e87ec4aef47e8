"""The ``codegen:`` section: settings and the plugin check (before CasADi is called)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from mmstab.config import ConfigError, MmstabError
from mmstab.controller.settings import CODEGEN_PLUGINS

QPOASES_MESSAGE = "CasADi cannot generate C for qpOASES; use qrqp, daqp or osqp"


@dataclasses.dataclass(frozen=True)
class CodegenSettings:
    """The ``codegen:`` section of a problem file.

    Attributes:
        plugin: QP plugin to generate C for, one of :data:`CODEGEN_PLUGINS`.
        directory: output root; a plugin's files go to ``directory/plugin`` [path].
    """

    plugin: str
    directory: str

    @classmethod
    def from_section(cls, section: Mapping[str, Any]) -> CodegenSettings:
        """Build from a validated ``codegen:`` section."""
        return cls(plugin=str(section["plugin"]), directory=str(section["directory"]))


def check_plugin(plugin: str) -> None:
    """Raise :class:`MmstabError` unless CasADi can generate C for ``plugin``."""
    if plugin == "qpoases":
        raise MmstabError(QPOASES_MESSAGE)
    if plugin not in CODEGEN_PLUGINS:
        raise MmstabError(f"unknown QP plugin {plugin!r}; choose one of {CODEGEN_PLUGINS}")


def check_settings(path: Path, section: Mapping[str, Any]) -> None:
    """Semantic check of the ``codegen:`` section (a plugin CasADi can generate C for).

    Raises:
        ConfigError: naming ``codegen.plugin``.
    """
    try:
        check_plugin(str(section["plugin"]))
    except MmstabError as exc:
        raise ConfigError(path, "codegen.plugin", str(exc)) from None
