"""A robots-only host's wait for the world server (``Launcher._serve_until_world_ends``),
driven by scripted liveliness events: a run that came and went before the host looked is
still seen to end, and a host whose router is gone (the world host hosted it) stops
waiting."""

from __future__ import annotations

import asyncio
from types import SimpleNamespace

from cekm_swarm.launch.launcher import LaunchConfig, Launcher
from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.runtime.bridge import LivelinessEvent

WORLD = K.alive("world", "server")


class ScriptedWatcher:
    """The part of LivelinessWatcher the wait uses: ``alive`` and ``next_event``."""

    def __init__(self, events: list[LivelinessEvent], alive: set[str]) -> None:
        self.events, self.alive = list(events), frozenset(alive)

    async def next_event(self, timeout: float | None = None) -> LivelinessEvent:
        if self.events:
            return self.events.pop(0)
        await asyncio.sleep(0)
        raise TimeoutError


def session_with_routers(*zids: str) -> SimpleNamespace:
    return SimpleNamespace(info=SimpleNamespace(routers_zid=lambda: list(zids)))


def wait(tmp_path, watcher, session) -> list[str]:
    said: list[str] = []
    launcher = Launcher(LaunchConfig("lone_obstacle", tmp_path), echo=said.append)
    launcher.startup_s = 1.0
    asyncio.run(asyncio.wait_for(launcher._serve_until_world_ends(watcher, 14, session), 5))
    return said


def test_a_world_that_came_and_went_before_the_first_look_is_seen_to_end(tmp_path):
    events = [LivelinessEvent(K.alive("r1", "motor"), True, 0.0), LivelinessEvent(WORLD, True, 0.1),
              LivelinessEvent(WORLD, False, 0.4)]
    said = wait(tmp_path, ScriptedWatcher(events, alive=set()), session_with_routers("a1"))
    assert [s.split("] ", 1)[1] for s in said[1:]] == ["the world server is up", "the world server has ended"]


def test_a_lost_router_ends_the_wait_once_the_world_was_seen(tmp_path):
    said = wait(tmp_path, ScriptedWatcher([], alive={WORLD}), session_with_routers())
    assert said[-1].endswith("the world server has ended (its host's Zenoh router is gone)")


def test_no_router_before_the_world_was_seen_keeps_waiting(tmp_path):
    events = [LivelinessEvent(WORLD, True, 0.0), LivelinessEvent(WORLD, False, 0.1)]
    watcher = ScriptedWatcher([], alive=set())
    said: list[str] = []
    launcher = Launcher(LaunchConfig("lone_obstacle", tmp_path), echo=said.append)
    launcher.startup_s = 1.0

    async def scenario() -> None:
        task = asyncio.ensure_future(launcher._serve_until_world_ends(watcher, 14, session_with_routers()))
        for _ in range(20):  # many timeouts with no router: not taken for the world's end
            await asyncio.sleep(0)
        assert not task.done()
        watcher.events.extend(events)
        await asyncio.wait_for(task, 5)

    asyncio.run(scenario())
    assert said[-1].endswith("the world server has ended")


def test_the_worlds_ended_token_ends_the_wait_without_waiting_for_a_lost_router(tmp_path):
    """A world host that also hosted the router: its token and the router go together, but
    the world declared ``world_ended`` first, so a --connect host does not wait for the router."""
    events = [LivelinessEvent(WORLD, True, 0.0), LivelinessEvent(K.world_ended(), True, 0.3),
              LivelinessEvent(WORLD, False, 0.4)]
    said: list[str] = []
    launcher = Launcher(LaunchConfig("lone_obstacle", tmp_path, connect="tcp/127.0.0.1:1"), echo=said.append)
    launcher.startup_s = 1.0
    session = session_with_routers()  # the router is gone too
    asyncio.run(asyncio.wait_for(launcher._serve_until_world_ends(ScriptedWatcher(events, set()), 14, session), 5))
    assert [s.split("] ", 1)[1] for s in said[1:]] == ["the world server is up", "the world server has ended"]
