"""The one mapping-to-dataclass builder: unknown, missing and bad keys are named."""

from __future__ import annotations

from dataclasses import dataclass, field

import pytest

from folder_line.core.numerics.validate import among, build, check_fields, check_keys, positive, within
from folder_line.errors import ParameterError


@dataclass(frozen=True)
class Gear:
    ratio: float
    teeth: int = 20
    note: str = field(default='', compare=False)
    derived: float = field(init=False, default=0.0)

    def __post_init__(self) -> None:
        object.__setattr__(self, 'ratio', positive('ratio', self.ratio))


def test_build_makes_the_dataclass_with_its_defaults() -> None:
    assert build(Gear, {'ratio': 2.0}, 'gear', 'gear parameter') == Gear(2.0)
    assert build(Gear, {'ratio': 2, 'teeth': 30}, 'gear', 'gear parameter').teeth == 30


@pytest.mark.parametrize(
    ('values', 'message'),
    [
        ({'ratio': 1.0, 'pitch': 3}, 'gear.pitch=3: unknown gear parameter; known: ratio, teeth, note'),
        ({'ratio': 1.0, 'derived': 1.0}, 'gear.derived=1.0: unknown gear parameter; known: ratio, teeth, note'),
        ({'teeth': 3}, 'gear.ratio=None: missing gear parameter; required: ratio'),
        ([1, 2], 'gear=[1, 2]: must be a mapping of key: value'),
        ({'ratio': -1.0}, 'gear.ratio=-1.0: must be > 0'),  # the dataclass's bare key, prefixed
    ],
)
def test_build_names_the_key(values: object, message: str) -> None:
    with pytest.raises(ParameterError) as exc:
        build(Gear, values, 'gear', 'gear parameter')
    assert str(exc.value) == message


def test_a_dotted_key_of_the_dataclass_is_kept_and_the_top_level_has_no_prefix() -> None:
    @dataclass(frozen=True)
    class Named:
        x: float

        def __post_init__(self) -> None:
            positive('effects.named.x', self.x)

    with pytest.raises(ParameterError, match=r'^effects\.named\.x=0: must be > 0$'):
        build(Named, {'x': 0}, 'effects.named', 'parameter of effect named')
    with pytest.raises(ParameterError, match=r"^colour='red': unknown scene key; known: name, seed$"):
        check_keys({'name': 'x', 'colour': 'red'}, ('name', 'seed'), '', 'scene key')


@dataclass(frozen=True)
class Belt:
    speed: float
    share: float
    kind: str

    def __post_init__(self) -> None:
        check_fields(self, 'belt', speed=positive, share=within(0.0, 1.0, hi_open=True), kind=among(('flat', 'round')))


def test_check_fields_keeps_what_the_checks_return_and_names_the_field() -> None:
    belt = Belt(2, 0, 'flat')
    assert (belt.speed, belt.share, belt.kind) == (2.0, 0.0, 'flat') and type(belt.speed) is float
    for args, message in (
        ((0.0, 0.5, 'flat'), 'belt.speed=0.0: must be > 0'),
        ((1.0, 1.0, 'flat'), 'belt.share=1.0: must be in [0, 1)'),
        ((1.0, 0.5, 'v'), "belt.kind='v': must be one of flat, round"),
        ((-1.0, 2.0, 'v'), 'belt.speed=-1.0: must be > 0'),  # in the order given
    ):
        with pytest.raises(ParameterError) as exc:
            Belt(*args)
        assert str(exc.value) == message
