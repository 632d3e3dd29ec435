"""The reference generated from the code (pdoc, the command in docs/reference.md and
.ci/run): it builds, and every public name of cekm_swarm.node and cekm_swarm.protocol is
in it, so it cannot drift from the code."""

from __future__ import annotations

import importlib
from pathlib import Path

import pytest

MODULES = ("cekm_swarm.node", "cekm_swarm.protocol", "cekm_swarm.robot", "cekm_swarm.errors", "cekm_swarm.ticks")


@pytest.fixture(scope="module")
def built(tmp_path_factory) -> Path:
    import pdoc  # the test extra's: CI builds the reference here
    import pdoc.render

    out = tmp_path_factory.mktemp("reference")
    pdoc.render.configure(search=False)  # the search index would start node.js
    pdoc.pdoc(*MODULES, output_directory=out)
    return out


@pytest.mark.parametrize("package", ["cekm_swarm.node", "cekm_swarm.protocol"])
def test_every_public_name_is_in_the_reference(built, package):
    page = (built / (package.replace(".", "/") + ".html")).read_text()
    names = importlib.import_module(package).__all__
    missing = [n for n in names if f'id="{n}"' not in page]
    assert not missing, f"{package}: not in the reference: {missing}"


def test_the_reference_says_what_a_user_had_to_find_by_inspect(built):
    node = (built / "cekm_swarm/node.html").read_text()
    protocol = (built / "cekm_swarm/protocol.html").read_text()
    robot = (built / "cekm_swarm/robot.html").read_text()
    assert "exit code 1" in node and "exit code 2" in node  # the exit codes
    assert "from the robot&#39;s centre" in protocol or "from the robot's centre" in protocol  # SenseRange.d
    assert "clamps" in protocol and "clamps" in robot  # a wheel speed beyond v_max
    for attr in ("axle", "v_max", "body_radius", "sensor_range", "sensor_angles"):
        assert attr in robot
