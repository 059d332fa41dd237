"""Node ``sheet_counter``: the pile of the delivery and the floor of the layup container.

Counts sheets released on the pile (scenes with the delivery) or, without a delivery,
leaves landed in the container (layup scenes), and publishes, at every point ``t`` of
its grid (``rate`` Hz of sim time):

* ``/line/sheet_counter/count`` (``std_msgs/UInt64``): sheets counted up to ``t``;
* ``/line/sheet_counter/rate`` (``std_msgs/Float64``): sheets per second over the last
  ``rate_window`` s of sim time (over the elapsed time while ``t`` is shorter);
* ``/line/sheet_counter/joint_states`` (``sensor_msgs/JointState``): the table under the
  counted sheets, one prismatic joint (:mod:`folder_line.core.mechanisms.pile`), lowered by the
  sheet thickness ``h`` (scene key ``sheets.thickness``, m) per counted sheet at constant
  speed over ``τ`` = :data:`folder_line.core.mechanisms.pile.T_LOWER` (0.02 s) from the sheet's
  event time ``t_i``, so that the top of the stack stays where the sheets arrive:

  - ``pile_table`` (scenes with the delivery): the pile table's height, m, 0 at t = 0,
    negative downward, and its velocity, m/s;
  - ``container_floor`` (other scenes): the container floor's height relative to
    ``container.y_floor`` (where the leaves land), m, 0 at t = 0, negative downward,
    and its velocity, m/s;

  position ``z(t) = -h Σ_i clip((t - t_i)/τ, 0, 1)`` (exactly ``-h n`` once n sheets
  have settled), velocity ``-(h/τ) #{i: t_i <= t < t_i + τ}``; no effort;

and, per landed leaf, ``/line/sheet_counter/landing_x`` (``std_msgs/Float64``, m), besides
its ``released_on_pile``, ``leaf_landed`` and ``leaf_spilled`` events on ``/line/events``.

It also draws the whole line: ``/line/markers`` (``visualization_msgs/MarkerArray``, frame
``line``) at ``marker_rate`` Hz of sim time on its own grid, stamps ``i / marker_rate``
(0 = off), the scenery of its line (:class:`folder_line.core.line.scenery.Scenery` of its
stream) as :mod:`folder_line.bag.markers` lays it out. This node runs the whole line like
every machine node and runs in every scene, so no node is added to the line for it.
Other parameters: see :mod:`folder_line.ros.nodes.machine`.
"""

from __future__ import annotations

import sys

import numpy as np
from std_msgs.msg import Float64, UInt64
from visualization_msgs.msg import MarkerArray

from folder_line.bag.batch import SheetRate
from folder_line.bag.markers import marker_specs, marker_stamps
from folder_line.config.run_config import MARKER_RATE, MARKER_RATES
from folder_line.core.line.scenery import Scenery
from folder_line.core.mechanisms.pile import counted_event
from folder_line.interfaces import (
    EVENT_KINDS,
    LANDING_TOPIC,
    MARKERS_TOPIC,
    NS_PER_S,
    SHEET_COUNT_TOPIC,
    SHEET_RATE_TOPIC,
)
from folder_line.ros.lockstep import LINE_QOS
from folder_line.ros.markers import marker_array
from folder_line.ros.nodes.machine import MachineNode, node_exit_code
from folder_line.ros.parameters import ParamSpec
from folder_line.ros.runtime import run_node

__all__ = ['RATE_WINDOWS', 'SheetCounter', 'counted_kind', 'main']

#: the range of ``rate_window``, s: the counted sheets of the longest are kept (bounded memory)
RATE_WINDOWS = (0.001, 3600.0)


def counted_kind(has_delivery: bool) -> int:
    """Event-kind index the counter counts: sheets on the pile, else leaves in the container."""
    return EVENT_KINDS.index(counted_event(has_delivery))


