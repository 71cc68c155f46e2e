"""One-strike envs: ``SpinStrike/RodSpin-v0`` and ``SpinStrike/PuckSpeed-v1`` (``-v0``: its
heading-angle action, kept).

Each episode is one strike: the action launches a striker disk at a resting target (a rod or a
puck), the exact solver simulates until no further contact can happen (or ``time_cap``), and the
reward is computed from the target's spin or velocity after the last contact.
"""

from __future__ import annotations

import itertools
import math
from abc import abstractmethod
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from spinstrike.envs import fast
from spinstrike.envs.config import (
    GOAL_BOUND,
    ConfigError,
    PuckSpeedConfig,
    RodSpinConfig,
    build_scene,
    build_world,
)
from spinstrike.envs.core import SpinStrikeEnv, SpinStrikeVectorEnv, Task, check_actions
from spinstrike.envs.layout import ObsField, layout_table
from spinstrike.envs.rendering import (
    BodyDraw,
    Frame,
    Gauge,
    Marker,
    Renderer,
    Vector,
    body_draws,
    body_points,
    strike_times,
    view_need,
)
from spinstrike.physics import SceneError
from spinstrike.physics.layout import FALLBACK_NONFINITE, STATE_COLUMNS, X, Y
from spinstrike.physics.solvers import TRACE_DROPPED, TRACE_ENTRIES

__all__ = ["PuckSpeedEnv", "PuckSpeedTask", "PuckSpeedV1Env", "PuckSpeedV1VectorEnv",
           "PuckSpeedVectorEnv", "PuckSpeedVelocityTask", "RodSpinEnv", "RodSpinTask",
           "RodSpinVectorEnv", "StrikeClip", "rod_spin_after_strike", "rod_spin_max"]

#: longest chunk of a strike, s (the solver's step inside the strike kernel; time_cap is cut into
#: equal chunks of at most this)
CHUNK = 1.0 / 30.0
#: margin between the striker's start and the target's reach, m
START_MARGIN = 0.02


def rod_spin_after_strike(lever, speed, e, inv_mass_sum, inertia):
    """Spin of a resting rod struck with impulse lever ``lever`` (|r x n|, m) by a disk whose
    normal approach speed is ``speed``: ``(1+e) v l / (I (1/m_s + 1/m_r) + l^2)`` (rad/s).

    The seed's §1 closed form is the case ``I = m_r r^2 / 3``, ``l = r cos(theta)`` (seen from the
    striker's frame: the rod moves into a resting point mass).
    """
    return (1.0 + e) * speed * lever / (inertia * inv_mass_sum + lever**2)


def rod_spin_max(half_length, speed, e, inv_mass_sum, inertia):
    """Most spin one strike at ``speed`` can give: the lever ``min(h, sqrt(I K))`` (rad/s).

    It is at the tip (theta = 0 in the seed's terms) only when ``sqrt(I K) >= h``; otherwise a
    lever inside the rod (theta > 0) gives more.
    """
    lever = np.minimum(half_length, np.sqrt(inertia * inv_mass_sum))
    return rod_spin_after_strike(lever, speed, e, inv_mass_sum, inertia), lever


