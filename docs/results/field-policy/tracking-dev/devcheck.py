"""Issue 41's tracking diagnosis and field-lever checks on development seeds (5001+, never
reported; docs/fields.md, "Tracking: the weak cells on development seeds").

  python devcheck.py losses CELLS SEEDS DURATION CONTROLLERS [NAME=VALUE ...]
  python devcheck.py run OUT.json CELLS SEEDS DURATION CONTROLLERS [NAME=VALUE ...]
  python devcheck.py compare BASE.json BASELINES.json CANDIDATE.json ...   (A.json+B.json: both files' runs)
  python devcheck.py turns [NAME=VALUE ...]

CELLS: comma-separated parts of the grid's cell labels (``fast``, ``R0.35``, a full label)
or ``all``; SEEDS: ``A-B``; NAME=VALUE: overrides of cekm's TrackingParams (as ``--param``).
``run`` calls the grid's own runner (``run_grid``, one worker), so each run is the run that
``cekm experiment tracking --grid --first-seed A --duration DURATION`` makes of that cell and seed.
``losses`` counts, from the true paths, per run: A; the fraction of robot-ticks that see no
target (idle); the fraction of targets seen by two robots or more (redundant); covered
targets lost per target-minute; the share of those losses whose one observer lost it; and
the share of the observers losing a target that had it more than 1 rad off their heading.
``turns`` tabulates, for the default model the tracker uses, the command Eq. 11 gives at the
goal states (alpha, 0), alpha from 0 to pi each side (the winner's neuron, the motor's
winner, the wheels and the turn rate (v_r - v_l) / axle); then what the tracker (today's, or
with NAME=VALUE a candidate) commands for a lone target sensed at (alpha, 0.9 R), R = 0.35 m
(after its face_angle rule); and A-CMOMMT's motor (force_wheels) toward a unit force at alpha.
"""

from __future__ import annotations

import collections
import json
import math
import sys
import time

import numpy as np

from cekm_swarm.experiments.commands import parse_cekm_params
from cekm_swarm.experiments.default_model import default_model, default_model_path
from cekm_swarm.experiments.grid_design import design, grid_scenario
from cekm_swarm.experiments.grid_run import run_grid
from cekm_swarm.experiments.tracking_run import run_tracking
from cekm_swarm.models.params import TrackingParams

TICK_S = 0.128


def cells_of(sel: str) -> list:
    return [c for c in design() if sel == "all" or any(s in c.label for s in sel.split(","))]


def seeds_of(text: str) -> list[int]:
    a, b = text.split("-")
    return list(range(int(a), int(b) + 1))


def params_of(items: list[str]) -> TrackingParams | None:
    """NAME=VALUE overrides of cekm's TrackingParams, read as ``--param`` reads them."""
    return TrackingParams(**parse_cekm_params(tuple(items))) if items else None


def losses(run) -> dict[str, float]:
    """The counts of one run, from the robots' and targets' true paths."""
    rob = np.stack([np.array([(x, y) for (_, x, y, _) in p]) for p in run.paths.values()])
    heading = np.stack([np.array([th for (_, _, _, th) in p]) for p in run.paths.values()])
    tgt = np.stack([np.array(p) for p in run.target_paths.values()])
    n = min(rob.shape[1], tgt.shape[1])
    d = np.linalg.norm(rob[:, None, :n] - tgt[None, :, :n], axis=-1)  # robot, target, tick
    seen = d <= run.target_range
    covered, observers = seen.any(0), seen.sum(0)
    lost = covered[:, :-1] & ~covered[:, 1:]
    beside = []
    for t, k in zip(*np.nonzero(lost), strict=True):  # where its observers had it the tick before
        for r in np.nonzero(seen[:, t, k])[0]:
            dx, dy = tgt[t, k] - rob[r, k]
            bearing = math.atan2(dy, dx) - heading[r, k]
            beside.append(abs(math.atan2(math.sin(bearing), math.cos(bearing))) > 1.0)
    return {"A": float(covered.mean()), "idle": float((~seen.any(1)).mean()),
            "redundant": float((observers >= 2).mean()),
            "lost_per_target_min": float(lost.sum() / (n * TICK_S / 60.0) / tgt.shape[0]),
            "lost_by_one": float((observers[:, :-1][lost] == 1).mean()) if lost.any() else 0.0,
            "lost_beside": float(np.mean(beside)) if beside else 0.0}


def cmd_losses(sel: str, seeds: str, duration: str, controllers: str, over: list[str]) -> None:
    model, tp = default_model(progress=False), params_of(over)
    for cell in cells_of(sel):
        for ctl in controllers.split(","):
            rows = [losses(run_tracking(grid_scenario(cell, s), ctl, model if ctl == "cekm" else None, s,
                                        float(duration), tparams=tp if ctl == "cekm" else None))
                    for s in seeds_of(seeds)]
            print(cell.label, ctl, " ".join(f"{k} {np.mean([r[k] for r in rows]):.3f}" for k in rows[0]), flush=True)


def cmd_run(out: str, sel: str, seeds: str, duration: str, controllers: str, over: list[str]) -> None:
    default_model(progress=False)
    t0 = time.time()
    rows = run_grid(cells_of(sel), seeds_of(seeds), float(duration), default_model_path(), workers=1,
                    progress=False, controllers=tuple(controllers.split(",")), tparams=params_of(over))
    with open(out, "w") as f:
        json.dump({"params": over, "seeds": seeds, "duration": float(duration), "wall_s": round(time.time() - t0),
                   "rows": [{k: r[k] for k in ("cell", "seed", "controller", "A", "collisions")} for r in rows]}, f)