class SheetCounter(MachineNode):
    """The ``sheet_counter`` node."""

    NODE_NAME = 'sheet_counter'
    EXTRA_SPECS = (
        ParamSpec('rate_window', 5.0, 'Window of the sheet rate, in sim time', unit='s', bounds=RATE_WINDOWS),
        ParamSpec(
            'marker_rate',
            MARKER_RATE,
            'Rate of /line/markers in sim time, stamps i/marker_rate (0 = off)',
            unit='Hz',
            bounds=MARKER_RATES.bounds,
        ),
    )

    def setup(self) -> None:
        self._count_pub = self.create_publisher(UInt64, SHEET_COUNT_TOPIC, LINE_QOS)
        self._rate_pub = self.create_publisher(Float64, SHEET_RATE_TOPIC, LINE_QOS)
        self._landing_pub = self.create_publisher(Float64, LANDING_TOPIC, LINE_QOS)
        self._landed = EVENT_KINDS.index('leaf_landed')
        self.published_count = self.published_rate = self.published_landing = self.published_markers = 0
        self._marker_pub = self.create_publisher(MarkerArray, MARKERS_TOPIC, LINE_QOS)
        self._marker_ns: int | None = None  # the latest marker stamp published
        self._marker_rate = self.values['marker_rate']  # the rate of the grid _marker_ns is on
        self._counted = counted_kind(self.scene.has_delivery)
        self._sheets = SheetRate(self.values['rate_window'])  # the counted sheets the rate still reads
        self._scenery: Scenery | None = None  # built when a marker is first due

    def on_events(self, events: np.ndarray) -> None:
        """Count the sheets counted at this tick (published before the grid points that read them)."""
        self._sheets.window = self.values['rate_window']
        self._sheets.add(events['t'][events['kind'] == self._counted])

    def count_at(self, t: float) -> int:
        """Sheets counted with event time <= t (t not before the rate window of the last tick)."""
        return int(self._sheets.count(np.array([t]))[0])

    def rate_at(self, t: float) -> float:
        """Sheets per second over ``(t - window, t]`` (the elapsed time if shorter), 0 at t = 0."""
        return float(self._sheets.rate(np.array([t]))[0])

    def publish_sample(self, stamp_ns: int, t: float) -> None:
        self.publish(self._count_pub, UInt64(data=self.count_at(t)))
        self.published_count += 1
        self.publish(self._rate_pub, Float64(data=self.rate_at(t)))
        self.published_rate += 1

    def publish_extra(self, stamp_ns: int, t: float, events: np.ndarray) -> None:
        for row in events[events['kind'] == self._landed]:
            self.publish(self._landing_pub, Float64(data=float(row['value'])))
            self.published_landing += 1
        rate = self.values['marker_rate']
        if rate != self._marker_rate or self._marker_ns is None:
            # the first tick, a new rate, or markers on again after 0: the grid starts at this tick, not at the
            # last stamp drawn (nor at 0, for a line joined far into it)
            self._marker_ns = stamp_ns - 1
        self._marker_rate = rate
        self._sheets.forget(t, RATE_WINDOWS[1])  # no rate after this tick reads further back, whatever its window
        for g in marker_stamps(self._marker_ns, stamp_ns, rate):
            if self._scenery is None:
                self._scenery = Scenery(self.stream)
            specs = marker_specs(self._scenery.at(g / NS_PER_S))
            self.publish(self._marker_pub, marker_array(specs, g, delete_all=self.published_markers == 0))
            self._marker_ns = g
            self.published_markers += 1

    def published_counts(self) -> dict[str, int]:
        return {
            **super().published_counts(),
            SHEET_COUNT_TOPIC: self.published_count,
            SHEET_RATE_TOPIC: self.published_rate,
            LANDING_TOPIC: self.published_landing,
            MARKERS_TOPIC: self.published_markers,
        }


def main(args: list[str] | None = None) -> int:
    """Run ``sheet_counter`` until Ctrl-C; exit code 0 (2 on a bad parameter, 3 if the line did not end)."""
    return run_node(SheetCounter, args, exit_code=node_exit_code)


if __name__ == '__main__':
    sys.exit(main())
