"""What a mechanism or an effect reads of a scene: :class:`SceneView`.

The line's :class:`~folder_line.core.line.scene.Scene` is one. Code below the line layer names
this protocol rather than the ``Scene`` class above it, so the core's layers run one way
(``numerics -> types -> mechanisms -> effects -> line -> supervision``).
"""

from __future__ import annotations

from typing import Any, Protocol

__all__ = ['SceneView']


class SceneView(Protocol):
    """A scene as the mechanisms and effects read it: its name, its effects, its machine sections."""

    @property
    def name(self) -> str:
        """The scene's name."""
        ...

    def has(self, effect: str) -> bool:
        """Whether the scene lists ``effect``."""
        ...

    def effect(self, name: str) -> Any:
        """Params of a listed effect, or None."""
        ...

    def machine(self, section: str) -> Any:
        """Params of a machine section (``Scene.machine`` types them by section; read them typed:
        ``p: ChainParams = scene.machine('delivery_chain')``)."""
        ...
