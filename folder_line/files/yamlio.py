"""Bounded reading of the YAML files a user hands us: scenes, parameters, bag metadata.

Every read is bounded before it starts:

- the file must be a regular file (a FIFO or a device would block or never end) of at
  most ``limit`` bytes (:data:`TEXT_LIMIT` for scenes and parameters,
  :data:`METADATA_LIMIT` for a bag's ``metadata.yaml``);
- it must be UTF-8 (a UTF-8 byte-order mark is allowed; UTF-16 is named as such);
- :class:`BoundedLoader`, a PyYAML ``SafeLoader``, refuses explicit tags (``!!python/...``,
  ``!!binary``, ``!custom``), duplicate keys, more than :data:`MAX_ALIASES` aliases,
  nesting deeper than :data:`MAX_DEPTH` and documents that would expand to more than
  ``max_nodes`` nodes (a "billion laughs" bomb fails at composition, in bounded memory),
  and integers of more than :data:`MAX_INT_DIGITS` digits.

Every failure is a :class:`~folder_line.errors.InputFileError` (a ``ParameterError``)
whose message is one line naming the file, the line and the column (1-based), e.g.
``--scene='s.yaml': line 3, column 5: duplicate key 'V_tr' (first at line 2)``.
"""

from __future__ import annotations

import errno
import os
import stat
from collections.abc import Hashable
from pathlib import Path
from typing import NoReturn

import yaml
from yaml.constructor import ConstructorError
from yaml.nodes import MappingNode, Node, ScalarNode, SequenceNode

from folder_line.errors import InputFileError, bounded_repr, shorten
from folder_line.files.atomic import file_kind

__all__ = [
    'MAX_ALIASES',
    'MAX_DEPTH',
    'MAX_INT_DIGITS',
    'MAX_NODES',
    'METADATA_LIMIT',
    'TEXT_LIMIT',
    'BoundedLoader',
    'load_yaml',
    'load_yaml_file',
    'read_text_bounded',
]

#: largest scene or parameter file, bytes (the shipped ones are under 4 kB)
TEXT_LIMIT = 1 << 20
#: largest bag ``metadata.yaml``, bytes (it carries the scene and one entry per segment)
METADATA_LIMIT = 16 << 20
#: most aliases (``*name``) in one document; the shipped files use none
MAX_ALIASES = 64
#: deepest nesting of sequences and mappings
MAX_DEPTH = 32
#: most nodes of a document with every alias expanded (the default of :func:`load_yaml`)
MAX_NODES = 100_000
#: longest integer literal, digits (Python refuses ``int()`` of more than 4300)
MAX_INT_DIGITS = 100

_MERGE_TAG = 'tag:yaml.org,2002:merge'


class _Refused(yaml.MarkedYAMLError):
    """A document the bounded loader will not build (carries the position)."""


class BoundedLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` that refuses tags, duplicate keys and alias bombs.

    ``max_nodes`` bounds the document's size with every alias expanded: a node's weight
    is 1 plus its children's weights, an alias weighs what its anchor does, and the
    composition stops as soon as a weight passes the bound, before anything is built.
    """

    max_nodes = MAX_NODES

    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self._weights: dict[int, int] = {}
        self._aliases = 0
        self._depth = 0

    def _refuse(self, problem: str, event: yaml.Event) -> NoReturn:
        # a SafeLoader (pure Python) event carries a yaml.error.Mark; the stubs' Event also allows the C parser's
        raise _Refused(problem=problem, problem_mark=event.start_mark)  # type: ignore[arg-type]

    def compose_node(self, parent: Node | None, index: object) -> Node:
        # types-PyYAML leaves Parser.peek_event unannotated; it returns the next Event
        event: yaml.Event = self.peek_event()  # type: ignore[no-untyped-call]
        if isinstance(event, yaml.AliasEvent):
            self._aliases += 1
            if self._aliases > MAX_ALIASES:
                self._refuse(f'more than {MAX_ALIASES} aliases', event)
        else:
            tag = getattr(event, 'tag', None)
            if tag is not None:
                self._refuse(f'tag {shorten(tag, 40)!r} not allowed (plain YAML only)', event)
        self._depth += 1
        if self._depth > MAX_DEPTH:
            self._refuse(f'nested deeper than {MAX_DEPTH} levels', event)
        try:
            # types-PyYAML says index: int; PyYAML passes None (document, mapping key) or the key node
            node = super().compose_node(parent, index)  # type: ignore[arg-type]
        finally:
            self._depth -= 1
        assert node is not None, 'PyYAML composes a node for every node event (types-PyYAML: Node | None)'
        if isinstance(event, yaml.AliasEvent):
            if id(node) not in self._weights:
                self._refuse('alias to an anchor that contains it (recursive)', event)
            return node
        if isinstance(node, ScalarNode):
            weight = 1
        elif isinstance(node, SequenceNode):
            weight = 1 + sum(self._weights[id(c)] for c in node.value)
        else:
            weight = 1 + sum(self._weights[id(k)] + self._weights[id(v)] for k, v in node.value)
        if weight > self.max_nodes:
            self._refuse(f'expands to more than {self.max_nodes} nodes (aliases of aliases?)', event)
        self._weights[id(node)] = weight
        return node

    def construct_mapping(self, node: MappingNode, deep: bool = False) -> dict[Hashable, object]:
        seen: dict[Hashable, Node] = {}
        for key_node, _ in node.value:
            if key_node.tag == _MERGE_TAG:
                continue
            key = self.construct_object(key_node, deep=True)
            try:
                first = seen.setdefault(key, key_node)
            except TypeError:
                raise ConstructorError(None, None, 'a key must be a plain value', key_node.start_mark) from None
            if first is not key_node:
                raise ConstructorError(
                    None,
                    None,
                    f'duplicate key {bounded_repr(key, 40)} (first at line {first.start_mark.line + 1})',
                    key_node.start_mark,
                )
        return super().construct_mapping(node, deep=deep)

    def construct_yaml_int(self, node: ScalarNode) -> int:
        digits = sum(ch.isalnum() for ch in str(node.value))
        if digits > MAX_INT_DIGITS:
            raise ConstructorError(
                None, None, f'integer of {digits} digits (at most {MAX_INT_DIGITS})', node.start_mark
            )
        return super().construct_yaml_int(node)


BoundedLoader.add_constructor('tag:yaml.org,2002:int', BoundedLoader.construct_yaml_int)


def read_text_bounded(path: str | os.PathLike[str], what: str, limit: int = TEXT_LIMIT) -> str:
    """The UTF-8 text of a regular file of at most ``limit`` bytes.

    Parameters
    ----------
    path : path-like
        The file (a symlink is followed).
    what : str
        Names the file in errors (``'--scene'``, ``'bag metadata'``).
    limit : int
        Largest accepted size, bytes.

    Raises
    ------
    InputFileError
        Cannot be opened (the OS reason), not a regular file, too large, not UTF-8 (with
        the line and column of the first bad byte) or UTF-16.
    """
    name = str(path)
    try:  # O_NONBLOCK: opening a FIFO must not wait for a writer
        fd = os.open(name, os.O_RDONLY | os.O_NONBLOCK | getattr(os, 'O_CLOEXEC', 0))
    except OSError as exc:
        raise InputFileError(what, name, f'cannot read file: {exc.strerror}') from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise InputFileError(what, name, f'is {file_kind(info.st_mode)}, not a regular file')
        if info.st_size > limit:
            raise InputFileError(what, name, f'is {info.st_size} bytes; at most {limit} are read')
        chunks: list[bytes] = []
        size = 0
        while size <= limit:  # the file may grow while we read: never read more than limit + 1
            chunk = os.read(fd, min(1 << 16, limit + 1 - size))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
    except OSError as exc:
        raise InputFileError(
            what, name, f'cannot read file: {exc.strerror or errno.errorcode.get(exc.errno or 0)}'
        ) from None
    finally:
        os.close(fd)
    data = b''.join(chunks)
    if len(data) > limit:
        raise InputFileError(what, name, f'is over {limit} bytes; at most {limit} are read')
    if data[:2] in (b'\xff\xfe', b'\xfe\xff'):
        raise InputFileError(what, name, 'is UTF-16 (byte-order mark); save it as UTF-8')
    try:
        text = data.decode('utf-8')
    except UnicodeDecodeError as exc:
        line = data.count(b'\n', 0, exc.start) + 1
        column = exc.start - (data.rfind(b'\n', 0, exc.start) + 1) + 1
        raise InputFileError(
            what, name, f'line {line}, column {column}: not UTF-8 (byte 0x{data[exc.start]:02x}); save it as UTF-8'
        ) from None
    return text[1:] if text.startswith('\ufeff') else text


def _position(text: str, index: int) -> tuple[int, int]:
    """1-based (line, column) of character ``index`` of ``text``."""
    line = text.count('\n', 0, index) + 1
    return line, index - (text.rfind('\n', 0, index) + 1) + 1


def load_yaml(text: str, what: str, source: str, max_nodes: int = MAX_NODES) -> object:
    """Parse one YAML document with :class:`BoundedLoader`.

    Parameters
    ----------
    text : str
        The document.
    what, source : str
        Name the document in errors: the option or role, and the file (or a description).
    max_nodes : int
        Bound on the document's size with aliases expanded, nodes.

    Raises
    ------
    InputFileError
        One line: ``what='source': line L, column C: problem``.
    """
    loader: BoundedLoader | None = None
    try:
        loader = BoundedLoader(text)  # checks every character first (ReaderError)
        loader.max_nodes = max_nodes
        return loader.get_single_data()
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        problem = ' '.join(str(exc.problem or exc.context or 'invalid YAML').split())
        where = f'line {mark.line + 1}, column {mark.column + 1}: ' if mark is not None else ''
        raise InputFileError(what, source, f'{where}{shorten(problem, 120)}') from None
    except yaml.reader.ReaderError as exc:  # a character YAML does not allow (NUL, other controls)
        line, column = _position(text, exc.position)
        raise InputFileError(
            what,
            source,
            f'line {line}, column {column}: character '
            f'U+{exc.character if isinstance(exc.character, int) else 0:04X} '
            'is not allowed in YAML',
        ) from None
    except yaml.YAMLError as exc:
        raise InputFileError(what, source, f'not valid YAML: {shorten(" ".join(str(exc).split()), 120)}') from None
    except RecursionError:
        raise InputFileError(what, source, f'nested too deeply (at most {MAX_DEPTH} levels)') from None
    finally:
        if loader is not None:
            loader.dispose()


def load_yaml_file(
    path: str | os.PathLike[str], what: str, limit: int = TEXT_LIMIT, max_nodes: int = MAX_NODES
) -> object:
    """:func:`read_text_bounded` then :func:`load_yaml`."""
    return load_yaml(read_text_bounded(path, what, limit), what, str(Path(path)), max_nodes)
