"""A separate OS process for the end-to-end tests: ``python zenoh_helper.py MODE ...``.

Modes (each prints ``READY`` on stdout once set up, then works):

- ``sub ENDPOINT KEYEXPR N``: receive N samples, print each as ``key<TAB>payload hex``, then ``DONE``.
- ``token ENDPOINT KEY``: hold a liveliness token until killed.
- ``pub ENDPOINT KEY N``: wait for a subscriber, publish N WheelCommand messages (seq 0..N-1).
- ``router PORT``: a Zenoh router on ``tcp/127.0.0.1:PORT`` (an "outside" router, to be
  killed and started again), until killed.
- ``mcap PATH N``: write N messages to an MCAP recorder, flush, print ``FLUSHED N``, then
  keep the file open (unfinished) until killed.
"""

from __future__ import annotations

import queue
import sys
import threading


def main(argv: list[str]) -> None:
    mode = argv[0]
    if mode == "mcap":
        from cekm_swarm.protocol import DEFAULT_KEYS, Clock, encode
        from cekm_swarm.runtime.mcap_log import McapRecorder

        path, n = argv[1], int(argv[2])
        rec = McapRecorder(path, chunk_size=4096, flush_interval=None)
        print("READY", flush=True)
        for i in range(n):
            rec.write(DEFAULT_KEYS.world_clock(), encode(Clock(i * 0.01, "world", i)), i * 0.01)
        rec.flush()
        print(f"FLUSHED {n}", flush=True)
        for i in range(n, n + 5):  # in the open chunk only: lost when killed
            rec.write(DEFAULT_KEYS.world_clock(), encode(Clock(i * 0.01, "world", i)), i * 0.01)
        threading.Event().wait()
        return

    if mode == "router":
        from cekm_swarm.runtime.config import open_embedded_router

        router = open_embedded_router(int(argv[1]))
        print("READY", flush=True)
        threading.Event().wait()
        router.close()
        return

    from cekm_swarm.runtime.config import open_client

    session = open_client(argv[1])
    try:
        if mode == "sub":
            key_expr, n = argv[2], int(argv[3])
            q: queue.SimpleQueue = queue.SimpleQueue()
            sub = session.declare_subscriber(key_expr, lambda s: q.put((str(s.key_expr), s.payload.to_bytes())))
            print("READY", flush=True)
            lines = []
            for _ in range(n):
                key, payload = q.get(timeout=30)
                lines.append(f"{key}\t{payload.hex()}")
            sys.stdout.write("\n".join(lines) + "\nDONE\n")
            sys.stdout.flush()
            sub.undeclare()
        elif mode == "token":
            from cekm_swarm.runtime.bridge import declare_alive

            token = declare_alive(session, argv[2])  # keep a reference: a dropped token is undeclared
            print("READY", flush=True)
            threading.Event().wait()
            token.undeclare()
        elif mode == "pub":
            from cekm_swarm.protocol import WheelCommand
            from cekm_swarm.runtime.bridge import Publishers

            key, n = argv[2], int(argv[3])
            with Publishers(session, block=True) as pubs:
                print("READY", flush=True)
                if not pubs.wait_matching(key, 20):
                    print("NO SUBSCRIBER", flush=True)
                    return
                for i in range(n):
                    pubs.send(key, WheelCommand(i * 0.1, "helper", 0.01 * i, -0.01 * i, i))
                print("DONE", flush=True)
        else:
            raise SystemExit(f"unknown mode {mode}")
    finally:
        session.close()


if __name__ == "__main__":
    main(sys.argv[1:])
