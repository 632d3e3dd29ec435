"""The protocol package imports nothing from cekm_swarm but cekm_swarm.errors and the tick
clock cekm_swarm.ticks (plain constants) (the world server imports it and must not pull
in controller code)."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

import cekm_swarm.protocol

PKG = Path(cekm_swarm.protocol.__file__).parent


def test_protocol_imports_only_errors_from_the_package():
    for path in PKG.glob("*.py"):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:  # relative: must stay inside the protocol package
                    assert node.level == 1, f"{path.name}: relative import leaves the protocol package"
                    continue
                names = [node.module or ""]
            else:
                continue
            for name in names:
                if name.startswith("cekm_swarm"):
                    assert name in ("cekm_swarm.errors", "cekm_swarm.ticks"), f"{path.name} imports {name}"


@pytest.mark.slow
def test_importing_the_protocol_loads_no_other_project_module():
    code = ("import sys, cekm_swarm.protocol; "
            "print(sorted(m for m in sys.modules if m.startswith(('cekm_swarm', 'world'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    loaded = eval(out)
    assert all(
        m in ("cekm_swarm", "cekm_swarm.errors", "cekm_swarm.ticks") or m.startswith("cekm_swarm.protocol")
        for m in loaded
    ), loaded