def cmd_turns(over: list[str]) -> None:
    from cekm_swarm.controller.acmommt import force_wheels  # noqa: PLC0415
    from cekm_swarm.controller.team import TeamView  # noqa: PLC0415
    from cekm_swarm.controller.tracking import TrackingActivity, TrackingEKM  # noqa: PLC0415
    from cekm_swarm.models.params import ACMOMMTParams  # noqa: PLC0415
    from cekm_swarm.robot import KHEPERA  # noqa: PLC0415
    model, tp, ap = default_model(progress=False), params_of(over) or TrackingParams(), ACMOMMTParams()
    R = 0.35
    ctl = TrackingEKM("r1", model, R, tp)
    ekm, axle, c = ctl.ekm, KHEPERA.axle, model.v_max
    print(f"c* = {c:.4f} m/s, axle {axle} m: the fastest turn in place is 2 c* / axle = {2 * c / axle:.2f} rad/s; "
          f"turn = (v_r - v_l) / axle, + = left")
    print("| alpha | map at (alpha, 0): s (alpha_s, d_s) | k | v_l, v_r (m/s) | turn (rad/s) | "
          "tracker, lone target at (alpha, 0.9 R): k | v_l, v_r | turn | A-CMOMMT v_l, v_r | turn |")
    print("|---:|---|---:|---|---:|---:|---|---:|---|---:|")
    for alpha in [x * sign for x in (0.0, 0.25, 0.5, 0.75, 0.9, 1.0, 1.1, 1.25, 1.5, 2.0, 2.5, 3.0, math.pi)
                  for sign in (1, -1) if x or sign > 0]:
        s = ekm.winner(alpha, 0.0)
        raw = TrackingEKM("r1", model, R, TrackingParams(face_turn_gain=1.0)).integrate(  # Eq. 11 as it is
            TrackingActivity(0.0, ekm.target_activity(s), np.zeros(ekm.n), ((s, alpha, 0.0, 1.0),), {}, False), [])
        act = TrackingEKM("r1", model, R, tp).localize(0.0, (0.0, 0.0, 0.0), {"t1": (alpha, 0.9 * R)}, TeamView("r1"))
        out = ctl.integrate(act, [])
        al, ar = force_wheels(math.cos(alpha), math.sin(alpha), [], 0.0, 1.0, axle, c, ap.obstacle_gain,
                              ap.turn_gain)
        print(f"| {alpha:+.2f} | {s} ({ekm.w[s, 0]:+.2f}, {ekm.w[s, 1]:.3f}) | {raw.k} | {raw.v_l:+.3f}, "
              f"{raw.v_r:+.3f} | {(raw.v_r - raw.v_l) / axle:+.2f} | {out.k} | {out.v_l:+.3f}, {out.v_r:+.3f} | "
              f"{(out.v_r - out.v_l) / axle:+.2f} | {al:+.3f}, {ar:+.3f} | {(ar - al) / axle:+.2f} |")


def _a(doc: dict, controller: str) -> dict[str, dict[int, float]]:
    out: dict[str, dict[int, float]] = collections.defaultdict(dict)
    for r in doc["rows"]:
        if r["controller"] == controller:
            out[r["cell"]][r["seed"]] = r["A"]
    return out


def _load(paths: str) -> dict:
    """The runs of one or more ``run`` files (``A.json+B.json``: other seeds of the same setting)."""
    rows = []
    for path in paths.split("+"):
        with open(path) as f:
            rows += json.load(f)["rows"]
    return {"rows": rows}


def cmd_compare(base_file: str, baselines_file: str, candidates: list[str]) -> None:
    from scipy import stats  # noqa: PLC0415 -- lazy, as the project's statistics modules do
    base = _a(_load(base_file), "cekm")
    bl = _load(baselines_file)
    acm, km = _a(bl, "acmommt"), _a(bl, "kmeans")
    for path in candidates:
        cand = _a(_load(path), "cekm")
        diffs, lines, better, worse = [], [], 0, 0
        for cell in sorted(cand, key=lambda c: ("fast" not in c, c)):
            seeds = sorted(set(cand[cell]) & set(base[cell]))
            dd = np.array([cand[cell][s] - base[cell][s] for s in seeds])
            diffs += list(dd)
            p = float(stats.ttest_1samp(dd, 0.0).pvalue) if dd.std() > 0 else 1.0
            better += int(dd.mean() > 0 and p < 0.05)
            worse += int(dd.mean() < 0 and p < 0.05)
            best = max(np.mean([acm[cell][s] for s in seeds]), np.mean([km[cell][s] for s in seeds]))
            b, c = np.mean([base[cell][s] for s in seeds]), np.mean([cand[cell][s] for s in seeds])
            lines.append(f"| {cell} | {b:.3f} | {c:.3f} | {dd.mean():+.4f} (p = {p:.2f}) | {best:.3f} | "
                         f"{b - best:+.3f} | {c - best:+.3f} |")
        arr = np.array(diffs)
        print(f"{path}: paired candidate - base {arr.mean():+.4f} +- {1.96 * arr.std(ddof=1) / math.sqrt(len(arr)):.4f}"
              f" ({len(arr)} runs); cells significantly better {better}, worse {worse}")
        print("| cell | A base | A candidate | paired difference | best baseline | base - best | candidate - best |")
        print("|---|---:|---:|---|---:|---:|---:|")
        print("\n".join(lines))


if __name__ == "__main__":
    cmd, args = sys.argv[1], sys.argv[2:]
    if cmd == "losses":
        cmd_losses(args[0], args[1], args[2], args[3], args[4:])
    elif cmd == "run":
        cmd_run(args[0], args[1], args[2], args[3], args[4], args[5:])
    elif cmd == "turns":
        cmd_turns(args)
    elif cmd == "compare":
        cmd_compare(args[0], args[1], args[2:])
    else:
        sys.exit(__doc__)
