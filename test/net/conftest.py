"""Fixtures of the network tests: the switch built once, a three-host network per test.

The tests are skipped only where namespaces cannot be made (:func:`netns.available`: not
root, no ``ip``, no gcc, ``ip netns add`` refused); anything else that fails is a failure.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from .netns import Network, available, build_switch


@pytest.fixture(scope='session')
def switch_binary(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The switch, built once per test session (skips the test where namespaces cannot be made)."""
    reason = available()
    if reason is not None:
        pytest.skip(reason)
    return build_switch(tmp_path_factory.mktemp('switch'))


@pytest.fixture
def net(switch_binary: Path, tmp_path: Path) -> Iterator[Network]:
    """Hosts ``a``, ``b``, ``c`` on the switch, no impairment; closed after the test."""
    with Network(['a', 'b', 'c'], tmp_path / 'net', switch=switch_binary) as network:
        yield network
