"""The field policy: field widths per situation from what the fields see (docs/fields.md).

p_i = base_i * exp(span_i * tanh((W f)_i)) for the features f (:mod:`.features`): a linear
map squashed to +-1, so every width stays within a factor exp(span_i) of its base (today's
hand-tuned value); W = 0 gives the base values exactly, bit for bit. Only the fields'
parameters move: the fields are still Eqs. 6 and 8, integrated by the motor EKM (Eqs. 9-11).

Per-field widths (optional, V): the widths of obstacle field b_j are
base * exp(span * tanh(W f + V g_j)) with g_j that field's own features
(:func:`.features.obstacle_features`), so one tick can give a near wall end a wide field
and the far jambs of a doorway narrow ones. V moves Eq. 8's three widths only (the
teammate gain stays one per tick); V = 0 is the policy without it, exactly.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ParameterError
from ..models.params import FieldParams
from .features import FEATURES, FEATURES_V3, FEATURES_V5, FIELD_FEATURES, N_FEATURES, N_FIELD_FEATURES

FORMAT = "cekm-field-policy"
VERSION = 6
"""The file format's version: 1 has W only; 2 adds the per-field weights V over five field
features; 3 adds the sixth field feature, ``closing``, and navigation's fourth output,
``sigma_a_d``; 4 adds the tick's tenth feature, ``pocket``; 5 adds navigation's fifth
output, ``sigma_a_alpha``; 6 adds the tick's eleventh feature, ``stalled``. An older file
loads with what it did not have at weight 0 (V's ``closing`` column, W's ``sigma_a_d`` and
``sigma_a_alpha`` rows, W's ``pocket`` and ``stalled`` columns):
the same policy exactly. A policy a version-1 file can hold (no V, no target-field
output, no pocket) is still written as version 1."""
FIELD_FEATURES_V2 = FIELD_FEATURES[:5]
"""The per-field features of a version-2 file."""
TASKS = ("navigation", "tracking")

OUTPUTS: dict[str, tuple[str, ...]] = {
    "navigation": ("sigma_b_alpha", "sigma_b_d_beyond", "sigma_b_d_near", "sigma_a_d", "sigma_a_alpha"),
    "tracking": ("sigma_b_alpha", "sigma_b_d_beyond", "sigma_b_d_near", "teammate_gain"),
}
"""What the policy sets, by task: the obstacle field's widths (Eq. 8, the paper's
sigma_b_alpha and sigma_b_d); for navigation, from format version 3, also the target
field's width along the distance (Eq. 6's sigma_a_d) and, from version 5, across the angle
(Eq. 6's sigma_a_alpha: the paper's field is angle-insensitive, 2.475 rad); for tracking, a
gain on the teammate fields' sum."""
OUTPUTS_V2 = {"navigation": OUTPUTS["navigation"][:3], "tracking": OUTPUTS["tracking"]}
"""The outputs of a version-1 or -2 file (navigation's had no sigma_a_d)."""
OUTPUTS_V3 = {"navigation": OUTPUTS["navigation"][:4], "tracking": OUTPUTS["tracking"]}
"""The outputs of a version-3 or -4 file (navigation's had no sigma_a_alpha)."""

SPAN = {"sigma_b_alpha": math.log(2.0), "sigma_b_d_beyond": math.log(4.0), "sigma_b_d_near": math.log(2.0),
        "sigma_a_d": math.log(2.0), "sigma_a_alpha": math.log(4.0), "teammate_gain": math.log(2.0)}
"""How far (log factor) the policy may move each parameter from its base."""

WIDTHS = ("sigma_b_alpha", "sigma_b_d_beyond", "sigma_b_d_near")
"""The outputs the per-field weights V move: Eq. 8's widths, the first outputs of every task."""


