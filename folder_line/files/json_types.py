"""The types of JSON documents as the package writes them."""

from __future__ import annotations

from typing import TypeAlias

__all__ = ['JsonObject', 'JsonValue']
JsonValue: TypeAlias = 'bool | int | float | str | list[JsonValue] | dict[str, JsonValue] | None'
#: a JSON object: key -> value, in the order written
JsonObject: TypeAlias = 'dict[str, JsonValue]'
