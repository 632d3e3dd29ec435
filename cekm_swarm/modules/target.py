"""Target localization module: on each ``sense/target`` (every 0.256 s) the winner s and
the target field a (section 3.2), published on ``field/target``.

``python -m cekm_swarm.modules.target --robot r1 --model M.npz --connect tcp/127.0.0.1:7447``
"""

from __future__ import annotations

import argparse
import math

from cekm_swarm.protocol import KeySpace, SenseTarget, TargetField
from cekm_swarm.protocol.hotpath import Splice, sense_target_values, unpack

from .shell import Admit, FastHandler, ModuleSpec, base_parser, keyspace, load_controller, main_of

NAME = "target"


def target_field(ekm, msg: SenseTarget, sender: str) -> TargetField:
    """The target field of one target reading: what ``RobotBrain.tick`` computes with
    ``ekm.localize_target(TargetReading(alpha, d, visible), stamp)``, as a message.

    The world sends (0, 0, visible=False) for a target out of range; the in-process
    runner hands the controller NaNs there; either way the reading is not usable."""
    from cekm_swarm.controller.readings import TargetReading

    act = ekm.localize_target(TargetReading(msg.alpha, msg.d, msg.visible), msg.stamp)
    if act.at_goal:
        return TargetField(msg.stamp, sender, None, None, act.alpha, act.d, at_goal=True)
    if act.a is None or not (math.isfinite(act.alpha) and math.isfinite(act.d)):
        return TargetField(msg.stamp, sender, None, None)
    return TargetField(msg.stamp, sender, act.winner, act.a, act.alpha, act.d)


def fast_target_field(ekm, sender: str, out_key: str, admit: Admit | None = None) -> FastHandler:
    """The hot path of :func:`target_field` for a visible target short of the goal:
    payload bytes in, the field's bytes out, equal to the general path's (tested). The
    field a is a fixed row per winner (Eq. 6), so its bytes are packed once per winner and
    only the stamp and the sensed (alpha, d) per message. Anything else (no target, the
    goal state, a malformed message) returns None: the general path takes it. ``admit``
    (the module's stamp check) drops a well-formed reading with an unbelievable stamp."""
    splices: dict[int, Splice] = {}

    def fast(key: str, payload: bytes) -> list[tuple[str, bytes]] | None:
        u = sense_target_values(unpack(payload))
        if u is None or not u[3] or u[2] == 0.0:
            return None
        stamp, alpha, d, _ = u
        if admit is not None and not admit(key, stamp):
            return []
        s = ekm.winner(alpha, d)  # Eqs. 2-4 (memoised)
        enc = splices.get(s)
        if enc is None:
            template = TargetField(0.0, sender, s, ekm.target_activity(s), 0.0, 0.0)  # Eqs. 5-6
            enc = splices[s] = Splice(template, ("stamp", "alpha", "d"))
        return [(out_key, enc(stamp, alpha, d))]

    return fast


def build_spec(ekm, robot: str, keys: KeySpace = KeySpace()) -> ModuleSpec:
    out_key = keys.field_target(robot)
    sender = f"{robot}/{NAME}"

    def handle(msg, rec):
        if not isinstance(msg, SenseTarget):
            return []
        return [(out_key, target_field(ekm, msg, sender))]

    spec = ModuleSpec(NAME, robot, keys.sense_target(robot), handle, keys, outputs=(out_key,))
    spec.fast = fast_target_field(ekm, sender, out_key, spec.admit)
    return spec


def _build(args: argparse.Namespace) -> ModuleSpec:
    return build_spec(load_controller(args.model), args.robot, keyspace(args))


def main(argv: list[str] | None = None) -> int:
    return main_of(_build, base_parser("cekm target localization module"), argv)


if __name__ == "__main__":
    raise SystemExit(main())
