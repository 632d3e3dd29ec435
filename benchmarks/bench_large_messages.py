"""Large messages from an outside client against a lockstep run (docs/robustness.md).

A lockstep ``cekm launch`` of the paper's concave obstacle with its goal walled in (seed 4,
313 ticks to --max-time, as in tests/runtime/test_fuzz.py) while a client publishes
``--count`` messages of zeros, one (or ``--burst`` back to back) every 4 ticks from tick
20, on one key: a key only the world's recorder hears, the motor's key, an obstacle
module's key. Prints, per case, the
re-published ticks (each a 1 s wait for a command), the run's wall seconds and its ratio to
a run with no message at all, and how many of the messages the world's recorder and the
module counted (dropped as malformed: they are zeros). A message the router refuses
(over ``MAX_MESSAGE_BYTES``) is counted by neither.

``--before REV`` runs the same cases first on the code of git revision REV (exported
with ``git archive``), so one run prints the story before and after a change.
``--reading`` sends, instead of zeros, well-formed ``sense/range`` readings stamped with
the world's latest tick (``--keys`` then an obstacle module's key), the burst a peer inside
the key space can send.

``--code DIR`` runs the launches from another source tree; ``--env NAME=VALUE`` sets a
variable in the launch's environment (e.g. ``ZENOH_RUNTIME=()``: Zenoh's default threads).

Run: python benchmarks/bench_large_messages.py [--sizes 32769,102400,1048576] [--port 7462]
         [--before REV] [--count 40 --burst 4]
The table in docs/robustness.md: --before a1fa352 (the code before the size limit and the
router's sending thread), then --sizes 32768 --count 40 --burst 4 and --sizes 1024
--count 2000 --burst 200 on the two module keys.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import subprocess
import sys
import tarfile
import tempfile
import threading
import time
from pathlib import Path

import zenoh

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from cekm_swarm.experiments.default_model import default_model_path  # noqa: E402
from cekm_swarm.protocol import DEFAULT_KEYS as K  # noqa: E402
from cekm_swarm.protocol import Clock, MessageError, SenseRange, decode, encode  # noqa: E402
from cekm_swarm.runtime.config import open_client  # noqa: E402
from cekm_swarm.ticks import tick_time  # noqa: E402

START_TICK = 20
EVERY = 4  # ticks between two messages (or bursts)
STUCK_S = 120.0  # the world not past the next message's tick in this long: stop sending
NONE = "(no message)"


def shut_concave(folder: Path) -> Path:
    """Fig. 8's concave obstacle with its goal shut in by four walls (as in
    tests/runtime/test_fuzz.py): the run lasts to --max-time (313 ticks), whatever arrives."""
    path = folder / "concave-shut.toml"
    path.write_text((ROOT / "world" / "scenarios" / "concave.toml").read_text()
                    .replace('name = "concave"', 'name = "concave-shut"')
                    + "".join(f"\n[[walls]]\na = {a}\nb = {b}\n" for a, b in (
                        ([1.94, 1.44], [2.06, 1.44]), ([2.06, 1.44], [2.06, 1.56]),
                        ([2.06, 1.56], [1.94, 1.56]), ([1.94, 1.56], [1.94, 1.44]))))
    return path


def wait_tick(sub, past: int, timeout: float) -> int:
    """The world's tick once it is past ``past`` (from a ring channel: no callback)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        sample = sub.try_recv()
        if sample is None:
            time.sleep(0.005)
            continue
        try:
            msg = decode(K.world_clock(), sample.payload.to_bytes())
        except MessageError:
            continue
        if isinstance(msg, Clock) and msg.tick > past:
            return msg.tick
    raise TimeoutError(f"the world did not pass tick {past}")


def module_log(key: str) -> str | None:
    """The log of the r1 module that listens on ``key`` (None: no module does)."""
    m = re.match(r"cekm/r1/(field/|sense/range/(\d+))", key)
    if not m:
        return None
    return "r1-motor.log" if m.group(1) == "field/" else f"r1-obstacle-{m.group(2)}.log"


def reading(key: str, tick: int) -> bytes:
    """A well-formed reading for the obstacle module of ``key`` at ``tick``: an obstacle
    0.1 m away along its sensor."""
    j = int(key.rsplit("/", 1)[1])
    return encode(SenseRange(tick_time(tick), "burst", j, -math.pi + (j + 0.5) * 2 * math.pi / 12, 0.1))


