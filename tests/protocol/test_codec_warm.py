"""``protocol.codec.warm``: what a fork server makes once before forking its nodes."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from cekm_swarm.protocol.schema import MESSAGE_TYPES


@pytest.mark.slow  # a fresh interpreter: the caches are empty in it
def test_warm_makes_everything_a_message_of_any_kind_needs():
    """In a fresh interpreter: after ``warm()``, encoding and decoding a message of every
    kind (and every record inside one) makes no decoder, head or check any more."""
    script = textwrap.dedent("""
        import json
        from cekm_swarm.protocol import checks, codec
        from test_wire_format import samples
        made = codec.warm()
        before = (len(codec._CODECS), len(codec._HEADS), len(checks._CHECKS))
        for key, msg in samples():
            codec.decode(key, codec.encode(msg))
        after = (len(codec._CODECS), len(codec._HEADS), len(checks._CHECKS))
        print(json.dumps({"made": made, "before": before, "after": after, "again": codec.warm()}))
    """)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(Path(__file__).parent), os.environ.get("PYTHONPATH", "")]))
    out = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, check=True)
    doc = json.loads(out.stdout)
    kinds = len(MESSAGE_TYPES)
    assert doc["before"][:2] == [kinds, kinds]
    assert doc["after"] == doc["before"]  # nothing left to make on a first message
    assert doc["made"] == doc["again"] >= kinds
