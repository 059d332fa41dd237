"""Drawing one frame of an animation: the machine seen from the side, and the overlays.

The machine's shapes come from the core's scenery (:mod:`folder_line.core.line.scenery`: every
part of every machine at a line time, in the frame ``line``, metres, x along the line, z up; the
mechanisms move in the x-z plane), and are drawn as seen from the side, x to the right and z up,
at equal scale: a ``strip`` as a polyline, ``segments`` as separate lines (point pairs), ``points``
as dots, a ``box`` as the rectangle around its points; each in its colour, its ``width`` (m) drawn
to scale (at least :data:`MIN_LINE_PT` so that a belt stays visible); a pale colour (paper) gets a dark
outline. The axes are fixed for the whole animation (:func:`extent`: every shape over the span), in
metres, with a scale bar; machines and small parts (:data:`PART_LABELS`) are named on the drawing,
clear of each other. A line with the layup and the folder gets two panels (:class:`FrameDrawer`):
the whole line, and the folder with the delivery down to the pile in detail.

Above the drawing, the overlay (:class:`~folder_line.analysis.animation.timeline.OverlayText`): line
time, machine cycle, PackML state (coloured by what it means: running, stopping, stopped,
aborted), the violations on screen, and the time scale.

The figure is drawn once; each frame only redraws the moving shapes and the words (matplotlib's
blitting on the Agg canvas) and hands the pixels over as an RGB array (:meth:`FrameDrawer.draw`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol

import numpy as np

from folder_line.analysis.animation.timeline import OverlayText
from folder_line.analysis.figures import pyplot

if TYPE_CHECKING:  # matplotlib is imported when a frame is drawn (folder_line.analysis.figures.pyplot)
    from matplotlib.artist import Artist
    from matplotlib.axes import Axes

__all__ = [
    'DETAIL_MACHINES',
    'DPI',
    'MIN_LINE_PT',
    'PART_LABELS',
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
_AXES_RECT = (0.07, 0.09, 0.90, 0.67)
#: with other machines in the frame too (the layup), these get a panel of their own at a larger scale: the
#: folder from the folding cylinder to the front stops, and the delivery from the knife down to the pile
DETAIL_MACHINES = ('folder', 'pile')
#: machines that may share the frame with :data:`DETAIL_MACHINES` without a detail panel (a line of its own)
_DETAIL_WITH = ('folder', 'delivery', 'pile')
#: the whole line and the detail: left, bottom, width, height (fractions)
_SPLIT_RECTS = ((0.06, 0.09, 0.47, 0.67), (0.58, 0.09, 0.40, 0.67))
#: where a machine's name goes first (else above it): under the pile, whose carriages pass above it
_LABEL_SIDE: Mapping[str, str] = {'pile': 'below', 'container': 'below'}
#: the frame size the font sizes are set for, px (a smaller frame scales them down)
_DESIGN_SIZE = (1280, 720)
#: parts named on the drawing besides the machines (too small or too plain to recognise), with their names
PART_LABELS: Mapping[tuple[str, str], str] = {
    ('folder', 'cylinder'): 'folding cylinder',
    ('folder', 'knife'): 'knife',
    ('folder', 'stop'): 'front stops',
    ('folder', 'feed_belt'): 'feed belt',
    ('delivery', 'chain_path'): 'chain',
}
#: a colour this light (relative luminance) is drawn with a dark outline: paper on a white frame
_PALE = 0.8
_OUTLINE = (0.35, 0.33, 0.28, 1.0)


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
    parts : dict of (str, str) to (float, float, float, float)
        ``(machine, part)`` -> its box, m.
    """

    x: tuple[float, float]
    z: tuple[float, float]
    machines: dict[str, tuple[float, float, float, float]]
    parts: dict[tuple[str, str], tuple[float, float, float, float]]


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
    parts: dict[tuple[str, str], list[float]] = {}
    for t in times:
        for shape in scenery.at(float(t)):
            xz = _xz(shape)
            xz = xz[np.all(np.isfinite(xz), axis=1)]
            if not xz.size:
                continue
            half = 0.5 * float(shape.width)
            lo, hi = xz.min(axis=0) - half, xz.max(axis=0) + half
            for b in (
                boxes.setdefault(shape.machine, [math.inf, -math.inf, math.inf, -math.inf]),
                parts.setdefault((shape.machine, shape.part), [math.inf, -math.inf, math.inf, -math.inf]),
            ):
                b[0], b[1] = min(b[0], lo[0]), max(b[1], hi[0])
                b[2], b[3] = min(b[2], lo[1]), max(b[3], hi[1])
    if not boxes:
        msg = 'the scenery has no shape to draw at any frame time'
        raise ValueError(msg)
    all_b = np.array(list(boxes.values()))
    return Extent(
        x=(float(all_b[:, 0].min()), float(all_b[:, 1].max())),
        z=(float(all_b[:, 2].min()), float(all_b[:, 3].max())),
        machines={m: (float(b[0]), float(b[1]), float(b[2]), float(b[3])) for m, b in boxes.items()},
        parts={k: (float(b[0]), float(b[1]), float(b[2]), float(b[3])) for k, b in parts.items()},
    )