def case(key: str, size: int, count: int, burst: int, port: int, out: Path, scenario: Path, code: Path,
         env: dict[str, str], readings: bool = False) -> dict:
    """One lockstep run with ``count`` messages of ``size`` zeros on ``key`` (none for NONE),
    ``burst`` back to back every EVERY ticks (``readings``: well-formed readings instead)."""
    run_env = dict(os.environ, PYTHONPATH=str(code), PYTHONUNBUFFERED="1", **env)
    proc = subprocess.Popen([sys.executable, "-m", "cekm_swarm", "launch", str(scenario), "--mode", "lockstep",
                             "--seed", "4", "--max-time", "40", "--model", str(default_model_path()), "--no-plot",
                             "--port", str(port), "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=run_env, cwd=code)
    started = threading.Event()

    def read() -> None:
        for line in proc.stdout:
            if "world started ticking" in line:
                started.set()

    threading.Thread(target=read, daemon=True).start()
    try:
        if not started.wait(180):
            raise RuntimeError("the launch did not start ticking")
        stuck = None
        if key != NONE:
            session = open_client(f"tcp/127.0.0.1:{port}")
            sub = session.declare_subscriber(K.world_clock(), zenoh.handlers.RingChannel(16))
            tick = wait_tick(sub, START_TICK - 1, 60)
            for _ in range(count // burst):
                payload = reading(key, tick) if readings else bytes(size)
                for _ in range(burst):
                    session.put(key, payload, congestion_control=zenoh.CongestionControl.BLOCK)
                try:
                    tick = wait_tick(sub, tick + EVERY - 1, STUCK_S)
                except TimeoutError:  # give up sending; the run goes on to its end
                    stuck = tick
                    break
            session.close()
        proc.wait(900)
    finally:
        if proc.poll() is None:
            proc.kill()
    o = json.loads((out / "outcome.json").read_text())
    r = {"republished": o["republished"], "wall_s": o["wall_seconds"], "stuck_at": stuck,
         "world_counted": o["drops"]["recorder"].get(key, 0) if key != NONE else None, "module_counted": None}
    log = module_log(key)
    if log:
        doc = json.loads(re.findall(r"DROPS (\{.*\})", (out / "logs" / log).read_text())[0])
        r["module_counted"] = doc["dropped"].get(key, 0)
    return r


def export(rev: str, folder: Path) -> Path:
    """The source tree of git revision ``rev`` in ``folder``."""
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", "--format=tar", rev], check=True,
                             capture_output=True).stdout
    folder.mkdir(parents=True)
    with tarfile.open(fileobj=__import__("io").BytesIO(archive)) as tar:
        tar.extractall(folder, filter="data")
    return folder


def report(title: str, count: int, burst: int, results: dict[tuple[str, int], dict], readings: bool = False) -> None:
    base = results[(NONE, 0)]["wall_s"]
    how = "one" if burst == 1 else f"a burst of {burst} back to back"
    what = "well-formed readings for the tick" if readings else "messages of zeros"
    print(f"\n{title}: {count} {what}, {how} every {EVERY} ticks from tick {START_TICK}, "
          f"lockstep shut concave seed 4 (313 ticks); world, module: messages they counted")
    print(f"{'key':28s} {'bytes':>8s} {'re-pub':>6s} {'wall s':>7s} {'x base':>6s} {'world':>5s} {'module':>6s}")
    for (key, size), r in results.items():
        stuck = "" if r["stuck_at"] is None else \
            f"  (the world did not pass tick {r['stuck_at'] + EVERY - 1} in {STUCK_S:.0f} s: sending stopped)"
        print(f"{key:28s} {size:8d} {r['republished']:6d} {r['wall_s']:7.1f} {r['wall_s'] / base:6.1f} "
              f"{'-' if r['world_counted'] is None else r['world_counted']:>5} "
              f"{'-' if r['module_counted'] is None else r['module_counted']:>6}{stuck}", flush=True)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", default="32769,102400,1048576", help="comma-separated payload sizes in bytes")
    p.add_argument("--keys", default=f"cekm/fuzz/big,{K.field_obstacle('r1', 3)},{K.sense_range('r1', 3)}")
    p.add_argument("--count", type=int, default=10)
    p.add_argument("--burst", type=int, default=1, help="messages back to back at each event")
    p.add_argument("--port", type=int, default=7462)
    p.add_argument("--before", metavar="REV", help="first run the cases on the code of this git revision")
    p.add_argument("--code", type=Path, default=ROOT, help="source tree to launch from (default: this one)")
    p.add_argument("--env", action="append", default=[], metavar="NAME=VALUE")
    p.add_argument("--reading", action="store_true", help="well-formed readings for the tick instead of zeros")
    args = p.parse_args()
    env = dict(e.split("=", 1) for e in args.env)
    cases = [(NONE, 0)] + [(k, int(s)) for s in args.sizes.split(",") for k in args.keys.split(",")]
    with tempfile.TemporaryDirectory() as tmp:
        scenario = shut_concave(Path(tmp))
        trees = [(f"before ({args.before})", export(args.before, Path(tmp) / "before"))] if args.before else []
        trees.append(("after (this tree)" if args.code == ROOT else str(args.code), args.code))
        for t, (title, code) in enumerate(trees):
            results = {}
            for i, (key, size) in enumerate(cases):
                out = Path(tmp) / f"run-{t}-{i}"
                results[(key, size)] = case(key, size, args.count, args.burst, args.port, out, scenario, code, env,
                                               args.reading)
            report(title, args.count, args.burst, results, args.reading)


if __name__ == "__main__":
    main()
