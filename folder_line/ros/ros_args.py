"""The parameter values a node's ``--ros-args`` give it, read without rcl: a node process refuses a bad start
before it makes a DDS participant (``folder_line.ros.runtime.run_node``).

A participant made and torn down again at once, while other participants are discovering each
other (a line of six processes started together with a bad parameter), now and then crashes
inside Fast DDS's teardown (SIGSEGV in ``Node.destroy_node``). A start refused from the command
line alone makes no participant. What this module cannot read with certainty -- a node renamed
or put in a namespace (``ros2 launch`` names a node by its own name: that is read), a list value,
an integer written as rcl's ``strtol`` reads it but Python does not, an option it does not know --
makes it answer None, and the node refuses the start itself, with rcl's reading of the arguments.

The values are read as rcl reads a ``-p NAME:=VALUE`` rule (``rcl_yaml_param_parser``):
quoted text is a string; then ``true`` or ``false``, a decimal integer, a float (``nan`` and
``inf`` too), else a string. A ``--params-file`` is read with rclpy's own
:func:`rclpy.parameter.parameter_dict_from_yaml_file`. As with rcl, the last rule or file that sets a
parameter wins, in the order of the arguments.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Sequence

from rclpy.parameter import Parameter, parameter_dict_from_yaml_file

__all__ = ['command_line_values']

_TRUE = frozenset({'true', 'True', 'TRUE'})
_FALSE = frozenset({'false', 'False', 'FALSE'})
#: YAML 1.1's other bool words, which rcl's reading of a rule may or may not take as bools
_MAYBE_BOOL = frozenset({'y', 'yes', 'n', 'no', 'on', 'off'})
_DECIMAL = re.compile(r'[+-]?(0|[1-9][0-9]*)')
#: YAML's spellings of the special floats, which rcl takes besides strtod's
_SPECIAL = {'.nan': math.nan, '.inf': math.inf, '+.inf': math.inf, '-.inf': -math.inf}
#: options of --ros-args that take one argument and give no parameter
_WITH_ARGUMENT = frozenset({'--log-level', '--log-config-file', '-e', '--enclave', '--log-file-name'})
#: options of --ros-args that take no argument
_FLAGS = frozenset(
    {
        '--enable-rosout-logs',
        '--disable-rosout-logs',
        '--enable-stdout-logs',
        '--disable-stdout-logs',
        '--enable-external-lib-logs',
        '--disable-external-lib-logs',
    }
)


class _Unsure(Exception):
    """The arguments hold something this module does not read as rcl would."""


def _value(text: str) -> object:
    """What rcl makes of ``text`` in ``-p NAME:=text`` (raises _Unsure where it cannot tell)."""
    stripped = text.strip()
    if len(stripped) >= 2 and stripped[0] == stripped[-1] and stripped[0] in '\'"':
        return stripped[1:-1]
    if stripped in _TRUE:
        return True
    if stripped in _FALSE:
        return False
    if _DECIMAL.fullmatch(stripped):
        return int(stripped)
    if stripped.lower() in _SPECIAL:
        return _SPECIAL[stripped.lower()]
    if (
        stripped[:1] in '[{'
        or stripped.lower() in _MAYBE_BOOL
        or re.search(r'0[xXbBoO]', stripped)
        or re.fullmatch(r'[+-]?0[0-9]+', stripped)
    ):
        raise _Unsure(text)  # a list, a mapping, a YAML 1.1 bool word, a number in another base
    if '_' in stripped:  # Python's float reads 1_000; strtod does not: a string to rcl
        return text
    try:
        return float(stripped)
    except ValueError:
        return text


def _file_values(path: str, node: str) -> dict[str, object]:
    """The values a parameter file gives ``node`` (rclpy's reader; raises _Unsure on a file it refuses)."""
    try:
        found = parameter_dict_from_yaml_file(path, use_wildcard=True, target_nodes=[f'/{node}'])
    except Exception as exc:
        raise _Unsure(path) from exc
    return {name: Parameter.from_parameter_msg(msg).value for name, msg in found.items()}


def command_line_values(args: Sequence[str], node: str) -> dict[str, object] | None:
    """The parameter values the ``--ros-args`` in ``args`` give the node named ``node``.

    Parameters
    ----------
    args : sequence of str
        The process's arguments (``sys.argv[1:]``).
    node : str
        The node's name (a rule ``-p other:name:=v`` of another node is skipped).

    Returns
    -------
    dict or None
        Parameter name -> value, for the parameters the arguments set; None when they hold
        something not read here with certainty (the node then reads them with rcl).
    """
    values: dict[str, object] = {}
    inside = False
    words = list(args)
    i = 0
    try:
        while i < len(words):
            word = words[i]
            i += 1
            if word == '--ros-args':
                inside = True
            elif word == '--' and inside:
                inside = False
            elif not inside:
                continue
            elif word in _WITH_ARGUMENT:
                i += 1
            elif word in _FLAGS:
                continue
            elif word not in _RULES or i >= len(words) or not _RULES[word](words[i], node, values):
                return None
            else:
                i += 1
    except _Unsure:
        return None
    return values


def _param_rule(rule: str, node: str, values: dict[str, object]) -> bool:
    """``-p [node:]name:=value``: the value into ``values`` if the rule is this node's; False if unsure."""
    name, sep, text = rule.partition(':=')
    if not sep:
        return False
    target, colon, param = name.rpartition(':')
    if not colon or target in (node, f'/{node}', '*', '/**'):
        values[param] = _value(text)
    return True


def _params_file(path: str, node: str, values: dict[str, object]) -> bool:
    """``--params-file PATH``: the file's values for this node into ``values``."""
    values.update(_file_values(path, node))
    return True


def _remap_rule(rule: str, node: str, values: dict[str, object]) -> bool:
    """``-r RULE``: False when it gives the node another name or a namespace (the rules that apply are rcl's
    to find); any other remapping changes no parameter."""
    target, _, value = rule.partition(':=')
    key = target.rsplit(':', 1)[-1]
    return not (key == '__ns' or (key in ('__node', '__name') and value != node))


#: the options that take an argument and may set the node's parameters or name: each reads its argument
_RULES: dict[str, Callable[[str, str, dict[str, object]], bool]] = {
    '-p': _param_rule,
    '--param': _param_rule,
    '--params-file': _params_file,
    '-r': _remap_rule,
    '--remap': _remap_rule,
}