def _pale(rgba: Sequence[float]) -> bool:
    """Whether a colour is too light to see on white (relative luminance above :data:`_PALE`)."""
    return 0.2126 * rgba[0] + 0.7152 * rgba[1] + 0.0722 * rgba[2] > _PALE


def _inside(x: float, z: float, box: tuple[float, float, float, float]) -> bool:
    return box[0] <= x <= box[1] and box[2] <= z <= box[3]


def _label_places(
    ext: Extent, own: tuple[str, str | None], box: tuple[float, float, float, float], gap: float
) -> list[tuple[float, float, str, str]]:
    """Where a name of ``box`` may go, best first: ``(x, z, ha, va)`` above, below, right, left of it; a place
    inside another machine's box (or another named part's of the same machine) comes last."""
    x0, x1, z0, z1 = box
    xm, zm = 0.5 * (x0 + x1), 0.5 * (z0 + z1)
    places = [
        (xm, z1 + gap, 'center', 'bottom'),
        (xm, z0 - gap, 'center', 'top'),
        (x1 + gap, zm, 'left', 'center'),
        (x0 - gap, zm, 'right', 'center'),
    ]
    machine, part = own
    first = _LABEL_SIDE.get(machine) if part is None else None
    if first == 'below':
        places = [places[1], places[0], *places[2:]]
    others = [b for m, b in ext.machines.items() if m != machine]
    if part is not None:
        others += [b for (m, p), b in ext.parts.items() if m == machine and p != part and (m, p) in PART_LABELS]
    return sorted(places, key=lambda pl: any(_inside(pl[0], pl[1], b) for b in others))


def _overlap(a: tuple[float, float, float, float], b: tuple[float, float, float, float]) -> bool:
    return a[0] < b[1] and b[0] < a[1] and a[2] < b[3] and b[2] < a[3]


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
    """A scale bar's length in the axes' unit, m."""
    return f'{metres:g} m'


@dataclass
class _Gathered:
    """One frame's shapes in one panel, sorted by how they are drawn (a collection each).

    Attributes
    ----------
    segs, seg_rgba, seg_lw
        The lines (strips and segments, m), their colours and widths (pt).
    under, under_lw
        The dark lines under the pale ones (m) and their widths (pt).
    dots, dot_rgba, dot_edge, dot_size
        The points (m), their colours, edge colours and sizes (pt²).
    boxes, box_rgba
        The boxes (lower-left and upper-right corners, m) and their colours.
    """

    segs: list[np.ndarray] = field(default_factory=list)
    seg_rgba: list[Sequence[float]] = field(default_factory=list)
    seg_lw: list[float] = field(default_factory=list)
    under: list[np.ndarray] = field(default_factory=list)
    under_lw: list[float] = field(default_factory=list)
    dots: list[np.ndarray] = field(default_factory=list)
    dot_rgba: list[Sequence[float]] = field(default_factory=list)
    dot_edge: list[Sequence[float]] = field(default_factory=list)
    dot_size: list[float] = field(default_factory=list)
    boxes: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)
    box_rgba: list[Sequence[float]] = field(default_factory=list)


