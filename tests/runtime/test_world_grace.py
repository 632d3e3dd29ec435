"""A robots-only host's wait for the world (``launch.robot_host``) with ``--world-grace``:
the world's token going without its end (a cut link looks the same) is waited out for that
long, with a real router and sessions in this process."""

from __future__ import annotations

import asyncio

import pytest

from cekm_swarm.launch.launcher import LaunchConfig, Launcher
from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.runtime.bridge import LivelinessWatcher, declare_alive
from cekm_swarm.runtime.config import open_client

pytestmark = pytest.mark.slow  # Zenoh sessions and 1 s settles: left out of the fast lane

WAIT = 20.0  # s any wait for something that must happen is bounded by


def serve(tmp_path, endpoint: str, grace: float, script) -> list[str]:
    """Run ``_serve_until_world_ends`` while ``script(world_session, until_said)`` plays the
    world's token; the lines the launcher said."""
    said: list[str] = []
    mine, world = open_client(endpoint), open_client(endpoint)

    async def scenario() -> None:
        more = asyncio.Event()

        def echo(line: str) -> None:
            said.append(line.split("] ", 1)[-1])
            more.set()

        async def until_said(needle: str) -> None:
            while not any(needle in line for line in said):
                more.clear()
                await more.wait()

        launcher = Launcher(LaunchConfig("lone_obstacle", tmp_path, connect=endpoint, world_grace=grace), echo=echo)
        launcher.startup_s = 1.0
        token = declare_alive(world, K.alive("world", "server"))
        with LivelinessWatcher(mine, K.alive_all()) as watcher:
            await watcher.wait_for(K.alive("world", "server"), True, WAIT)
            task = asyncio.ensure_future(launcher._serve_until_world_ends(watcher, 14, mine))
            await until_said("the world server is up")
            await script(world, token, until_said, task)
            await asyncio.wait_for(task, WAIT)

    try:
        asyncio.run(asyncio.wait_for(scenario(), 3 * WAIT))
    finally:
        mine.close()
        world.close()
    return said


def test_a_world_token_gone_without_its_end_is_waited_for_and_taken_back(tmp_path, router):
    async def script(world, token, until_said, task) -> None:
        token.undeclare()  # as a cut link past Zenoh's lease shows it
        await until_said("went without its end")
        assert not task.done()
        back = declare_alive(world, K.alive("world", "server"))  # the link is back
        await until_said("the world server is back")
        assert not task.done()
        declare_alive(world, K.world_ended())  # the world's normal end
        back.undeclare()

    said = serve(tmp_path, router, 30.0, script)
    assert said[1:] == ["the world server is up",
                        "the world server's token went without its end (a cut link?); waiting up to 30 s for it",
                        said[3], "the world server has ended"], said
    assert said[3].startswith("the world server is back after")


def test_the_wait_ends_after_the_grace_and_without_one_at_once(tmp_path, router):
    async def script(world, token, until_said, task) -> None:
        token.undeclare()

    said = serve(tmp_path, router, 0.3, script)
    assert said[-2:] == ["the world server's token went without its end (a cut link?); waiting up to 0.3 s for it",
                         "the world server has ended"], said
    said = serve(tmp_path / "b", router, 0.0, script)
    assert said[-1] == "the world server has ended" and not any("went without" in x for x in said), said
