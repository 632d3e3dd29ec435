"""The floor of a module process's cost on this machine, measured beside the runtime's own.

A floor process is the least a module can be: a bare Python process with a Zenoh client
session, woken by one message per tick on its own key, that publishes one reply. The
driver here forks ``processes`` floor processes from a parent that has imported zenoh
(before any session exists in it, so starting 448 of them takes seconds, as the launcher's
warm start does), opens a router (the launcher's embedded router config), ticks every ``tick_s`` of real
time for ``seconds``, and reads each floor process's CPU from ``/proc``. The result is the
floor's CPU per process per tick, and how many replies came back (each a tick's round
trip).

Used by ``bench_runtime_scale.py`` (the floor at each team size's process count, each in a
fresh process: a process that has had a Zenoh session cannot fork working children) and on
its own: ``python benchmarks/floor.py --processes 14 --seconds 10``.

``--mode`` measures what a module adds to it, step by step: ``callback`` answers from a
callback on Zenoh's receiving thread, as a module does (:mod:`cekm_swarm.node.process`);
``numpy`` adds one subtraction and one argmax on a 100-neuron field; ``decode`` instead
decodes and checks one 100-neuron obstacle field. In a process that sleeps between ticks
among a hundred others, such a little work costs far more than it does in a loop, because
the code and data it touches are no longer in the caches (``docs/performance.md``).
``motor-messages`` sends each process a tracking motor's messages instead of one a tick
(2.4 a tick: :func:`motor_messages`) and answers the last; ``lean-motor`` also decodes each
with the protocol's checks and runs Eqs. 9-10 on them: the least a motor module of the
shipped tracking graph can do, with none of the runtime around it. Several modes at once
(``--mode fifo,motor-messages,lean-motor --rounds 3``) alternate and print each against
the floor of the same round.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

import zenoh

from cekm_swarm.launch.cpu import cpu_seconds, host_shares, host_times
from cekm_swarm.runtime.config import (
    ONE_THREAD_RUNTIME,
    ROUTER_RUNTIME,
    client_config,
    free_port,
    open_embedded_router,
    open_session,
)

PAYLOAD = bytes(120)  # about one sense message's size


def _nothing() -> Callable[[bytes], Any]:
    return lambda payload: None


def _numpy() -> Callable[[bytes], Any]:
    import numpy as np

    field = np.full(100, 0.3)
    return lambda payload: int(np.argmax(field - 0.1))  # one subtraction and one argmax on a 100-neuron field


def _decode() -> Callable[[bytes], Any]:
    import numpy as np

    from cekm_swarm.protocol import KeyKind, ObstacleField
    from cekm_swarm.protocol.codec import decode, encode

    field = encode(ObstacleField(0.128, "r1/obstacle-1", 1, 1, np.full(100, 0.5)))
    return lambda payload: decode(KeyKind.FIELD_OBSTACLE, field)  # one 100-neuron field, decoded and checked


WORK: dict[str, Callable[[], Callable[[bytes], Any]]] = {"callback": _nothing, "numpy": _numpy, "decode": _decode}
"""What a floor process does per tick beside answering, by ``--mode`` (``fifo``: the floor)."""
MOTOR_MODES = ("motor-messages", "lean-motor")
"""A tracking motor's messages per tick instead of one: ``motor-messages`` only answers
the tick's last one; ``lean-motor`` also decodes each and runs Eqs. 9-10 (the least a motor
module of this graph can do, with nothing of the runtime around it)."""
MODES = ("fifo", *WORK, *MOTOR_MODES)
LATTICE = 225  # the shipped map's neurons
SENSORS = 12
OBSTACLE_FIELDS_PER_TICK = 0.9  # measured: r1 of tracking-crowd, lockstep, 856 changed fields in 939 ticks


def motor_messages(k: int) -> list[tuple[str, bytes]]:
    """What a tracking motor receives at tick ``k``, in arrival order, as (kind, encoded
    message): the world's notice of the readings it held back, the obstacle fields of the
    readings that changed (0.9 a tick, one sensor in turn) and, every other tick, the
    tracking field; 2.4 messages a tick, as ``tracking-crowd``'s r1 receives them."""
    import numpy as np

    from cekm_swarm.protocol import ObstacleField, TrackingField, Unchanged
    from cekm_swarm.protocol.codec import encode

    t = round((k + 1) * 0.128, 3)
    changed = [k % SENSORS] if int(OBSTACLE_FIELDS_PER_TICK * (k + 1)) > int(OBSTACLE_FIELDS_PER_TICK * k) else []
    held = tuple(f"sense/range/{j}" for j in range(SENSORS) if j not in changed)
    rng = np.random.default_rng(k)
    sent = [("sense/unchanged", encode(Unchanged(t, "world", held, tuple(0.0 for _ in held))))]
    for j in changed:
        sent.append(("field/obstacle", encode(ObstacleField(t, f"r1/obstacle-{j}", j, 3, rng.random(LATTICE)))))
    if k % 2 == 0:
        sent.append(("field/tracking", encode(TrackingField(t, "r1/target", rng.random(LATTICE), rng.random(LATTICE),
                                                            ((3, 0.2, 0.1, 1.0), (40, -0.5, 0.2, 0.25)),
                                                            {"t1": 1.0, "t2": 0.25}, False))))
    return sent


