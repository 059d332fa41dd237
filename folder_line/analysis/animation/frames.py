"""Drawing one frame of an animation: the machine seen from the side, and the overlays.

The machine's shapes come from the core's scenery (:mod:`folder_line.core.line.scenery`: every
part of every machine at a line time, in the frame ``line``, metres, x along the line, z up; the
mechanisms move in the x-z plane), and are drawn as seen from the side, x to the right and z up,
at equal scale: a ``strip`` as a polyline, ``segments`` as separate lines (point pairs), ``points``
as dots, a ``box`` as the rectangle around its points; each in its colour, its ``width`` (m) drawn
to scale (at least :data:`MIN_LINE_PT` so that a belt stays visible). The axes are fixed for the
whole animation (:func:`extent`: every shape over the span), with axes in metres, a scale bar,
and each machine's name above it.

Above the drawing, the overlay (:class:`~folder_line.analysis.animation.timeline.OverlayText`): line
time, machine cycle, PackML state (coloured by what it means: running, stopping, stopped,
aborted), the violations on screen, and the time scale.

The figure is drawn once; each frame only redraws the moving shapes and the words (matplotlib's
blitting on the Agg canvas) and hands the pixels over as an RGB array (:meth:`FrameDrawer.draw`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from folder_line.analysis.animation.timeline import OverlayText
from folder_line.analysis.figures import pyplot

__all__ = [
    'DPI',
    'MIN_LINE_PT',
    'STATE_COLOURS',
    'Extent',
    'FrameDrawer',
    'SceneryLike',
    'ShapeLike',
    'extent',
]

#: pixels per inch of the canvas (a frame of W x H px is W/DPI x H/DPI inches)
DPI = 100
#: thinnest line drawn, points (a 1 mm belt at 0.5 px/mm would vanish)
MIN_LINE_PT = 0.8
#: smallest dot, points
MIN_DOT_PT = 3.0
#: PackML state -> colour of its word: running green, on its way to a stop amber, stopped grey, aborted red
STATE_COLOURS: Mapping[str, str] = {
    'EXECUTE': '#1a7f37',
    'STARTING': '#1a7f37',
    'UNHOLDING': '#1a7f37',
    'UNSUSPENDING': '#1a7f37',
    'COMPLETING': '#1a7f37',
    'HOLDING': '#b35900',
    'HELD': '#b35900',
    'SUSPENDING': '#b35900',
    'SUSPENDED': '#b35900',
    'STOPPING': '#57606a',
    'STOPPED': '#57606a',
    'IDLE': '#57606a',
    'RESETTING': '#57606a',
    'COMPLETE': '#57606a',
    'CLEARING': '#57606a',
    'ABORTING': '#cf222e',
    'ABORTED': '#cf222e',
}
_VIOLATION_COLOUR = '#cf222e'
#: where the drawing sits in the figure: left, bottom, width, height (fractions); the words above it
_AXES_RECT = (0.07, 0.09, 0.90, 0.70)


class ShapeLike(Protocol):
    """One drawn part of a machine at one line time (:class:`folder_line.core.line.scenery.Shape`)."""

    @property
    def machine(self) -> str: ...

    @property
    def part(self) -> str: ...

    @property
    def kind(self) -> str: ...

    @property
    def points(self) -> np.ndarray: ...

    @property
    def width(self) -> float: ...

    @property
    def rgba(self) -> Sequence[float]: ...


class SceneryLike(Protocol):
    """The machine's shapes at any line time (:class:`folder_line.core.line.scenery.Scenery`)."""

    def at(self, t: float) -> Sequence[ShapeLike]: ...


@dataclass(frozen=True)
class Extent:
    """Where the machine is: the box around every shape over the span, and each machine's own box.

    Attributes
    ----------
    x, z : (float, float)
        Smallest and largest x and z over every shape, m.
    machines : dict of str to (float, float, float, float)
        Machine -> its ``(x_min, x_max, z_min, z_max)``, m, in the order first seen.
    """

    x: tuple[float, float]
    z: tuple[float, float]
    machines: dict[str, tuple[float, float, float, float]]


def _xz(shape: ShapeLike) -> np.ndarray:
    pts = np.asarray(shape.points, dtype=float).reshape(-1, 3)
    return pts[:, (0, 2)]


