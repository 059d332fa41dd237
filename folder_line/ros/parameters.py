"""Node parameters: a table of :class:`ParamSpec` declared and validated in one call.

A node of the line declares its parameters from a table of :class:`ParamSpec` with
:func:`declare_parameters`, which checks the starting values and installs the
validation (:func:`make_screen` before rclpy's own checks, :func:`make_validator` on
set), so that every refusal names the parameter and the value. A float parameter also takes
an integer, at start (``--ros-args -p rate:=200``, a parameter file, overrides) and at run time
(``ros2 param set /node rate 200``), and stores it as a float: ROS users type integers.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter

from folder_line.errors import FolderLineError, ParameterError
from folder_line.ros.signing import SIGNATURE_PARAMETER, RequestGuard, line_signer, sign_request

__all__ = [
    'CrossCheck',
    'ParamSpec',
    'ParamValue',
    'declare_parameters',
    'given_values',
    'guard_changes',
    'make_screen',
    'make_validator',
    'parameter_values',
    'proposed_value',
    'signed_change',
    'sim_time_overrides',
    'starting_values',
]

ParamValue = bool | int | float | str
"""The scalar parameter types a :class:`ParamSpec` supports."""

CrossCheck = Callable[[Mapping[str, Any]], None]
"""A node's check across its parameters: gets the values the node would have after a
change and raises :class:`folder_line.errors.FolderLineError` (typically by building
the core's parameter dataclass) if that combination is invalid."""

_KINDS: dict[type, tuple[str, Parameter.Type]] = {
    bool: ('a bool', Parameter.Type.BOOL),
    int: ('an integer', Parameter.Type.INTEGER),
    float: ('a float', Parameter.Type.DOUBLE),
    str: ('a string', Parameter.Type.STRING),
}


def _as_float(value: int) -> float:
    try:
        return float(value)
    except OverflowError:  # beyond any float: not finite
        return math.inf


def _type_name(value: object) -> str:
    return 'nothing (parameter unset)' if value is None else type(value).__name__


@dataclass(frozen=True)
class ParamSpec:
    """Declaration of one node parameter: default, meaning, unit, allowed values.

    The parameter's ROS type is that of ``default``: a float parameter has a float
    default (``200.0``, not ``200``). Unlike ROS, it also takes an integer (``200``),
    which it stores as a float; a bool or a string it refuses.

    Parameters
    ----------
    name : str
        Parameter name, e.g. ``'rtf'``.
    default : bool, int, float or str
        Default value; also fixes the type.
    description : str
        One line: what the parameter does.
    unit : str, optional
        Unit of a number (``'s'``, ``'Hz'``, ``'m/s'``; empty for a dimensionless one).
    bounds : (lo, hi), optional
        Allowed range of a number, closed unless ``low_open``/``high_open``;
        either end may be infinite. Finite bounds become the descriptor's
        ``FloatingPointRange``/``IntegerRange``.
    low_open, high_open : bool, optional
        Exclude ``lo``/``hi`` themselves (ROS ranges are closed; the open end is
        enforced by the validation callback and stated in ``additional_constraints``).
    choices : tuple of str, optional
        Allowed values of a string parameter.
    read_only : bool, optional
        Settable only at start (``--ros-args -p name:=value`` or overrides).

    Raises
    ------
    ParameterError
        The spec itself is inconsistent (default of an unsupported type or outside
        its own bounds or choices, bounds on a string, choices on a number, ...).
    """

    name: str
    default: ParamValue
    description: str
    unit: str = ''
    bounds: tuple[float, float] | None = None
    low_open: bool = False
    high_open: bool = False
    choices: tuple[str, ...] = ()
    read_only: bool = False

    def __post_init__(self) -> None:
        if not self.name or not isinstance(self.name, str):
            raise ParameterError('ParamSpec.name', self.name, 'must be a non-empty string')
        if type(self.default) not in _KINDS:
            raise ParameterError(self.name, self.default, 'default must be a bool, int, float or str')
        numeric = type(self.default) in (int, float)
        if self.bounds is not None:
            if not numeric:
                raise ParameterError(self.name, self.bounds, 'bounds are for int or float parameters')
            lo, hi = self.bounds
            if math.isnan(lo) or math.isnan(hi) or not lo < hi:
                raise ParameterError(self.name, self.bounds, 'bounds must be (lo, hi) with lo < hi')
        elif self.low_open or self.high_open:
            raise ParameterError(self.name, self.bounds, 'low_open/high_open need bounds')
        if self.choices:
            if not isinstance(self.default, str):
                raise ParameterError(self.name, self.choices, 'choices are for string parameters')
            if not all(isinstance(c, str) for c in self.choices) or len(set(self.choices)) != len(self.choices):
                raise ParameterError(self.name, self.choices, 'choices must be distinct strings')
        self.check(self.default)

    @property
    def type(self) -> Parameter.Type:
        """ROS type of the parameter (from the default)."""
        return _KINDS[type(self.default)][1]

    def constraint_text(self) -> str:
        """Allowed values in words, e.g. ``'a float in (0, 1000]'``, ``'a float in [1, 1000] Hz'``."""
        parts = [_KINDS[type(self.default)][0]]
        if self.bounds is not None:
            lo, hi = self.bounds
            left = '(' if self.low_open else '['
            right = ')' if self.high_open else ']'
            parts.append(f'in {left}{lo:g}, {hi:g}{right}')
        if self.choices:
            parts.append('one of ' + ', '.join(self.choices))
        if self.unit:
            parts.append(self.unit)
        return ' '.join(parts)

    def check(self, value: object) -> ParamValue:
        """The value this parameter stores for ``value``, if it accepts it, else raise.

        Parameters
        ----------
        value : object
            Proposed value (a ``Parameter.value``).

        Returns
        -------
        bool, int, float or str
            ``value`` itself, or for a float parameter given an integer, that integer as a float.

        Raises
        ------
        ParameterError
            Wrong type (a bool or a string for a number, a float for an integer, ...), NaN or
            infinite, out of bounds, or not one of the choices; the message names the
            parameter and the value as given.
        """
        kind = type(self.default)
        stored = value
        if kind is float and type(value) is int:  # not a bool: exact types
            stored = _as_float(value)
        # bool is an int subclass and int is not a float here: compare exact types.
        if type(stored) is not kind:
            raise ParameterError(self.name, value, f'must be {_KINDS[kind][0]}, got {_type_name(value)}')
        if isinstance(stored, float) and not math.isfinite(stored):  # type(stored) is kind: kind is float
            raise ParameterError(self.name, value, 'must be finite (not NaN or inf)')
        if self.bounds is not None and isinstance(stored, (int, float)):  # bounds only on numbers (__post_init__)
            lo, hi = self.bounds
            bad_lo = stored <= lo if self.low_open else stored < lo
            bad_hi = stored >= hi if self.high_open else stored > hi
            if bad_lo or bad_hi:
                raise ParameterError(self.name, value, f'must be {self.constraint_text()}')
        if self.choices and stored not in self.choices:
            raise ParameterError(self.name, value, f'must be one of {", ".join(self.choices)}')
        return stored

    def from_text(self, text: str) -> ParamValue:
        """The value ``text`` stands for, checked (:meth:`check`): a launch argument, read as ``launch_ros`` does.

        A float parameter reads ``text`` with ``float`` (``'200'`` is 200.0), an integer one with
        ``int``, a bool one as ``true``/``false`` (any case) or ``1``/``0``; a string one takes it as
        it is. Text that does not read as the parameter's type is refused as the string it is.

        Parameters
        ----------
        text : str
            The value as typed, e.g. ``'200'`` of ``rate:=200``.

        Returns
        -------
        bool, int, float or str
            The value the parameter stores.

        Raises
        ------
        ParameterError
            ``text`` is not of the parameter's type or not an allowed value; the message names the
            parameter and the value as read (``rtf='fast'``, ``lost_timeout=0.01``).
        """
        kind = type(self.default)
        value: object = text
        if kind is bool:
            value = {'true': True, '1': True, 'false': False, '0': False}.get(text.strip().lower(), text)
        elif kind in (int, float):
            with contextlib.suppress(ValueError):  # not a number: refused below as the text
                value = kind(text)
        return self.check(value)

    def descriptor(self) -> ParameterDescriptor:
        """The ``ParameterDescriptor`` to declare the parameter with (a new one each call)."""
        description = self.description + (f' [{self.unit}]' if self.unit else '')
        descriptor = ParameterDescriptor(
            description=description,
            additional_constraints=self.constraint_text(),
            read_only=self.read_only,
        )
        if self.bounds is not None and all(math.isfinite(b) for b in self.bounds):
            lo, hi = self.bounds
            if self.type == Parameter.Type.DOUBLE:
                descriptor.floating_point_range = [
                    FloatingPointRange(from_value=float(lo), to_value=float(hi), step=0.0)
                ]
            else:
                descriptor.integer_range = [IntegerRange(from_value=math.ceil(lo), to_value=math.floor(hi), step=0)]
        return descriptor


def parameter_values(node: Node, specs: Iterable[ParamSpec]) -> dict[str, Any]:
    """Current values of the spec'd parameters of ``node``, by name."""
    return {spec.name: node.get_parameter(spec.name).value for spec in specs}


class _Refused(Parameter[Any]):
    """Stand-in for a proposed value that its spec refuses (see :func:`make_screen`).

    It carries the spec's default, so rclpy's own descriptor checks pass, the reason,
    which the validator then returns, and the value proposed (:func:`proposed_value`).
    """

    def __init__(self, spec: ParamSpec, reason: str, proposed: object) -> None:
        super().__init__(spec.name, spec.type, spec.default)
        self.reason = reason
        self.proposed = proposed


def proposed_value(parameter: Parameter[Any]) -> object:
    """The value proposed for ``parameter``, as the caller sent it, after :func:`make_screen` (which may
    have put a stand-in in its place)."""
    return parameter.proposed if isinstance(parameter, _Refused) else parameter.value


def make_screen(specs: Sequence[ParamSpec]) -> Callable[[list[Parameter[Any]]], list[Parameter[Any]]]:
    """The pre-set parameters callback of a node (see :func:`declare_parameters`).

    rclpy applies the declared descriptor before any on-set callback and refuses
    a value of the wrong ROS type with ``"Wrong parameter type, expected '1' got
    '4'"`` (type codes, no name), an integer for a float parameter included. This
    callback runs first. An integer for a float parameter it replaces by the same
    value as a float (``ros2 param set /node rate 200`` sets 200.0). So that every
    refusal has one format naming the parameter and the value, it replaces each
    proposed value its :class:`ParamSpec` refuses by a stand-in holding the
    spec's default and the reason; the validator of :func:`make_validator` then
    refuses the stand-in with that reason, so nothing is applied. Other values the
    spec accepts pass unchanged. (rclpy still answers read-only parameters itself.)
    """
    by_name = {spec.name: spec for spec in specs}

    def screen(parameters: list[Parameter[Any]]) -> list[Parameter[Any]]:
        out: list[Parameter[Any]] = []
        for parameter in parameters:
            spec = by_name.get(parameter.name)
            if spec is not None and not isinstance(parameter, _Refused):
                try:
                    value = spec.check(parameter.value)
                except ParameterError as err:
                    parameter = _Refused(spec, str(err), parameter.value)
                else:
                    if type(value) is not type(parameter.value):  # an integer for a float parameter
                        parameter = Parameter(parameter.name, spec.type, value)
            out.append(parameter)
        return out

    return screen


def make_validator(
    specs: Sequence[ParamSpec],
    current: Callable[[], Mapping[str, Any]],
    cross_check: CrossCheck | None = None,
) -> Callable[[list[Parameter[Any]]], SetParametersResult]:
    """The on-set parameters callback of a node (see :func:`declare_parameters`).

    Each proposed parameter that has a spec is checked with :meth:`ParamSpec.check`
    (or, if :func:`make_screen` already refused it, carries its reason); parameters
    without a spec (``use_sim_time``, QoS overrides, ...) pass. Then
    ``cross_check`` gets the current values updated with every proposed parameter.
    A refusal keeps the old values (rclpy applies nothing) and its reason names the
    parameter and the value: ``"rtf=nan: must be finite (not NaN or inf)"``,
    ``"rtf='fast': must be a float, got str"``, or for the cross-check
    ``"lo=2.0 rejected: <the core's error>"``.

    Parameters
    ----------
    specs : sequence of ParamSpec
        The node's parameters.
    current : callable
        Returns the node's current values by name (e.g. ``lambda: parameter_values(node, specs)``).
    cross_check : CrossCheck, optional
        Node-specific check across parameters; its ``FolderLineError`` becomes the reason.

    Returns
    -------
    callable
        ``callback(parameters) -> SetParametersResult``.
    """
    by_name = {spec.name: spec for spec in specs}

    def validate(parameters: list[Parameter[Any]]) -> SetParametersResult:
        for parameter in parameters:
            if isinstance(parameter, _Refused):
                return SetParametersResult(successful=False, reason=parameter.reason)
            spec = by_name.get(parameter.name)
            if spec is not None:
                try:
                    spec.check(parameter.value)
                except ParameterError as err:
                    return SetParametersResult(successful=False, reason=str(err))
        if cross_check is not None:
            values = dict(current())
            values.update({p.name: p.value for p in parameters})
            try:
                cross_check(values)
            except FolderLineError as err:
                change = ', '.join(f'{p.name}={p.value!r}' for p in parameters if p.name != SIGNATURE_PARAMETER)
                return SetParametersResult(successful=False, reason=f'{change} rejected: {err}')
        return SetParametersResult(successful=True)

    return validate


def declare_parameters(node: Node, specs: Sequence[ParamSpec], cross_check: CrossCheck | None = None) -> dict[str, Any]:
    """Declare ``specs`` on ``node``, check the starting values, install the validation.

    Starting values are the defaults unless overridden (``--ros-args -p``,
    parameter files, ``parameter_overrides``); they pass the same checks as later
    changes, so a node never starts on a value it would refuse, and a float parameter
    takes an integer there too (see :func:`starting_values`). Then
    :func:`make_screen` is installed as the pre-set and :func:`make_validator` as
    the on-set parameters callback. Call it once per node, with all its specs, and
    add no other pre-set callback (rclpy concatenates the lists they return);
    apply accepted changes in a post-set callback
    (``node.add_post_set_parameters_callback``).

    Parameters
    ----------
    node : rclpy.node.Node
        The node (declares nothing else with these names).
    specs : sequence of ParamSpec
        Its parameters; names must be distinct.
    cross_check : CrossCheck, optional
        See :func:`make_validator`; also run once on the starting values.

    Returns
    -------
    dict
        The starting values by name.

    Raises
    ------
    ParameterError
        A starting value is refused by its spec (of the wrong type, out of range, ...).
    FolderLineError
        ``cross_check`` refuses the starting values.
    rclpy.exceptions.ParameterException
        rclpy refused a declaration itself (e.g. a parameter already declared).
    """
    names = [spec.name for spec in specs]
    if len(set(names)) != len(names):
        raise ParameterError('specs', names, 'parameter names must be distinct')
    start = starting_values(node, specs)
    node.declare_parameters(
        '', [(spec.name, start[spec.name], spec.descriptor()) for spec in specs], ignore_override=True
    )
    values = parameter_values(node, specs)
    if cross_check is not None:
        cross_check(dict(values))
    node.add_pre_set_parameters_callback(make_screen(specs))
    node.add_on_set_parameters_callback(make_validator(specs, lambda: parameter_values(node, specs), cross_check))
    return values


def starting_values(node: Node, specs: Sequence[ParamSpec]) -> dict[str, ParamValue]:
    """The value each of ``specs`` starts at on ``node``: its override, else its default, checked by the spec.

    rclpy takes a parameter's override (``--ros-args -p``, a parameter file, the node's
    ``parameter_overrides``) only as it declares the parameter, and there refuses an override
    of another type than the descriptor's, an integer for a float parameter included, with a
    message of its own. So each parameter is first declared with a dynamically typed
    descriptor, which takes any type, and its value read; then the declaration is undone
    (``undeclare_parameter`` calls no callback and publishes no parameter event; the probe's
    declaration published one, as the real one will) and the value checked with
    :meth:`ParamSpec.check`, which stores an integer for a float parameter as a float. Only
    rclpy's public API is used; the caller declares the parameters with these values and
    ``ignore_override=True``.

    Parameters
    ----------
    node : rclpy.node.Node
        The node; none of ``specs`` is declared on it.
    specs : sequence of ParamSpec
        Its parameters, with distinct names.

    Returns
    -------
    dict
        The starting values by name, as the parameters store them.

    Raises
    ------
    ParameterError
        A starting value is refused by its spec; the message names the parameter and the value.
    """
    probes = node.declare_parameters(
        '', [(spec.name, spec.default, ParameterDescriptor(dynamic_typing=True)) for spec in specs]
    )
    given = {probe.name: probe.value for probe in probes}
    for spec in specs:
        node.undeclare_parameter(spec.name)
    return {spec.name: spec.check(given[spec.name]) for spec in specs}


def given_values(specs: Iterable[ParamSpec], given: Mapping[str, object]) -> dict[str, ParamValue]:
    """The value each of ``specs`` starts at with the command line's values ``given``
    (:func:`folder_line.ros.ros_args.command_line_values`), else its default, checked by the spec: what
    :func:`starting_values` finds on a node, found before any node is made.

    Raises
    ------
    ParameterError
        A value its spec refuses.
    """
    return {spec.name: spec.check(given.get(spec.name, spec.default)) for spec in specs}


def sim_time_overrides(
    parameter_overrides: Iterable[Parameter[Any]] | None = None, *, use_sim_time: bool = True
) -> list[Parameter[Any]]:
    """Node ``parameter_overrides`` with ``use_sim_time`` set.

    A helper for nodes outside the line (tests): the line's own nodes set
    ``use_sim_time`` themselves and refuse it off (:class:`folder_line.ros.nodes.machine.MachineNode`),
    or refuse it on (``line_clock``). An explicit ``use_sim_time`` among
    ``parameter_overrides`` wins; constructor overrides take precedence over ``--ros-args -p``.

    Parameters
    ----------
    parameter_overrides : iterable of Parameter, optional
        The caller's overrides, kept.
    use_sim_time : bool, optional
        Value to add when the caller gave none.
    """
    overrides = list(parameter_overrides or [])
    if not any(p.name == 'use_sim_time' for p in overrides):
        overrides.append(Parameter('use_sim_time', Parameter.Type.BOOL, use_sim_time))
    return overrides


def guard_changes(node: Node) -> RequestGuard:
    """Declare :data:`SIGNATURE_PARAMETER` on ``node`` and refuse, on a keyed line, every change of its
    parameters from now on that it does not sign (:class:`RequestGuard`). Call it once the node has set
    what it sets itself."""
    guard = RequestGuard(node.get_name())
    node.declare_parameter(
        SIGNATURE_PARAMETER,
        '',
        ParameterDescriptor(
            description='Signature of the latest change at run time on a keyed line, set with the change '
            '(folder-line tune and hold sign theirs)'
        ),
    )

    def check(parameters: list[Parameter[Any]]) -> SetParametersResult:
        if not guard.signer.keyed:
            return SetParametersResult(successful=True)
        signature = next((p.value for p in parameters if p.name == SIGNATURE_PARAMETER), None)
        values = [(p.name, proposed_value(p)) for p in parameters if p.name != SIGNATURE_PARAMETER]
        why = guard.check(signature, values) if values else f'{SIGNATURE_PARAMETER} alone signs no change'
        return SetParametersResult(successful=not why, reason=why)

    node.add_on_set_parameters_callback(check)
    return guard


def signed_change(node: str, parameters: list[Parameter[Any]]) -> list[Parameter[Any]]:
    """``parameters`` for node ``node`` (its name), with :data:`SIGNATURE_PARAMETER` signing them on a keyed
    line (unchanged on an open one): to set at once (``set_parameters_atomically``)."""
    if not line_signer().keyed:
        return parameters
    signature = sign_request(node, [(p.name, p.value) for p in parameters])
    return [*parameters, Parameter(SIGNATURE_PARAMETER, value=signature)]