class _StrikeTask(Task):
    """A striker launched at a resting target, batched."""

    TARGET: ClassVar[str]
    SCENE: ClassVar[str]
    ACTIONS = ("offset", "approach", "speed")
    render_fps = 30

    def __init__(self, cfg, batch_size: int, single: bool = False) -> None:
        super().__init__(cfg, batch_size, single)
        scene = build_scene(self.SCENE, cfg, self._body_overrides(cfg),
                            (self.TARGET, "striker"), self.NEEDS, self.REFUSES, self.SHAPES)
        self.world = build_world(self._park_striker(scene), batch_size)
        w = self.world
        self._check_free_table(cfg)
        self._free = True
        self.it = w.index(self.TARGET)
        self.js = w.index("striker")
        # the largest reach the config allows (the scene's target, or the longest rod a
        # randomize range draws), which frames every picture: a view taken from element 0's
        # rod at the first drawing fixed the scale for good, so the same state gave other
        # pixels after another history, and a longer rod drawn later left the frame
        reach = float(w.half_length[0, self.it] + w.radius[0, self.it])
        if "rod_length" in cfg.randomize:
            reach = max(reach, 0.5 * cfg.randomize["rod_length"][1] + float(w.radius[0, self.it]))
        self._view_reach = reach
        if cfg.obs_mode == "pixels":
            self._check_caption_fits(cfg)
        B = batch_size
        self.goal = np.zeros((B, self.GOAL_WIDTH))
        # the compiled strike's buffers (envs.fast): outcome per element, constants, and (when
        # recording) element 0's trace, from which its video frames are sampled
        # chunks of at most CHUNK that end at time_cap exactly (chunks of CHUNK itself ran to
        # the next multiple of 1/30 s past the cap, and contacts after the cap were paid)
        n_chunks = max(1, math.ceil(cfg.time_cap / CHUNK - 1e-9))
        self._sbuf = np.zeros((B, fast.S_COLUMNS))
        sc = np.zeros(fast.SC_SIZE)
        sc[[fast.SC_CHUNK, fast.SC_CHUNKS, fast.SC_TARGET, fast.SC_STRIKER]] = (
            cfg.time_cap / n_chunks, n_chunks, self.it, self.js)
        sc[fast.SC_FREE] = self._free
        self._scfg = sc
        self._strace = fast.strike_trace(n_chunks, w.n_bodies)
        #: element 0's last strike as recorded (``record_trace``; None after a reset), its
        #: reward, and its video frames (drawn up when first asked for)
        self.clip: StrikeClip | None = None
        self._clip_reward = 0.0
        self._clip_frames_cache: list[Frame] | None = None
        #: each element struck since its reset, and the strike's reward (the frame of an
        #: element with no clip: a native vector env's, which records none)
        self._struck = np.zeros(batch_size, dtype=bool)
        self._last_reward = np.zeros(batch_size)
        self._zero_result()
        self._check_observable()

    def _check_observable(self) -> None:
        """Refuse arguments that would set a parameter the observation cannot show: beyond a
        field's bounds the clipped value makes different tasks look alike (a rod_length of 12
        and of 20 both observed as a half length of 5). Element 0 is reset at each corner of the
        ``randomize`` ranges (the fixed values in all) and put back."""
        keys = [k for k in self.CONFIG.RANDOMIZABLE if k in self.cfg.randomize]
        w = self.world
        saved = w.get_state(parameters=True), self.snapshot()
        env = np.zeros(1, dtype=np.int64)
        skip = np.zeros(len(self.LAYOUT), dtype=bool)
        skip[self.GOAL] = True  # drawn by the env within its bounds
        try:
            for corner in itertools.product((0.0, 1.0), repeat=len(keys)):
                u = np.full((1, self.UNIFORMS), 0.5)
                for key, x in zip(keys, corner, strict=True):
                    u[0, self.CONFIG.RANDOMIZABLE.index(key)] = x
                self.reset(env, u)
                flat = self.observe()[0]
                for i, f in enumerate(self.LAYOUT):
                    if not skip[i] and not f.low <= flat[i] <= f.high:
                        drawn = {k: self.cfg.randomize[k][int(x)] for k, x in zip(keys, corner,
                                                                                   strict=True)}
                        raise ConfigError(self._unobservable(f, flat[i], drawn))
        finally:
            w.restore(saved[0])
            self.restore(saved[1])

    GOAL_WIDTH: ClassVar[int] = 1
    SHAPES = {"striker": ("disk", "the action launches a striker disk (its angle is neither set "
                                  "nor observed)")}
    #: checked before the scene (which, given walls, asked for a table size first)
    REFUSES = {"walls": "a strike env measures the strike once no further contact can happen, "
                        "on an unbounded table, and cushions would turn the target first (it was "
                        "measured at time_cap); walls are for the control envs and "
                        "spinstrike.physics.World scenes"}

    def _check_free_table(self, cfg) -> None:
        """A strike is measured on an unbounded frictionless table: once no further contact
        can happen, the target's spin and velocity are the strike's (the closed forms behind
        ``best_reward`` and the oracles assume it). Cushions turn the target and cloth friction
        stops it before then: the strike was measured at rest or at ``time_cap`` (PuckSpeed with
        ``table_friction=0.3`` paid 0 where ``best_reward`` said 1), so they are refused."""
        effects = self.world.effects
        if "table_friction" in effects:
            what = ("table_friction: must be 0" if cfg.table_friction
                    else "effects: 'table_friction' is not allowed")
            raise ConfigError(
                f"{what} for a strike env: the strike is measured once no further contact can "
                f"happen, on an unbounded frictionless table, and cloth friction would stop the "
                f"{self.TARGET} first (reward 0). Table friction is for the control envs and "
                f"spinstrike.physics.World scenes")

    #: the arguments that set each observed parameter (else the scene sets it)
    _SET_BY: ClassVar[dict[str, tuple[str, ...]]] = {
        "log_mass_ratio": ("striker_mass", "target_mass"), "half_length": ("rod_length",),
        "restitution": ("restitution",), "friction": ("friction",)}

    def _unobservable(self, field: ObsField, value: float, drawn: dict) -> str:
        """The message for a parameter the observation would clip, naming what set it."""
        args = [a for a in self._SET_BY.get(field.name, ())
                if getattr(self.cfg, a, None) is not None or a in self.cfg.randomize]
        side = f"above its bound {field.high:g}" if value > field.high else \
            f"below its bound {field.low:g}"
        return (f"{', '.join(args) or 'scene'}: would make the observed {field.name} "
                f"({field.doc}) {value:.8g}, {side}, where the clipped value looks the same for "
                f"every task" + (f" (at the randomize draw {drawn})" if drawn else ""))

    def _check_caption_fits(self, cfg) -> None:
        """A pixel observation shows the goal only in its caption: refuse an ``obs_size`` too
        narrow for it (at 84 x 84 the caption stopped before 'target', and a CNN trained on a
        task it could not see). Every sign of the widest goal is measured: in the font a '+' is
        wider than a '-', and at the width the negative goal needed a positive one's last digit
        was cut."""
        widest = np.asarray(self._widest_goal(cfg), float)
        renderer = Renderer(cfg.obs_size, (1.0, 1.0))
        lack, caption = max(
            (renderer.text_fits(text), text) for text in (
                self._caption_text(0.0, widest * np.reshape(signs, widest.shape))
                for signs in itertools.product((1.0, -1.0), repeat=widest.size)))
        if lack:
            w, h = cfg.obs_size
            raise ConfigError(
                f"obs_size: ({w}, {h}) is too narrow for the pixel observation's caption, the "
                f"only place it shows the goal ({caption!r}): it needs a width of at least "
                f"{w + lack} pixels at height {h}")

    def _park_striker(self, scene):
        """The scene's striker position is only a parking place (every reset and strike places
        the striker): move it clear of the target's reach, which a large ``rod_length`` or
        ``rod_thickness`` can make overlap the scene's own placement."""
        bodies = list(scene.bodies)
        names = [b.name for b in bodies]
        target = bodies[names.index(self.TARGET)]
        k = names.index("striker")
        striker = bodies[k]
        clear = target.half_length + target.core_radius + striker.core_radius + START_MARGIN
        dx = striker.position[0] - target.position[0]
        dy = striker.position[1] - target.position[1]
        if math.hypot(dx, dy) >= clear:
            return scene
        bodies[k] = striker.model_copy(
            update={"position": (target.position[0], target.position[1] + clear)})
        return scene.model_copy(update={"bodies": tuple(bodies)})

    def _body_overrides(self, cfg) -> dict:
        return {"striker": {"mass": cfg.striker_mass}, self.TARGET: {"mass": cfg.target_mass}}

    def _zero_result(self) -> None:
        B = self.batch_size
        self.result_v = np.zeros((B, 2))
        self.result_w = np.zeros(B)
        self.result_vs = np.zeros((B, 2))

    # -- randomisation ------------------------------------------------------------------------
    def _set_random(self, edit, key, value) -> None:
        if key == "striker_mass":
            edit.set_body("striker", mass=value)
        elif key == "target_mass":
            edit.set_body(self.TARGET, mass=value)
        elif key == "rod_length":
            edit.set_body("rod", length=value)
        elif key == "restitution":
            edit.set_material(self.TARGET, "striker", restitution=value)
        elif key == "friction":
            edit.set_material(self.TARGET, "striker", friction=value)

    def _reach(self) -> np.ndarray:
        """[B] largest distance of the target's surface from its centre, m."""
        w = self.world
        return w.half_length[:, self.it] + w.radius[:, self.it]

    def reset(self, env: np.ndarray, uniforms: np.ndarray) -> dict[str, np.ndarray]:
        n_rand = len(self.CONFIG.RANDOMIZABLE)
        u = uniforms[:, n_rand:]
        w = self.world
        with w.edit(env) as e:
            self._apply_random(e, uniforms[:, :n_rand])
            angle = 2 * math.pi * u[:, 0] - math.pi
            centre = 0.1 * (2 * u[:, 1:3] - 1)
            # park the striker where a straight, centred strike would start: beyond the
            # target's reach, so nothing overlaps
            reach = e.half_length[:, self.it] + e.radius[:, self.it]
            dist = reach + e.radius[:, self.js] + START_MARGIN
            normal = np.stack([-np.sin(angle), np.cos(angle)], axis=1)
            pos = np.zeros((len(env), w.n_bodies, 2))
            pos[:, self.it] = centre
            pos[:, self.js] = centre + dist[:, None] * normal
            angles = np.zeros((len(env), w.n_bodies))
            angles[:, self.it] = angle
            e.set_state(positions=pos, angles=angles, velocities=0.0, omegas=0.0)
        self._sample_goal(env, u[:, 3:])
        self._zero_result_rows(env)
        self._struck[env] = False
        if self.clip is not None and 0 in env:
            self._forget_clip()
        return self._reset_info(env)

    def _forget_clip(self) -> None:
        self.clip = None
        self._clip_frames_cache = None

    def _zero_result_rows(self, env) -> None:
        self.result_v[env] = 0.0
        self.result_w[env] = 0.0
        self.result_vs[env] = 0.0

    # -- the strike ---------------------------------------------------------------------------
    @abstractmethod
    def _launch(self, actions: np.ndarray) -> None:
        """Put the striker on its line, moving (subclasses: geometry of the action)."""

    def _put_striker(self, start: np.ndarray, velocity: np.ndarray) -> None:
        """Launch every element's striker from ``start`` [B, 2] at ``velocity`` [B, 2] (the
        compiled strike places it, every other body at rest, and refuses an overlap)."""
        sb = self._sbuf
        sb[:, fast.S_LAUNCH_X:fast.S_LAUNCH_Y + 1] = start
        sb[:, fast.S_LAUNCH_VX:fast.S_LAUNCH_VY + 1] = velocity

    def _speed(self, a: np.ndarray) -> np.ndarray:
        lo, hi = self.cfg.speed_range
        return lo + 0.5 * (a + 1.0) * (hi - lo)

    def _simulate(self) -> dict[str, np.ndarray]:
        """Run every element's strike to its end (``envs.fast.STRIKE``: compiled, each element
        only as long as it needs; pymunk: chunk by chunk from Python, booked by the same code)."""
        sb = self._sbuf
        w = self.world
        if self.record_trace:
            before = w.get_state(), sb.copy()
            self._traced_strike()
            tr = self._strace
            events = int(tr.events.count[TRACE_ENTRIES] + tr.events.count[TRACE_DROPPED])
            contacts = int(tr.contact_count[TRACE_ENTRIES] + tr.contact_count[TRACE_DROPPED])
            if (events > len(tr.events.time) or contacts > len(tr.contacts)) and \
                    len(tr.events.time) < MAX_TRACE_EVENTS:
                # a strike of many contacts (e = 0, a heavy striker) filled the trace, and its
                # frames after that were free flights from the last state kept: the striker
                # drawn up to 27 mm inside the rod. The strike is run again (the same, bit for
                # bit) with room for all of it
                self._strace = fast.strike_trace(
                    len(tr.chunks.time) - 1, w.n_bodies, min(events, MAX_TRACE_EVENTS),
                    max(contacts, len(tr.contacts)))
                w.restore(before[0])
                sb[:] = before[1]
                self._traced_strike()
        else:
            w.run(fast.STRIKE, sb, self._scfg, None)
        refused = np.flatnonzero(sb[:, fast.S_OVERLAP_PAIR] != -1)
        if len(refused):
            b = refused[0]
            p = int(sb[b, fast.S_OVERLAP_PAIR])
            if p < 0:
                raise SceneError(f"strike: the striker's launch in element {b} is not finite")
            raise SceneError(
                f"strike: launching the striker in element {b} would make "
                f"{w.names[w.pair_a[p]]!r} and {w.names[w.pair_b[p]]!r} overlap by "
                f"{-sb[b, fast.S_OVERLAP_GAP]:.3g} m")
        if (sb[:, fast.S_FALLBACK] >= FALLBACK_NONFINITE).any():
            # a strike float64 cannot carry (a launch at 1.5e308 m/s: the rod's speed
            # overflowed, and the env returned it as an ordinary strike), or one the
            # travel bound left unstepped: raised, as world.step raises
            w.check_fallback(sb[:, fast.S_FALLBACK].astype(np.int64),
                             float(self._scfg[fast.SC_CHUNK]))
        self.result_v[:] = sb[:, fast.S_TARGET_VX:fast.S_TARGET_VY + 1]
        self.result_w[:] = sb[:, fast.S_TARGET_W]
        self.result_vs[:] = sb[:, fast.S_STRIKER_VX:fast.S_STRIKER_VY + 1]
        contacts = sb[:, fast.S_CONTACTS].astype(np.int64)
        return {"n_contacts": contacts, "impulse": sb[:, fast.S_IMPULSE].copy(),
                "first_contact_time": sb[:, fast.S_FIRST_TIME].copy(),
                "first_impulse": sb[:, fast.S_FIRST_J].copy(),
                "first_contact_point": sb[:, fast.S_FIRST_PX:fast.S_FIRST_PY + 1].copy(),
                "fallback": sb[:, fast.S_FALLBACK] != 0,
                "sim_time": sb[:, fast.S_SIM_TIME].copy(), "second_contact": contacts >= 2}

    def _traced_strike(self) -> None:
        for counts in (self._strace.events.count, self._strace.chunks.count,
                       self._strace.contact_count):
            counts[:] = 0
        self.world.run(fast.STRIKE_TRACED, self._sbuf, self._scfg, self._strace)

    def step(self, actions, batch_info: bool = True):
        a = check_actions(actions, self.action_shape)
        self._launch(a.reshape(self.batch_size, len(self.ACTIONS)))
        sim = self._simulate()
        reward, terms = self._reward()
        reward = self.dict_reward(reward)
        info = {**sim, **terms, **self._result_info()}
        self._struck[:] = True
        self._last_reward[:] = reward
        if self.record_trace:
            self.clip = self._record_clip()
            self._clip_reward = float(reward[0])
            self._clip_frames_cache = None
        return reward, np.ones(self.batch_size, dtype=bool), info

    def show_rewards(self, rewards: np.ndarray, returns_before=None) -> bool:
        struck = self._struck
        paid = np.asarray(rewards, dtype=np.float64)[struck]
        changed = not np.array_equal(paid, self._last_reward[struck])
        self._last_reward[struck] = paid
        if (self.record_trace and self.clip is not None and struck[0]
                and self._last_reward[0] != self._clip_reward):
            self._clip_reward = float(self._last_reward[0])
            self._clip_frames_cache = None
            changed = True
        return changed

    # -- snapshots ----------------------------------------------------------------------------
    def snapshot(self) -> dict:
        return {"goal": self.goal.copy(), "result_v": self.result_v.copy(),
                "result_w": self.result_w.copy(), "result_vs": self.result_vs.copy(),
                "struck": self._struck.copy(), "last_reward": self._last_reward.copy()}

    def trace(self) -> dict:
        return {"clip": self.clip, "clip_reward": self._clip_reward}

    def put_trace(self, trace: dict) -> None:
        self._forget_clip()
        self.clip = trace.get("clip")
        self._clip_reward = float(trace.get("clip_reward", 0.0))

    def restore(self, snap: dict) -> None:
        self._forget_clip()
        self.goal[:] = snap["goal"]
        self.result_v[:] = snap["result_v"]
        self.result_w[:] = snap["result_w"]
        self.result_vs[:] = snap["result_vs"]
        # what the frame says (before or after the strike): a snapshot's own (one taken before
        # this was kept: not struck)
        self._struck[:] = snap.get("struck", False)
        self._last_reward[:] = snap.get("last_reward", 0.0)

    # -- rendering ----------------------------------------------------------------------------
    def _record_clip(self) -> StrikeClip:
        """Element 0's strike as the solver computed it, sampled at its frames' instants."""
        tr = self._strace
        n_ev, n_ch = int(tr.events.count[TRACE_ENTRIES]), int(tr.chunks.count[TRACE_ENTRIES])
        # the launch and chunk ends first: at a tie, the event's (post-impulse) state wins
        key_time = np.concatenate([tr.chunks.time[:n_ch], tr.events.time[:n_ev]])
        key_state = np.concatenate([tr.chunks.state[:n_ch], tr.events.state[:n_ev]])
        order = np.argsort(key_time, kind="stable")
        contacts = tr.contacts[:int(tr.contact_count[TRACE_ENTRIES])].copy()
        duration = float(self._sbuf[0, fast.S_SIM_TIME])
        # each contact has a frame at its instant, the first MAX_CONTACT_FRAMES of them (a
        # strike of 1,000 contacts was a 35 s video of its first few ms)
        times, factor = strike_times(duration, self.render_fps,
                                     contacts[:MAX_CONTACT_FRAMES, fast.TC_TIME])
        states = np.empty((len(times), self.world.n_bodies, STATE_COLUMNS))
        buf = self.world.buffers
        fast.sample_trace(buf.fbuf, buf.ibuf, 0, key_time[order], key_state[order], times,
                          states)
        return StrikeClip(times, states, contacts, factor, duration,
                          int(tr.events.count[TRACE_DROPPED]))

    def _clip_frames(self, clip: StrikeClip, reward: float) -> list[Frame]:
        """The video frames of a strike: trails, impulse markers (fading over
        ``MARKER_FRAMES``), the panel and gauge; the last frame also shows ghost poses and every
        impulse (it is what ``rgb_array`` shows after the step)."""
        shown = clip.contacts[:MAX_CONTACT_FRAMES]  # the contacts with frames of their own
        frame_of = np.searchsorted(clip.times, shown[:, fast.TC_TIME])
        last_contact = clip.contacts[:, fast.TC_TIME].max() if len(clip.contacts) else np.inf
        points = [[body_points(b) for b in body_draws(self.world, 0, S)] for S in clip.states]
        frames = []
        zoom = self._zoom(0, clip.states[..., X:Y + 1])  # one scale for the whole strike
        for f, S in enumerate(clip.states):
            t = clip.times[f]
            trails = [[points[g][i][k] for g in range(max(0, f - TRAIL_FRAMES), f + 1)]
                      for i in range(len(points[f])) for k in range(len(points[f][i]))]
            markers = [_marker(c, self.it, 1.0 - (f - frame_of[q]) / MARKER_FRAMES)
                       for q, c in enumerate(shown) if 0 <= f - frame_of[q] < MARKER_FRAMES]
            final = f == len(clip.states) - 1
            frames.append(self._video_frame(
                0, S, t, clip.slow_motion, reward if (t >= last_contact or final) else None,
                trails=trails, markers=markers, zoom=zoom))
        last = frames[-1]
        step = max(1, len(clip.states) // 8)
        last.ghosts = [body_draws(self.world, 0, S) for S in clip.states[::step]]
        last.markers = [_marker(c, self.it, 1.0) for c in shown]
        return frames

    def _zoom(self, b: int, positions: np.ndarray) -> float:
        """How far a video frame's view must widen (about the origin, >= 1) to show element
        ``b``'s bodies whole at all of ``positions`` (``[..., N, 2]``): on an unbounded table a
        fast puck or striker can leave the fixed view (1: they stay in it; else 5 % to spare)."""
        need = view_need(positions, self.world.half_length[b] + self.world.radius[b],
                         self.view_half())
        return 1.0 if need <= 1.0 else 1.05 * need

    def _video_frame(self, b: int, S: np.ndarray | None, t: float, slow_motion: int,
                     reward: float | None, trails=(), markers=(),
                     zoom: float | None = None) -> Frame:
        bodies = body_draws(self.world, b, S)
        target = bodies[self.it]
        pace = f"slow motion x{slow_motion}" if slow_motion > 1 else "real time (x1)"
        when = (f"t = {1000 * t:6.1f} ms   {pace}" if slow_motion
                else "after the strike" if reward is not None else "before the strike")
        score = "reward: after the last contact" if reward is None else f"reward {reward:.3f}"
        return Frame(bodies, tuple(self.world.table_half_size[b]),
                     walls="walls" in self.world.effects, trails=list(trails),
                     markers=list(markers), vectors=self._vectors(b, target),
                     gauge=self._gauge(b, target), smooth=True,
                     zoom=self._zoom(b, self.world.state.positions[b] if S is None
                                     else S[:, X:Y + 1]) if zoom is None else zoom,
                     panel=[f"{self.title}   {when}", self._achieved(b, target), score])

    def frame(self, b: int, decorate: bool = True) -> Frame:
        if not decorate:  # the pixel observation (its pixels are a contract: keep it plain)
            return Frame(body_draws(self.world, b), tuple(self.world.table_half_size[b]),
                         walls="walls" in self.world.effects, text=self._caption(b))
        if b == 0 and self.clip is not None:
            return self._strike_frames()[-1]
        # no clip (a native vector env's element): the state now, before or after its strike
        return self._video_frame(b, None, 0.0, 0,
                                 float(self._last_reward[b]) if self._struck[b] else None)

    def step_frames(self) -> list[Frame]:
        """Element 0's last strike, frame by frame (needs ``record_trace``)."""
        return list(self._strike_frames()) if self.clip is not None else [self.frame(0)]

    def _strike_frames(self) -> list[Frame]:
        if self._clip_frames_cache is None:
            self._clip_frames_cache = self._clip_frames(self.clip, self._clip_reward)
        return self._clip_frames_cache

    def _vectors(self, b: int, target: BodyDraw) -> list[Vector]:
        return []

    def view_half(self) -> tuple[float, float]:
        hw = self.world.table_half_size[0]
        if np.all(np.isfinite(hw)):
            return float(hw[0]) + 0.05, float(hw[1]) + 0.05
        r = self._view_reach + float(self.world.radius[0, self.js]) + START_MARGIN
        return 2.2 * r * 1.5, 2.2 * r


#: frames over which a body's motion trail reaches back
TRAIL_FRAMES = 10
#: contacts of a strike with a video frame (and an impulse marker) of their own: the first
MAX_CONTACT_FRAMES = 64
#: the most solver states a strike's trace grows to hold (~0.1 KB each for two bodies)
MAX_TRACE_EVENTS = 500_000
#: frames over which an impulse marker fades out after its contact
MARKER_FRAMES = 12


def _norm(v: np.ndarray) -> np.ndarray:
    """Lengths of the 2-vectors along ``v``'s last axis, by ``np.hypot``: squaring overflowed
    from ~1.3e154 m/s (``speed_range`` and ``target_speed`` take any finite speed), and the
    info's speeds read ``inf`` and PuckSpeed's reward NaN with numpy overflow warnings."""
    return np.hypot(v[..., 0], v[..., 1])


def _polar(vx: float, vy: float) -> str:
    """A velocity as speed and heading (degrees CCW from +x)."""
    return f"{math.hypot(vx, vy):.2f} m/s at {math.degrees(math.atan2(vy, vx)):+4.0f}\u00b0"


def _marker(c: np.ndarray, target: int, fade: float) -> Marker:
    """A traced contact's marker: the push on the target."""
    return Marker.on(target, int(c[fast.TC_A]), int(c[fast.TC_B]), c[fast.TC_PX:fast.TC_PY + 1],
                     c[fast.TC_NX:fast.TC_NY + 1], c[fast.TC_J], fade)


@dataclass(frozen=True)
class StrikeClip:
    """Element 0's last strike as recorded for its video.

    Attributes:
        times: the frames' simulated instants, s from the launch (the regular grid, the end,
            and the instants of the first ``MAX_CONTACT_FRAMES`` contacts:
            ``rendering.strike_times``).
        states: the state rows ``[len(times), N, 6]`` at those instants, sampled from the
            solver's trace (``fast.sample_trace``).
        contacts: ``[C, fast.TRACE_CONTACT]``: each contact's time, point, normal, impulse and
            bodies, as the solver recorded them.
        slow_motion: the video's slow-motion factor (a whole number).
        duration: the strike's simulated time, s (``info['sim_time']``).
        dropped: solver states the trace had no room for (0: the frames are exact; it grows
            to hold ``MAX_TRACE_EVENTS``, running the strike again).
    """

    times: np.ndarray
    states: np.ndarray
    contacts: np.ndarray
    slow_motion: int
    duration: float
    dropped: int


class RodSpinTask(_StrikeTask):
    TARGET = "rod"
    SCENE = "rod_spin"
    SHAPES = {**_StrikeTask.SHAPES,
              "rod": ("rod", "its reward, observation, oracle and best_reward are a rod's (a "
                             "struck disk turns only by contact friction)")}
    NEEDS = {"rotation": "its reward is the rod's spin, which a scene without rotation never "
                         "changes (reward 0 for every action)"}
    CONFIG = RodSpinConfig
    LAYOUT = (
        ObsField("target_spin", -1.0, 1.0,
                 "target spin / max of `target_spin` (CCW > 0); 0 when goal='max'"),
        ObsField("log_mass_ratio", -6.0, 6.0, "log10(striker mass / rod mass)"),
        ObsField("restitution", 0.0, 1.0, "e of the rod-striker pair"),
        ObsField("half_length", 0.0, 5.0, "the rod's half length, m"),
    )
    GOAL = slice(0, 1)
    ACHIEVED = (ObsField("spin", -GOAL_BOUND, GOAL_BOUND,
                         "rod spin after the strike / max target spin"),)
    TITLE = "RodSpin-v0"
    UNIFORMS = len(RodSpinConfig.RANDOMIZABLE) + 4

    def _body_overrides(self, cfg) -> dict:
        out = super()._body_overrides(cfg)
        out["rod"].update(length=cfg.rod_length, thickness=cfg.rod_thickness)
        if cfg.rod_inertia != "capsule":
            out["rod"]["inertia"] = cfg.rod_inertia
        return out

    def _sample_goal(self, env, u) -> None:
        lo, hi = self.cfg.target_spin
        if self.cfg.goal == "target":
            sign = np.where(u[:, 0] < 0.5, -1.0, 1.0)
            self.goal[env, 0] = sign * (lo + (2 * np.abs(u[:, 0] - 0.5)) * (hi - lo))
        else:
            self.goal[env, 0] = 0.0

    def _reset_info(self, env) -> dict[str, np.ndarray]:
        return {"target_spin": self.goal[env, 0].copy()}

    def _launch(self, actions: np.ndarray) -> None:
        w = self.world
        reach = self._reach()
        rs = w.radius[:, self.js]
        offset = actions[:, 0] * (reach + rs)
        alpha = actions[:, 1] * math.radians(self.cfg.approach_max)
        speed = self._speed(actions[:, 2])
        phi = w.state.angles[:, self.it]
        u = np.stack([np.cos(phi), np.sin(phi)], 1)
        n = np.stack([-np.sin(phi), np.cos(phi)], 1)
        # in the rod's frame (xi along the rod, eta along its normal) the striker moves along
        # (sin a, -cos a) on the line whose point closest to the rod's centre is b (cos a, sin a)
        d = np.sin(alpha)[:, None] * u - np.cos(alpha)[:, None] * n
        c = (offset * np.cos(alpha))[:, None] * u + (offset * np.sin(alpha))[:, None] * n
        start = w.state.positions[:, self.it] + c - (reach + rs + START_MARGIN)[:, None] * d
        self._put_striker(start, speed[:, None] * d)

    def analytic(self) -> dict[str, np.ndarray]:
        """Closed-form optimum per element: the largest spin and the lever that gives it."""
        w = self.world
        k = 1.0 / w.mass[:, self.it] + 1.0 / w.mass[:, self.js]
        e = w.restitution("rod", "striker")
        spin_max, lever = rod_spin_max(w.half_length[:, self.it], self.cfg.speed_range[1], e, k,
                                       w.inertia[:, self.it])
        return {"spin_max": spin_max, "lever": lever, "inv_mass_sum": k, "restitution": e}

    def _reward(self):
        spin = self.result_w
        a = self.analytic()
        if self.cfg.goal == "target":
            target = self.goal[:, 0]
            width = self.cfg.reward_width * np.abs(target)
            reward = np.exp(-0.5 * ((spin - target) / width) ** 2)
            reachable = np.minimum(np.abs(target), a["spin_max"])
            best = np.exp(-0.5 * ((reachable - np.abs(target)) / width) ** 2)
        else:
            reward = np.abs(spin) / a["spin_max"]
            best = np.ones(self.batch_size)
        return reward, {"reward_spin": reward.copy(), "best_reward": best,
                        "analytic_max_spin": a["spin_max"], "analytic_best_lever": a["lever"]}

    def _result_info(self) -> dict[str, np.ndarray]:
        return {"spin": self.result_w.copy(), "target_spin": self.goal[:, 0].copy(),
                "rod_velocity": self.result_v.copy(),
                "speed": _norm(self.result_v), "striker_speed": _norm(self.result_vs)}

    def observe(self) -> np.ndarray:
        w = self.world
        return self.by_layout(
            target_spin=self.goal[:, 0] / self.cfg.target_spin[1],
            log_mass_ratio=np.log10(w.mass[:, self.js] / w.mass[:, self.it]),
            restitution=w.restitution("rod", "striker"),
            half_length=w.half_length[:, self.it])

    def achieved(self) -> np.ndarray:
        return (self.result_w / self.cfg.target_spin[1])[:, None]

    @staticmethod
    def goal_reward(achieved, desired, cfg) -> np.ndarray:
        a = achieved[..., 0]
        d = desired[..., 0]
        width = np.maximum(cfg.reward_width * np.abs(d), 1e-12)
        z = (a - d) / width
        # z * z, not z ** 2: on a NumPy scalar (compute_reward on one goal, as SB3's checker and
        # a user call it) ** goes through libm's pow, which can differ from the product by an
        # ulp, while on the batch that step pays it is the product: the reward and
        # compute_reward of the same goals differed about once in 2,000 strikes
        return np.exp(-0.5 * (z * z))

    def _caption(self, b: int) -> str:
        return self._caption_text(self.world.state.omegas[b, self.it], self.goal[b])

    @staticmethod
    def _caption_text(spin, goal) -> str:
        return f"spin {spin:+.2f} rad/s   target {goal[0]:+.2f}"

    @staticmethod
    def _widest_goal(cfg) -> tuple:
        return (cfg.target_spin[1],)

    def _achieved(self, b: int, rod: BodyDraw) -> str:
        if self.cfg.goal == "target":
            return f"spin {rod.omega:+6.2f} rad/s   target {self.goal[b, 0]:+6.2f} rad/s"
        return f"spin {rod.omega:+6.2f} rad/s   goal: the most spin"

    def _gauge(self, b: int, rod: BodyDraw) -> Gauge:
        top = 1.25 * self.cfg.target_spin[1]
        target = self.goal[b, 0] if self.cfg.goal == "target" else None
        return Gauge("rod spin (rad/s): achieved | target", rod.omega, target, -top, top)


class PuckSpeedTask(_StrikeTask):
    TARGET = "puck"
    SCENE = "puck_speed"
    SHAPES = {**_StrikeTask.SHAPES,
              "puck": ("disk", "its oracle and best_reward invert a disk's closed forms")}
    CONFIG = PuckSpeedConfig
    LAYOUT = (
        ObsField("target_vx", -1.0, 1.0, "target velocity x / max of `target_speed`"),
        ObsField("target_vy", -1.0, 1.0, "target velocity y / max of `target_speed`"),
        ObsField("log_mass_ratio", -6.0, 6.0, "log10(striker mass / puck mass)"),
        ObsField("restitution", 0.0, 1.0, "e of the puck-striker pair"),
        ObsField("friction", 0.0, 5.0, "contact friction mu of the puck-striker pair"),
    )
    GOAL = slice(0, 2)
    ACHIEVED = (ObsField("vx", -GOAL_BOUND, GOAL_BOUND, "puck velocity x / max target speed"),
                ObsField("vy", -GOAL_BOUND, GOAL_BOUND, "puck velocity y / max target speed"))
    UNIFORMS = len(PuckSpeedConfig.RANDOMIZABLE) + 5
    GOAL_WIDTH = 2
    TITLE = "PuckSpeed-v0"

    def _sample_goal(self, env, u) -> None:
        lo, hi = self.cfg.target_speed
        speed = lo + u[:, 0] * (hi - lo)
        heading = 2 * math.pi * u[:, 1] - math.pi
        self.goal[env, 0] = speed * np.cos(heading)
        self.goal[env, 1] = speed * np.sin(heading)

    def _reset_info(self, env) -> dict[str, np.ndarray]:
        return {"target_velocity": self.goal[env].copy()}

    def _launch(self, actions: np.ndarray) -> None:
        w = self.world
        reach = self._reach() + w.radius[:, self.js]
        offset = actions[:, 0] * reach
        heading = actions[:, 1] * math.pi
        speed = self._speed(actions[:, 2])
        d = np.stack([np.cos(heading), np.sin(heading)], 1)
        side = np.stack([-np.sin(heading), np.cos(heading)], 1)
        start = (w.state.positions[:, self.it] + offset[:, None] * side
                 - (reach + START_MARGIN)[:, None] * d)
        self._put_striker(start, speed[:, None] * d)

    def analytic(self) -> dict[str, np.ndarray]:
        """Closed form of a centred, frictionless strike: puck speed per unit striker speed."""
        w = self.world
        ms, mp = w.mass[:, self.js], w.mass[:, self.it]
        e = w.restitution("puck", "striker")
        gain = (1 + e) * ms / (ms + mp)
        return {"gain": gain, "speed_max": gain * self.cfg.speed_range[1],
                "speed_min": gain * self.cfg.speed_range[0]}

    def _reward(self):
        target = self.goal
        err = _norm(self.result_v - target)
        t_speed = _norm(target)
        width = self.cfg.reward_width * t_speed
        reward = np.exp(-0.5 * (err / width) ** 2)
        a = self.analytic()
        # every speed up to the fastest centred strike's: a slower one than the slowest
        # centred strike's off centre (cos(theta) of it, frictionless; friction turns and
        # slows it a little, continuously down to a grazing strike's nothing)
        reach = np.minimum(t_speed, a["speed_max"])
        best = np.exp(-0.5 * ((reach - t_speed) / width) ** 2)
        return reward, {"reward_velocity": reward.copy(), "best_reward": best,
                        "analytic_speed_gain": a["gain"]}

    def _result_info(self) -> dict[str, np.ndarray]:
        return {"velocity": self.result_v.copy(), "speed": _norm(self.result_v),
                "spin": self.result_w.copy(), "target_velocity": self.goal.copy(),
                "striker_speed": _norm(self.result_vs)}

    def observe(self) -> np.ndarray:
        w = self.world
        hi = self.cfg.target_speed[1]
        return self.by_layout(
            target_vx=self.goal[:, 0] / hi, target_vy=self.goal[:, 1] / hi,
            log_mass_ratio=np.log10(w.mass[:, self.js] / w.mass[:, self.it]),
            restitution=w.restitution("puck", "striker"),
            friction=w.friction("puck", "striker"))

    def achieved(self) -> np.ndarray:
        return self.result_v / self.cfg.target_speed[1]

    @staticmethod
    def goal_reward(achieved, desired, cfg) -> np.ndarray:
        diff = achieved - desired
        err = _norm(diff)
        width = np.maximum(cfg.reward_width * _norm(desired), 1e-12)
        z = err / width
        return np.exp(-0.5 * (z * z))

    def _caption(self, b: int) -> str:
        return self._caption_text(self.world.state.velocities[b, self.it], self.goal[b])

    @staticmethod
    def _caption_text(v, goal) -> str:
        v = np.broadcast_to(v, (2,))
        return f"puck ({v[0]:+.2f}, {v[1]:+.2f}) m/s   target ({goal[0]:+.2f}, {goal[1]:+.2f})"

    @staticmethod
    def _widest_goal(cfg) -> tuple:
        return (cfg.target_speed[1], cfg.target_speed[1])

    def _achieved(self, b: int, puck: BodyDraw) -> str:
        g = self.goal[b]
        return (f"velocity {_polar(puck.vx, puck.vy)}   target {_polar(*g)}")

    def _gauge(self, b: int, puck: BodyDraw) -> Gauge:
        return Gauge("puck speed (m/s): achieved | target",
                     math.hypot(puck.vx, puck.vy), math.hypot(*self.goal[b]), 0.0,
                     1.25 * self.cfg.target_speed[1])

    def _vectors(self, b: int, puck: BodyDraw) -> list[Vector]:
        return [Vector(puck.x, puck.y, *self.goal[b], colour="target", outline=True),
                Vector(puck.x, puck.y, puck.vx, puck.vy)]


class PuckSpeedVelocityTask(PuckSpeedTask):
    """``PuckSpeed-v1``: the strike's velocity as a vector, not as a heading angle.

    v0's heading is ``pi * a`` with ``a`` in [-1, 1], so a target heading near +-pi needs an
    action at either end of the box, and the best action jumps from +1 to -1 across that line: a
    smooth policy (an MLP) cannot follow it and fails on the episodes whose heading lies near
    the wrap. v1 gives the striker's velocity as ``(vx, vy) = speed_max * (a1, a2)`` (its length
    clipped into ``speed_range``), which is continuous in the target everywhere.
    """

    ACTIONS = ("offset", "velocity_x", "velocity_y")
    TITLE = "PuckSpeed-v1"

    def _launch(self, actions: np.ndarray) -> None:
        w = self.world
        reach = self._reach() + w.radius[:, self.js]
        offset = actions[:, 0] * reach
        d, speed = self.velocity_of(actions[:, 1:3], self.cfg.speed_range)
        side = np.stack([-d[:, 1], d[:, 0]], 1)
        start = (w.state.positions[:, self.it] + offset[:, None] * side
                 - (reach + START_MARGIN)[:, None] * d)
        self._put_striker(start, speed[:, None] * d)

    @staticmethod
    def velocity_of(a: np.ndarray, speed_range) -> tuple[np.ndarray, np.ndarray]:
        """Unit direction [B, 2] and speed [B] of the action's velocity part ``a`` [B, 2]:
        ``speed_max * a``, its length clipped into ``speed_range`` (a zero vector: +x at the
        slowest speed)."""
        lo, hi = speed_range
        norm = np.sqrt((a**2).sum(1))
        safe = norm > 1e-12
        d = np.where(safe[:, None], a / np.where(safe, norm, 1.0)[:, None], [1.0, 0.0])
        return d, np.clip(hi * norm, lo, hi)

    @staticmethod
    def action_for(heading, speed, speed_range) -> np.ndarray:
        """The velocity part of the action that strikes along ``heading`` at ``speed``."""
        hi = speed_range[1]
        return np.array([math.cos(heading), math.sin(heading)]) * (speed / hi)


class _StrikeEnv(SpinStrikeEnv):
    metadata = dict(SpinStrikeEnv.metadata, render_fps=30)


class RodSpinEnv(_StrikeEnv):
    """Strike a free rod once and give it a target spin.

    ## Description
    A rod (a capsule, 0.4 m by default) rests on an unbounded frictionless table at a random
    pose. The agent launches a striker disk at it; the exact solver resolves the impact (and any
    later contact: a spinning rod can come round and hit the striker again) with the seed note's
    impulse law, until no further contact can happen or ``time_cap`` seconds. The reward depends
    on the rod's spin after the last contact.

    ## Action Space
    ``Box(-1, 1, (3,), float32)``, in the rod's frame (so the rod's random pose does not matter):

    * ``offset``: signed distance of the striker's line from the rod's centre, as a fraction of
      ``half_length + thickness/2 + striker radius``, the reach of a square-on strike; at an
      approach angle ``a`` the line meets the rod only where ``|offset| x reach <
      half_length cos(a) + thickness/2 + striker radius``, so part of the box misses
      (``[0.5, 1, 0.5]`` does; ~22 % of uniform random actions in the default config);
    * ``approach``: angle of the striker's velocity from the rod's normal, as a fraction of
      ``approach_max`` (75 deg);
    * ``speed``: strike speed, mapped linearly onto ``speed_range`` (0.5..4 m/s).

    NaN or infinite actions raise ``ValueError``; finite values outside [-1, 1] are clipped.

    ## Observation Space
    ``Box(float32)`` with the layout below (``obs_mode='dict'``: goal-conditioned with
    ``achieved_goal`` = spin after the strike; ``'pixels'``: the rendered frame).

{layout}

    ## Rewards
    ``goal='target'`` (default): a target spin w* is drawn per episode (sign and magnitude in
    ``target_spin``) and ``reward = exp(-((w - w*) / (reward_width |w*|))^2 / 2)``: 1 at the
    target, 0.61 one width away; a miss scores ``exp(-1/(2 reward_width^2))``, what the formula
    gives for zero spin. ``goal='max'``: ``reward = |w| / w_max`` with ``w_max`` the analytic
    largest spin of a strike of one impact (lever ``min(h, sqrt(I (1/m_s + 1/m_r)))``, not
    always at the tip). ``info['best_reward']`` is the best reward the closed forms of one impact
    allow. A strike of several contacts can beat them: at low restitution the striker may
    stay on the rod and push it round (``restitution=0``: |w| up to ~1.56 ``w_max`` found by a
    search, a strike of many contacts), so with ``goal='max'`` a reward above 1 is possible;
    ``info['n_contacts']`` shows such strikes (every contact: 11,036 in one seeded strike at
    e = 0; ``info['impulse']`` sums all their impulses). The exact solver holds that sustained
    contact as a frictionless constraint (``physics.solvers._hold``; it settled it in fixed substeps
    before, ~4x the time, ``info['fallback']``), within ~2e-4 of the converged spin. Strikes where
    the rod, turning fast, left the striker slowly ran out of events in stalled time-of-impact
    searches and were settled (1 in 60 random strikes); a stalled search now adds a
    second-order bound (``physics.events.curved_step``) and none of those settle. A strike it
    still settles (events run out) uses the scene's ``settle_substep`` of 1e-5 s (the
    1 ms default of other scenes was 25 % off there, and a search over actions found that
    error). A ``solver`` argument in exact mode keeps it (its keys override the scene's, the
    others stay); one of another mode replaces the block.

    ## Starting State
    Rod at rest, angle uniform, centre's x and y each uniform in [-0.1, 0.1] m; striker
    parked beside it.

    ## Episode End
    Terminates after the one strike.

    ## Arguments
    See :class:`spinstrike.envs.config.RodSpinConfig` (masses, rod size and inertia,
    restitution, effects, solver, randomisation ranges, goal, obs_mode) and ``render_mode``; or
    one ``config`` dict.

    ## Info
    ``spin`` (rad/s), ``speed``/``rod_velocity`` (m/s), ``striker_speed``, ``n_contacts``,
    ``second_contact``, ``impulse`` (normal impulses summed over the strike's contacts, N s;
    friction's tangential part left out), ``first_impulse``, ``first_contact_point``,
    ``first_contact_time`` (s), ``sim_time``, ``analytic_max_spin``, ``analytic_best_lever``,
    ``best_reward``, ``reward_spin``, ``fallback`` (the solver settled a resting contact,
    or solved a jam without its contact friction: ``physics.StepStats``).

{rendering}    ## Version History
    * v0: initial version.
    """

    TASK = RodSpinTask


class PuckSpeedEnv(_StrikeEnv):
    """Strike a puck once and send it off at a target velocity.

    ## Description
    A puck rests on an unbounded table; the agent launches a striker disk at it. Reward from the
    puck's velocity after the strike against a target speed and heading drawn per episode. With
    ``contact_friction`` on (``friction > 0``) an off-centre strike also spins the puck
    (``info['spin']``).

    ## Action Space
    ``Box(-1, 1, (3,), float32)``: ``offset`` of the striker's line from the puck's centre (as a
    fraction of the sum of radii), ``heading`` of the strike (fraction of pi, CCW from +x),
    ``speed`` (mapped onto ``speed_range``). NaN raises; out-of-range values are clipped.

    ## Observation Space

{layout}

    ## Rewards
    ``reward = exp(-|v - v*|^2 / (2 (reward_width |v*|)^2))``.

    ## Starting State
    Puck at rest, its x and y each uniform in [-0.1, 0.1] m; striker parked beside it.

    ## Episode End
    Terminates after the one strike.

    ## Arguments
    See :class:`spinstrike.envs.config.PuckSpeedConfig`.

    ## Info
    ``velocity``, ``speed``, ``spin``, ``target_velocity``, ``n_contacts``, ``impulse`` (normal
    impulses summed, N s; friction's tangential part left out), ``first_contact_point``,
    ``best_reward``, ``analytic_speed_gain``, ``reward_velocity``.

{rendering}    ## Version History
    * v1 (``PuckSpeed-v1``): the action gives the strike's velocity as a vector; v0's heading
      angle wraps at +-pi, where trained policies fail (see :class:`PuckSpeedV1Env`).
    * v0: initial version.
    """

    TASK = PuckSpeedTask


class PuckSpeedV1Env(PuckSpeedEnv):
    """Strike a puck once and send it off at a target velocity (the strike's velocity given as a
    vector).

    ## Description
    The task of ``PuckSpeed-v0`` (same scene, observation, reward, randomisation and info) with
    a different action: v0 gives the strike's heading as an angle (``pi * a``), which wraps at
    +-pi, so the best action for a target heading near +-pi jumps from one end of the box to the
    other and a smooth policy fails there (PPO, seed 0, shipped config, scored 0.16 on the
    targets within 30 degrees of -x and 0.85 elsewhere, over 300 episodes). v1 gives the
    striker's velocity as a vector, continuous in the target.

    ## Action Space
    ``Box(-1, 1, (3,), float32)``: ``offset`` of the striker's line from the puck's centre (as a
    fraction of the sum of radii, perpendicular to the strike), then ``velocity_x``,
    ``velocity_y``: the striker's velocity is ``speed_range[1] * (velocity_x, velocity_y)``, its
    length clipped into ``speed_range`` (a zero vector strikes along +x at the slowest speed).
    NaN raises; out-of-range values are clipped to [-1, 1].

    ## Observation Space

{layout}

    ## Rewards
    ``reward = exp(-|v - v*|^2 / (2 (reward_width |v*|)^2))``.

    ## Starting State
    Puck at rest, its x and y each uniform in [-0.1, 0.1] m; striker parked beside it.

    ## Episode End
    Terminates after the one strike.

    ## Arguments
    See :class:`spinstrike.envs.config.PuckSpeedConfig`.

    ## Info
    As ``PuckSpeed-v0``: ``velocity``, ``speed``, ``spin``, ``target_velocity``,
    ``n_contacts``, ``impulse``, ``first_contact_point``, ``best_reward``,
    ``analytic_speed_gain``, ``reward_velocity``.

{rendering}    ## Version History
    * v1: the strike's velocity as a vector (v0: heading angle and speed).
    """

    TASK = PuckSpeedVelocityTask


class RodSpinVectorEnv(SpinStrikeVectorEnv):
    """Native vector version of :class:`RodSpinEnv` (one batched world)."""

    TASK = RodSpinTask
    metadata = dict(SpinStrikeVectorEnv.metadata, render_fps=30)


class PuckSpeedVectorEnv(SpinStrikeVectorEnv):
    """Native vector version of :class:`PuckSpeedEnv` (one batched world)."""

    TASK = PuckSpeedTask
    metadata = dict(SpinStrikeVectorEnv.metadata, render_fps=30)


class PuckSpeedV1VectorEnv(SpinStrikeVectorEnv):
    """Native vector version of :class:`PuckSpeedV1Env` (one batched world)."""

    TASK = PuckSpeedVelocityTask
    metadata = dict(SpinStrikeVectorEnv.metadata, render_fps=30)


#: the one-strike envs' Rendering section
_RENDERING = """    ## Rendering
    ``render_mode="rgb_array_list"``: ``render()`` returns the frames since its last call (the
    reset's frame, then each strike): a strike's frames are sampled from the trajectory the
    exact solver computed, slowed by the smallest whole factor that makes the strike last at
    least 1 s at ``render_fps`` (30), with a frame at the very instant of each contact.
    Overlays: the time and slow-motion factor, achieved and target {what},
    the reward once the last contact is past, an impulse marker per contact, motion trails.
    ``"rgb_array"``: the strike's last frame (ghost poses, every impulse); ``"human"``: the
    frames in a window, at the slowed pace. Record them with
    ``spinstrike.envs.recording.RecordEveryFrame`` (Gymnasium's ``RecordVideo`` keeps one frame
    per step). Frames are ``render_size`` (720 x 480); pixel observations ``obs_size``
    (480 x 320), without overlays: the bodies (a spinning body with its arc arrow, as in the
    video) at one scale for every state (set by the largest
    target the config and its ``randomize`` ranges allow) and a caption, the only place they
    show the goal (``obs_size`` too narrow for it is refused: RodSpin needs ~155 pixels of
    width, PuckSpeed ~220).

"""
RodSpinEnv.__doc__ = RodSpinEnv.__doc__.format(
    layout=layout_table(RodSpinTask.LAYOUT),
    rendering=_RENDERING.format(what="spin (a gauge; the spin arrow)"))
PuckSpeedEnv.__doc__ = PuckSpeedEnv.__doc__.format(
    layout=layout_table(PuckSpeedTask.LAYOUT),
    rendering=_RENDERING.format(what="velocity (arrows, a speed gauge)"))
PuckSpeedV1Env.__doc__ = PuckSpeedV1Env.__doc__.format(
    layout=layout_table(PuckSpeedVelocityTask.LAYOUT),
    rendering=_RENDERING.format(what="velocity (arrows, a speed gauge)"))
