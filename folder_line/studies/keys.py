"""Scene keys as the studies vary them: checked against the scene, read back, and their units.

A study varies any key ``--set`` accepts for the scene. The one source of what those keys are,
their units, the scene's values and their ranges is :func:`folder_line.config.keys.scene_keys`
(what ``simulate --list-keys`` prints); here they are looked up by name, and a key the scene
does not have, or never reads, is refused before any work in the words of the option that
named it.
"""

from __future__ import annotations

from collections.abc import Mapping

from folder_line.config.keys import KeyInfo, inert_keys, scene_keys
from folder_line.config.scenes import apply_overrides
from folder_line.errors import ParameterError

__all__ = ['check_key', 'key_info', 'key_unit', 'scene_value']


def key_info(source: Mapping[str, object], key: str, option: str) -> KeyInfo:
    """What ``simulate --list-keys`` says of ``key`` in the scene ``source``.

    Parameters
    ----------
    source : mapping
        The complete scene mapping (:func:`folder_line.config.scenes.scene_mapping`).
    key : str
        ``SECTION.FIELD`` (or ``seed``, ``sample_rate``) as ``--set`` takes it.
    option : str
        The option that named it (``--vary``, ``--find``), for the error.

    Raises
    ------
    ParameterError
        Naming ``option`` and ``key``: a section the scene does not have, a field its section does not
        have, or a key the scene never reads (with why).
    """
    known = {info.key: info for info in scene_keys(source)}
    if key in known:
        return known[key]
    why = inert_keys(source).get(key)
    if why is not None:
        raise ParameterError(option, key, why)
    try:  # the loader's own words for a section the scene lacks
        apply_overrides(source, {key: 0.0})
    except ParameterError as exc:
        raise ParameterError(option, key, exc.reason) from None
    head = key.partition('.')[0]
    fields = [k.partition('.')[2] for k in known if k.partition('.')[0] == head]
    has = f'; it has {", ".join(fields)}' if fields else ''
    raise ParameterError(option, key, f'{head} has no parameter {key.partition(".")[2]!r}{has}')


def check_key(source: Mapping[str, object], key: str, option: str) -> None:
    """Refuse, before any work, a key the scene does not have (:func:`key_info`)."""
    key_info(source, key, option)


def scene_value(source: Mapping[str, object], key: str) -> object:
    """The value the scene itself gives ``key`` (its file, the defaults and ``--set`` merged), or None."""
    try:
        return key_info(source, key, 'key').value
    except ParameterError:
        return None


def key_unit(source: Mapping[str, object], key: str) -> str:
    """Unit of a scene key (``'m/s'`` for ``feed_transporter.V_tr``); '' for a ratio, a count or a name."""
    try:
        return key_info(source, key, 'key').unit
    except ParameterError:
        return ''
