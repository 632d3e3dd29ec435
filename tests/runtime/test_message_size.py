"""The transport's message-size limit (runtime.config.MAX_MESSAGE_BYTES): every router the
runtime opens drops a message over it as it comes in, before any subscriber (the router's
own session included) sees it; clients refuse to reassemble a fragmented one.

Every check sends the messages over the limit first and a small one last from the same
session: a Zenoh session delivers in order, so once the last one has arrived, the ones
before it that did not arrive were dropped (no waiting for something not to happen)."""

from __future__ import annotations

import json
import queue
import time
from pathlib import Path

import pytest
import zenoh

from cekm_swarm.runtime.config import (
    MAX_MESSAGE_BYTES,
    check_endpoint,
    client_config,
    client_config_from_file,
    free_port,
    open_client,
    open_embedded_router,
    open_session,
)

L = MAX_MESSAGE_BYTES
T = 20.0
BLOCK = zenoh.CongestionControl.BLOCK
DEPLOY = Path(__file__).resolve().parents[2] / "deploy"


class Inbox:
    """(key, size) of each sample a subscriber gets, in order."""

    def __init__(self, session: zenoh.Session, key_expr: str) -> None:
        self.q: queue.SimpleQueue[tuple[str, int]] = queue.SimpleQueue()
        self.sub = session.declare_subscriber(key_expr,
                                              lambda s: self.q.put((str(s.key_expr), len(s.payload.to_bytes()))))

    def until(self, last: str) -> list[tuple[str, int]]:
        got = []
        while (item := self.q.get(timeout=T))[0] != last:
            got.append(item)
        return got + [item]


def handshake(session: zenoh.Session, *inboxes: Inbox) -> None:
    """Return once every inbox's subscription has reached the router: ``big/0`` is sent
    until each inbox has one (a subscription travels to the router on its own, so a put
    right after declaring may find no route), then ``big/ready`` once, which arrives after
    every extra ``big/0`` (in order, from one session) and leaves every inbox empty."""
    deadline, pending = time.monotonic() + T, list(inboxes)
    while pending:
        assert time.monotonic() < deadline, "a subscription never reached the router"
        session.put("big/0", b"", congestion_control=BLOCK)
        for inbox in list(pending):
            try:
                inbox.q.get(timeout=0.1)
                pending.remove(inbox)
            except queue.Empty:
                pass
    session.put("big/ready", b"", congestion_control=BLOCK)
    for inbox in inboxes:
        inbox.until("big/ready")


def test_the_limit_is_above_every_legitimate_message_and_below_zenohs_batch():
    from cekm_swarm.experiments.default_model import default_model, default_model_path

    default_model(progress=False)
    assert default_model_path().stat().st_size + 64 < L  # the served model and its digest
    assert L + 1024 < 65_535  # with the key and headers, in one of Zenoh's batches: never cut into fragments


@pytest.mark.parametrize("sizes", [(L + 1, 48_000, 65_535, 100_000, 1 << 20)])
def test_the_embedded_router_drops_what_is_over_the_limit_before_anyone_sees_it(sizes):
    port = free_port()
    router = open_embedded_router(port)
    sub, pub = open_client(f"tcp/127.0.0.1:{port}"), open_client(f"tcp/127.0.0.1:{port}")
    try:
        remote, local = Inbox(sub, "big/**"), Inbox(router, "big/**")  # local: the world's recorder is there
        handshake(pub, remote, local)
        for n in sizes:
            pub.put(f"big/{n}", bytes(n), congestion_control=BLOCK)
        pub.put("big/att", bytes(L - 10), attachment=bytes(11), congestion_control=BLOCK)  # the attachment counts
        pub.put("big/edge", bytes(L), congestion_control=BLOCK)  # inclusive
        pub.put("big/att-ok", bytes(L - 10), attachment=bytes(10), congestion_control=BLOCK)
        pub.put("big/last", b"x", congestion_control=BLOCK)
        want = [("big/edge", L), ("big/att-ok", L - 10), ("big/last", 1)]
        assert remote.until("big/last") == want
        assert local.until("big/last") == want
    finally:
        for s in (sub, pub, router):
            s.close()