def extent(scenery: SceneryLike, times: Iterable[float]) -> Extent:
    """The box around every shape of ``scenery`` at ``times`` (the frames' axes stay fixed on it).

    Raises
    ------
    ValueError
        No shape has a point at any of the times.
    """
    boxes: dict[str, list[float]] = {}
    for t in times:
        for shape in scenery.at(float(t)):
            xz = _xz(shape)
            xz = xz[np.all(np.isfinite(xz), axis=1)]
            if not xz.size:
                continue
            half = 0.5 * float(shape.width)
            lo, hi = xz.min(axis=0) - half, xz.max(axis=0) + half
            b = boxes.setdefault(shape.machine, [math.inf, -math.inf, math.inf, -math.inf])
            b[0], b[1] = min(b[0], lo[0]), max(b[1], hi[0])
            b[2], b[3] = min(b[2], lo[1]), max(b[3], hi[1])
    if not boxes:
        msg = 'the scenery has no shape to draw at any frame time'
        raise ValueError(msg)
    all_b = np.array(list(boxes.values()))
    return Extent(
        x=(float(all_b[:, 0].min()), float(all_b[:, 1].max())),
        z=(float(all_b[:, 2].min()), float(all_b[:, 3].max())),
        machines={m: (b[0], b[1], b[2], b[3]) for m, b in boxes.items()},
    )


def _limits(lo_hi: tuple[float, float], pad: float) -> tuple[float, float]:
    """``lo_hi`` widened by ``pad`` of its span on each side (and 2 cm, for a span of nothing)."""
    lo, hi = lo_hi
    margin = pad * (hi - lo) + 0.02
    return lo - margin, hi + margin


def nice_length(span: float) -> float:
    """A round length for a scale bar about a sixth of ``span`` (m): 1, 2, 2.5 or 5 times a power of ten."""
    target = max(span / 6.0, 1e-6)
    power = 10.0 ** math.floor(math.log10(target))
    return max((f * power for f in (1.0, 2.0, 2.5, 5.0) if f * power <= target), default=power)


def _length_text(metres: float) -> str:
    return f'{metres:g} m' if metres >= 1.0 else f'{metres * 1000:g} mm'