def _motor(mode: str, reply: Any, sender: str) -> Callable[[str, bytes, bool], None]:
    """A motor-pattern process's work per message (``last``: the tick's last one, answered)."""
    if mode == "motor-messages":
        def answer(kind: str, payload: bytes, last: bool) -> None:
            if last:
                reply.put(PAYLOAD)
        return answer
    import numpy as np

    from cekm_swarm.protocol import KeyKind, WheelCommand
    from cekm_swarm.protocol.codec import decode, encode

    kinds = {k.value: k for k in KeyKind}
    eligible = np.ones(LATTICE, dtype=bool)
    eligible[::7] = False
    held: dict[int, Any] = {}
    state: dict[str, Any] = {"tracking": None, "seq": 0}

    def lean(kind: str, payload: bytes, last: bool) -> None:
        msg = decode(kinds[kind], payload)
        if kind == "field/obstacle":
            held[msg.index] = msg
        elif kind == "field/tracking":
            state["tracking"] = msg
        if not last:
            return
        f = state["tracking"]
        e = f.a - f.b  # Eq. 9
        for ob in held.values():
            if ob.b is not None:
                e = e - ob.b
        k = int(np.argmax(np.where(eligible, e, -np.inf)))  # Eq. 10
        state["seq"] += 1
        reply.put(encode(WheelCommand(msg.stamp, sender, 0.01 * (k % 5), 0.01, state["seq"])))
    return lean


def floor_process(endpoint: str, index: int, mode: str = "fifo") -> None:
    """One floor process: subscribe to floor/<i>/tick, answer each tick on floor/<i>/reply
    (``mode``: the floor's loop over a FIFO channel, or a callback on Zenoh's thread with
    the work ``WORK[mode]``)."""
    for attempt in range(40):  # a router takes so many opening sessions at once (accept_pending): retry
        try:
            session = open_session(client_config(endpoint), "floor process")
            break
        except Exception:
            if attempt == 39:
                raise
            time.sleep(0.05 * (1 + attempt % 8))
    with session:
        reply = session.declare_publisher(f"floor/{index}/reply")
        ticks = session.declare_subscriber(f"floor/{index}/tick")
        while True:  # announce until the first tick arrives (the driver starts once all are here)
            reply.put(b"ready")
            sample = ticks.try_recv()
            if sample is not None:
                break
            time.sleep(0.05)
        reply.put(PAYLOAD)
        if mode in MOTOR_MODES:
            _motor_loop(session, ticks, reply, index, mode)
            return
        if mode == "fifo":
            for sample in ticks:  # a node at its simplest: a loop over events
                if sample.payload.to_bytes() == b"stop":
                    break
                reply.put(PAYLOAD)
            return
        # the modules' way: the work on Zenoh's receiving thread (node.process), plus a little of it
        from cekm_swarm.runtime.bridge import keep_thread_state

        work = WORK[mode]()
        stop = threading.Event()

        def on_tick(sample: zenoh.Sample) -> None:
            keep_thread_state()
            payload = sample.payload.to_bytes()
            if payload == b"stop":
                stop.set()
                return
            work(payload)
            reply.put(PAYLOAD)

        ticks.undeclare()
        on = session.declare_subscriber(f"floor/{index}/tick", zenoh.handlers.Callback(on_tick, indirect=False))
        stop.wait()
        on.undeclare()


