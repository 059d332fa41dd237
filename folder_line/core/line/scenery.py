"""The machine as drawable shapes at any line time: :class:`Scenery`, :class:`Shape`, :data:`LINE_FRAME`.

What a viewer needs to *see* the line (the ROS markers, an animation): the layup
six-bar with its chutes and belts, the leaves in the air and on the container floor,
the container, the folding cylinder, the knife, the front stops and the signatures,
the delivery chain with its carriages, and the pile. Every moving position is the
core's closed form at the drive phase of the line at ``t`` (``line.drive.theta``):
the six-bar from :class:`folder_line.core.mechanisms.layup.LayupModel`, the knife from
:func:`folder_line.core.mechanisms.knife.position`, the carriages from the chain
schedule and path (:mod:`folder_line.core.mechanisms.chain`), the signatures on the feed
belt from the belt's travel since their hand-over, the leaves from
:func:`folder_line.core.effects.leaf_flight.state` on the flights the layup computed,
the pile from :class:`folder_line.core.mechanisms.pile.PileStream`. Nothing here is
integrated or guessed from a sample grid, so a shape at ``t`` is the same live and in
a batch run. The line is a :class:`folder_line.core.line.stream.LineStream`: a shape can
be asked for at any time of its last window (the signatures and leaves it still holds).

Frame ``line`` (:data:`LINE_FRAME`)
-----------------------------------
One fixed frame, m: x along the line, z up, y across (the planar mechanisms lie in
the x-z plane, y = 0). Each machine keeps its own project frame and is placed by a
fixed offset, the same in every scene (a scene without a machine leaves its place
empty), so the machines never overlap:

* L (``layup``, ``container``): the project frame (x toward O3, y up) mapped to
  ``x -> x``, ``y -> z``, origin O2 at :data:`LAYUP_ORIGIN` = (0, 0, 1.5). With the
  default geometry the six-bar spans x -0.6 .. 1.0, the container x -0.45 .. 1.10 with
  its floor at z = 0.25.
* F (``folder``): the knife's stroke axis is vertical at x = :data:`FOLDER_ORIGIN` x
  (3.0); the table, where the knife edge reaches the level ``s_clear``, is at z = 1.0.
  The knife crank centre O is ``s_clear`` above the table (offset ``e`` across the
  axis); the knife edge is ``O - (0, s(φ_k))``. The signature comes in along +x on the
  feed belt and stops with its leading edge at the front stops, ``L_a/2`` past the
  knife (the knife folds it in the middle); the feed belt starts ``L_feed + L_a``
  before the stops, above the folding cylinder (diameter ``D_fc``, turning at ω_c).
* D (``delivery``, ``pile``): the carriages take the folded signature at the folding
  rollers, :data:`PICKUP_DROP` (0.2 m) below the table under the knife; the chain
  runs ``L_transfer`` along +x, then over the stroke (pin at
  ``x_max u``, ``y_max ψ(ξ(u))`` above the carriage guide), then back under on a
  return run whose two end arcs make the loop a whole number of pitches (so a
  carriage is always at the same place of the loop each cycle). The pile lies under
  the carriage's gripper at the release point ``u_rel``; its table is lowered by the
  counted sheets (the ``counter`` joint).

Parts (``Shape.machine`` / ``Shape.part``), in the order :meth:`Scenery.at` returns them
------------------------------------------------------------------------------------------
``layup``: ``ground`` (segments O1-O2, O2-O3), ``link`` (segments O1-A, A-B, O2-C,
C-E, O3-E: the crank, the rod l2, chute 3 through B, the coupler l4, chute 4), ``pivot``
(points O1, O2, O3), ``joint`` (points A, B, C, E), ``belt`` (segments along both chutes,
:data:`BELT_GAP` above them), ``belt_mark`` (points riding the belts, with belts),
``leaf`` (points: leaves in the air), ``leaf_landed`` (points: the last
:data:`LANDED_SHOWN` leaves landed between the walls); ``container``: ``wall`` (segments)
and ``floor`` (strip) — with ``leaf_flight`` and a container only.
``folder``: ``cylinder`` (strip: the circle and a spoke that turns with it), ``table``
(strip), ``feed_belt`` (strip), ``belt_mark`` (points), ``stop`` (segment), ``knife``
(segments: crank O-pin, rod pin-edge, blade), ``knife_pivot`` (points: O, pin, edge),
``signature`` (segments: the signatures on the belt, at the stops, in the fold).
``delivery`` (with D): ``chain_path`` (strip, closed), ``carriage_guide`` (segment),
``carriage`` (points: the chain pins of the carriages), ``rod`` (segments pin-gripper of
the carriages on the stroke), ``gripper`` (points), ``signature`` (segments: folded
signatures on the carriages); ``pile``: ``pile`` (box: the top of the stack, at most
:data:`PILE_SHOWN` deep), ``table`` (box).

Shape kinds: ``strip`` (a polyline through the points), ``segments`` (consecutive
pairs), ``points`` (dots of diameter ``width``), ``box`` (two opposite corners, min and
max). A shape with nothing to show has no points (it keeps its place in the order).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from folder_line.core.effects import leaf_flight
from folder_line.core.line.folder_stream import FolderStream
from folder_line.core.line.layup_stream import LayupStream
from folder_line.core.line.model import LineModel
from folder_line.core.line.stream import LineStream
from folder_line.core.mechanisms import knife as knf
from folder_line.core.mechanisms.delivery_laws import LAWS
from folder_line.core.mechanisms.layup import LayupParams
from folder_line.core.mechanisms.layup_angles import TAU
from folder_line.core.mechanisms.pile import PileStream

__all__ = [
    'BELT_GAP',
    'FOLDER_ORIGIN',
    'LANDED_SHOWN',
    'LAYUP_ORIGIN',
    'LINE_FRAME',
    'PICKUP_DROP',
    'PILE_SHOWN',
    'Scenery',
    'Shape',
    'chain_loop',
]

#: the one fixed frame of the drawn line
LINE_FRAME = 'line'
#: where the layup's O2 sits in the line frame, m
LAYUP_ORIGIN = (0.0, 0.0, 1.5)
#: where the knife's stroke axis meets the table in the line frame, m
FOLDER_ORIGIN = (3.0, 0.0, 1.0)
#: drop from the table to the folding rollers, where the carriages take the signatures, m
PICKUP_DROP = 0.2
#: gap between a chute and its belt as drawn, m
BELT_GAP = 0.03
#: landed leaves shown on the container floor (the latest)
LANDED_SHOWN = 60
#: depth of the pile stack shown under its top, m (an hour's pile is metres deep)
PILE_SHOWN = 0.25
#: spacing of the marks that show a belt moving, m
_MARK = 0.1
#: the last signatures handed over that may still be in the folder or on a carriage
_SHEETS_SHOWN = 24
#: the smallest radius of the chain loop's end arcs, m
_MIN_ARC = 0.1

_GREY = (0.55, 0.55, 0.58, 1.0)
_DARK = (0.25, 0.25, 0.28, 1.0)
_STEEL = (0.35, 0.45, 0.75, 1.0)
_BLUE = (0.2, 0.4, 0.9, 1.0)
_ORANGE = (0.95, 0.55, 0.1, 1.0)
_GREEN = (0.2, 0.65, 0.25, 1.0)
_RED = (0.85, 0.15, 0.15, 1.0)
_PAPER = (0.97, 0.95, 0.85, 1.0)
_LEAF = (0.45, 0.6, 0.15, 1.0)
_WOOD = (0.6, 0.45, 0.3, 1.0)


@dataclass(frozen=True, eq=False)
class Shape:
    """One drawable part of a machine (see the module docstring for the parts).

    Attributes
    ----------
    machine : str
        Namespace: ``'layup'``, ``'container'``, ``'folder'``, ``'delivery'``, ``'pile'``.
    part : str
        What it is (``'link'``, ``'knife'``, ``'carriage'``, ...).
    kind : str
        ``'strip'``, ``'segments'``, ``'points'`` or ``'box'``.
    points : ndarray, shape (N, 3)
        m in :data:`LINE_FRAME`, float64, read-only.
    width : float
        Line width, dot diameter or (box) ignored, m.
    rgba : tuple of 4 floats
        Colour, each in [0, 1] (values a float32 holds exactly, as ``std_msgs/ColorRGBA``).
    """

    machine: str
    part: str
    kind: str
    points: np.ndarray
    width: float
    rgba: tuple[float, float, float, float]


#: each colour as a message carries it (float32), made once
_RGBA32: dict[tuple[float, ...], tuple[float, float, float, float]] = {}


def _shape(machine: str, part: str, kind: str, points: npt.ArrayLike, width: float, rgba: tuple[float, ...]) -> Shape:
    p = np.array(points, dtype=np.float64).reshape(-1, 3)
    p.setflags(write=False)
    colour = _RGBA32.get(rgba)
    if colour is None:
        r, g, b, a = (float(np.float32(c)) for c in rgba)  # as a message carries them (float32)
        colour = _RGBA32[rgba] = (r, g, b, a)
    return Shape(machine, part, kind, p, float(width), colour)


def _xz(x: npt.ArrayLike, z: npt.ArrayLike, origin: tuple[float, float, float]) -> np.ndarray:
    """Points (x, z) of a planar frame placed at ``origin``, shape (N, 3)."""
    xx = np.asarray(x, dtype=float).reshape(-1)
    zz = np.asarray(z, dtype=float).reshape(-1)
    return np.stack([xx + origin[0], np.full(xx.shape, origin[1]), zz + origin[2]], axis=1)


def _theta(line: LineStream, t: float) -> float:
    return float(np.asarray(line.drive.theta(np.array([t])), dtype=float).reshape(-1)[0])


def _marks(a: np.ndarray, b: np.ndarray, travel: float) -> np.ndarray:
    """Points every :data:`_MARK` along segment a -> b, shifted by a belt's travel."""
    ab = b - a
    length = math.sqrt(float(ab.dot(ab)))  # np.linalg.norm of a vector, without its checks
    if length <= 0.0:
        return np.zeros((0, 3))
    off = travel % _MARK
    d = off + _MARK * np.arange(math.floor((length - off) / _MARK) + 1)
    d = d[d <= length]
    return a + np.outer(d / length, ab)