class FrameDrawer:
    """Draws frames of one animation (see the module docstring).

    Parameters
    ----------
    ext : Extent
        The fixed axes (:func:`extent`).
    size : (int, int)
        Frame width and height, px.
    title : str
        The first line of the header (the scene, or the bag).
    scale_note : str
        The time scale in words (``video 10 x slower than the line ...``).
    """

    def __init__(self, ext: Extent, size: tuple[int, int], title: str, scale_note: str) -> None:
        plt = pyplot()
        from matplotlib.collections import LineCollection, PatchCollection  # after pyplot() chose Agg
        from matplotlib.patches import Rectangle

        self._line_collection, self._patch_collection, self._rectangle = LineCollection, PatchCollection, Rectangle
        self.size = size
        w, h = size
        self.fig = fig = plt.figure(figsize=(w / DPI, h / DPI), dpi=DPI, facecolor='white')
        ax = self.ax = fig.add_axes(_AXES_RECT)
        ax.set_xlim(*_limits(ext.x, 0.04))
        ax.set_ylim(*_limits(ext.z, 0.10))  # room above for the machines' names
        x0, x1 = ax.get_xlim()
        z0, z1 = ax.get_ylim()
        # equal scale: the range that is short for the axes' box is widened about its middle
        box_w, box_h = _AXES_RECT[2] * w, _AXES_RECT[3] * h
        m_per_px = max((x1 - x0) / box_w, (z1 - z0) / box_h)
        xc, zc = 0.5 * (x0 + x1), 0.5 * (z0 + z1)
        ax.set_xlim(xc - 0.5 * m_per_px * box_w, xc + 0.5 * m_per_px * box_w)
        ax.set_ylim(zc - 0.5 * m_per_px * box_h, zc + 0.5 * m_per_px * box_h)
        ax.set_aspect('equal', adjustable='box')
        ax.set_xlabel('x along the line, m')
        ax.set_ylabel('z up, m')
        ax.grid(True, color='#d0d7de', linewidth=0.5)
        ax.set_axisbelow(True)
        ax.tick_params(labelsize=8)
        fig.text(0.01, 0.975, title, fontsize=10, va='top', ha='left', color='#24292f')
        fig.text(0.99, 0.975, scale_note, fontsize=8, va='top', ha='right', color='#57606a')
        fig.canvas.draw()  # fixes the limits that the equal aspect widened
        x0, x1 = ax.get_xlim()
        z0, z1 = ax.get_ylim()
        for name, (mx0, mx1, _, mz1) in ext.machines.items():
            ax.text(
                0.5 * (mx0 + mx1),
                mz1 + 0.02 * (z1 - z0),
                name,
                ha='center',
                va='bottom',
                fontsize=8,
                color='#24292f',
                bbox={'boxstyle': 'round,pad=0.2', 'facecolor': 'white', 'edgecolor': '#d0d7de', 'alpha': 0.85},
            )
        bar = nice_length(x1 - x0)
        bx, bz = x0 + 0.03 * (x1 - x0), z0 + 0.05 * (z1 - z0)
        ax.plot([bx, bx + bar], [bz, bz], color='black', linewidth=3, solid_capstyle='butt')
        ax.text(bx + 0.5 * bar, bz + 0.015 * (z1 - z0), _length_text(bar), ha='center', va='bottom', fontsize=8)
        origin, unit = ax.transData.transform([[0.0, 0.0], [1.0, 0.0]])
        self.pt_per_m = float(unit[0] - origin[0]) * 72.0 / DPI
        self._head = [
            fig.text(0.01, 0.93, '', fontsize=13, va='top', ha='left', family='monospace', animated=True),
            fig.text(0.40, 0.93, '', fontsize=13, va='top', ha='left', family='monospace', animated=True),
            fig.text(0.63, 0.93, '', fontsize=13, va='top', ha='left', weight='bold', animated=True),
        ]
        self._flags = fig.text(
            0.01,
            0.875,
            '',
            fontsize=10,
            va='top',
            ha='left',
            family='monospace',
            color=_VIOLATION_COLOUR,
            animated=True,
        )
        fig.canvas.draw()
        self._background = fig.canvas.copy_from_bbox(fig.bbox)
        self._dynamic: list[Any] = []

    def _shapes(self, shapes: Sequence[ShapeLike]) -> list[Any]:
        """The moving artists of one frame: one collection per kind of shape."""
        segs: list[np.ndarray] = []
        seg_rgba: list[Sequence[float]] = []
        seg_lw: list[float] = []
        dots: list[np.ndarray] = []
        dot_rgba: list[Sequence[float]] = []
        dot_size: list[float] = []
        boxes: list[Any] = []
        box_rgba: list[Sequence[float]] = []
        for s in shapes:
            xz = _xz(s)
            if not xz.size:
                continue
            lw = max(float(s.width) * self.pt_per_m, MIN_LINE_PT)
            rgba = tuple(float(c) for c in s.rgba)
            if s.kind == 'strip':
                segs.append(xz)
                seg_rgba.append(rgba)
                seg_lw.append(lw)
            elif s.kind == 'segments':
                pairs = xz[: len(xz) // 2 * 2].reshape(-1, 2, 2)
                segs.extend(pairs)
                seg_rgba.extend([rgba] * len(pairs))
                seg_lw.extend([lw] * len(pairs))
            elif s.kind == 'points':
                dots.append(xz)
                dot_rgba.extend([rgba] * len(xz))
                dot_size.extend([max(lw, MIN_DOT_PT) ** 2] * len(xz))
            elif s.kind == 'box':
                lo, hi = xz.min(axis=0), xz.max(axis=0)
                boxes.append(self._rectangle((lo[0], lo[1]), hi[0] - lo[0], hi[1] - lo[1]))
                box_rgba.append(rgba)
        out: list[Any] = []
        ax = self.ax
        if boxes:
            faces = [(r, g, b, 0.18 * a) for r, g, b, a in box_rgba]
            pc = self._patch_collection(boxes, facecolors=faces, edgecolors=box_rgba, linewidths=1.0, animated=True)
            out.append(ax.add_collection(pc))
        if segs:
            lc = self._line_collection(
                segs, colors=seg_rgba, linewidths=seg_lw, capstyle='round', joinstyle='round', animated=True
            )
            out.append(ax.add_collection(lc))
        if dots:
            xy = np.vstack(dots)
            out.append(ax.scatter(xy[:, 0], xy[:, 1], s=dot_size, c=dot_rgba, linewidths=0, animated=True, zorder=3))
        return out

    def draw(self, shapes: Sequence[ShapeLike], text: OverlayText) -> np.ndarray:
        """The frame: ``(height, width, 3)`` uint8 RGB."""
        fig, canvas = self.fig, self.fig.canvas
        for artist in self._dynamic:
            artist.remove()
        self._dynamic = self._shapes(shapes)
        canvas.restore_region(self._background)
        for artist in self._dynamic:
            self.ax.draw_artist(artist)
        time_text, cycle_text, state_text = self._head
        time_text.set_text(text.time)
        cycle_text.set_text(text.cycle)
        state_text.set_text(f'PackML {text.state}')
        state_text.set_color(STATE_COLOURS.get(text.state, '#24292f'))
        lines = [f'VIOLATED {v}' if not v.startswith('+') else v for v in text.violations]
        if text.count and not lines:
            lines = [f'{text.count} violation{"s" if text.count != 1 else ""} so far']
        self._flags.set_text('\n'.join(lines))
        for artist in (*self._head, self._flags):
            fig.draw_artist(artist)
        rgba = np.asarray(canvas.buffer_rgba())
        w, h = self.size
        frame = np.zeros((h, w, 3), dtype=np.uint8) + 255
        hh, ww = min(h, rgba.shape[0]), min(w, rgba.shape[1])
        frame[:hh, :ww] = rgba[:hh, :ww, :3]
        return frame

    def close(self) -> None:
        """Free the figure."""
        pyplot().close(self.fig)