def _gather(shapes: Sequence[ShapeLike], pt_per_m: float) -> _Gathered:
    """Sort one frame's shapes by kind, with their colours and widths at ``pt_per_m`` (pt per m)."""
    g = _Gathered()
    for s in shapes:
        xz = _xz(s)
        if not xz.size:
            continue
        lw = max(float(s.width) * pt_per_m, MIN_LINE_PT)
        rgba = tuple(float(c) for c in s.rgba)
        pale = _pale(rgba)
        if s.kind in ('strip', 'segments'):
            lines = [xz] if s.kind == 'strip' else list(xz[: len(xz) // 2 * 2].reshape(-1, 2, 2))
            g.segs.extend(lines)
            g.seg_rgba.extend([rgba] * len(lines))
            g.seg_lw.extend([lw] * len(lines))
            if pale:
                g.under.extend(lines)
                g.under_lw.extend([lw + 1.6] * len(lines))
        elif s.kind == 'points':
            g.dots.append(xz)
            g.dot_rgba.extend([rgba] * len(xz))
            g.dot_edge.extend([_OUTLINE if pale else rgba] * len(xz))
            g.dot_size.extend([max(lw, MIN_DOT_PT) ** 2] * len(xz))
        elif s.kind == 'box':
            g.boxes.append((xz.min(axis=0), xz.max(axis=0)))
            g.box_rgba.append(rgba)
    return g


@dataclass
class _Panel:
    """One axes of a frame: its limits and scale, and the moving artists it holds now."""

    ax: Axes
    pt_per_m: float
    dynamic: list[Artist]


def _fit(
    x: tuple[float, float], z: tuple[float, float], box_px: tuple[float, float]
) -> tuple[tuple[float, float], tuple[float, float]]:
    """Limits of an axes of ``box_px`` (w, h) holding ``x`` and ``z`` at equal scale: the short range widened
    about its middle."""
    m_per_px = max((x[1] - x[0]) / box_px[0], (z[1] - z[0]) / box_px[1])
    xc, zc = 0.5 * (x[0] + x[1]), 0.5 * (z[0] + z[1])
    hw, hh = 0.5 * m_per_px * box_px[0], 0.5 * m_per_px * box_px[1]
    return (xc - hw, xc + hw), (zc - hh, zc + hh)


class FrameDrawer:
    """Draws frames of one animation (see the module docstring).

    With both the layup and the folder in the scene, the line is 5 m long and the folder's knife
    stroke 8 cm: the frame then has two panels, the whole line (the folder's region framed in it)
    and the folder with the delivery down to the pile in detail (:data:`DETAIL_MACHINES`), at a larger
    scale, both at equal scale in x and z.

    Parameters
    ----------
    ext : Extent
        The fixed axes (:func:`extent`).
    size : (int, int)
        Frame width and height, px.
    title : str
        The first line of the header (the scene, or the bag).
    scale_note : str
        The time scale in words (``slow motion 10x: ...``), the header's second line.
    """

    def __init__(self, ext: Extent, size: tuple[int, int], title: str, scale_note: str) -> None:
        plt = pyplot()
        from matplotlib.collections import LineCollection, PatchCollection  # after pyplot() chose Agg
        from matplotlib.patches import Rectangle

        self._line_collection, self._patch_collection, self._rectangle = LineCollection, PatchCollection, Rectangle
        self.size = size
        w, h = size
        self.fs = fs = max(0.45, min(w / _DESIGN_SIZE[0], h / _DESIGN_SIZE[1]))  # font scale of a smaller frame
        self.fig = fig = plt.figure(figsize=(w / DPI, h / DPI), dpi=DPI, facecolor='white')
        boxes = [ext.machines[m] for m in DETAIL_MACHINES if m in ext.machines]
        split = bool(boxes) and not set(ext.machines) <= set(_DETAIL_WITH)
        whole_rect, detail_rect = _SPLIT_RECTS if split else (_AXES_RECT, _AXES_RECT)
        self.panels = [
            self._panel(whole_rect, ext.x, ext.z, ext, 'the whole line' if split else '', _DETAIL_WITH if split else ())
        ]
        if split:
            dx = _limits((min(b[0] for b in boxes), max(b[1] for b in boxes)), 0.03)
            dz = _limits((min(b[2] for b in boxes), max(b[3] for b in boxes)), 0.15)
            panel = self._panel(
                detail_rect, dx, dz, ext, f'{" and ".join(DETAIL_MACHINES)} in detail', (), DETAIL_MACHINES
            )
            self.panels.append(panel)
            (x0, x1), (z0, z1) = panel.ax.get_xlim(), panel.ax.get_ylim()
            self.panels[0].ax.add_patch(
                self._rectangle(
                    (x0, z0), x1 - x0, z1 - z0, fill=False, edgecolor='#57606a', linestyle='--', linewidth=0.8
                )
            )
        fig.text(0.01, 0.985, title, fontsize=10 * fs, va='top', ha='left', color='#24292f')
        fig.text(0.01, 0.945, scale_note, fontsize=8 * fs, va='top', ha='left', color='#57606a')
        big = {'fontsize': 14 * fs, 'va': 'top', 'ha': 'left', 'animated': True}
        self._head = [
            fig.text(0.01, 0.905, '', family='monospace', **big),
            fig.text(0.30, 0.905, '', family='monospace', **big),
            fig.text(0.58, 0.905, '', weight='bold', **big),
        ]
        self._flags = fig.text(
            0.01,
            0.855,
            '',
            fontsize=10 * fs,
            va='top',
            ha='left',
            family='monospace',
            color=_VIOLATION_COLOUR,
            animated=True,
        )
        fig.canvas.draw()
        self._background = fig.canvas.copy_from_bbox(fig.bbox)

    def _panel(
        self,
        rect: tuple[float, float, float, float],
        x: tuple[float, float],
        z: tuple[float, float],
        ext: Extent,
        heading: str,
        elsewhere: Sequence[str] = (),
        detail: Sequence[str] = (),
    ) -> _Panel:
        """An axes at ``rect`` showing ``x``, ``z`` (m) at equal scale, with the machines' and parts' names (no
        part of a machine ``elsewhere``: a detail panel names them; a ``detail`` panel names the parts of
        :data:`_DETAIL_WITH` and the pile), axes in metres and a scale bar."""
        w, h = self.size
        fs = self.fs
        ax = self.fig.add_axes(rect)
        (x0, x1), (z0, z1) = _fit(_limits(x, 0.04), _limits(z, 0.12), (rect[2] * w, rect[3] * h))
        ax.set_xlim(x0, x1)
        ax.set_ylim(z0, z1)
        ax.set_aspect('equal', adjustable='box')
        ax.set_xlabel('x along the line, m', fontsize=9 * fs)
        ax.set_ylabel('z up, m', fontsize=9 * fs)
        ax.grid(True, color='#d0d7de', linewidth=0.5)
        ax.set_axisbelow(True)
        ax.tick_params(labelsize=8 * fs)
        if heading:
            ax.set_title(heading, fontsize=9 * fs, color='#57606a', loc='left')
        origin, unit = ax.transData.transform([[0.0, 0.0], [1.0, 0.0]])
        pt_per_m = float(unit[0] - origin[0]) * 72.0 / DPI
        gap = 0.012 * (z1 - z0)
        names: list[tuple[tuple[str, str | None], str, tuple[float, float, float, float], bool]] = []
        names += [((m, None), m, box, True) for m, box in ext.machines.items() if not detail or m == 'pile']
        names += [
            ((m, p), PART_LABELS[(m, p)], box, False)
            for (m, p), box in ext.parts.items()
            if (m, p) in PART_LABELS and m not in elsewhere and (not detail or m in _DETAIL_WITH)
        ]
        placed: list[tuple[float, float, float, float]] = []
        for own, name, box, bold in names:
            size_pt = (8.0 if bold else 7.0) * fs
            tw, th = 0.62 * size_pt * len(name) / pt_per_m, 1.3 * size_pt / pt_per_m  # the name's box, m
            best = None
            for px, pz, ha, va in _label_places(ext, own, box, gap):
                lx = px - {'left': 0.0, 'center': 0.5, 'right': 1.0}[ha] * tw
                lz = pz - {'bottom': 0.0, 'center': 0.5, 'top': 1.0}[va] * th
                mine = (lx, lx + tw, lz, lz + th)
                if not (x0 <= mine[0] and mine[1] <= x1 and z0 <= mine[2] and mine[3] <= z1):
                    continue
                if not any(_overlap(mine, other) for other in placed):
                    best = (px, pz, ha, va, mine)
                    break
                if best is None:
                    best = (px, pz, ha, va, mine)
            if best is None:
                continue
            px, pz, ha, va, mine = best
            placed.append(mine)
            ax.text(
                px,
                pz,
                name,
                ha=ha,
                va=va,
                fontsize=(8.0 if bold else 7.0) * fs,
                weight='bold' if bold else 'normal',
                color='#24292f' if bold else '#57606a',
                zorder=4,
                bbox={'boxstyle': 'round,pad=0.15', 'facecolor': 'white', 'edgecolor': 'none', 'alpha': 0.7},
            )
        bar = nice_length(x1 - x0)
        bx, bz = x0 + 0.03 * (x1 - x0), z0 + 0.05 * (z1 - z0)
        ax.plot([bx, bx + bar], [bz, bz], color='black', linewidth=3, solid_capstyle='butt')
        ax.text(bx + 0.5 * bar, bz + gap, _length_text(bar), ha='center', va='bottom', fontsize=8 * fs)
        return _Panel(ax, pt_per_m, [])

    def _shapes(self, panel: _Panel, shapes: Sequence[ShapeLike]) -> list[Artist]:
        """The moving artists of one frame in one panel: one collection per kind of shape (a pale line over a
        dark one)."""
        g = _gather(shapes, panel.pt_per_m)
        out: list[Artist] = []
        ax = panel.ax
        if g.boxes:
            boxes = [self._rectangle((lo[0], lo[1]), hi[0] - lo[0], hi[1] - lo[1]) for lo, hi in g.boxes]
            faces = [(r, gr, b, (1.0 if _pale((r, gr, b)) else 0.25) * a) for r, gr, b, a in g.box_rgba]
            edges = [_OUTLINE if _pale(c) else c for c in g.box_rgba]
            pc = self._patch_collection(boxes, facecolors=faces, edgecolors=edges, linewidths=1.0, animated=True)
            out.append(ax.add_collection(pc))
        if g.under:
            lc = self._line_collection(g.under, colors=[_OUTLINE], linewidths=g.under_lw, animated=True)
            out.append(ax.add_collection(lc))
        if g.segs:
            lc = self._line_collection(
                g.segs, colors=g.seg_rgba, linewidths=g.seg_lw, capstyle='round', joinstyle='round', animated=True
            )
            out.append(ax.add_collection(lc))
        if g.dots:
            xy = np.vstack(g.dots)
            sc = ax.scatter(
                xy[:, 0],
                xy[:, 1],
                s=g.dot_size,
                c=g.dot_rgba,
                edgecolors=g.dot_edge,  # type: ignore[arg-type]  # RGBA sequences: matplotlib's types want tuples
                linewidths=0.6,
                animated=True,
            )
            sc.set_zorder(3)
            out.append(sc)
        return out

    def draw(self, shapes: Sequence[ShapeLike], text: OverlayText) -> np.ndarray:
        """The frame: ``(height, width, 3)`` uint8 RGB."""
        fig, canvas = self.fig, self.fig.canvas
        canvas.restore_region(self._background)
        for panel in self.panels:
            for artist in panel.dynamic:
                artist.remove()
            panel.dynamic = self._shapes(panel, shapes)
            for artist in panel.dynamic:
                panel.ax.draw_artist(artist)
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
