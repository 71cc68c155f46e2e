"""Top-down rendering with pygame-ce: ``rgb_array`` frames (no display needed) and ``human``.

Two kinds of frame, drawn by one :class:`Renderer`:

* *plain* frames (pixel observations): the table and its cushions, every body (rods as
  capsules, disks), an arc arrow for each spinning body, one caption line. Their pixels are a
  contract (``obs_mode="pixels"``): the overlays below never touch them.
* *video* frames (``render()``): the same, plus a short motion trail of each body, impulse
  markers at contacts (an arrow along the normal, scaled by the impulse, fading out over the
  next frames), ghost poses of a whole strike, velocity arrows (achieved and target), a gauge of
  the achieved against the target value and an information panel (time, slow-motion factor,
  achieved and target spin or speed, reward).

This module also times a strike's video (:func:`strike_times`): how much it is slowed and which
simulated instants become frames. pygame is imported lazily, when the first frame is drawn.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import numpy as np

from spinstrike.physics.layout import ANGLE, OMEGA, VX, VY, X, Y

__all__ = ["BodyDraw", "Frame", "Gauge", "Marker", "Renderer", "Vector", "body_draws",
           "body_points", "strike_times"]

COLOURS = {
    "table": (28, 84, 58),
    "cloth_edge": (18, 60, 40),
    "cushion": (112, 72, 38),
    "rod": (235, 196, 80),
    "puck": (226, 86, 70),
    "striker": (90, 160, 235),
    "mallet": (90, 160, 235),
    "other": (200, 200, 200),
    "spin": (255, 255, 255),
    "impulse": (255, 60, 200),
    "ghost": (255, 255, 255),
    "text": (240, 240, 240),
    "panel": (0, 0, 0),
    "target": (120, 255, 140),
    "velocity": (255, 255, 255),
    "band": (14, 32, 24),
}

#: the smallest impulse (N s) a marker is drawn for: its label's "j = 0.000 N s" below (a body
#: at rest on a cushion, 1e-7 N s a step, was marked every step; a walk had hidden markers
#: under 1 px of arrow instead, 3.6 % of a control env's real contacts at 720 x 480)
SHOWN_IMPULSE = 5e-4

#: opacity (0..255) of the information panel's background
PANEL_ALPHA = 150
#: metres drawn per m/s of a velocity arrow
VELOCITY_SCALE = 0.1
#: padding of the panel's text, pixels
PAD = 6
#: the smallest font a line of text is shrunk to where it is wider than the frame, pixels
MIN_TEXT = 9


@dataclass
class BodyDraw:
    """One body to draw: name picks the colour; pose in metres and radians (CCW from +x); spin
    (rad/s, CCW > 0) and velocity (m/s)."""

    name: str
    x: float
    y: float
    angle: float
    radius: float
    half_length: float
    omega: float = 0.0
    vx: float = 0.0
    vy: float = 0.0


@dataclass
class Marker:
    """An impulse at a contact: point (m), unit direction of the push drawn, normal impulse
    (N s); ``fade`` 1 on the contact's own frame, towards 0 after (see :meth:`on`)."""

    x: float
    y: float
    nx: float
    ny: float
    j: float
    fade: float = 1.0

    @classmethod
    def on(cls, target: int, a: int, b: int, point, normal, j: float,
           fade: float = 1.0) -> Marker:
        """The marker of a contact between bodies a and b (normal from a to b: b is pushed
        along it, a against it), drawn as the push on ``target`` if it is one of them, else on
        a (a cushion, static, is always b)."""
        sign = -1.0 if (a == target or b != target) else 1.0
        return cls(float(point[0]), float(point[1]), sign * float(normal[0]),
                   sign * float(normal[1]), float(j), fade)


