"""The obstacle suite's statistics: each (scenario, controller) over the seeds by its
success rate and its collision-free success rate, each with a 95 % Wilson score
interval, and the number of contacts (new contacts with a wall or obstacle, summed over
the runs). The runs are :mod:`.obstacle_run`'s."""

from __future__ import annotations

import math


def wilson_interval(k: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """The 95 % Wilson score interval of a success rate k/n (sound at k = 0 or k = n,
    unlike the normal approximation)."""
    if n <= 0:
        return (0.0, 1.0)
    p = k / n
    den = 1.0 + z * z / n
    mid = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1.0 - p) / n + z * z / (4.0 * n * n)) / den
    return (max(0.0, mid - half), min(1.0, mid + half))


def summarize(rows: list[dict], scenarios: dict[str, tuple[str, ...]]) -> dict:
    """Per scenario and controller: successes, collision-free successes (each with its 95 %
    Wilson interval), contacts summed over the runs, runs with a contact, the smallest
    clearance (None when no run had anything within sensor range: every run's is None)."""
    summary: dict = {}
    for s, cs in scenarios.items():
        summary[s] = {}
        for c in cs:
            mine = [r for r in rows if r["scenario"] == s and r["controller"] == c]
            n = len(mine)
            k = sum(r["success"] for r in mine)
            k_free = sum(r["collision_free"] for r in mine)
            summary[s][c] = {"success": k, "of": n, "success_ci95": list(wilson_interval(k, n)),
                             "collision_free": k_free, "collision_free_ci95": list(wilson_interval(k_free, n)),
                             "contacts": sum(r["collisions"] for r in mine),
                             "runs_with_contact": sum(r["collisions"] > 0 for r in mine),
                             "min_clearance_m": min((r["min_clearance_m"] for r in mine
                                                     if r["min_clearance_m"] is not None), default=None)}
    return summary