def base_values(task: str) -> dict[str, float]:
    """Today's hand-tuned values (navigation: FieldParams(); tracking: the paper's widths it
    was tuned with, and teammate fields at full weight)."""
    fp = FieldParams() if task == "navigation" else FieldParams.paper()
    out = {"sigma_b_alpha": fp.sigma_b_alpha, "sigma_b_d_beyond": fp.sigma_b_d_beyond,
           "sigma_b_d_near": fp.sigma_b_d_near}
    if task == "navigation":
        out["sigma_a_d"] = fp.sigma_a_d
        out["sigma_a_alpha"] = fp.sigma_a_alpha
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
    """W (outputs x features) and, optionally, V (widths x field features) for one task;
    :meth:`choose` maps features to one tick's field parameters, :meth:`field_params` the
    tick's and each obstacle field's own features to each field's widths."""

    def __init__(self, task: str, weights: np.ndarray | None = None, meta: dict | None = None,
                 field_weights: np.ndarray | None = None) -> None:
        self.task = check_task(task)
        self.outputs = OUTPUTS[task]
        shape = (len(self.outputs), N_FEATURES)
        W = np.zeros(shape) if weights is None else np.asarray(weights, dtype=np.float64).reshape(shape)
        V = None if field_weights is None else np.asarray(field_weights, dtype=np.float64).reshape(
            len(WIDTHS), N_FIELD_FEATURES)
        if not np.all(np.isfinite(W)) or (V is not None and not np.all(np.isfinite(V))):
            raise ParameterError("FieldPolicy: the weights must be finite")
        self.W = W
        self.V = V
        self.per_field = V is not None and bool(np.any(V != 0.0))
        """True when some field's widths can differ from the tick's (V has a nonzero weight)."""
        self.meta = dict(meta or {})
        base = base_values(task)
        self.base = np.array([base[o] for o in self.outputs])
        self.span = np.array([SPAN[o] for o in self.outputs])
        self._fields = FieldParams() if task == "navigation" else FieldParams.paper()
        self.base_fields = self._fields
        """The field parameters of W = 0 (today's constants): what the modules compute with."""

    @classmethod
    def size(cls, task: str, per_field: bool = False) -> int:
        """How many weights a policy of ``task`` has (with V: W's and V's)."""
        return len(OUTPUTS[check_task(task)]) * N_FEATURES + (len(WIDTHS) * N_FIELD_FEATURES if per_field else 0)

    @classmethod
    def from_flat(cls, task: str, flat: tuple[float, ...] | list[float] | np.ndarray) -> FieldPolicy:
        """The policy of a flat weight vector (:meth:`flat`): W's entries, then V's if there are any."""
        x = np.asarray(flat, dtype=np.float64).ravel()
        n_w, n_all = cls.size(task), cls.size(task, per_field=True)
        if x.size not in (n_w, n_all):
            raise ParameterError(f"field policy weights: a {task} policy takes {n_w} (W) or {n_all} (W and V) "
                                 f"numbers, got {x.size}")
        return cls(task, x[:n_w], field_weights=x[n_w:] if x.size == n_all else None)

    def flat(self) -> tuple[float, ...]:
        """W's entries row by row, then V's if the policy has V (:meth:`from_flat` inverts it)."""
        parts = [self.W.ravel()] + ([] if self.V is None else [self.V.ravel()])
        return tuple(float(v) for v in np.concatenate(parts))

    def values(self, action: np.ndarray) -> dict[str, float]:
        """The parameters of an action in [-1, 1]^outputs: base * exp(span * action)."""
        a = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
        return dict(zip(self.outputs, (self.base * np.exp(self.span * a)).tolist(), strict=True))

    def choice(self, action: np.ndarray) -> FieldChoice:
        """The field parameters of an action (see :meth:`values`)."""
        v = self.values(action)
        gain = v.pop("teammate_gain", 1.0)
        f = self._fields
        return FieldChoice(FieldParams(v.get("sigma_a_alpha", f.sigma_a_alpha), v.get("sigma_a_d", f.sigma_a_d),
                                       v["sigma_b_alpha"], v["sigma_b_d_beyond"], v["sigma_b_d_near"]), gain)

    def check_task(self, task: str, where: Path | str) -> FieldPolicy:
        """This policy, or a ParameterError naming ``where`` when it is for another task."""
        if self.task != task:
            raise ParameterError(f"{where}: a field policy for {self.task}, not {task}")
        return self

    def outputs_of(self, choice: FieldChoice) -> dict[str, float]:
        """The value of each of the task's outputs in ``choice``, by name (the inverse of :meth:`choice`)."""
        return {o: choice.teammate_gain if o == "teammate_gain" else float(getattr(choice.fields, o))
                for o in self.outputs}

    def action(self, features: np.ndarray) -> np.ndarray:
        """tanh(W f): the policy's action for the features f."""
        return np.tanh(self.W @ features)

    def choose(self, features: np.ndarray) -> FieldChoice:
        return self.choice(self.action(features))

    def field_widths(self, features: np.ndarray, field_features: np.ndarray) -> np.ndarray:
        """Each obstacle field's widths (sigma_b_alpha, sigma_b_d_beyond, sigma_b_d_near), one
        row per row g_j of ``field_features`` (:func:`.features.obstacle_features`):
        base * exp(span * tanh(W f + V g_j)); the tick's widths (:meth:`choose`'s) in every row
        when the policy has no V."""
        k = len(WIDTHS)
        if self.V is None:
            fp = self.choose(features).fields
            return np.tile([fp.sigma_b_alpha, fp.sigma_b_d_beyond, fp.sigma_b_d_near], (len(field_features), 1))
        pre = (self.W @ features)[:k]  # not W[:k] @ f: a 3-row product may round otherwise than choose()'s
        a = np.tanh(pre[None, :] + np.asarray(field_features, dtype=np.float64) @ self.V.T)
        out: np.ndarray = self.base[:k] * np.exp(self.span[:k] * a)
        return out

    def widths_params(self, widths: tuple[float, float, float]) -> FieldParams:
        """The field parameters of one row of :meth:`field_widths` (the target field's as the base's)."""
        f = self._fields
        return FieldParams(f.sigma_a_alpha, f.sigma_a_d, *widths)

    def field_params(self, features: np.ndarray, field_features: np.ndarray) -> list[FieldParams]:
        """:meth:`field_widths` as each obstacle field's FieldParams (the target field's widths the tick's)."""
        tick = self.choose(features).fields
        return [FieldParams(tick.sigma_a_alpha, tick.sigma_a_d, *r)
                for r in self.field_widths(features, field_features).tolist()]

    def to_dict(self) -> dict:
        old, n3 = OUTPUTS_V2[self.task], len(FEATURES_V3)
        if self.V is None and not self.W[len(old):].any() and not self.W[:, n3:].any():
            # what a version-1 file can say: written as one
            doc = {"format": FORMAT, "version": 1, "task": self.task, "features": list(FEATURES_V3),
                   "outputs": list(old), "base": self.base[:len(old)].tolist(),
                   "span": self.span[:len(old)].tolist(), "weights": self.W[:len(old), :n3].tolist()}
        else:
            doc = {"format": FORMAT, "version": VERSION, "task": self.task, "features": list(FEATURES),
                   "outputs": list(self.outputs), "base": self.base.tolist(), "span": self.span.tolist(),
                   "weights": self.W.tolist()}
        if self.V is not None:
            doc.update(field_features=list(FIELD_FEATURES), field_outputs=list(WIDTHS), field_weights=self.V.tolist())
        return {**doc, **({"meta": self.meta} if self.meta else {})}

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
        version = doc.get("version", 1)
        if version not in range(1, VERSION + 1):
            raise ParameterError(f"{path}: format version {version!r}; this code reads versions 1 to {VERSION}")
        outputs = OUTPUTS[task] if version >= 5 else OUTPUTS_V3[task] if version >= 3 else OUTPUTS_V2[task]
        features = FEATURES if version >= 6 else FEATURES_V5 if version >= 4 else FEATURES_V3
        if doc.get("features") != list(features) or doc.get("outputs") != list(outputs):
            raise ParameterError(f"{path}: its features/outputs are not version {version}'s {list(features)} / "
                                 f"{list(outputs)}")
        try:
            W = np.asarray(doc.get("weights"), dtype=np.float64)
            has_v = version == 2 or (version >= 3 and "field_weights" in doc)  # from 3 on, W only is a policy too
            V = np.asarray(doc.get("field_weights"), dtype=np.float64) if has_v else None
        except (TypeError, ValueError) as exc:
            raise ParameterError(f"{path}: weights must be arrays of numbers: {exc}") from None
        if W.shape != (len(outputs), len(features)):
            raise ParameterError(f"{path}: weights must be {len(outputs)} x {len(features)}, got shape {W.shape}")
        # an older file: the outputs and features it did not have stay at weight 0 (their base)
        W = np.pad(W, ((0, len(OUTPUTS[task]) - len(outputs)), (0, N_FEATURES - len(features))))
        if V is not None:
            names = FIELD_FEATURES_V2 if version == 2 else FIELD_FEATURES
            if doc.get("field_features") != list(names) or doc.get("field_outputs") != list(WIDTHS):
                raise ParameterError(f"{path}: its field_features/field_outputs are not version {version}'s "
                                     f"{list(names)} / {list(WIDTHS)}")
            if V.shape != (len(WIDTHS), len(names)):
                raise ParameterError(f"{path}: field_weights must be {len(WIDTHS)} x {len(names)}, "
                                     f"got shape {V.shape}")
            if version == 2:  # the features it was trained on, and closing not read: the same policy
                V = np.concatenate([V, np.zeros((len(WIDTHS), N_FIELD_FEATURES - len(names)))], axis=1)
        return cls(task, W, doc.get("meta"), V)


def shipped_policy(task: str) -> Path:
    """The policy shipped for ``task`` (``--fields learned``)."""
    return Path(__file__).parent / "policies" / f"{check_task(task)}.json"