@dataclass
class Vector:
    """A velocity arrow from (x, y) (m) of (vx, vy) (m/s); ``colour`` a key of ``COLOURS``;
    ``outline``: drawn thin (a target, not a state)."""

    x: float
    y: float
    vx: float
    vy: float
    colour: str = "velocity"
    outline: bool = False


@dataclass
class Gauge:
    """A bar of an achieved value against its target, on the axis [low, high]."""

    label: str
    value: float
    target: float | None
    low: float
    high: float


@dataclass
class Frame:
    """Everything a frame shows (the fields after ``text`` are the video overlays)."""

    bodies: list[BodyDraw]
    half_size: tuple[float, float]
    walls: bool = False
    ghosts: list[list[BodyDraw]] = field(default_factory=list)
    text: str = ""
    trails: list[list[tuple[float, float]]] = field(default_factory=list)
    markers: list[Marker] = field(default_factory=list)
    vectors: list[Vector] = field(default_factory=list)
    gauge: Gauge | None = None
    panel: list[str] = field(default_factory=list)
    #: draw rods as anti-aliased capsules (video frames; plain frames keep their pixels)
    smooth: bool = False
    #: the renderer's view widened by this factor about the origin (>= 1: a video frame whose
    #: bodies went beyond the view; plain frames keep theirs)
    zoom: float = 1.0


def body_draws(world, b: int, S: np.ndarray | None = None) -> list[BodyDraw]:
    """Element b's bodies of a ``physics.World`` to draw, in its current state or in the state
    rows ``S [N, 6]`` (a traced instant of a strike)."""
    if S is None:
        st = world.state
        pos, ang, vel, om = st.positions[b], st.angles[b], st.velocities[b], st.omegas[b]
    else:
        pos, ang, vel, om = S[:, X:Y + 1], S[:, ANGLE], S[:, VX:VY + 1], S[:, OMEGA]
    return [BodyDraw(world.names[i], *pos[i], ang[i], world.radius[b, i],
                     world.half_length[b, i], om[i], *vel[i]) for i in range(world.n_bodies)]


def view_need(positions: np.ndarray, reach: np.ndarray, view_half) -> float:
    """How far a view of half extents ``view_half`` (m, about the origin) must widen to show
    bodies reaching ``reach`` [N] (m) from their centres at all of ``positions`` [..., N, 2]
    whole: at most 1, they are in it (a ``Frame``'s ``zoom`` of this shows them to the edge)."""
    extent = np.abs(positions) + np.asarray(reach)[:, None]
    return max(float(np.max(extent[..., 0])) / view_half[0],
               float(np.max(extent[..., 1])) / view_half[1])


def body_points(b: BodyDraw) -> list[tuple[float, float]]:
    """The points of a body whose paths make its motion trail (m): the centre, and a rod's
    two tips (they show the spin)."""
    if b.half_length <= 0:
        return [(b.x, b.y)]
    c, s = math.cos(b.angle), math.sin(b.angle)
    h = b.half_length
    return [(b.x, b.y), (b.x + h * c, b.y + h * s), (b.x - h * c, b.y - h * s)]


def strike_times(duration: float, fps: float, contacts: np.ndarray,
                 min_seconds: float = 1.0) -> tuple[np.ndarray, int]:
    """The simulated instants (s) that become a strike's frames, and its slow-motion factor.

    The strike (``duration`` s of simulated time) is slowed by the smallest whole factor that
    makes it last at least ``min_seconds`` at ``fps``; frames fall on the regular grid of
    ``1 / (fps * factor)`` s from 0, then the end of the strike, then every contact instant
    the grid misses (so that each contact has its own frame, at the very instant of the impulse).
    """
    factor = max(1, math.ceil(min_seconds / duration - 1e-9)) if duration > 0 else 1
    h = 1.0 / (fps * factor)
    n = int(math.floor(duration / h + 1e-9))
    grid = np.arange(n + 1) * h
    times = np.concatenate([grid, [duration], np.asarray(contacts, dtype=float)])
    times = np.unique(times[(times >= 0.0) & (times <= duration)])
    return times, factor


