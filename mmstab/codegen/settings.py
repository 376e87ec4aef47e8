"""The ``codegen:`` section: settings (the plugin check: :mod:`mmstab.core.setting_checks`)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

from mmstab.core.setting_checks import CODEGEN_PLUGINS as CODEGEN_PLUGINS  # re-exported
from mmstab.core.setting_checks import QPOASES_MESSAGE as QPOASES_MESSAGE
from mmstab.core.setting_checks import check_codegen
from mmstab.core.setting_checks import check_plugin as check_plugin


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


#: The ``codegen:`` check of the settings registry
#: (:func:`mmstab.core.setting_checks.check_codegen`).
check_settings = check_codegen
