"""The model over Zenoh: the launcher's queryable serves the file's bytes, a module reads
them with the same checks as a file; tampered bytes, damaged files and a missing server
give errors that name the key."""

from __future__ import annotations

import time

import numpy as np
import pytest

from cekm_swarm.errors import ModelFormatError
from cekm_swarm.experiments.default_model import default_model, default_model_path
from cekm_swarm.models.io import load_model, load_model_bytes
from cekm_swarm.modules.ekm import cooperative_ekm
from cekm_swarm.node import Context
from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.runtime.config import (
    MAX_MESSAGE_BYTES,
    client_config_from_file,
    free_port,
    open_client,
    open_embedded_router,
)
from cekm_swarm.runtime.errors import RuntimeTransportError
from cekm_swarm.runtime.model_service import ModelServer, fetch_model_bytes, is_zenoh_source


@pytest.fixture
def two_sessions():
    port = free_port()
    router = open_embedded_router(port)
    a = open_client(f"tcp/127.0.0.1:{port}")
    b = open_client(f"tcp/127.0.0.1:{port}")
    yield a, b
    a.close()
    b.close()
    router.close()


def test_served_model_equals_the_file(two_sessions):
    default_model(progress=False)
    path = default_model_path()
    serving, asking = two_sessions
    server = ModelServer(serving, K.world_model(), path)
    try:
        blob = fetch_model_bytes(asking, K.world_model(), timeout=10)
    finally:
        server.close()
    assert blob == path.read_bytes() and server.served == 1
    got, want = load_model_bytes(blob, "zenoh:x"), load_model(path)
    assert np.array_equal(got.w, want.w) and np.array_equal(got.M, want.M)
    ekm = cooperative_ekm(Context("r1", "target", model_source=("zenoh:" + K.world_model(), blob), backend="numpy"))
    assert ekm.n == want.w.shape[0]


def test_tampered_bytes_are_refused(two_sessions):
    default_model(progress=False)
    serving, asking = two_sessions
    server = ModelServer(serving, K.world_model(), default_model_path())
    server.blob = server.blob[:-1] + bytes([server.blob[-1] ^ 1])  # the digest no longer matches
    try:
        with pytest.raises(RuntimeTransportError, match="do not match their SHA-256"):
            fetch_model_bytes(asking, K.world_model(), timeout=10)
    finally:
        server.close()


def test_a_model_too_large_for_the_transport_is_refused_at_once(two_sessions, tmp_path):
    big = tmp_path / "big.npz"
    big.write_bytes(bytes(MAX_MESSAGE_BYTES))  # with its digest, over the limit: the router would drop the reply
    serving, asking = two_sessions
    server = ModelServer(serving, K.world_model(), big)
    t0 = time.monotonic()
    try:
        with pytest.raises(RuntimeTransportError, match=r"big.npz is too large to serve over Zenoh: 32832 bytes.*"
                                                        r"--model PATH"):
            fetch_model_bytes(asking, K.world_model(), timeout=30)
    finally:
        server.close()
    assert time.monotonic() - t0 < 10 and server.served == 0  # not the 30 s timeout


def test_no_server_is_a_clear_error(two_sessions):
    _, asking = two_sessions
    with pytest.raises(RuntimeTransportError, match="cekm/world/model: no queryable answered"):
        fetch_model_bytes(asking, K.world_model(), timeout=0.3)


def test_damaged_bytes_name_their_source():
    with pytest.raises(ModelFormatError, match="zenoh:cekm/world/model: not a readable .npz"):
        load_model_bytes(b"not a zip file", "zenoh:cekm/world/model")


def test_zenoh_source_and_client_config_files(tmp_path):
    assert is_zenoh_source("zenoh") and not is_zenoh_source("model.npz")
    router = tmp_path / "router.json5"
    router.write_text('{ mode: "router" }')
    with pytest.raises(RuntimeTransportError, match="router.json5: mode is 'router'"):
        client_config_from_file(router, "tcp/127.0.0.1:7447")
    with pytest.raises(RuntimeTransportError, match="no such file"):
        client_config_from_file(tmp_path / "missing.json5", "tcp/127.0.0.1:7447")
    client = tmp_path / "client.json5"
    client.write_text('{ mode: "client", connect: { endpoints: ["tcp/elsewhere:1"] } }')
    config = client_config_from_file(client, "tcp/127.0.0.1:7999")
    assert '"tcp/127.0.0.1:7999"' in config.get_json("connect/endpoints")
    assert config.get_json("scouting/multicast/enabled") == "false"
