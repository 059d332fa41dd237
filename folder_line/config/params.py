"""Load the mechanisms' parameters: defaults from ``config/`` merged with a user file.

The defaults live only in ``config/<kind>.yaml``; the frozen dataclasses of the
core carry no defaults of their own, so there is one place to change them.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Literal, overload

from folder_line.core.line.scene import MACHINES, MachineParams
from folder_line.core.mechanisms.cyclogram import CyclogramParams
from folder_line.core.mechanisms.delivery import DeliveryParams
from folder_line.core.mechanisms.knife import KnifeParams
from folder_line.core.mechanisms.layup import LayupParams
from folder_line.core.numerics.validate import build
from folder_line.core.types.machines import ContainerParams
from folder_line.errors import ParameterError
from folder_line.files.yamlio import load_yaml_file

__all__ = ['KINDS', 'config_dir', 'load_container', 'load_params', 'read_yaml_mapping']

#: the mechanisms ``folder-line kinematics`` samples: machine sections of :data:`folder_line.core.line.scene.MACHINES`
KINDS: tuple[str, ...] = ('layup', 'knife', 'delivery', 'cyclogram')


def config_dir() -> Path:
    """Directory holding the default ``*.yaml`` files.

    Looked up, in order: ``$FOLDER_LINE_CONFIG``; ``config/`` beside the
    package source (a checkout or an editable install); ``share/folder_line/config``
    under the interpreter prefix (pip or colcon install); the ament index.
    """
    candidates: list[Path] = []
    env = os.environ.get('FOLDER_LINE_CONFIG')
    if env:
        candidates.append(Path(env))
    candidates.append(Path(__file__).resolve().parents[2] / 'config')
    candidates.append(Path(sys.prefix) / 'share' / 'folder_line' / 'config')
    try:  # a real ROS 2 install
        from ament_index_python.packages import get_package_share_directory

        candidates.append(Path(get_package_share_directory('folder_line')) / 'config')
    except Exception:
        pass
    for c in candidates:
        if (c / 'layup.yaml').is_file():
            return c
    msg = 'no folder_line config directory found; looked in ' + ', '.join(str(c) for c in candidates)
    raise FileNotFoundError(msg)


def read_yaml_mapping(path: Path, what: str) -> dict[str, object]:
    """Read a YAML file that must hold a mapping (an empty file is an empty mapping).

    Read by :func:`folder_line.files.yamlio.load_yaml_file`: a regular UTF-8 file of at most
    1 MiB, no tags, no duplicate keys, aliases bounded; errors name the line and column.
    """
    data = load_yaml_file(path, what)
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ParameterError(what, str(path), 'must be a YAML mapping of key: value')
    return data


@overload
def load_params(
    kind: Literal['layup'], path: str | os.PathLike[str] | None = None, overrides: Mapping[str, object] | None = None
) -> LayupParams: ...
@overload
def load_params(
    kind: Literal['knife'], path: str | os.PathLike[str] | None = None, overrides: Mapping[str, object] | None = None
) -> KnifeParams: ...
@overload
def load_params(
    kind: Literal['delivery'], path: str | os.PathLike[str] | None = None, overrides: Mapping[str, object] | None = None
) -> DeliveryParams: ...
@overload
def load_params(
    kind: Literal['cyclogram'],
    path: str | os.PathLike[str] | None = None,
    overrides: Mapping[str, object] | None = None,
) -> CyclogramParams: ...
@overload
def load_params(
    kind: str, path: str | os.PathLike[str] | None = None, overrides: Mapping[str, object] | None = None
) -> MachineParams: ...


def load_params(
    kind: str, path: str | os.PathLike[str] | None = None, overrides: Mapping[str, object] | None = None
) -> MachineParams:
    """Validated parameters of one mechanism.

    Parameters
    ----------
    kind : {'layup', 'knife', 'delivery', 'cyclogram'}
        Which mechanism.
    path : path-like, optional
        YAML file with any subset of the keys; the rest come from the defaults.
    overrides : mapping, optional
        Applied last (e.g. from the command line).

    Raises
    ------
    ParameterError
        Unknown key, wrong type, out of range; the message names the key and value.
    """
    if kind not in KINDS:
        raise ParameterError('kind', kind, f'must be one of {", ".join(KINDS)}')
    values = read_yaml_mapping(config_dir() / f'{kind}.yaml', f'{kind} defaults')
    values.update(read_yaml_mapping(Path(path), '--params') if path is not None else {})
    values.update(overrides or {})
    return build(MACHINES[kind], values, kind, f'{kind} parameter')


def load_container(overrides: Mapping[str, object] | None = None) -> ContainerParams:
    """The container the layup lays the leaves into (``config/container.yaml``; the layup's frame),
    with ``overrides`` (``{'x_left': 0.1}``) applied last.

    Raises
    ------
    ParameterError
        An unknown key or a value out of range (the message names the key and value).
    """
    values = read_yaml_mapping(config_dir() / 'container.yaml', 'container defaults')
    values.update(overrides or {})
    return build(ContainerParams, values, 'container', 'container parameter')
