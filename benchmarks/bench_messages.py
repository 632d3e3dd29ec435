"""Per-message CPU of the runtime's hot path: what a module process and the world server
spend on each message they decode or encode (docs/performance.md).

Measured through the interfaces every version of the protocol has had, so ``--before
REV`` can run the same cases on the code of a git revision (exported with ``git
archive``) and print both in one run, alternating rounds (old, new, old, new, ...) so
the host's load falls on both alike; each number is the median over the rounds of the
CPU time (``time.process_time``) per message of a loop, and the last column the ratio
new / old.

Cases: a node's decode (``cekm_swarm.node.wire.Decoder``) of a range reading, a target
reading, an obstacle field and a target field (225 neurons); a node's encode
(``Encoder``) of an obstacle field and a target field built from a model's read-only row,
and the building of the field; the world's sense encoding (``world.sense.SenseEncoder``,
per message of a tick's 13); the world recorder's check of a field
(``world.recorder.RecordFilter``); the world's building of a 3-robot world state from
``World.state()`` and a monitor's decode of it.

Run: python benchmarks/bench_messages.py [--before f3c6712] [--rounds 7] [--n 20000]
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def measure(n: int) -> dict[str, float]:
    """us of CPU per message of each case, in this process's code."""
    import numpy as np

    from cekm_swarm.node.wire import Decoder, Encoder
    from cekm_swarm.protocol import DEFAULT_KEYS as K
    from cekm_swarm.protocol import (
        DropCounter,
        KeyKind,
        ObstacleField,
        SenseRange,
        SenseTarget,
        TargetField,
        WorldState,
        decode,
        encode,
    )
    from world import World, load_scenario
    from world.episode import Episode
    from world.recorder import RecordFilter
    from world.sense import SenseEncoder

    table = np.random.default_rng(1).random((225, 225))
    table.flags.writeable = False
    rows = [table[s] for s in range(225)]
    t = 12.8
    of = ObstacleField(t, "r1/obstacle-3", 3, 17, rows[17])
    tf = TargetField(t, "r1/target", 17, rows[17], 0.3, 0.5)
    payloads = {
        "decode range reading": (
            K.sense_range("r1", 3),
            KeyKind.SENSE_RANGE,
            encode(SenseRange(t, "world", 3, 0.5, 0.1)),
        ),
        "decode target reading": (
            K.sense_target("r1"),
            KeyKind.SENSE_TARGET,
            encode(SenseTarget(t, "world", 0.5, 0.1, True)),
        ),
        "decode obstacle field": (K.field_obstacle("r1", 3), KeyKind.FIELD_OBSTACLE, encode(of)),
        "decode target field": (K.field_target("r1"), KeyKind.FIELD_TARGET, encode(tf)),
    }
    world = World(load_scenario("crossing"))
    st = world.state()
    state = encode(WorldState(t, "world", st["robots"], st["targets"], st["obstacles"]))
    readings = Episode(world).readings()[0]
    sense = SenseEncoder(K, readings.robot, world.sensor_angles, world.body_radius)
    per_tick = len(sense(readings))
    dec, enc = Decoder(K, DropCounter("bench")), Encoder()
    filt = RecordFilter(K, ["r1"], DropCounter("bench"))
    cases = {
        name: (lambda key=key, kind=kind, p=p: dec.decode(key, kind, p)) for name, (key, kind, p) in payloads.items()
    }
    cases["build obstacle field"] = lambda: ObstacleField(t, "r1/obstacle-3", 3, 17, rows[17])
    cases["encode obstacle field"] = lambda: enc(of)
    cases["encode target field"] = lambda: enc(tf)
    cases["world: sense encoding, per message"] = lambda: sense(readings)
    obstacle_key, obstacle_payload = payloads["decode obstacle field"][0], payloads["decode obstacle field"][2]
    cases["world: record check of a field"] = lambda: filt.check(obstacle_key, obstacle_payload, t)
    cases["world: build world state (3 robots)"] = lambda: WorldState(t, "world", st["robots"], st["targets"],
                                                                    st["obstacles"])
    cases["decode world state (3 robots)"] = lambda: decode(K.world_state(), state)
    out = {}
    for name, f in cases.items():
        f()
        t0 = time.process_time()
        for _ in range(n):
            f()
        us = (time.process_time() - t0) / n * 1e6
        out[name] = us / per_tick if name.startswith("world: sense") else us
    return out


def export(rev: str) -> Path:
    """The tree of git revision ``rev`` in a temporary directory."""
    where = Path(tempfile.mkdtemp(prefix=f"bench-messages-{rev}-"))
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", "--format=tar", rev], check=True,
                             capture_output=True).stdout
    tar = where / "src.tar"
    tar.write_bytes(archive)
    with tarfile.open(tar) as t:
        t.extractall(where, filter="data")
    return where


def child(code: Path, n: int) -> dict[str, float]:
    out = subprocess.run([sys.executable, __file__, "--child", "--n", str(n)], check=True, capture_output=True,
                         text=True, cwd=code, env={"PYTHONPATH": str(code), "PATH": "/usr/bin:/bin"}).stdout
    return json.loads(out.strip().splitlines()[-1])


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--before", metavar="REV", help="also measure the code of this git revision, alternating")
    p.add_argument("--rounds", type=int, default=7)
    p.add_argument("--n", type=int, default=20000, help="messages per case and round")
    p.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.child:
        sys.path.insert(0, str(Path.cwd()))
        print(json.dumps(measure(args.n)))
        return
    trees = {"new": ROOT}
    if args.before:
        trees = {"old": export(args.before), "new": ROOT}
    runs: dict[str, list[dict[str, float]]] = {k: [] for k in trees}
    for r in range(args.rounds):
        for name, code in trees.items():
            runs[name].append(child(code, args.n))
        print(f"round {r + 1}/{args.rounds} done", file=sys.stderr)
    cases = list(runs["new"][0])
    head = f"{'us of CPU per message (median of ' + str(args.rounds) + ' rounds)':52s}" + "".join(
        f"{k:>9s}" for k in trees) + ("    new/old" if "old" in trees else "")
    print(head)
    for case in cases:
        med = {k: statistics.median(run[case] for run in runs[k]) for k in trees}
        row = f"{case:52s}" + "".join(f"{med[k]:9.2f}" for k in trees)
        if "old" in trees:
            row += f"    {med['new'] / med['old']:7.2f}"
        print(row)


if __name__ == "__main__":
    main()
