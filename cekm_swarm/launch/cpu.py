"""Where a run's CPU goes: the CPU seconds of every process a launcher started, read
from ``/proc`` when the world starts ticking and when it is done, per tick and per kind of
process (world server, target, obstacle, motor module, and the launcher itself).

A tick's CPU on this machine is the budget of a real-time run (2 cores give 256 ms of CPU
per 128 ms tick), so this is what tells which process to make cheaper
(``benchmarks/bench_runtime_scale.py`` prints it against the number of robots). Linux
only: elsewhere (no ``/proc``) :func:`cpu_seconds` gives None and the split is empty. A
process restarted between the two readings (another pid) is left out.

It also says what the machine was doing meanwhile (``host``, from ``/proc/stat``): the
share of all cores' time that was idle, and the share *stolen*, which a virtual
machine's hypervisor gave to other guests while this one wanted to run. On a shared host
the same run's wall time moves by a factor of two with steal, so a speed measured
without it cannot be compared with another.
"""

from __future__ import annotations

import os
import resource
from collections.abc import Mapping
from dataclasses import dataclass

_HZ = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100


def cpu_seconds(pid: int) -> float | None:
    """CPU seconds of process ``pid``, all its threads (None if it is gone or there is no ``/proc``).

    From each thread's ``/proc/PID/task/TID/schedstat`` (nanoseconds on the CPU) where the
    kernel has it, else ``/proc/PID/stat``'s utime + stime, whose clock ticks (10 ms) are
    too coarse for a module's fraction of a millisecond per tick over a short run."""
    total = _schedstat_seconds(pid)
    if total is not None:
        return total
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            fields = f.read().rsplit(b")", 1)[1].split()
    except (OSError, IndexError):
        return None
    return (int(fields[11]) + int(fields[12])) / _HZ  # utime, stime (proc(5), fields 14 and 15)


def _schedstat_seconds(pid: int) -> float | None:
    try:
        tids = os.listdir(f"/proc/{pid}/task")
    except OSError:
        return None
    ns = 0
    for tid in tids:
        try:
            with open(f"/proc/{pid}/task/{tid}/schedstat", "rb") as f:
                ns += int(f.read().split()[0])  # time spent on the cpu, ns (sched-stats.rst)
        except OSError:
            continue  # the thread ended meanwhile (ENOENT, ESRCH): its time is in no file any more
        except (IndexError, ValueError):
            return None
    return ns / 1e9


def host_times() -> tuple[int, int, int] | None:
    """(all, idle + iowait, steal) clock ticks of every core since boot, from ``/proc/stat``
    (None without it)."""
    try:
        with open("/proc/stat", "rb") as f:
            fields = f.readline().split()
    except OSError:
        return None
    if not fields or fields[0] != b"cpu":
        return None
    ticks = [int(x) for x in fields[1:9]]  # user nice system idle iowait irq softirq steal (proc(5))
    while len(ticks) < 8:
        ticks.append(0)
    return sum(ticks), ticks[3] + ticks[4], ticks[7]


def host_shares(start: tuple[int, int, int] | None, end: tuple[int, int, int] | None) -> dict:
    """Between two :func:`host_times`: the shares of all cores' time that were idle and
    stolen by the hypervisor (empty when unknown or no time passed)."""
    if start is None or end is None or end[0] <= start[0]:
        return {}
    span = end[0] - start[0]
    return {"idle": round((end[1] - start[1]) / span, 3), "steal": round((end[2] - start[2]) / span, 3)}


def own_cpu_seconds() -> float:
    """This process's user + system CPU seconds."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def kind_of(label: str) -> str:
    """The kind of a process from its launcher label (``r1/obstacle-3`` -> ``obstacle``,
    ``world/server`` -> ``world``, ``launch/fork-server`` -> ``fork-server``)."""
    if label == "world/server":
        return "world"
    if label.startswith("launch/"):
        return label.partition("/")[2]
    name = label.rpartition("/")[2]
    return name.partition("-")[0]


@dataclass(frozen=True)
class CpuSnapshot:
    """CPU seconds per process label (``world/server``, ``launcher``, ``r1/motor``, ...), keyed with its pid."""

    seconds: Mapping[tuple[str, int], float]
    host: tuple[int, int, int] | None = None
    """The machine's :func:`host_times` at the same moment."""


def snapshot(pids: Mapping[str, int], reported: Mapping[tuple[str, int], float] | None = None) -> CpuSnapshot:
    """Read every process of ``pids`` (label -> pid) and the launcher's own CPU now;
    a process that ``reported`` its CPU seconds itself ((label, pid) -> s) is taken at its
    word, even when it is gone by now."""
    out: dict[tuple[str, int], float] = {("launcher", os.getpid()): own_cpu_seconds()}
    for label, pid in pids.items():
        s = cpu_seconds(pid)
        if s is not None:
            out[(label, pid)] = s
    out.update(reported or {})
    return CpuSnapshot(out, host_times())


def cpu_per_tick(start: CpuSnapshot, end: CpuSnapshot, ticks: int, robots: int) -> dict:
    """Milliseconds of CPU per tick by kind of process, between two snapshots: the
    processes present in both (same pid), summed over robots; also the total per tick and
    per robot-tick, the processes of each kind and the CPU per process of each kind per tick,
    the process lives left out (``not_counted``: begun or ended between the snapshots, a
    restart's two lives), and the machine's idle and stolen shares meanwhile (:func:`host_shares`).
    Empty when nothing could be read or no tick passed."""
    if ticks <= 0:
        return {}
    by_kind: dict[str, float] = {}
    count: dict[str, int] = {}
    for key, s1 in end.seconds.items():
        s0 = start.seconds.get(key)
        if s0 is None:
            continue
        kind = kind_of(key[0])
        by_kind[kind] = by_kind.get(kind, 0.0) + (s1 - s0)
        count[kind] = count.get(kind, 0) + 1
    if not by_kind:
        return {}
    total = sum(by_kind.values())
    return {"ticks": ticks,
            "ms_per_tick": {k: round(1000 * v / ticks, 3) for k, v in sorted(by_kind.items(), key=lambda kv: -kv[1])},
            "processes": {k: count[k] for k in sorted(count)},
            "ms_per_process_tick": {k: round(1000 * by_kind[k] / ticks / count[k], 4) for k in sorted(count)},
            "total_ms_per_tick": round(1000 * total / ticks, 3),
            "ms_per_robot_tick": round(1000 * total / ticks / max(1, robots), 3),
            "not_counted": len(set(start.seconds) ^ set(end.seconds)),  # a process's life begun or ended between
            "host": host_shares(start.host, end.host)}
