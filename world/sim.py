"""The pymunk world: Khepera-like differential-drive robots, walls, static and moving
obstacles, moving targets, noisy range and target sensors.

Physics (docs/design.md sections 2 and 7):

* Each robot is a dynamic circle driven through a kinematic *control body* joined by a
  ``PivotJoint`` (max_bias 0, finite max_force) and a ``GearJoint`` (pymunk's tank
  pattern), so contacts are solved by pymunk and the robot never tunnels.
* One world sub-step is 0.032 s (Webots' basic step). Wheel noise is drawn once per
  wheel per sub-step; the executed wheel speeds give (v, omega), and the robot is
  moved along the exact arc chord of the sub-step (velocity along heading + omega
  dt / 2, magnitude v sinc(omega dt / 2)), so in free space the end pose of a
  sub-step is the exact differential-drive arc.
* pymunk integrates positions before it resolves contacts, so the world runs
  ``PHYSICS_STEPS`` pymunk steps per sub-step (8 ms each; at most 1.25 mm of travel
  per pymunk step bounds the penetration of a fresh contact).
* pymunk also integrates positions with the velocity solved in the previous step;
  for a robot with no contact the world therefore sets the robot body's velocity to
  the commanded one directly, so a command acts in the very sub-step it is given (no
  one-step lag). A robot that touches something is left to the contact solver and
  the joints.

Noise: one seed per world. Independent streams are spawned from it with numpy's
``SeedSequence`` (wheels, target motion, and per robot one stream for range sensors
and one for the target sensor), so reading a sensor more or less often never changes
the wheel noise or the targets' paths, and one robot's reads never change another's.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pymunk
import pymunk.batch as pbatch

from cekm_swarm.robot import KHEPERA
from cekm_swarm.ticks import SUBSTEP_S

from . import _physics as ph
from . import chipmunk as cp
from . import geometry as geo
from .motion import CircleMotion, Fixed, LineMotion, RandomWalk
from .scenario_spec import BODY_RADIUS, Scenario
from .sensors import RangeSensors, target_reading
from .snapshot import static_geometry, world_state

#: Robot body radius (m), axle length (m), wheel speed limit v* (m/s): the Khepera's
#: (cekm_swarm.robot, the one home of the robot's constants).
ROBOT_RADIUS = BODY_RADIUS
AXLE = KHEPERA.axle
V_MAX = KHEPERA.v_max
#: World sub-step (s), from the protocol's clock.
SUBSTEP = SUBSTEP_S
#: pymunk steps per world sub-step.
PHYSICS_STEPS = 4
#: Number of distance sensors.
N_SENSORS = KHEPERA.n_range_sensors
#: Relative half-width of the uniform wheel noise.
WHEEL_NOISE = KHEPERA.wheel_noise
#: Robot mass (kg), about a Khepera's.
ROBOT_MASS = 0.08
#: Wheel traction: the pivot joint's max force (N), about 0.5 m g. With it the robot
#: reaches full speed within one sub-step even when in contact.
TRACTION_FORCE = 0.5 * ROBOT_MASS * 9.81
#: A contact with the same item that resumes within this time (s) after it ended is
#: the same collision (contact solvers flicker when a robot pushes into a corner).
COLLISION_DEBOUNCE = 0.256
#: Max torque of the gear joint (N m).
TRACTION_TORQUE = 0.01


def quantize_speed(v: float, unit: float, v_max: float = V_MAX) -> float:
    """A wheel speed as the Khepera's motor controller executes it: the nearest whole
    number of speed units (half a unit rounds away from zero), at most the largest whole
    number within +-v_max. A command below half a unit is a stop. ``unit`` 0: unchanged."""
    if unit <= 0.0:
        return v
    n = math.floor(abs(v) / unit + 0.5)
    n = min(n, math.floor(v_max / unit + 1e-9))
    return math.copysign(n * unit, v) if n else 0.0


_FIELDS = (
    pbatch.BodyFields.POSITION
    | pbatch.BodyFields.ANGLE
    | pbatch.BodyFields.VELOCITY
    | pbatch.BodyFields.ANGULAR_VELOCITY
)
_SENSOR_ANGLES = np.array([geo.wrap_angle(2.0 * math.pi * j / N_SENSORS) for j in range(N_SENSORS)])


class World:
    """A simulated world built from a :class:`~world.scenario.Scenario`.

    Time advances only through :meth:`step` / :meth:`advance`. The same scenario and
    seed (and the same sequence of calls) give bit-identical results.
    """

    def __init__(self, scenario: Scenario, seed: int | None = None) -> None:
        self.scenario = scenario
        self.seed = int(scenario.seed if seed is None else seed)
        n = len(scenario.robots)
        self._n = n
        self._ids = [r.id for r in scenario.robots]
        self._index = {rid: i for i, rid in enumerate(self._ids)}
        self._k = 0  # sub-steps taken

        # -- noise streams -----------------------------------------------------------
        ss = np.random.SeedSequence(self.seed)
        kids = ss.spawn(2 + 2 * n)
        self._rng_wheels = np.random.Generator(np.random.PCG64(kids[0]))
        self._rng_targets = np.random.Generator(np.random.PCG64(kids[1]))
        self._rng_range = [np.random.Generator(np.random.PCG64(kids[2 + i])) for i in range(n)]
        self._rng_target = [np.random.Generator(np.random.PCG64(kids[2 + n + i])) for i in range(n)]

        # -- space ----------------------------------------------------------------------
        dt = SUBSTEP / PHYSICS_STEPS
        space = pymunk.Space()
        space.gravity = (0.0, 0.0)
        space.iterations = 10
        space.collision_slop = 2e-4
        # correct 20 % of an overlap per pymunk step
        space.collision_bias = 0.8 ** (1.0 / dt)
        self._space = space
        self._cpspace = cp.cp_space(space)
        self._item_of: dict[pymunk.Shape, str] = ph.add_static(space, scenario)

        # robots first, then control bodies, then moving obstacles (batch row order)
        self._bodies, self._shapes, self._controls = ph.add_robots(space, scenario, self._item_of, ROBOT_MASS,
                                                                   ROBOT_RADIUS, TRACTION_FORCE, TRACTION_TORQUE)
        self._robot_of: dict[pymunk.Shape, int] = {shape: i for i, shape in enumerate(self._shapes)}
        self._movers = [o for o in scenario.obstacles if o.motion is not None]
        mover_bodies = []
        for o in self._movers:
            assert o.motion is not None
            body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
            mover_bodies.append(body)
            body.position = o.motion.position(0.0)
            shapes = ph.moving_obstacle_shapes(body, o)
            space.add(body, *shapes)
            for s in shapes:
                self._item_of[s] = f"{o.source} ({o.id})"

        # contact bookkeeping through collision callbacks
        self._touch: list[dict[str, int]] = [dict() for _ in range(n)]
        self._touching = [0] * n
        self._released: list[dict[str, float]] = [dict() for _ in range(n)]
        self._collisions = [0] * n
        self._left_at: list[float | None] = [None] * n  # when first pushed through a boundary wall
        self._collided_with: list[dict[str, int]] = [{} for _ in range(n)]
        space.on_collision(ph.CT_ROBOT, None, begin=self._on_begin, separate=self._on_separate)

        # batch buffers; check the row order once
        self._buf = pbatch.Buffer()
        pbatch.get_space_bodies(space, pbatch.BodyFields.BODY_ID, self._buf)
        ids = list(np.frombuffer(self._buf.int_buf(), dtype=np.uintp))
        expected = [b.id for b in self._bodies + self._controls + mover_bodies]
        # static bodies (pymunk's own static body, once shapes hang on it) come last
        if ids[: len(expected)] != expected or len(ids) - len(expected) > 1:  # pragma: no cover
            raise RuntimeError("unexpected pymunk body order; the batch API cannot be used")
        self._nb = len(ids)
        self._set_buf = pbatch.Buffer()
        self._state = self._read_bodies()

        # commands, targets, stats
        self._cmd = np.zeros((n, 2))
        self._exec = np.zeros((n, 2))
        self._goal: list[tuple[str, Any] | None] = []
        tindex = {t.id: k for k, t in enumerate(scenario.targets)}
        self._tindex = tindex
        self._encoders = np.zeros((n, 2))  # wheel encoders: each wheel's travel (m) since t = 0
        for r in scenario.robots:
            self._goal.append(("target", tindex[r.goal]) if r.goal is not None else None)
        self._tpos = np.array([t.position for t in scenario.targets], dtype=float).reshape(-1, 2)
        self._theading = np.array(
            [t.motion.heading if isinstance(t.motion, RandomWalk) else 0.0 for t in scenario.targets], dtype=float
        )
        self._path = [0.0] * n
        self._contact_steps = [0] * n
        self._sensor_range = scenario.sensor_range
        self._ranges = RangeSensors(space, n, _SENSOR_ANGLES, ROBOT_RADIUS, scenario.sensor_range, self._rng_range,
                                    ph.CAT_RAY, ph.MASK_SEEN)
        self._pose_cache()
        self._ranges.update_clearance(self._px, self._py)

    # ------------------------------------------------------------------ properties
    @property
    def time(self) -> float:
        """Sim time (s): number of sub-steps taken times the sub-step."""
        return self._k * SUBSTEP

    @property
    def substep(self) -> float:
        """Length of one sub-step (0.032 s)."""
        return SUBSTEP

    @property
    def robot_ids(self) -> list[str]:
        """Robot ids in scenario order."""
        return list(self._ids)

    @property
    def target_ids(self) -> list[str]:
        """Target ids in scenario order."""
        return [t.id for t in self.scenario.targets]

    @property
    def sensor_angles(self) -> np.ndarray:
        """Distance-sensor directions relative to heading, shape (12,), in (-pi, pi]."""
        return _SENSOR_ANGLES.copy()

    @property
    def body_radius(self) -> float:
        """Robot body radius (m)."""
        return ROBOT_RADIUS

    @property
    def axle(self) -> float:
        """Axle length (m)."""
        return AXLE

    @property
    def v_max(self) -> float:
        """Wheel speed limit v* (m/s)."""
        return V_MAX

    @property
    def sensor_range(self) -> float:
        """Distance-sensor range from the body surface (m)."""
        return self._sensor_range

    @property
    def target_range(self) -> float:
        """Target sensing range from the robot centre (m); inf if unlimited."""
        return self.scenario.target_range

    # ------------------------------------------------------------------ commands
    def _i(self, robot_id: str) -> int:
        try:
            return self._index[robot_id]
        except KeyError:
            raise KeyError(f"unknown robot id {robot_id!r} (robots: {self._ids})") from None

    def set_wheels(self, robot_id: str, v_l: float, v_r: float) -> None:
        """Set the wheel speeds (m/s), clipped to +-v* and quantized to the plant's speed
        unit (:func:`quantize_speed`, when ``[plant] speed_unit`` > 0); held until changed."""
        i = self._i(robot_id)
        vl, vr = float(v_l), float(v_r)
        if not (math.isfinite(vl) and math.isfinite(vr)):
            raise ValueError(f"wheel speeds must be finite, got ({v_l}, {v_r})")
        vl, vr = min(max(vl, -V_MAX), V_MAX), min(max(vr, -V_MAX), V_MAX)
        unit = self.scenario.speed_unit
        if unit > 0.0:
            vl, vr = quantize_speed(vl, unit), quantize_speed(vr, unit)
        self._cmd[i, 0] = vl
        self._cmd[i, 1] = vr

    def wheel_command(self, robot_id: str) -> tuple[float, float]:
        """The wheel speeds the robot's motor controller holds (m/s): the last command,
        clipped to +-v* and, with ``[plant] speed_unit`` > 0, quantized; slip noise acts on these."""
        i = self._i(robot_id)
        return float(self._cmd[i, 0]), float(self._cmd[i, 1])

    @property
    def speed_unit(self) -> float:
        """Wheel speed unit (m/s) of this world's plant; 0 = continuous speeds."""
        return self.scenario.speed_unit

    def set_goal(self, robot_id: str, goal: str | tuple[float, float]) -> None:
        """Point the robot's target sensor at a target id or at a fixed point (x, y)
        (e.g. the next checkpoint of a planner)."""
        i = self._i(robot_id)
        if isinstance(goal, str):
            if goal not in self._tindex:
                raise KeyError(f"unknown target id {goal!r} (targets: {self.target_ids})")
            self._goal[i] = ("target", self._tindex[goal])
        else:
            x, y = (float(v) for v in goal)
            if not (math.isfinite(x) and math.isfinite(y)):
                raise ValueError(f"goal must be finite, got {goal}")
            self._goal[i] = ("point", (x, y))

    # ------------------------------------------------------------------ stepping
    def _read_bodies(self) -> np.ndarray:
        self._buf.clear()
        pbatch.get_space_bodies(self._space, _FIELDS, self._buf)
        return np.frombuffer(self._buf.float_buf(), dtype=np.float64).reshape(self._nb, 6).copy()

    def _pose_cache(self) -> None:
        n = self._n
        st = self._state
        self._px = st[:n, 0].tolist()
        self._py = st[:n, 1].tolist()
        self._pth = st[:n, 2].tolist()

    def step(self) -> None:
        """Advance exactly one sub-step (0.032 s)."""
        n = self._n
        dt = SUBSTEP
        t0 = self._k * dt
        t1 = (self._k + 1) * dt
        st = self._state
        # executed wheel speeds: commanded x (1 + U(-0.1, 0.1)), per wheel per sub-step
        u = self._rng_wheels.uniform(-WHEEL_NOISE, WHEEL_NOISE, size=(n, 2))
        ex = self._cmd * (1.0 + u)
        self._exec = ex
        self._encoders += ex * dt
        exl = ex.tolist()
        th = self._pth
        touching = self._touching
        new = st.copy()
        rows = []
        for i in range(n):
            vl, vr = exl[i]
            v = 0.5 * (vl + vr)
            w = (vr - vl) / AXLE
            half = 0.5 * w * dt
            # move along the chord of the arc: exact end pose in free space
            vc = v * (math.sin(half) / half if abs(half) > 1e-6 else 1.0 - half * half / 6.0)
            hd = th[i] + half
            rows.append((vc * math.cos(hd), vc * math.sin(hd), w, touching[i] == 0))
        if n:
            vel = np.array([r[:3] for r in rows])
            free = np.array([r[3] for r in rows])
            # control bodies follow their robot and carry the command
            new[n : 2 * n, 0:3] = st[:n, 0:3]
            new[n : 2 * n, 3:6] = vel
            # free robots move exactly as commanded in this sub-step; a robot in
            # contact is left to the contact solver and the joints
            new[:n, 3:6][free] = vel[free]
        # moving obstacles: exactly on their script at t0, chord velocity to t1
        for k, o in enumerate(self._movers):
            assert o.motion is not None
            p0 = o.motion.position(t0)
            p1 = o.motion.position(t1)
            new[2 * n + k] = (p0[0], p0[1], 0.0, (p1[0] - p0[0]) / dt, (p1[1] - p0[1]) / dt, 0.0)
        self._set_buf.set_float_buf(new.reshape(-1))
        pbatch.set_space_bodies(self._space, _FIELDS, self._set_buf)

        h = dt / PHYSICS_STEPS
        if self._k == 0:
            self._space.step(h)  # pymunk's wrapper validates the bodies once
            rest = PHYSICS_STEPS - 1
        else:
            rest = PHYSICS_STEPS
        cp_step = cp.space_step  # bodies are never added or removed after __init__
        sp = self._cpspace
        for _ in range(rest):
            cp_step(sp, h)
        self._k += 1

        self._state = self._read_bodies()
        ox, oy = self._px, self._py
        self._pose_cache()
        px, py = self._px, self._py
        path = self._path
        cs = self._contact_steps
        for i in range(n):
            path[i] += math.hypot(px[i] - ox[i], py[i] - oy[i])
            if touching[i]:
                cs[i] += 1
        if self.scenario.boundary_walls:  # a centre outside walled bounds was pushed through a wall
            x0, y0, x1, y1 = self.scenario.bounds
            for i in range(n):
                if self._left_at[i] is None and not (x0 <= px[i] <= x1 and y0 <= py[i] <= y1):
                    self._left_at[i] = t1
        self._ranges.update_clearance(self._px, self._py)
        self._step_targets(t1)

    def advance(self, duration: float) -> None:
        """Advance round(duration / 0.032) sub-steps."""
        k = round(float(duration) / SUBSTEP)
        if k < 0:
            raise ValueError(f"duration must be >= 0, got {duration}")
        for _ in range(k):
            self.step()

    def _step_targets(self, t: float) -> None:
        for k, tg in enumerate(self.scenario.targets):
            m = tg.motion
            if isinstance(m, Fixed):
                continue
            if isinstance(m, (CircleMotion, LineMotion)):
                self._tpos[k] = m.position(t)
            else:
                x, y, hd = m.step(self._tpos[k, 0], self._tpos[k, 1], self._theading[k], SUBSTEP, self._rng_targets)
                self._tpos[k] = (x, y)
                self._theading[k] = hd

    # ------------------------------------------------------------------ contacts
    def _contact_pairs(self, arb: pymunk.Arbiter) -> list[tuple[int, str]]:
        a, b = arb.shapes
        out = []
        ia = self._robot_of.get(a)
        ib = self._robot_of.get(b)
        if ia is not None:
            out.append((ia, self._item_of[b]))
        if ib is not None:
            out.append((ib, self._item_of[a]))
        return out

    def _on_begin(self, arb: pymunk.Arbiter, space: pymunk.Space, data: Any) -> None:
        now = self._k * SUBSTEP
        for i, item in self._contact_pairs(arb):
            c = self._touch[i].get(item, 0)
            if c == 0 and now - self._released[i].get(item, -math.inf) > COLLISION_DEBOUNCE:
                self._collisions[i] += 1
                self._collided_with[i][item] = self._collided_with[i].get(item, 0) + 1
            self._touch[i][item] = c + 1
            self._touching[i] += 1

    def _on_separate(self, arb: pymunk.Arbiter, space: pymunk.Space, data: Any) -> None:
        for i, item in self._contact_pairs(arb):
            c = self._touch[i].get(item, 0) - 1
            if c <= 0:
                self._touch[i].pop(item, None)
                self._released[i][item] = self._k * SUBSTEP
            else:
                self._touch[i][item] = c
            self._touching[i] = max(0, self._touching[i] - 1)

    # ------------------------------------------------------------------ sensing
    def pose(self, robot_id: str) -> tuple[float, float, float]:
        """True pose (x, y, theta), theta wrapped to (-pi, pi]."""
        i = self._i(robot_id)
        return (self._px[i], self._py[i], geo.wrap_angle(self._pth[i]))

    def true_ranges(self, robot_id: str) -> np.ndarray:
        """Noise-free surface ranges of the 12 sensors (m), NaN beyond range."""
        i = self._i(robot_id)
        return self._ranges.true_ranges(i, self._px[i], self._py[i], self._pth[i])

    def range_readings(self, robot_id: str) -> np.ndarray:
        """The 12 noisy distance readings (m), shape (12,): true surface range x
        (1 + U(-0.1, 0.1)), quantized to 0.005 m; NaN when nothing is within range
        (:class:`world.sensors.RangeSensors`)."""
        i = self._i(robot_id)
        return self._ranges.readings(i, self._px[i], self._py[i], self._pth[i])

    def _goal_xy(self, i: int) -> tuple[float, float]:
        g = self._goal[i]
        if g is None:
            raise ValueError(f"robot {self._ids[i]!r} has no goal (set one with set_goal or robots.goal)")
        if g[0] == "point":
            return g[1]
        k = g[1]
        return (float(self._tpos[k, 0]), float(self._tpos[k, 1]))

    def goal_of(self, robot_id: str) -> tuple[float, float]:
        """True position of the robot's current goal (a target or a set point)."""
        return self._goal_xy(self._i(robot_id))

    def target_reading(self, robot_id: str, target_id: str | None = None) -> tuple[float, float, bool]:
        """(alpha, d, visible) of the robot's goal, or of ``target_id``.

        The target's position in the robot frame, each coordinate x (1 + U(-0.1,
        0.1)), converted to alpha = atan2 in (-pi, pi] and d rounded to 0.001 m
        (alpha = 0 when the rounded d is 0). ``visible`` = true distance <= the
        target range; when not visible, alpha and d are NaN.
        """
        i = self._i(robot_id)
        if target_id is None:
            gx, gy = self._goal_xy(i)
        else:
            if target_id not in self._tindex:
                raise KeyError(f"unknown target id {target_id!r} (targets: {self.target_ids})")
            k = self._tindex[target_id]
            gx, gy = float(self._tpos[k, 0]), float(self._tpos[k, 1])
        return target_reading(self._rng_target[i], (self._px[i], self._py[i], self._pth[i]), (gx, gy),
                              self.scenario.target_range)

    # ------------------------------------------------------------------ records
    def stats(self, robot_id: str) -> dict[str, Any]:
        """path_length_m (sum over sub-steps), collisions (new contacts with a wall, an obstacle
        or a robot: one per item touched; touching the same item again within 0.256 s counts
        once), collisions_with (those counts per item touched), min_clearance_m (smallest
        body-surface distance to any wall/obstacle/robot so far, negative when penetrating; inf
        if the world has nothing else in it), contact_s (time spent touching something, counted
        per sub-step that ends in contact), left_arena_s (when its centre first left the bounds
        of a walled arena, pushed through a wall; None: never)."""
        i = self._i(robot_id)
        return {
            "path_length_m": self._path[i],
            "collisions": self._collisions[i],
            "collisions_with": dict(self._collided_with[i]),
            "min_clearance_m": self._ranges.clear[i],
            "contact_s": self._contact_steps[i] * SUBSTEP,
            "left_arena_s": self._left_at[i],
        }

    def in_contact(self, robot_id: str) -> bool:
        """True if the robot's body touches a wall, obstacle or robot now."""
        return self._touching[self._i(robot_id)] > 0

    def state(self) -> dict[str, Any]:
        """Plain-data snapshot (:func:`world.snapshot.world_state`)."""
        return world_state(self)

    def static_geometry(self) -> dict[str, Any]:
        """Plain-data geometry for drawing and planning (:func:`world.snapshot.static_geometry`)."""
        return static_geometry(self.scenario, ROBOT_RADIUS, self._sensor_range)