def _area(rect) -> int:
    return rect.width * rect.height


def _mix(colour, background, fade: float) -> tuple[int, int, int]:
    """``colour`` faded towards ``background`` (``fade`` 1: the colour, 0: the background)."""
    f = min(1.0, max(0.0, fade))
    return tuple(int(round(b + (c - b) * f)) for c, b in zip(colour, background, strict=True))


#: a cushion's width in pixels
CUSHION_PX = 5


class Renderer:
    """Draws :class:`Frame` objects into ``(height, width, 3)`` uint8 arrays.

    Args:
        size: (width, height) in pixels.
        view_half: half extents (m) of the visible area, centred on the origin.
        spin_scale: angular speed (rad/s) drawn as a full-circle arc.
        impulse_scale: impulse (N s) drawn as an arrow of a quarter of the view's height.
        panel_lines: lines of text in a band along the top (video frames: the information
            panel and the gauge), which the view then fits below; 0: no band (plain frames).
            A frame too small for the band to take at most half its height shows neither.
    """

    def __init__(self, size: tuple[int, int], view_half: tuple[float, float],
                 spin_scale: float = 30.0, impulse_scale: float = 0.5,
                 panel_lines: int = 0) -> None:
        self.width, self.height = int(size[0]), int(size[1])
        self.text_size = max(14, self.height // 22)
        self.header_size = max(14, self.height // 20)  # a plain frame's text
        # the band's height: pygame's default font takes 3/4 of its size per line
        self.band = (math.ceil(0.75 * self.text_size * panel_lines) + 2 * PAD
                     if panel_lines else 0)
        #: whether video frames show their panel and gauge: not where the band would take more
        #: than half the height (a 64 x 48 frame kept a 4 px strip of table under the text,
        #: and below 44 px the view's scale went negative: the table drawn mirrored, off frame)
        self.panels = 2 * self.band <= self.height
        if not self.panels:
            self.band = 0
        self.scale = min(self.width / (2 * view_half[0]),
                         (self.height - self.band) / (2 * view_half[1]))
        self.spin_scale = spin_scale
        self.impulse_scale = impulse_scale
        self._pygame = None
        self._surface = None
        self._font = None
        self._small = None
        self._fonts: dict[int, object] = {}  # smaller fonts, by size, for text that must fit
        self._window = None
        self._clock = None

    def __getstate__(self) -> dict:
        """Copies and pickles (a vector env that has drawn) keep the geometry; pygame, its
        surfaces, fonts and window are made again at the next draw."""
        return dict(self.__dict__, _pygame=None, _surface=None, _font=None, _small=None,
                    _window=None, _clock=None, _fonts={})

    def _init(self):
        if self._pygame is None:
            os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
            try:
                import pygame
            except ImportError as exc:  # pragma: no cover - depends on the install
                # a ModuleNotFoundError naming pygame: the CLI names the extra in one line
                raise ModuleNotFoundError(
                    'rendering needs pygame-ce: pip install "spinstrike[render]"',
                    name="pygame") from exc
            pygame.font.init()
            self._pygame = pygame
            self._surface = pygame.Surface((self.width, self.height))
            self._font = pygame.font.Font(None, self.header_size)
            self._small = pygame.font.Font(None, self.text_size)
        return self._pygame

    def text_fits(self, text: str) -> int:
        """Pixels of width a plain frame's ``text`` lacks (0: it fits; it starts 8 px in)."""
        self._init()
        return max(0, 8 + self._font.size(text)[0] - self.width)

    def _fitted(self, text: str, font, size: int, room: int):
        """``text`` rendered in ``font`` (of ``size``), or where it is wider than ``room``
        pixels in a smaller one that fits (down to ``MIN_TEXT``): a narrow video cut its
        caption, the only place a strike video states its goal, mid-word (walk W17)."""
        out = font.render(text, True, COLOURS["text"])
        while out.get_width() > room and size > MIN_TEXT:
            size = max(MIN_TEXT, min(size - 1, int(size * room / out.get_width())))
            if size not in self._fonts:
                self._fonts[size] = self._pygame.font.Font(None, size)
            out = self._fonts[size].render(text, True, COLOURS["text"])
        return out

    def _px(self, x: float, y: float) -> tuple[int, int]:
        return (int(round(self.width / 2 + x * self.scale)),
                int(round(self.band + (self.height - self.band) / 2 - y * self.scale)))

    def _capsule(self, surf, b: BodyDraw, colour) -> None:
        """A rod as a filled capsule with anti-aliased edges (video frames)."""
        pg = self._pygame
        c, s = math.cos(b.angle), math.sin(b.angle)
        r = max(1.0, b.radius * self.scale)
        x0, y0 = self._px(b.x - b.half_length * c, b.y - b.half_length * s)
        x1, y1 = self._px(b.x + b.half_length * c, b.y + b.half_length * s)
        nx, ny = -s * r, -c * r  # the rod's normal in screen coordinates (y down)
        corners = [(x0 + nx, y0 + ny), (x1 + nx, y1 + ny), (x1 - nx, y1 - ny), (x0 - nx, y0 - ny)]
        pg.draw.polygon(surf, colour, corners)
        pg.draw.aaline(surf, colour, corners[0], corners[1])
        pg.draw.aaline(surf, colour, corners[2], corners[3])
        for end in ((x0, y0), (x1, y1)):
            pg.draw.aacircle(surf, colour, end, r)
            pg.draw.circle(surf, colour, end, r)

    def _body(self, surf, b: BodyDraw, colour, width_px: int = 0, smooth: bool = False) -> None:
        pg = self._pygame
        r = max(1, int(round(b.radius * self.scale)))
        if b.half_length > 0 and smooth and width_px == 0:
            self._capsule(surf, b, colour)
        elif b.half_length > 0:
            c, s = math.cos(b.angle), math.sin(b.angle)
            p0 = self._px(b.x - b.half_length * c, b.y - b.half_length * s)
            p1 = self._px(b.x + b.half_length * c, b.y + b.half_length * s)
            pg.draw.line(surf, colour, p0, p1, max(1, 2 * r) if width_px == 0 else width_px)
            if width_px == 0:
                pg.draw.circle(surf, colour, p0, r)
                pg.draw.circle(surf, colour, p1, r)
        else:
            if smooth and width_px == 0:
                pg.draw.aacircle(surf, colour, self._px(b.x, b.y), r)
            pg.draw.circle(surf, colour, self._px(b.x, b.y), r, width_px)
            # a tick shows the disk's orientation (and so its spin)
            if width_px == 0:
                tip = self._px(b.x + b.radius * math.cos(b.angle),
                               b.y + b.radius * math.sin(b.angle))
                pg.draw.line(surf, COLOURS["table"], self._px(b.x, b.y), tip, max(1, r // 4))

    def _spin_arrow(self, surf, b: BodyDraw) -> None:
        if abs(b.omega) < 1e-3:
            return
        pg = self._pygame
        radius = (b.half_length + b.radius) * self.scale + 6
        sweep = min(1.0, abs(b.omega) / self.spin_scale) * 2 * math.pi * 0.9
        start = b.angle
        sign = 1.0 if b.omega > 0 else -1.0
        n = 24
        cx, cy = self._px(b.x, b.y)
        pts = [(cx + radius * math.cos(start + sign * sweep * k / n),
                cy - radius * math.sin(start + sign * sweep * k / n)) for k in range(n + 1)]
        pg.draw.lines(surf, COLOURS["spin"], False, pts, 2)
        end = start + sign * sweep
        tangent = (-math.sin(end) * sign, -math.cos(end) * sign)  # screen y points down
        ex, ey = pts[-1]
        left = (ex - 8 * tangent[0] + 5 * tangent[1], ey - 8 * tangent[1] - 5 * tangent[0])
        right = (ex - 8 * tangent[0] - 5 * tangent[1], ey - 8 * tangent[1] + 5 * tangent[0])
        pg.draw.polygon(surf, COLOURS["spin"], [(ex, ey), left, right])

    def _arrow(self, surf, start, end, colour, width: int) -> None:
        """A straight arrow between two pixel points, head at ``end``."""
        pg = self._pygame
        dx, dy = end[0] - start[0], end[1] - start[1]
        length = math.hypot(dx, dy)
        if length < 1.0:
            return
        pg.draw.line(surf, colour, start, end, width)
        ux, uy = dx / length, dy / length
        head = min(10.0, 0.4 * length) + width
        left = (end[0] - head * ux + 0.5 * head * uy, end[1] - head * uy - 0.5 * head * ux)
        right = (end[0] - head * ux - 0.5 * head * uy, end[1] - head * uy + 0.5 * head * ux)
        pg.draw.polygon(surf, colour, [end, left, right])

    def _trails(self, surf, trails) -> None:
        pg = self._pygame
        width = max(2, self.height // 160)
        for trail in trails:
            n = len(trail)
            for k in range(1, n):
                colour = _mix(COLOURS["ghost"], COLOURS["table"], 0.2 + 0.6 * k / n)
                pg.draw.line(surf, colour, self._px(*trail[k - 1]), self._px(*trail[k]), width)

    def _marker(self, surf, m: Marker) -> None:
        pg = self._pygame
        if m.j < SHOWN_IMPULSE:
            return
        colour = _mix(COLOURS["impulse"], COLOURS["table"], m.fade)
        start = self._px(m.x, m.y)
        end = self._marker_end(m)
        width = max(2, self.height // 160)
        self._arrow(surf, start, end, colour, width)
        pg.draw.circle(surf, colour, start, max(4, self.height // 80) + int(6 * m.fade), 2)

    def _marker_end(self, m: Marker) -> tuple[float, float]:
        """Pixels of the head of a marker's arrow."""
        length = min(1.0, m.j / self.impulse_scale) * 0.25 * self.height
        start = self._px(m.x, m.y)
        return start[0] + m.nx * length, start[1] - m.ny * length

    def _label(self, surf, m: Marker, taken: list, disks: list) -> None:
        """A marker's impulse label beside its arrow's head, on the first side that keeps it
        off the ``disks`` (pixel boxes: a striker was hidden under its own label, walk W22b),
        unless its box would overlap one in ``taken`` (labels drawn before in this frame; it
        joins them)."""
        pg = self._pygame
        if m.j < SHOWN_IMPULSE:
            return
        end = self._marker_end(m)
        text = f"j = {m.j:.3f} N s"
        w, h = self._small.size(text)
        # the first place clear of the disks, else the one that covers least of them
        boxes = [pg.Rect(x - 2, y - 1, w + 4, h + 2) for x, y in self._label_at(end, w, h)]
        box = min(boxes, key=lambda b: sum(_area(b.clip(d)) for d in disks))
        at = (box.x + 2, box.y + 1)
        if box.collidelist(taken) >= 0:
            return
        taken.append(box)
        label = self._small.render(text, True, _mix(COLOURS["impulse"], COLOURS["table"], m.fade))
        back = pg.Surface(box.size, pg.SRCALPHA)
        back.fill((*COLOURS["panel"], int(PANEL_ALPHA * m.fade)))
        surf.blit(back, box.topleft)
        surf.blit(label, at)

    def _label_at(self, end, w: int, h: int) -> list[tuple[int, int]]:
        """Where a ``w`` x ``h`` label may go beside an arrow's head at ``end``, best first:
        right of it (left where the right would leave the frame: an impulse at the right
        cushion), then the other side, then above and below it, each kept whole inside the
        frame."""
        right, left = end[0] + 6, end[0] - 6 - w
        sides = [right, left] if right + w + 2 <= self.width else [left, right]
        y = end[1] - h // 2
        places = [(x, y) for x in sides] + [(end[0] - w // 2, end[1] - 6 - h),
                                            (end[0] - w // 2, end[1] + 6)]
        return [(int(min(max(2, x), self.width - w - 2)),
                 int(min(max(1, y), self.height - h - 1))) for x, y in places]

    def _disk_boxes(self, bodies: list[BodyDraw]) -> list:
        """The pixel boxes of the disks among ``bodies`` (a striker, a puck, a mallet), which
        impulse labels keep clear of where they can."""
        pg = self._pygame
        boxes = []
        for b in bodies:
            if b.half_length == 0:
                x, y = self._px(b.x, b.y)
                r = max(1, int(round(b.radius * self.scale)))
                boxes.append(pg.Rect(x - r, y - r, 2 * r + 1, 2 * r + 1))
        return boxes

    def _vector(self, surf, v: Vector) -> None:
        start = self._px(v.x, v.y)
        end = self._px(v.x + VELOCITY_SCALE * v.vx, v.y + VELOCITY_SCALE * v.vy)
        self._arrow(surf, start, end, COLOURS[v.colour], 1 if v.outline else 3)

    def _panel(self, surf, lines: list[str]) -> int:
        """The information panel: lines of text at the top left (in the band, if any; else on
        a translucent box). Returns its width, pixels."""
        pg = self._pygame
        rendered = [self._fitted(line, self._small, self.text_size, self.width - 2 * PAD)
                    for line in lines]
        if not self.band:
            width = max(r.get_width() for r in rendered) + 2 * PAD
            height = sum(r.get_height() for r in rendered) + 2 * PAD
            box = pg.Surface((width, height), pg.SRCALPHA)
            box.fill((*COLOURS["panel"], PANEL_ALPHA))
            surf.blit(box, (0, 0))
        y = PAD
        for r in rendered:
            surf.blit(r, (PAD, y))
            y += r.get_height()
        return max(r.get_width() for r in rendered) + 2 * PAD

    def _gauge(self, surf, g: Gauge, left: int) -> None:
        """The achieved value as a bar on the axis [low, high] (filled from the axis' zero, or
        its low end), the target as a tick: at the top right, under its label, right of
        ``left`` (pixels; left out when that leaves it too little room)."""
        pg = self._pygame
        label = self._small.render(g.label, True, COLOURS["text"])
        x0, x1 = max(int(0.58 * self.width), left + 2 * PAD), self.width - 2 * PAD
        if x1 - x0 < max(label.get_width(), self.width // 5):
            return
        y = PAD + label.get_height() + max(6, self.text_size // 2)
        h = max(8, self.text_size // 2)
        surf.blit(label, (x0, PAD))

        def at(value: float) -> int:
            f = (min(max(value, g.low), g.high) - g.low) / (g.high - g.low)
            return int(round(x0 + f * (x1 - x0)))

        base = at(min(max(0.0, g.low), g.high))
        pg.draw.line(surf, COLOURS["text"], (x0, y), (x1, y), 1)
        pg.draw.line(surf, COLOURS["text"], (base, y - h // 2), (base, y + h // 2), 1)
        end = at(g.value)
        rect = pg.Rect(min(base, end), y - h // 2, max(1, abs(end - base)), h)
        pg.draw.rect(surf, COLOURS["velocity"], rect)
        if g.target is not None:
            t = at(g.target)
            pg.draw.line(surf, COLOURS["target"], (t, y - h), (t, y + h), 3)

    def draw(self, frame: Frame) -> np.ndarray:
        """Draw a frame; return it as ``(height, width, 3)`` uint8."""
        scale = self.scale
        self.scale = scale / max(1.0, frame.zoom)
        try:
            return self._draw(frame)
        finally:
            self.scale = scale

    def _draw(self, frame: Frame) -> np.ndarray:
        pg = self._init()
        surf = self._surface
        surf.fill(COLOURS["cloth_edge"])
        band = pg.Rect(0, 0, self.width, self.band)
        hw, hh = frame.half_size
        if math.isfinite(hw) and math.isfinite(hh):
            x0, y0 = self._px(-hw, hh)
            x1, y1 = self._px(hw, -hh)
            pg.draw.rect(surf, COLOURS["table"], pg.Rect(x0, y0, x1 - x0, y1 - y0))
            if frame.walls:  # video frames: the cushions outside the cloth, whose edge is
                #             the wall a body touches (drawn inside, they hid the last 5 px of
                #             cloth, and a body at rest on a cushion seemed sunk into it);
                #             plain frames (pixel observations) keep their pixels
                out = CUSHION_PX if frame.smooth else 0
                pg.draw.rect(surf, COLOURS["cushion"],
                             pg.Rect(x0 - out, y0 - out, x1 - x0 + 2 * out, y1 - y0 + 2 * out),
                             CUSHION_PX)
        else:
            surf.fill(COLOURS["table"])
        if self.band:
            surf.fill(COLOURS["band"], band)
        self._trails(surf, frame.trails)
        for ghosts in frame.ghosts:
            for g in ghosts:
                self._body(surf, g, COLOURS["ghost"], width_px=1)
        for b in frame.bodies:
            self._body(surf, b, COLOURS.get(b.name, COLOURS["other"]), smooth=frame.smooth)
            self._spin_arrow(surf, b)
        for v in frame.vectors:
            self._vector(surf, v)
        for m in frame.markers:
            self._marker(surf, m)
        # the labels over every arrow: the strongest first (the freshest, then the largest
        # impulse), each where it overlaps none drawn (a jam's hundreds of contacts in one
        # frame piled their labels into an unreadable block)
        taken: list = []
        disks = self._disk_boxes(frame.bodies) if frame.markers else []
        for m in sorted(frame.markers, key=lambda m: (-m.fade, -m.j)):
            self._label(surf, m, taken, disks)
        if frame.text:
            # (a plain frame's room as text_fits counts it: a pixel observation's caption,
            # which must fit, is drawn as it always was; a video's keeps 8 px to the right)
            room = self.width - (16 if frame.smooth else 8)
            surf.blit(self._fitted(frame.text, self._font, self.header_size, room), (8, 6))
        left = self._panel(surf, frame.panel) if frame.panel and self.panels else 0
        if frame.gauge is not None and self.panels:
            self._gauge(surf, frame.gauge, left)
        # a copy through a locked view of the pixels: 5x faster than array3d + transpose
        view = pg.surfarray.pixels3d(surf)
        try:
            return view.transpose(1, 0, 2).copy()
        finally:
            del view

    def show(self, image: np.ndarray, fps: float) -> None:
        """Show an image in a window (``human`` mode), at most ``fps`` frames per second."""
        pg = self._init()
        # pygame has one display: another renderer may have closed it or replaced the window
        if (self._window is None or not pg.display.get_init()
                or pg.display.get_surface() is not self._window):
            pg.display.init()
            self._window = pg.display.set_mode((self.width, self.height))
            pg.display.set_caption("SpinStrike")
            self._clock = pg.time.Clock()
        pg.event.pump()
        self._window.blit(pg.surfarray.make_surface(image.transpose(1, 0, 2)), (0, 0))
        pg.display.flip()
        self._clock.tick(fps)

    def close(self) -> None:
        """Close this renderer's window (if it is still the one shown)."""
        if self._window is not None:
            pg = self._pygame
            if pg.display.get_init() and pg.display.get_surface() is self._window:
                pg.display.quit()
            self._window = None