def _motor_loop(session: zenoh.Session, ticks: Any, reply: Any, index: int, mode: str) -> None:
    """A motor-pattern process: a callback on Zenoh's thread per message, as a module has."""
    from cekm_swarm.runtime.bridge import keep_thread_state

    work = _motor(mode, reply, f"r{index}/motor")
    stop = threading.Event()
    skip = len(f"floor/{index}/in/")

    def on_message(sample: zenoh.Sample) -> None:
        keep_thread_state()
        rest = str(sample.key_expr)[skip:]
        if rest == "stop":
            stop.set()
            return
        kind, _, place = rest.rpartition("/")
        work(kind, sample.payload.to_bytes(), place == "last")

    ticks.undeclare()
    on = session.declare_subscriber(f"floor/{index}/in/**", zenoh.handlers.Callback(on_message, indirect=False))
    stop.wait()
    on.undeclare()


def _fork_floor_processes(processes: int, endpoint: str, mode: str) -> tuple[list[int], int]:
    """Fork the floor processes (before any Zenoh session exists in this process); each
    waits for a byte on the returned pipe's write end before it joins ``endpoint``."""
    go_r, go_w = os.pipe()
    pids = []
    for i in range(processes):
        pid = os.fork()
        if pid == 0:
            code = 0
            try:
                os.close(go_w)
                os.environ["ZENOH_RUNTIME"] = ONE_THREAD_RUNTIME  # as a real-time module's Zenoh runs
                os.read(go_r, 1)  # wait for the router
                floor_process(endpoint, i, mode)
            except BaseException as exc:
                print(f"floor process {i}: {exc!r}", file=sys.stderr, flush=True)
                code = 1
            finally:
                os._exit(code)
        pids.append(pid)
    os.close(go_r)
    return pids, go_w


class _Replies:
    """The floor processes' replies: who announced itself ready, and how many answers came."""

    def __init__(self, processes: int) -> None:
        self.processes = processes
        self.ready: set[int] = set()
        self.count = 0
        self.lock = threading.Lock()
        self.all_ready = threading.Event()

    def on_reply(self, sample: zenoh.Sample) -> None:
        i = int(str(sample.key_expr).split("/")[1])
        with self.lock:
            if sample.payload.to_bytes() == b"ready":
                self.ready.add(i)
                if len(self.ready) == self.processes:
                    self.all_ready.set()
            else:
                self.count += 1

    def reset(self) -> None:
        with self.lock:
            self.count = 0


def _send_tick(router: Any, pubs: list[Any], pattern: list[Any] | None, k: int) -> None:
    """Tick ``k``: one message per process (fifo, callback, ...), or the motor pattern's
    messages on floor/<i>/in/<kind>/<more|last>."""
    if pattern is None:
        for p in pubs:
            p.put(PAYLOAD)
        return
    tick = pattern[k % len(pattern)]
    for i in range(len(pubs)):
        for j, (kind, payload) in enumerate(tick):
            router.put(f"floor/{i}/in/{kind}/{'last' if j == len(tick) - 1 else 'more'}", payload)


def _reap(pids: list[int]) -> None:
    """Wait up to 10 s for the floor processes to end; kill the rest."""
    deadline = time.monotonic() + 10
    for pid in pids:
        while time.monotonic() < deadline:
            done, _ = os.waitpid(pid, os.WNOHANG)
            if done:
                break
            time.sleep(0.02)
        else:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)


