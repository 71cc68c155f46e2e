"""Top-down rendering with pygame-ce: ``rgb_array`` frames (no display needed) and ``human``.

Draws the table and its cushions, every body (rods as capsules, disks), an arc arrow showing each
spinning body's direction and rate, the last contacts' impulses as arrows, ghost poses of a strike
(one-strike envs) and a line of text. pygame is imported lazily, when the first frame is drawn.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import numpy as np

__all__ = ["BodyDraw", "Frame", "Renderer"]

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
}


@dataclass
class BodyDraw:
    """One body to draw: name picks the colour; pose in metres and radians (CCW from +x)."""

    name: str
    x: float
    y: float
    angle: float
    radius: float
    half_length: float
    omega: float = 0.0


@dataclass
class Frame:
    """Everything a frame shows."""

    bodies: list[BodyDraw]
    half_size: tuple[float, float]
    walls: bool = False
    contacts: list[tuple[float, float, float, float, float]] = field(default_factory=list)
    ghosts: list[list[BodyDraw]] = field(default_factory=list)
    text: str = ""


class Renderer:
    """Draws :class:`Frame` objects into ``(height, width, 3)`` uint8 arrays.

    Args:
        size: (width, height) in pixels.
        view_half: half extents (m) of the visible area, centred on the origin.
        spin_scale: angular speed (rad/s) drawn as a full-circle arc.
        impulse_scale: impulse (N s) drawn as an arrow of a quarter of the view's height.
    """

    def __init__(self, size: tuple[int, int], view_half: tuple[float, float],
                 spin_scale: float = 30.0, impulse_scale: float = 0.5) -> None:
        self.width, self.height = int(size[0]), int(size[1])
        self.scale = min(self.width / (2 * view_half[0]), self.height / (2 * view_half[1]))
        self.spin_scale = spin_scale
        self.impulse_scale = impulse_scale
        self._pygame = None
        self._surface = None
        self._font = None
        self._window = None
        self._clock = None

    def _init(self):
        if self._pygame is None:
            os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
            try:
                import pygame
            except ImportError as exc:  # pragma: no cover - depends on the install
                raise ImportError(
                    'rendering needs pygame-ce: pip install "spinstrike[render]"') from exc
            pygame.font.init()
            self._pygame = pygame
            self._surface = pygame.Surface((self.width, self.height))
            self._font = pygame.font.Font(None, max(14, self.height // 20))
        return self._pygame

    def _px(self, x: float, y: float) -> tuple[int, int]:
        return (int(round(self.width / 2 + x * self.scale)),
                int(round(self.height / 2 - y * self.scale)))

    def _body(self, surf, b: BodyDraw, colour, width_px: int = 0) -> None:
        pg = self._pygame
        r = max(1, int(round(b.radius * self.scale)))
        if b.half_length > 0:
            c, s = math.cos(b.angle), math.sin(b.angle)
            p0 = self._px(b.x - b.half_length * c, b.y - b.half_length * s)
            p1 = self._px(b.x + b.half_length * c, b.y + b.half_length * s)
            pg.draw.line(surf, colour, p0, p1, max(1, 2 * r) if width_px == 0 else width_px)
            if width_px == 0:
                pg.draw.circle(surf, colour, p0, r)
                pg.draw.circle(surf, colour, p1, r)
        else:
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

    def draw(self, frame: Frame) -> np.ndarray:
        """Draw a frame; return it as ``(height, width, 3)`` uint8."""
        pg = self._init()
        surf = self._surface
        surf.fill(COLOURS["cloth_edge"])
        hw, hh = frame.half_size
        if math.isfinite(hw) and math.isfinite(hh):
            x0, y0 = self._px(-hw, hh)
            x1, y1 = self._px(hw, -hh)
            pg.draw.rect(surf, COLOURS["table"], pg.Rect(x0, y0, x1 - x0, y1 - y0))
            if frame.walls:
                pg.draw.rect(surf, COLOURS["cushion"], pg.Rect(x0, y0, x1 - x0, y1 - y0), 5)
        else:
            surf.fill(COLOURS["table"])
        for ghosts in frame.ghosts:
            for g in ghosts:
                self._body(surf, g, COLOURS["ghost"], width_px=1)
        for b in frame.bodies:
            self._body(surf, b, COLOURS.get(b.name, COLOURS["other"]))
            self._spin_arrow(surf, b)
        for px, py, nx, ny, j in frame.contacts:
            length = min(1.0, j / self.impulse_scale) * 0.25 * self.height
            start = self._px(px, py)
            end = (start[0] + nx * length, start[1] - ny * length)
            pg.draw.line(surf, COLOURS["impulse"], start, end, 3)
            pg.draw.circle(surf, COLOURS["impulse"], start, 4)
        if frame.text:
            surf.blit(self._font.render(frame.text, True, COLOURS["text"]), (8, 6))
        return np.ascontiguousarray(pg.surfarray.array3d(surf).transpose(1, 0, 2))

    def show(self, image: np.ndarray, fps: int) -> None:
        """Show an image in a window (``human`` mode), at most ``fps`` frames per second."""
        pg = self._init()
        if self._window is None:
            pg.display.init()
            self._window = pg.display.set_mode((self.width, self.height))
            pg.display.set_caption("SpinStrike")
            self._clock = pg.time.Clock()
        pg.event.pump()
        self._window.blit(pg.surfarray.make_surface(image.transpose(1, 0, 2)), (0, 0))
        pg.display.flip()
        self._clock.tick(fps)

    def close(self) -> None:
        if self._window is not None:
            self._pygame.display.quit()
            self._window = None
