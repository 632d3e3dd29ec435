"""Paired comparisons for docs/fields.md's per-field round, from the JSON files the
commands there write (run from the repository's root):

  python docs/results/field-policy/per-field/compare.py contacts A/contacts.json B/contacts.json
      runs contact-free in A and not B, and the reverse (the same validation seeds)
  python docs/results/field-policy/per-field/compare.py concave A/results.json B/results.json [VARIANT_A VARIANT_B]
      Fig. 9's cells negotiated by A's variant (default learned) and not by B's (default tuned),
      the reverse, and the narrow (<= 0.34 m) cells each fails
"""

from __future__ import annotations

import json
import sys
from pathlib import Path


def _load(path: str) -> dict:
    return json.loads(Path(path).read_text())


def contacts(a: str, b: str) -> None:
    ra, rb = (_load(p)["runs"] for p in (a, b))
    assert [r["seed"] for r in ra] == [r["seed"] for r in rb], "not the same seeds"

    def free(r: dict) -> bool:
        return r["reached"] and r["collisions"] == 0

    wins = sum(free(x) and not free(y) for x, y in zip(ra, rb, strict=True))
    losses = sum(free(y) and not free(x) for x, y in zip(ra, rb, strict=True))
    print(f"contact-free: A {sum(map(free, ra))}, B {sum(map(free, rb))}; A and not B {wins}, B and not A {losses}; "
          f"contacts A {sum(r['collisions'] for r in ra)}, B {sum(r['collisions'] for r in rb)}")


def concave(a: str, b: str, va: str = "learned", vb: str = "tuned") -> None:
    def cells(path: str, v: str) -> dict:
        return {(c["range"], c["depth"], c["width"]): c["reached"] >= 2 for c in _load(path)[v]["cells"]}

    ca, cb = cells(a, va), cells(b, vb)
    gained = sorted(k for k in ca if ca[k] and not cb[k])
    lost = sorted(k for k in ca if cb[k] and not ca[k])
    print(f"negotiated: A {sum(ca.values())}, B {sum(cb.values())}; gained {len(gained)} {gained}; "
          f"lost {len(lost)} {lost}")
    print(f"narrow (<= 0.34 m) cells failed: A {sum(not v for k, v in ca.items() if k[2] <= 0.34)}, "
          f"B {sum(not v for k, v in cb.items() if k[2] <= 0.34)}")


if __name__ == "__main__":
    {"contacts": contacts, "concave": concave}[sys.argv[1]](*sys.argv[2:])
