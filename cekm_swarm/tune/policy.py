"""The field policy: field widths per situation from what the fields see (docs/fields.md).

p_i = base_i * exp(span_i * tanh((W f)_i)) for the features f (:mod:`.features`): a linear
map squashed to +-1, so every width stays within a factor exp(span_i) of its base (today's
hand-tuned value); W = 0 gives the base values exactly, bit for bit. Only the fields'
parameters move: the fields are still Eqs. 6 and 8, integrated by the motor EKM (Eqs. 9-11).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ParameterError
from ..models.params import FieldParams
from .features import FEATURES, N_FEATURES

FORMAT = "cekm-field-policy"
TASKS = ("navigation", "tracking")

OUTPUTS: dict[str, tuple[str, ...]] = {
    "navigation": ("sigma_b_alpha", "sigma_b_d_beyond", "sigma_b_d_near"),
    "tracking": ("sigma_b_alpha", "sigma_b_d_beyond", "sigma_b_d_near", "teammate_gain"),
}
"""What the policy sets, by task: the obstacle field's widths (Eq. 8, the paper's
sigma_b_alpha and sigma_b_d) and, for tracking, a gain on the teammate fields' sum."""

SPAN = {"sigma_b_alpha": math.log(2.0), "sigma_b_d_beyond": math.log(4.0), "sigma_b_d_near": math.log(2.0),
        "teammate_gain": math.log(2.0)}
"""How far (log factor) the policy may move each parameter from its base."""


def base_values(task: str) -> dict[str, float]:
    """Today's hand-tuned values (navigation: FieldParams(); tracking: the paper's widths it
    was tuned with, and teammate fields at full weight)."""
    fp = FieldParams() if task == "navigation" else FieldParams.paper()
    out = {"sigma_b_alpha": fp.sigma_b_alpha, "sigma_b_d_beyond": fp.sigma_b_d_beyond,
           "sigma_b_d_near": fp.sigma_b_d_near}
    if task == "tracking":
        out["teammate_gain"] = 1.0
    return out


@dataclass(frozen=True)
class FieldChoice:
    """One tick's field parameters: the widths of Eqs. 6 and 8 and the teammate gain."""

    fields: FieldParams
    teammate_gain: float = 1.0


def check_task(task: str) -> str:
    if task not in TASKS:
        raise ParameterError(f"unknown task {task!r}; expected one of {list(TASKS)}")
    return task


class FieldPolicy:
    """W (outputs x features) for one task; :meth:`choose` maps features to field parameters."""

    def __init__(self, task: str, weights: np.ndarray | None = None, meta: dict | None = None) -> None:
        self.task = check_task(task)
        self.outputs = OUTPUTS[task]
        shape = (len(self.outputs), N_FEATURES)
        W = np.zeros(shape) if weights is None else np.asarray(weights, dtype=np.float64).reshape(shape)
        if not np.all(np.isfinite(W)):
            raise ParameterError("FieldPolicy: the weights must be finite")
        self.W = W
        self.meta = dict(meta or {})
        base = base_values(task)
        self.base = np.array([base[o] for o in self.outputs])
        self.span = np.array([SPAN[o] for o in self.outputs])
        self._fields = FieldParams() if task == "navigation" else FieldParams.paper()

    @classmethod
    def size(cls, task: str) -> int:
        """How many weights a policy of ``task`` has."""
        return len(OUTPUTS[check_task(task)]) * N_FEATURES

    def values(self, action: np.ndarray) -> dict[str, float]:
        """The parameters of an action in [-1, 1]^outputs: base * exp(span * action)."""
        a = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
        return dict(zip(self.outputs, (self.base * np.exp(self.span * a)).tolist(), strict=True))

    def choice(self, action: np.ndarray) -> FieldChoice:
        """The field parameters of an action (see :meth:`values`)."""
        v = self.values(action)
        gain = v.pop("teammate_gain", 1.0)
        f = self._fields
        return FieldChoice(FieldParams(f.sigma_a_alpha, f.sigma_a_d, v["sigma_b_alpha"], v["sigma_b_d_beyond"],
                                       v["sigma_b_d_near"]), gain)

    def action(self, features: np.ndarray) -> np.ndarray:
        """tanh(W f): the policy's action for the features f."""
        return np.tanh(self.W @ features)

    def choose(self, features: np.ndarray) -> FieldChoice:
        return self.choice(self.action(features))

    def to_dict(self) -> dict:
        return {"format": FORMAT, "version": 1, "task": self.task, "features": list(FEATURES),
                "outputs": list(self.outputs), "base": self.base.tolist(), "span": self.span.tolist(),
                "weights": self.W.tolist(), **({"meta": self.meta} if self.meta else {})}

    def save(self, path: Path) -> None:
        """The policy as JSON, written beside and renamed (whole or not at all)."""
        path = Path(path)
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_text(json.dumps(self.to_dict(), indent=1) + "\n")
        tmp.replace(path)

    @classmethod
    def load(cls, path: Path | str) -> FieldPolicy:
        """A policy file, or a ParameterError naming the file and what is wrong."""
        path = Path(path)
        try:
            doc = json.loads(path.read_text())
        except (OSError, ValueError) as exc:
            raise ParameterError(f"{path}: not a readable field policy: {exc}") from None
        if not isinstance(doc, dict) or doc.get("format") != FORMAT:
            raise ParameterError(f"{path}: not a field policy (format must be {FORMAT!r})")
        task = doc.get("task")
        if task not in TASKS:
            raise ParameterError(f"{path}: task must be one of {list(TASKS)}, got {task!r}")
        if doc.get("features") != list(FEATURES) or doc.get("outputs") != list(OUTPUTS[task]):
            raise ParameterError(f"{path}: its features/outputs are not this version's {list(FEATURES)} / "
                                 f"{list(OUTPUTS[task])}")
        W = np.asarray(doc.get("weights"), dtype=np.float64)
        if W.shape != (len(OUTPUTS[task]), N_FEATURES):
            raise ParameterError(f"{path}: weights must be {len(OUTPUTS[task])} x {N_FEATURES}, got shape {W.shape}")
        return cls(task, W, doc.get("meta"))


def shipped_policy(task: str) -> Path:
    """The policy shipped for ``task`` (``--fields learned``)."""
    return Path(__file__).parent / "policies" / f"{check_task(task)}.json"
