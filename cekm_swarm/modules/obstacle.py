"""Obstacle localization module j: on each ``sense/range/<j>`` (every 0.128 s) the winner
and the obstacle field b_j (section 3.3), published on ``field/obstacle/<j>``.

``python -m cekm_swarm.modules.obstacle --robot r1 --index 3 --model M.npz --connect ...``

The reading's ``d`` is the obstacle input u_j: the distance from the robot's centre
(surface range plus body radius), None when the sensor sees nothing, as
``controller.readings.range_readings`` forms it in one process.
"""

from __future__ import annotations

import argparse

from cekm_swarm.protocol import KeySpace, ObstacleField, SenseRange
from cekm_swarm.protocol.hotpath import Splice, sense_range_values, unpack
from cekm_swarm.runtime.process_args import add_params

from .shell import INDEX_PARAM, FastHandler, ModuleSpec, base_parser, keyspace, load_controller, main_of


def name_of(index: int) -> str:
    return f"obstacle-{index}"


def obstacle_field(ekm, msg: SenseRange, sender: str) -> ObstacleField:
    """What ``ekm.localize_obstacle(RangeReading(j, alpha_j, d_j), stamp)`` gives, as a message."""
    from cekm_swarm.controller.readings import RangeReading

    act = ekm.localize_obstacle(RangeReading(msg.index, msg.alpha, msg.d), msg.stamp)
    return ObstacleField(msg.stamp, sender, msg.index, act.winner, act.b)


def fast_obstacle_field(ekm, index: int, sender: str, out_key: str) -> FastHandler:
    """The hot path of :func:`obstacle_field`: payload bytes in, the field's bytes out,
    equal to ``encode(obstacle_field(ekm, decode(payload), sender))`` (tested). A field
    is a fixed row per winner (Eq. 8), so its bytes are built once per winner and only
    the stamp is packed per message. None for anything but a well-formed reading: the
    shell then takes the general path, which decodes, or drops and counts."""
    splices: dict[int | None, Splice] = {}

    def fast(key: str, payload: bytes) -> list[tuple[str, bytes]] | None:
        u = sense_range_values(unpack(payload), index)
        if u is None:
            return None
        stamp, alpha, d = u
        s = None if d is None else ekm.winner(alpha, d)  # Eqs. 2-4 (memoised)
        enc = splices.get(s)
        if enc is None:
            b = None if s is None else ekm.obstacle_activity(s)  # Eqs. 7-8
            enc = splices[s] = Splice(ObstacleField(0.0, sender, index, s, b))
        return [(out_key, enc(stamp))]

    return fast


def build_spec(ekm, robot: str, index: int, keys: KeySpace = KeySpace()) -> ModuleSpec:
    index = keys.check_index(index)
    out_key = keys.field_obstacle(robot, index)
    sender = f"{robot}/{name_of(index)}"

    def handle(msg, rec):
        if not isinstance(msg, SenseRange):
            return []
        return [(out_key, obstacle_field(ekm, msg, sender))]

    return ModuleSpec(name_of(index), robot, keys.sense_range(robot, index), handle, keys,
                      fast=fast_obstacle_field(ekm, index, sender, out_key), outputs=(out_key,))


def _build(args: argparse.Namespace) -> ModuleSpec:
    return build_spec(load_controller(args.model), args.robot, args.index, keyspace(args))


def main(argv: list[str] | None = None) -> int:
    p = base_parser("cekm obstacle localization module (one distance sensor)")
    add_params(p, (INDEX_PARAM,))
    return main_of(_build, p, argv)


if __name__ == "__main__":
    raise SystemExit(main())