def test_a_reply_or_query_over_the_limit_is_dropped_at_the_router():
    port = free_port()
    router = open_embedded_router(port)
    serving, asking = open_client(f"tcp/127.0.0.1:{port}"), open_client(f"tcp/127.0.0.1:{port}")
    asked: list[int] = []

    def answer(q: zenoh.Query) -> None:
        asked.append(len(q.payload.to_bytes()) if q.payload is not None else 0)
        n = int(str(q.key_expr).rsplit("/", 1)[1])
        q.reply(q.key_expr, bytes(n))

    qbl = serving.declare_queryable("q/*", answer)
    try:
        deadline = time.monotonic() + T
        while not [r for r in asking.get("q/1", timeout=T) if r.ok is not None]:  # until the router knows it
            assert time.monotonic() < deadline, "the queryable never answered"
        asked.clear()
        ok = [len(r.ok.payload.to_bytes()) for r in asking.get(f"q/{L}", timeout=T) if r.ok is not None]
        assert ok == [L]
        # the reply is dropped at the router; the query still ends (its final message is small)
        assert [r.ok for r in asking.get(f"q/{L + 1}", timeout=T) if r.ok is not None] == []
        # a query whose own payload is over the limit never reaches the queryable
        assert [r.ok for r in asking.get("q/1", payload=bytes(L + 1), timeout=T) if r.ok is not None] == []
        assert asked == [0, 0]
    finally:
        qbl.undeclare()
        for s in (serving, asking, router):
            s.close()


def test_a_client_refuses_to_reassemble_a_fragmented_message():
    """Behind a router without the limit (plain Zenoh defaults), a client of ours receives
    a message of the limit's size and drops what arrives in fragments (over 64 KB: the
    router cuts some over about 48 KB too, so the client's limit lies in between)."""
    port = free_port()
    plain = zenoh.Config()
    plain.insert_json5("mode", '"router"')
    plain.insert_json5("listen/endpoints", json.dumps([check_endpoint(f"tcp/127.0.0.1:{port}")]))
    plain.insert_json5("scouting/multicast/enabled", "false")
    router = open_session(plain, "plain router")
    sub, pub = open_client(f"tcp/127.0.0.1:{port}"), open_client(f"tcp/127.0.0.1:{port}")
    try:
        inbox = Inbox(sub, "big/**")
        handshake(pub, inbox)
        for n in (L, 100_000, 1 << 20):
            pub.put(f"big/{n}", bytes(n), congestion_control=BLOCK)
        pub.put("big/last", b"x", congestion_control=BLOCK)
        assert inbox.until("big/last") == [(f"big/{L}", L), ("big/last", 1)]
    finally:
        for s in (sub, pub, router):
            s.close()


def test_client_configs_take_the_limit_unless_theirs_is_smaller(tmp_path):
    get = lambda c: json.loads(c.get_json("transport/link/rx/max_message_size"))  # noqa: E731
    assert get(client_config("tcp/127.0.0.1:7447")) == L
    big, small = tmp_path / "big.json5", tmp_path / "small.json5"
    big.write_text('{ mode: "client", transport: { link: { rx: { max_message_size: 1073741824 } } } }')
    small.write_text('{ mode: "client", transport: { link: { rx: { max_message_size: 4096 } } } }')
    assert get(client_config_from_file(big, "tcp/127.0.0.1:7447")) == L
    assert get(client_config_from_file(small, "tcp/127.0.0.1:7447")) == 4096


def test_every_shipped_config_carries_the_limit():
    files = sorted(DEPLOY.glob("*.json5")) + sorted((DEPLOY / "tls").glob("*.json5"))
    assert len(files) == 14  # 7 plain (router, world, monitor, operator, robots r1-r3) and 7 with TLS
    for path in files:
        c = zenoh.Config.from_file(str(path))
        assert json.loads(c.get_json("transport/link/rx/max_message_size")) == L, path
        filters = json.loads(c.get_json("low_pass_filter"))
        if path.name == "router.json5":
            (f,) = filters
            assert (f["size_limit"], f["flows"], f["key_exprs"]) == (L, ["ingress"], ["**"]), path
            assert set(f["messages"]) == {"put", "delete", "query", "reply"}, path
        else:
            assert filters == [], path  # clients: no per-message filter on the hot path
