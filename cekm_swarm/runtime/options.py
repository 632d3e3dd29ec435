"""The runtime's click argument types: :data:`ENDPOINT`, a Zenoh locator checked when the
command line is parsed (``--connect tcp/10.0.0.1:7447``), so a bad one is a usage error
naming the option."""

from __future__ import annotations

from typing import Any

import click

from cekm_swarm.errors import CekmError

from .config import check_endpoint


class Endpoint(click.ParamType):
    """A Zenoh endpoint ``proto/host:port`` (:func:`.config.check_endpoint`)."""

    name = "endpoint"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        if not isinstance(value, str):
            return value
        try:
            return check_endpoint(value)
        except (CekmError, ValueError) as exc:
            self.fail(str(exc), param, ctx)


ENDPOINT = Endpoint()
