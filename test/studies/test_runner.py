"""``studies.runner``: where the tasks run, results in task order, a task's error re-raised, bad settings refused."""

from __future__ import annotations

import io
import math

import pytest

from folder_line.errors import ParameterError
from folder_line.studies.runner import Cluster, run_tasks


@pytest.mark.parametrize(
    ('settings', 'message'),
    [
        ({'workers': 0}, '^--workers=0: must be a whole number in'),
        ({'threads': 513}, '^--threads=513: must be a whole number in'),
        ({'scheduler': 'foo'}, "^--scheduler='foo': not a scheduler address .*missing port"),
        ({'scheduler': 'tcp://host'}, "^--scheduler='tcp://host': not a scheduler address .*missing port"),
        ({'scheduler': 'http://host:8786'}, "^--scheduler='http://host:8786': not a scheduler address .*scheme"),
    ],
)
def test_bad_settings_are_refused_naming_the_option(settings: dict, message: str) -> None:
    with pytest.raises(ParameterError, match=message):
        Cluster(**settings)


def test_good_addresses_are_taken() -> None:
    for address in ('tcp://127.0.0.1:8786', '127.0.0.1:8786', 'tls://host.example:8786'):
        assert Cluster(scheduler=address).scheduler == address


def test_results_come_in_task_order_and_a_task_error_keeps_its_type() -> None:
    out = io.StringIO()
    values = [float(v) for v in range(40, 0, -1)]  # later tasks finish first as often as not
    assert run_tasks(math.sqrt, values, Cluster(workers=2), label='roots', progress=out) == [
        math.sqrt(v) for v in values
    ]
    assert out.getvalue().startswith('roots: 40 of 40 done in')  # not a terminal: one closing line
    with pytest.raises(ValueError, match='math domain error'):
        run_tasks(math.sqrt, [1.0, -1.0], Cluster(workers=1), progress=None)
