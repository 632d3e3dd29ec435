"""docs/design.md's map of the tree (section 8) matches the tree: every module of
``cekm_swarm/`` and ``world/`` is named there, and every path it names exists."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _map_section() -> str:
    text = (ROOT / "docs" / "design.md").read_text(encoding="utf-8")
    start = text.index("## 8. Where each concept lives")
    end = text.find("\n## ", start + 5)
    return text[start:] if end == -1 else text[start:end]


def _modules() -> list[Path]:
    return sorted(p for pkg in ("cekm_swarm", "world") for p in (ROOT / pkg).rglob("*.py")
                  if p.name not in ("__init__.py", "__main__.py"))


def test_every_module_is_on_the_map() -> None:
    named = set(re.findall(r"`([^`]+)`", _map_section()))
    words = {w for n in named for w in re.split(r"[^\w]+", n) if w}
    missing = [str(p.relative_to(ROOT)) for p in _modules() if p.stem not in words]
    assert not missing, "docs/design.md section 8 does not name: " + ", ".join(missing)


def test_every_path_on_the_map_exists() -> None:
    paths = re.findall(r"`((?:cekm_swarm|world|tests|docs|benchmarks|deploy)/[\w./-]*)`", _map_section())
    inner = r"`((?:experiments|node|launch|runtime|ros2|tune|view|graph)/[\w.-]+\.py)`"
    paths += [f"cekm_swarm/{p}" for p in re.findall(inner, _map_section())]
    gone = [p for p in paths if not (ROOT / p).exists()]
    assert paths and not gone, f"docs/design.md section 8 names paths that are gone: {gone}"
