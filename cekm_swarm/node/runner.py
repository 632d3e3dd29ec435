"""A node and the checks of what its step returns (:class:`Runner`), and the one line that
names a step that raised (:func:`step_failure`): what every timing gate and the in-process
executor run a node through."""

from __future__ import annotations

import time
from typing import Any

from cekm_swarm.graph.plan import NodePlan
from cekm_swarm.protocol import Nothing
from cekm_swarm.ticks import tick_time

from .api import Inputs, Node, NodeError, NotReady, StepFailed, raised_at
from .checks import output_check


class Runner:
    """A node and the checks of what its step returns: one message per output port, of
    the port's type, stamped with the tick's time, and fitting what its readers check
    (:mod:`.checks`: a field over the run's lattice)."""

    __slots__ = ("plan", "node", "runs", "skip_not_ready", "stepping", "answer", "done", "live", "_outs", "_check")

    def __init__(self, plan: NodePlan, node: Node, answer: str | None = None) -> None:
        self.plan, self.node, self.runs = plan, node, 0
        self.answer = answer  # the run's answer key (the world needs it every tick: never nothing on it)
        self.done = -1  # the tick of its last run
        self.live: Any = None  # parameters changed while it runs (.live_params.LiveParams), in a node's process
        self.stepping: tuple[float, float] | None = None  # (t, time.monotonic() it began) while a step runs
        self.skip_not_ready = False  # set by the real-time gate, which takes NotReady
        # (port, key, message type): a type of the protocol's or a user's, read as Any
        self._outs: list[tuple[str, str, Any]] = [(port, key, node.outputs[port].type)
                                                  for port, key in plan.outputs.items()]
        self._check = output_check(plan, node)  # what its readers check of what it sends (None: nothing)

    def run(self, k: int, inputs: Inputs) -> list[tuple[str, Any]]:
        """The node's outputs of its run at tick ``k``, checked; raises NodeError naming the
        node, the tick and what failed when its step raises or returns something wrong
        (:class:`~.api.NotReady` passes through to the real-time gate, and is a failure elsewhere)."""
        t = tick_time(k)
        if self.live is not None and self.live.pending:
            self.live.apply_due(k)
        # the node's step is called here, in run: the step watchdog and the launcher's
        # reading of a stalled node's stack name the frame run calls (the node's own line)
        self.stepping = (t, time.monotonic())
        try:
            out = self.node.step(t, inputs)
        except NotReady:
            if self.skip_not_ready:
                raise
            raise StepFailed(f"{self.plan.label}: its step at t={t:.3f} s raised NotReady, but in lockstep and "
                             f"in one process every input of a run is there (NotReady is for real time)") from None
        except NodeError as exc:
            if str(exc).startswith(self.plan.label):
                raise StepFailed(str(exc)) from exc
            raise StepFailed(step_failure(self.plan.label, t, exc)) from exc
        except Exception as exc:  # noqa: BLE001 - a user's node may fail in any way
            raise StepFailed(step_failure(self.plan.label, t, exc)) from exc
        finally:
            self.stepping = None
        sent = self._messages(out, k, t)
        if self._check is not None:
            try:
                self._check(t, sent)
            except StepFailed:
                raise
            except NodeError as exc:  # what its readers check of what it sends: its step failed
                raise StepFailed(str(exc)) from exc
        self.runs += 1
        self.done = max(self.done, k)
        return sent

    def _messages(self, out: Any, k: int, t: float) -> list[tuple[str, Any]]:
        """What a step returned as (key, message) pairs to send: its own fields filled in,
        a None as a Nothing (not on the run's answer); anything else wrong is refused."""
        if type(out) is not dict or len(out) != len(self._outs):
            self._refuse(out, t)
        sent: list[tuple[str, Any]] = []
        for port, key, want in self._outs:
            msg = out.get(port)
            if type(msg) is dict:  # its own fields: the runner adds what it knows
                msg = self._fill(want, msg, k, t, port)
            elif msg is None and port in out:  # nothing on this output this tick
                if key == self.answer:
                    raise StepFailed(f"{self.plan.label}: its step at t={t:.3f} s failed: output {port!r} is the run's "
                                     f"answer ({key}): the world needs a {want.__name__} every tick, not None")
                sent.append((key, Nothing(t, self.plan.label)))
                continue
            if type(msg) is not want or msg.stamp != t:
                self._refuse(out, t)
            sent.append((key, msg))
        return sent

    def _fill(self, want: Any, fields: dict[str, Any], k: int, t: float, port: str) -> Any:
        """The message of type ``want`` a step gave as a dict of its own fields: stamped
        ``t``, signed with the node's sender, and a ``seq`` it left out set to the tick ``k``
        (what the shipped motors send: the same in every mode, across restarts)."""
        if "seq" in want.__struct_fields__ and "seq" not in fields:
            fields = {**fields, "seq": k}
        try:
            return want(stamp=t, sender=self.plan.label, **fields)
        except Exception as exc:  # noqa: BLE001 - a field missing, unknown or out of range
            what = " ".join(str(exc).split())
            raise StepFailed(f"{self.plan.label}: its step at t={t:.3f} s failed: output {port!r}: "
                             f"{want.__name__}: {what}") from None

    def _refuse(self, out: Any, t: float) -> None:
        """Raise the NodeError that says what is wrong with a step's return value."""
        label = self.plan.label
        if not isinstance(out, dict):
            raise StepFailed(f"{label}: step() returned {type(out).__name__}, expected a dict of its outputs")
        extra = set(out) - {p for p, _, _ in self._outs}
        if extra:
            raise StepFailed(f"{label}: step() returned unknown output {sorted(extra)[0]!r}")
        for port, _, want in self._outs:
            msg = out.get(port)
            if msg is None and port not in out:
                raise StepFailed(f"{label}: step() at t={t} gave no message for output {port!r} (None sends nothing "
                                 f"on it this tick)")
            if msg is None or type(msg) is dict:  # nothing, or filled in and checked by _fill
                continue
            if type(msg) is not want:
                raise StepFailed(f"{label}: output {port!r} must be {want.__name__}, got {type(msg).__name__}")
            if msg.stamp != t:
                raise StepFailed(f"{label}: output {port!r} is stamped {msg.stamp}, the tick is {t}")
        raise StepFailed(f"{label}: step() returned {out!r}")


def step_failure(label: str, t: float, exc: BaseException) -> str:
    """One line for a node's step that raised: the node, the tick, the exception and where
    in the node's code it was raised (the innermost frame)."""
    at = raised_at(exc)
    what = " ".join(f"{type(exc).__name__}: {exc}".split())
    return f"{label}: its step at t={t:.3f} s failed: {what}" + (f" ({at})" if at else "")


__all__ = ["Runner", "step_failure"]