def chain_loop(transfer: float, stroke: float, span: float, pitch: float) -> tuple[float, float, int]:
    """The drawn chain loop: (radius of its end arcs, its length, carriages on it).

    The loop is the transfer (``transfer`` m straight), the stroke (``stroke`` m of
    chain over ``span`` m of x), an end arc, the return run (``transfer + span``
    straight) and an end arc back to the pickup; the arcs' radius makes the length a
    whole number of pitches, at least :data:`_MIN_ARC`.
    """
    base = 2.0 * transfer + stroke + span
    n = max(1, math.ceil((base + 2.0 * math.pi * _MIN_ARC) / pitch))
    radius = (n * pitch - base) / (2.0 * math.pi)
    return radius, n * pitch, n


class Scenery:
    """The shapes of a line's machines at any time of its last window (see the module docstring).

    Parameters
    ----------
    line : LineStream or LineModel
        The line (a stream may advance between calls: the shapes are those of its state then;
        a model's stream keeps its whole span); the static geometry is built once here.
    """

    def __init__(self, line: LineStream | LineModel) -> None:
        self.line: LineStream = line.stream if isinstance(line, LineModel) else line
        scene = self.line.scene
        self._static: dict[str, Shape] = {}
        self._layup = self.line.part('layup') if scene.has_layup else None
        self._folder = self.line.part('folder') if scene.has_folder else None
        if self._layup is not None:
            self._init_layup()
        if self._folder is not None:
            self._init_folder()
            if self.folder_part.plan is not None:
                self._init_delivery()

    # ------------------------------------------------------------------ layup

    @property
    def layup_part(self) -> LayupStream:
        """The layup's stream (a scene with a layup only)."""
        if self._layup is None:
            raise KeyError(f'scene {self.line.scene.name!r} has no layup')
        return self._layup

    @property
    def folder_part(self) -> FolderStream:
        """The folder's stream (a scene with a folder only)."""
        if self._folder is None:
            raise KeyError(f'scene {self.line.scene.name!r} has no folder')
        return self._folder

    @property
    def _pile(self) -> PileStream:
        return self.line.pile  # with the operator's lowering times

    def _init_layup(self) -> None:
        scene = self.line.scene
        lp: LayupParams = scene.machine('layup')
        self._lp = lp
        o = LAYUP_ORIGIN
        self._static['ground'] = _shape(
            'layup', 'ground', 'segments', _xz([lp.a, 0.0, 0.0, lp.O2O3], [lp.b, 0.0, 0.0, 0.0], o), 0.02, _DARK
        )
        self._static['pivot'] = _shape(
            'layup', 'pivot', 'points', _xz([lp.a, 0.0, lp.O2O3], [lp.b, 0.0, 0.0], o), 0.05, _DARK
        )
        self._belts = scene.has('chute_belts')
        self._container = self.layup_part.flight_on and 'container' in scene.machines
        if self._container:
            c = scene.machine('container')
            top = 0.6 * c.y_floor
            self._static['wall'] = _shape(
                'container',
                'wall',
                'segments',
                _xz([c.x_left, c.x_left, c.x_right, c.x_right], [top, c.y_floor, top, c.y_floor], o),
                0.02,
                _WOOD,
            )
            self._static['floor'] = _shape(
                'container', 'floor', 'strip', _xz([c.x_left, c.x_right], [c.y_floor, c.y_floor], o), 0.02, _WOOD
            )
            self._y_floor = float(c.y_floor)
            self._drag: leaf_flight.Params = scene.effect_params('leaf_flight')

    def _layup_joints(self, theta: float) -> dict[str, np.ndarray]:
        kin = self.layup_part.kinematics
        phi = kin.wrap(np.array([theta * kin.turns_rate]))
        st = kin.model.arrays(phi, accelerations=False)
        lp = self._lp
        pts = _xz(
            [lp.a, 0.0, lp.O2O3, st.xA[0], st.xB[0], st.xC[0], st.xE[0]],
            [lp.b, 0.0, 0.0, st.yA[0], st.yB[0], st.yC[0], st.yE[0]],
            LAYUP_ORIGIN,
        )
        return dict(zip(('O1', 'O2', 'O3', 'A', 'B', 'C', 'E'), pts, strict=True))

    def _layup_shapes(self, t: float, theta: float, views: dict[str, np.ndarray]) -> list[Shape]:
        j = self._layup_joints(theta)
        links = np.stack([j['O1'], j['A'], j['A'], j['B'], j['O2'], j['C'], j['C'], j['E'], j['O3'], j['E']])
        out = [
            self._static['ground'],
            _shape('layup', 'link', 'segments', links, 0.025, _STEEL),
            self._static['pivot'],
            _shape('layup', 'joint', 'points', np.stack([j['A'], j['B'], j['C'], j['E']]), 0.04, _ORANGE),
        ]
        belts = []
        marks = []
        travel = 0.0
        if self._belts:
            pr = self.layup_part.profile
            assert pr is not None  # chute_belts, so a belt profile
            travel = float(pr.v_tr * np.asarray(pr.phase.at(np.array([t]), np.array([theta]))).reshape(-1)[0])
        for pivot, tip in ((j['O2'], j['C']), (j['O3'], j['E'])):
            d = tip - pivot
            n = np.array([-d[2], 0.0, d[0]]) / float(np.linalg.norm(d))
            if n[2] < 0.0:
                n = -n
            a, b = pivot + BELT_GAP * n, tip + BELT_GAP * n
            belts += [a, b]
            if self._belts:
                marks.append(_marks(a, b, travel))
        out.append(_shape('layup', 'belt', 'segments', belts, 0.012, _DARK if self._belts else _GREY))
        out.append(_shape('layup', 'belt_mark', 'points', np.concatenate(marks) if marks else [], 0.02, _ORANGE))
        if self._container:
            out += self._leaves(t, views)
            out += [self._static['wall'], self._static['floor']]
        return out

    def _leaves(self, t: float, views: dict[str, np.ndarray]) -> list[Shape]:
        f = views.get('flights')
        if f is None:
            f = views['flights'] = self.layup_part.flights_view()
        air = (f['t_exit'] <= t) & (f['t_land'] > t)
        x, y, _, _ = leaf_flight.state(
            self._drag, f['x0'][air], f['y0'][air], f['vx'][air], f['vy'][air], t - f['t_exit'][air]
        )
        down = f[(f['t_land'] <= t) & f['inside']]
        down = down[np.argsort(down['t_land'], kind='stable')]
        xl = down['x_land'][-LANDED_SHOWN:]
        return [
            _shape('layup', 'leaf', 'points', _xz(x, y, LAYUP_ORIGIN), 0.05, _LEAF),
            _shape(
                'layup', 'leaf_landed', 'points', _xz(xl, np.full(xl.shape, self._y_floor), LAYUP_ORIGIN), 0.04, _LEAF
            ),
        ]

    # ------------------------------------------------------------------ folder

    def _init_folder(self) -> None:
        scene = self.line.scene
        fl = self.folder_part
        kp: knf.KnifeParams = fl.knife
        cg = scene.machine('cyclogram')
        self._kp = kp
        ox, _, oz = FOLDER_ORIGIN
        self._knife_o = np.array([ox - kp.e, 0.0, oz + kp.s_clear])
        self._L_a = float(cg.L_a)
        self._L_feed = float(cg.L_feed)
        self._stops_x = ox + 0.5 * self._L_a
        self._belt_x0 = self._stops_x - self._L_feed - self._L_a
        self._R_c = 0.5 * float(cg.D_fc)
        self._cyl_c = np.array([self._belt_x0, 0.0, oz - self._R_c - 0.005])
        ang = np.linspace(0.0, TAU, 49)
        self._circle = self._cyl_c + self._R_c * np.stack([np.cos(ang), np.zeros_like(ang), np.sin(ang)], axis=1)
        self._static['table'] = _shape(
            'folder',
            'table',
            'strip',
            [[self._stops_x - self._L_a - 0.02, 0.0, oz], [self._stops_x + 0.05, 0.0, oz]],
            0.01,
            _GREY,
        )
        self._static['stop'] = _shape(
            'folder', 'stop', 'segments', [[self._stops_x, 0.0, oz], [self._stops_x, 0.0, oz + 0.06]], 0.015, _RED
        )
        self._belt_mark_ends = (
            np.array([self._belt_x0, 0.0, oz + 0.012]),
            np.array([self._stops_x - 0.01, 0.0, oz + 0.012]),
        )
        self._static['feed_belt'] = _shape(
            'folder',
            'feed_belt',
            'strip',
            [[self._belt_x0, 0.0, oz + 0.008], [self._stops_x - 0.01, 0.0, oz + 0.008]],
            0.008,
            _DARK,
        )

    def _knife(self, theta: float) -> dict[str, np.ndarray]:
        kp = self._kp
        phi = float(np.mod(self.folder_part.timing.omega_k * theta, TAU))
        s = float(knf.position(kp, phi))
        o = self._knife_o
        pin = o + np.array([kp.r_k * math.sin(phi), 0.0, -kp.r_k * math.cos(phi)])
        tip = o + np.array([kp.e, 0.0, -s])
        return {'knife_centre': o, 'knife_pin': pin, 'knife_tip': tip}

    def _folder_shapes(self, t: float, theta: float, sheets: np.ndarray) -> list[Shape]:
        fl = self.folder_part
        a = fl.timing.omega_c * theta
        spoke = self._cyl_c + self._R_c * np.array([math.cos(-a), 0.0, math.sin(-a)])
        b_t = float(np.asarray(fl.belt.at(np.array([t]), np.array([theta]))).reshape(-1)[0])
        travel = fl.V_tr * b_t
        k = self._knife(theta)
        blade_top = k['knife_tip'] + np.array([0.0, 0.0, 0.08])
        knife = np.stack([k['knife_centre'], k['knife_pin'], k['knife_pin'], k['knife_tip'], k['knife_tip'], blade_top])
        return [
            _shape('folder', 'cylinder', 'strip', np.concatenate([self._circle, [self._cyl_c, spoke]]), 0.01, _STEEL),
            self._static['table'],
            self._static['feed_belt'],
            _shape(
                'folder',
                'belt_mark',
                'points',
                _marks(*self._belt_mark_ends, travel),
                0.015,
                _ORANGE,
            ),
            self._static['stop'],
            _shape('folder', 'knife', 'segments', knife, 0.012, _BLUE),
            _shape('folder', 'knife_pivot', 'points', np.stack(list(k.values())), 0.025, _DARK),
            _shape(
                'folder', 'signature', 'segments', self._folder_sheets(t, k['knife_tip'], sheets, b_t), 0.006, _PAPER
            ),
        ]

    def _sheets_live(self, t: float, views: dict[str, np.ndarray]) -> np.ndarray:
        """The last :data:`_SHEETS_SHOWN` signatures handed over by ``t``, each time not yet come ``inf``."""
        view = views.get('sheets')
        if view is None:
            view = views['sheets'] = self.folder_part.sheets_view()
        sh: np.ndarray = view[~np.isnan(view['t_h']) & (view['t_h'] <= t)][-_SHEETS_SHOWN:].copy()
        for name in ('t_a', 't_c', 't_x', 't_r'):
            sh[name] = np.where(np.isnan(sh[name]) | (sh[name] > t), math.inf, sh[name])
        return sh

    def _folder_sheets(self, t: float, tip: np.ndarray, sheets: np.ndarray, b_t: float) -> np.ndarray:
        _, _, oz = FOLDER_ORIGIN
        z = oz + 0.004
        out: list[list[float]] = []
        columns = (sheets[name].tolist() for name in ('t_a', 't_c', 't_x', 'b_h', 'L'))
        for t_a, t_c, t_x, b_h, length in zip(*columns, strict=True):
            if t < t_a:  # on the feed belt: where the belt has carried it since the hand-over
                done = min(max(self.folder_part.V_tr * (b_t - float(b_h)), 0.0), float(length))
                lead = self._stops_x - float(length) + done
                out += [[lead - self._L_a, 0.0, z], [lead, 0.0, z]]
            elif t < t_c or t_a > t_c:  # at the stops (a jammed one stays there)
                out += [[self._stops_x - self._L_a, 0.0, z], [self._stops_x, 0.0, z]]
            elif t < t_x:  # in the fold: its middle follows the knife edge
                mid = [FOLDER_ORIGIN[0], 0.0, min(z, float(tip[2]))]
                out += [[self._stops_x - self._L_a, 0.0, z], mid, mid, [self._stops_x, 0.0, z]]
        return np.array(out, dtype=float).reshape(-1, 3)

    # ------------------------------------------------------------------ delivery

    def _init_delivery(self) -> None:
        plan = self.folder_part.plan
        assert plan is not None  # called for a scene with a delivery only
        sch = plan.schedule
        self._plan = plan
        self._psi = LAWS[plan.params.law].psi
        self._y_max = plan.params.Lambda * plan.chain.x_max
        ox, _, oz = FOLDER_ORIGIN
        self._p0 = np.array([ox, 0.0, oz - PICKUP_DROP])
        self._span = 2.0 * plan.chain.x_max
        self._radius, self.loop, self._n_car = chain_loop(sch.L_transfer, sch.S, self._span, sch.pitch)
        s = np.linspace(0.0, self.loop, 161)
        path = self._chain_point(s)
        self._static['chain_path'] = _shape(
            'delivery', 'chain_path', 'strip', np.concatenate([path, path[:1]]), 0.01, _DARK
        )
        x0 = self._p0[0] + sch.L_transfer
        self._static['carriage_guide'] = _shape(
            'delivery',
            'carriage_guide',
            'segments',
            [[x0 - plan.rod, 0.0, self._p0[2]], [x0 + self._span, 0.0, self._p0[2]]],
            0.008,
            _GREY,
        )
        grip_rel = self._gripper(np.array([plan.u_rel]))[0]
        self._pile_x = float(grip_rel[0])
        self._pile_top = self._p0[2] - 0.04

    def _chain_point(self, d: np.ndarray, stroke: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """Points of the drawn chain loop at chain travel ``d`` from the pickup, in [0, loop).

        ``stroke``: the points ``_stroke_xz`` gives for those of ``d`` on the stroke, if the caller has them.
        """
        plan = self._plan
        sch = plan.schedule
        L, S, R, span = sch.L_transfer, sch.S, self._radius, self._span
        x0, z0 = float(self._p0[0]), float(self._p0[2])
        d = np.asarray(d, dtype=float)
        x = np.empty(d.shape)
        z = np.empty(d.shape)
        a = d < L
        x[a], z[a] = x0 + d[a], z0
        b = (d >= L) & (d < L + S)
        if b.any():
            x[b], z[b] = self._stroke_xz(plan.path.position(d[b] - L)) if stroke is None else stroke
        xe = x0 + L + span
        c = (d >= L + S) & (d < L + S + math.pi * R)
        w = (d[c] - L - S) / R
        x[c], z[c] = xe + R * np.sin(w), z0 - R + R * np.cos(w)
        e0 = L + S + math.pi * R
        e = (d >= e0) & (d < e0 + L + span)
        x[e], z[e] = xe - (d[e] - e0), z0 - 2.0 * R
        f0 = e0 + L + span
        g = d >= f0
        w = math.pi + (d[g] - f0) / R
        x[g], z[g] = x0 + R * np.sin(w), z0 - R + R * np.cos(w)
        return np.stack([x, np.zeros(d.shape), z], axis=1)

    def _stroke_xz(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        plan = self._plan
        xi = np.where(u > 1.0, 2.0 - u, u)
        x = self._p0[0] + plan.schedule.L_transfer + plan.chain.x_max * u
        z = self._p0[2] + self._y_max * np.asarray(self._psi(xi), dtype=float)
        return x, z

    def _gripper(self, u: np.ndarray, stroke: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """The carriage (gripper B) on its guide for chain pins at stroke positions ``u``: behind the pin by l cos α
        (``stroke``: ``_stroke_xz(u)``, if the caller has it)."""
        x, z = self._stroke_xz(u) if stroke is None else stroke
        rod = self._plan.rod
        alpha = np.arcsin(np.clip((z - self._p0[2]) / rod, -1.0, 1.0))
        return np.stack([x - rod * np.cos(alpha), np.zeros(x.shape), np.full(x.shape, self._p0[2])], axis=1)

    def carriage_travel(self, theta: float) -> np.ndarray:
        """Chain travel since the pickup of the carriages of the loop, slot j = carriage k mod n, in [0, loop)."""
        sch = self._plan.schedule
        base = sch.v_A * (theta - sch.theta_pick0)
        travel: np.ndarray = np.mod(base - sch.pitch * np.arange(self._n_car), self.loop)
        return travel

    def _delivery_shapes(self, t: float, theta: float, live: np.ndarray) -> list[Shape]:
        sch = self._plan.schedule
        d = self.carriage_travel(theta)
        on = (d >= sch.L_transfer) & (d < sch.L_transfer + sch.S)  # the carriages on the stroke
        u = self._plan.path.position(d[on] - sch.L_transfer) if on.any() else np.zeros(0)
        stroke = self._stroke_xz(u) if u.size else None  # their chain pins, computed once for both
        pins = self._chain_point(d, stroke)
        grip = self._gripper(u, stroke) if u.size else np.zeros((0, 3))
        rods = np.stack([pins[on], grip], axis=1).reshape(-1, 3)
        sheets: list[np.ndarray] = []
        columns = (live[name].tolist() for name in ('fate', 't_x', 't_r', 'cycle'))
        for fate, t_x, t_r, cycle in zip(*columns, strict=True):
            if fate == 1 and t_x <= t < t_r:
                j = int(cycle) % self._n_car
                p = pins[j]
                sheets += [p, p - np.array([0.5 * self._L_a, 0.0, 0.0])]
        z_table, _ = self._pile.state(np.array([t]))
        n = int(self._pile.count(np.array([t]))[0])
        height = n * self._pile.thickness + float(z_table[0])  # the stack above the table's start, m
        top = self._pile_top + height
        stack = min(n * self._pile.thickness, PILE_SHOWN)
        half = 0.25 * self._L_a
        bottom = top - stack
        return [
            self._static['chain_path'],
            self._static['carriage_guide'],
            _shape('delivery', 'carriage', 'points', pins, 0.04, _ORANGE),
            _shape('delivery', 'rod', 'segments', rods, 0.01, _STEEL),
            _shape('delivery', 'gripper', 'points', grip, 0.035, _BLUE),
            _shape('delivery', 'signature', 'segments', np.array(sheets).reshape(-1, 3), 0.006, _PAPER),
            _shape(
                'pile',
                'pile',
                'box',
                [[self._pile_x - half, -0.15, bottom], [self._pile_x + half, 0.15, top]],
                0.0,
                _PAPER,
            ),
            _shape(
                'pile',
                'table',
                'box',
                [[self._pile_x - half - 0.02, -0.17, bottom - 0.02], [self._pile_x + half + 0.02, 0.17, bottom]],
                0.0,
                _WOOD,
            ),
        ]

    # ------------------------------------------------------------------ public

    def at(self, t: float) -> tuple[Shape, ...]:
        """The machine at line time ``t`` (s, in the line's last window), in a stable order (module docstring)."""
        return self._at(float(t), {})

    def at_times(self, times: Iterable[float]) -> list[tuple[Shape, ...]]:
        """:meth:`at` of each of ``times`` (of the line's last window), the same shapes: what the line holds
        (its signatures, its leaves' flights) is read once for them all."""
        views: dict[str, np.ndarray] = {}
        return [self._at(float(t), views) for t in times]

    def _at(self, t: float, views: dict[str, np.ndarray]) -> tuple[Shape, ...]:
        """:meth:`at`; ``views``: the line's tables read so far for times of this window (filled here)."""
        theta = _theta(self.line, t)
        out: list[Shape] = []
        if self._layup is not None:
            out += self._layup_shapes(t, theta, views)
        if self._folder is not None:
            live = self._sheets_live(t, views)
            out += self._folder_shapes(t, theta, live)
            if self.folder_part.plan is not None:
                out += self._delivery_shapes(t, theta, live)
        return tuple(out)

    def vertices(self, t: float) -> dict[str, np.ndarray]:
        """Named key points at line time ``t``, (3,) arrays in :data:`LINE_FRAME`.

        ``layup/O1``, ``layup/O2``, ``layup/O3`` (pivots), ``layup/A``, ``layup/B``,
        ``layup/C``, ``layup/E`` (link ends); ``folder/knife_centre``, ``folder/knife_pin``,
        ``folder/knife_tip``; ``delivery/carriage_<j>`` (chain pin of loop slot j: carriage
        k is in slot ``k mod n``) -- each where the scene has the machine.
        """
        t = float(t)
        theta = _theta(self.line, t)
        out: dict[str, np.ndarray] = {}
        if self._layup is not None:
            out.update({f'layup/{k}': v for k, v in self._layup_joints(theta).items()})
        if self._folder is not None:
            out.update({f'folder/{k}': v for k, v in self._knife(theta).items()})
            if self.folder_part.plan is not None:
                pins = self._chain_point(self.carriage_travel(theta))
                out.update({f'delivery/carriage_{j}': p for j, p in enumerate(pins)})
        return out