def measure(processes: int, seconds: float = 10.0, tick_s: float = 0.128, mode: str = "fifo") -> dict:
    """Run ``processes`` floor processes for ``seconds`` of real time; CPU ms per process per tick."""
    if mode != "fifo":  # imported before forking, as the launcher's fork server has
        import cekm_swarm.node.process  # noqa: F401
        from cekm_swarm.protocol import codec

        codec.warm()
    port = free_port()
    pids, go_w = _fork_floor_processes(processes, f"tcp/127.0.0.1:{port}", mode)
    os.environ["ZENOH_RUNTIME"] = ROUTER_RUNTIME  # as the world server's embedded router runs
    with open_embedded_router(port) as router:
        replies = _Replies(processes)
        sub = router.declare_subscriber("floor/*/reply", replies.on_reply)
        os.write(go_w, b"g" * processes)
        os.close(go_w)
        try:
            if not replies.all_ready.wait(60 + processes * 0.2):
                raise RuntimeError(f"only {len(replies.ready)} of {processes} floor processes came up")
            pubs = [router.declare_publisher(f"floor/{i}/tick") for i in range(processes)]
            for p in pubs:
                p.put(PAYLOAD)  # the first tick ends the announcing
            pattern = [motor_messages(k) for k in range(64)] if mode in MOTOR_MODES else None
            if pattern is not None:  # each message on floor/<i>/in/<kind>/<more|last>
                time.sleep(0.2)
                for i in range(processes):
                    for kind, payload in pattern[0]:
                        router.put(f"floor/{i}/in/{kind}/more", payload)  # a tracking field before the first tick
            time.sleep(0.5)
            replies.reset()
            cpu0 = {pid: cpu_seconds(pid) for pid in pids}
            host0 = host_times()
            n = max(1, round(seconds / tick_s))
            start = time.perf_counter()
            for k in range(n):
                _send_tick(router, pubs, pattern, k)
                delay = start + (k + 1) * tick_s - time.perf_counter()
                if delay > 0:
                    time.sleep(delay)
            time.sleep(min(0.5, tick_s * 2))
            cpu1 = {pid: cpu_seconds(pid) for pid in pids}
            host1 = host_times()
            for i, p in enumerate(pubs):
                p.put(b"stop")
                if pattern is not None:
                    router.put(f"floor/{i}/in/stop", b"")
        finally:
            _reap(pids)
            sub.undeclare()
    used = [cpu1[p] - cpu0[p] for p in pids if cpu0.get(p) is not None and cpu1.get(p) is not None]
    per = 1000.0 * sum(used) / max(1, len(used)) / n
    return {"processes": processes, "mode": mode, "ticks": n, "ms_per_process_tick": round(per, 4),
            "replies": replies.count, "expected_replies": n * processes, "host": host_shares(host0, host1)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--processes", type=int, default=14)
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--mode", default="fifo",
                    help="one mode or several, comma-separated (" + ", ".join(MODES) + "); fifo: the floor (a loop "
                         "over a FIFO channel); callback: the reply from a callback on Zenoh's thread, as a module "
                         "answers; numpy / decode: that plus one small numpy step / one field decoded; "
                         "motor-messages / lean-motor: a tracking motor's 2.4 messages a tick, answered / also "
                         "decoded with Eqs. 9-10 run on them. Several modes: each in turn, --rounds times, and a "
                         "table of each against fifo")
    ap.add_argument("--rounds", type=int, default=1, help="with several modes: rounds of all of them, alternating")
    args = ap.parse_args()
    modes = args.mode.split(",")
    unknown = [m for m in modes if m not in MODES]
    if unknown:
        ap.error(f"--mode: unknown mode {unknown[0]!r}; the modes are {', '.join(MODES)}")
    if len(modes) == 1:
        print(json.dumps(measure(args.processes, args.seconds, mode=modes[0])))
        return
    if "fifo" not in modes:
        modes.insert(0, "fifo")
    seen: dict[str, list[float]] = {m: [] for m in modes}
    for r in range(args.rounds):
        for m in modes:  # each in a fresh process: one that has had a Zenoh session cannot fork working children
            run = subprocess.run([sys.executable, __file__, "--processes", str(args.processes), "--seconds",
                                  str(args.seconds), "--mode", m], capture_output=True, text=True, check=False)
            if run.returncode != 0:
                sys.exit(f"floor.py --mode {m} failed (exit {run.returncode}):\n{run.stderr[-2000:]}")
            got = json.loads(run.stdout.splitlines()[-1])
            seen[m].append(got["ms_per_process_tick"])
            print(f"round {r + 1}: {m:15s} {got['ms_per_process_tick']:.3f} ms  replies {got['replies']}/"
                  f"{got['expected_replies']}  stolen {got['host'].get('steal', 0.0):.0%}", file=sys.stderr, flush=True)
    print(f"{'mode':15s} {'ms per process per tick':>24s}  {'x the floor (fifo), same round':>31s}")
    for m in modes:
        ratios = [v / f for v, f in zip(seen[m], seen["fifo"], strict=True)]
        print(f"{m:15s} {min(seen[m]):10.3f} - {max(seen[m]):.3f} ms {min(ratios):18.2f} - {max(ratios):.2f}x")


if __name__ == "__main__":
    main()
