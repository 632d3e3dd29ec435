"""A robots-only host's side of a launch (``cekm launch --no-world``, several hosts): learn
the run id from the world server's token, then keep the nodes supervised until the world
server (on another host) has come and gone; with an outside router that restarts, wait
for it and the world to come back."""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections.abc import Callable
from typing import Any

from cekm_swarm.runtime.bridge import LivelinessWatcher

from .errors import LaunchError

ROUTER_SETTLE = 1.0  # s a token's DELETE may come before the session notices its router is gone
ROUTER_GRACE = 10.0  # s a robots-only host with --connect waits for a lost router and the world to come back


class RobotHost:
    """The robots-only-host part of :class:`~cekm_swarm.launch.launcher.Launcher`."""

    c: Any
    keys: Any
    session: Any
    stopping: bool
    # what it shares with the rest of the launcher (declared here, set and defined there)
    say: Callable[[str], None]
    _choose_run_id: Callable[[], None]
    startup_s: float | None

    async def _join_run_id(self) -> None:
        """A robots-only host: the run id given, or the one the world server's token carries."""
        if self.c.run_id is None:
            self.say("waiting for the world server to learn the run id (or give --run-id)")
            self.c.run_id = await self._world_run_id()
            if self.c.run_id is None:
                return
        self._choose_run_id()

    async def _world_run_id(self) -> str | None:
        """The run id in the world server's token, once one is alive (None if interrupted)."""
        any_run = self.keys.with_run(None)
        with LivelinessWatcher(self.session, any_run.world_alive_any_run()) as watcher:
            while not self.stopping:
                runs = sorted({any_run.parse(k).run for k in watcher.alive} - {None})
                if len(runs) > 1:
                    raise LaunchError(f"several runs' world servers on this router ({', '.join(runs)}): "
                                      f"give --run-id")
                if runs:
                    return runs[0]
                with contextlib.suppress(asyncio.TimeoutError):
                    await watcher.next_event(timeout=1.0)
        return None


    async def _serve_until_world_ends(self, watcher: LivelinessWatcher, n: int, session: Any) -> None:
        """Robots-only host: keep the modules supervised until the world server (on another
        host) has come and gone, or until interrupted. Read from the token's events, in
        order, so a short run that came and went between two looks is still seen to end;
        and a lost router (the world host hosted it and has gone) ends the wait too."""
        world_key, ended_key = self.keys.alive("world", "server"), self.keys.world_ended()
        self.say(f"all {n} local modules alive after {self.startup_s:.1f} s; waiting for the world server")
        seen = world_key in watcher.alive
        if seen:
            self.say("the world server is up")
        while not self.stopping:
            try:
                event = await watcher.next_event(timeout=1.0)
            except TimeoutError:
                if seen and not session.info.routers_zid():
                    if (await self._router_back(watcher, world_key, session)
                            or await self._world_back(watcher, world_key)):
                        continue
                    self.say("the world server has ended (its host's Zenoh router is gone)")
                    return
                continue
            if event.key == ended_key and event.alive:  # the world said so: no router to wait for
                self.say("the world server has ended")
                return
            if event.key != world_key:
                continue
            if event.alive and not seen:
                self.say("the world server is up")
                seen = True
            elif not event.alive:
                if ended_key not in watcher.alive and (await self._router_back(watcher, world_key, session)
                                                       or await self._world_back(watcher, world_key)):
                    continue
                self.say("the world server has ended")
                return

    async def _router_back(self, watcher: LivelinessWatcher, world_key: str, session: Any) -> bool:
        """The world's token went with the router: with ``--connect`` (an outside router,
        which may be restarted) wait up to :data:`ROUTER_GRACE` s for the world's token to
        come back (Zenoh clients reconnect and re-declare their tokens by themselves). True
        if it did; False at once if the router is still there (the world really ended) or
        when this host serves its own router."""
        if not self.c.connect or not await self._router_lost(session):
            return False
        return await self._await_world(
            watcher, world_key, ROUTER_GRACE,
            f"lost the Zenoh router; waiting up to {ROUTER_GRACE:.0f} s for it and the world server to come back",
            "reconnected: the world server is up again after")

    async def _world_back(self, watcher: LivelinessWatcher, world_key: str) -> bool:
        """The world's token went without its end (``world/alive/ended``): a cut link looks
        the same as a dead world from here. With ``--world-grace S`` wait up to S s for the
        token to come back (the link returned; Zenoh reconnects and re-declares by itself):
        True if it did. False at once without it (ending at once, as before)."""
        grace = self.c.world_grace
        if grace <= 0 or self.stopping:
            return False
        return await self._await_world(
            watcher, world_key, grace,
            f"the world server's token went without its end (a cut link?); waiting up to {grace:g} s for it",
            "the world server is back after")

    async def _await_world(self, watcher: LivelinessWatcher, world_key: str, limit: float, waiting: str,
                           back: str) -> bool:
        """Say ``waiting``, then wait up to ``limit`` s for the world's token: True (saying
        ``back`` and how long it took) if it came back."""
        self.say(waiting)
        t0 = time.monotonic()
        try:
            await watcher.wait_for(world_key, True, limit)
        except TimeoutError:
            return False
        self.say(f"{back} {time.monotonic() - t0:.1f} s")
        return True

    @staticmethod
    async def _router_lost(session: Any) -> bool:
        """True once the session has no router. A router's death reaches us as the DELETE
        of every token it carried, which can come a moment before the session drops the
        router from its list: so a token gone with a router still listed is looked at
        again for up to :data:`ROUTER_SETTLE` s before it counts as really gone."""
        deadline = time.monotonic() + ROUTER_SETTLE
        while session.info.routers_zid():
            if time.monotonic() >= deadline:
                return False
            await asyncio.sleep(0.05)
        return True

