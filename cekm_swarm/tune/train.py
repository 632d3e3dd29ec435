"""``cekm tune fields``: the field policy trained by CMA-ES, seeded and resumable (docs/fields.md).

Why CMA-ES (the ``cma`` package): the policy has a few dozen weights and its objective is
a whole run's outcome (reached without contact; Parker's A), noisy and not
differentiable -- the setting evolution strategies are made for, with no value function
to learn and nothing to tune but the population. ``cma`` is pure Python, seeded, and its
ask/tell loop makes a resume exact: the strategy and numpy's global random state (which
``cma`` samples from) are saved after every generation.

Each generation every candidate runs the same ``batch`` training scenarios (seeds
:data:`~.scenarios.SEED_BASE` ``["train"]`` + generation * batch + i: common random numbers,
so candidates are compared on equal terms, and new scenarios every generation). Every
``validate_every`` generations the strategy's mean runs the validation scenarios; the
policy kept (``policy.json``) is the best on validation, today's constants (W = 0)
included, so a training that finds nothing better keeps them. The held-out evaluation
(``cekm tune evaluate``) uses a third seed range.

DIR holds ``config.json`` (a resume must match it), ``state.pkl`` (the strategy after the
last whole generation), ``history.jsonl`` (one line per generation) and ``policy.json``.
"""

from __future__ import annotations

import functools
import json
import pickle
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from ..errors import ParameterError
from .features import N_FEATURES, N_FIELD_FEATURES
from .policy import OUTPUTS, WIDTHS, FieldPolicy, check_task
from .rollout import run_many
from .scenarios import check_mix, seed_of

STATE_VERSION = 1


@dataclass(frozen=True)
class TuneConfig:
    """A training's settings (every one is in config.json)."""

    task: str = "navigation"
    seed: int = 1
    generations: int = 30
    popsize: int = 12
    sigma0: float = 0.5
    batch: int = 24
    validation: int = 48
    validate_every: int = 5
    max_time: float = 90.0
    mix: str = "default"  # navigation: the geometry mix trained and validated on (scenarios.MIXES)
    hold: tuple[str, ...] = ()  # outputs held at today's value (their rows of W and V stay 0)
    per_field: bool = False  # also train V: each obstacle field's widths from its own features
    init: str = ""  # a policy file the search starts from (its mean), "" = today's constants (0)
    keep: tuple[str, ...] = ()  # outputs whose rows of W and V stay at --init's weights (not searched)

    def __post_init__(self) -> None:
        check_task(self.task)
        check_mix(self.mix)
        if self.mix != "default" and self.task != "navigation":
            raise ParameterError("--mix goes with --task navigation")
        outputs = OUTPUTS[self.task]
        for h in self.hold:
            if h not in outputs:
                raise ParameterError(f"--hold: {h!r} is not an output of the {self.task} policy {list(outputs)}")
        for k in self.keep:
            if k not in outputs:
                raise ParameterError(f"--keep: {k!r} is not an output of the {self.task} policy {list(outputs)}")
            if k in self.hold:
                raise ParameterError(f"--keep {k} and --hold {k}: an output is kept at --init's weights or held at 0")
        if self.keep and not self.init:
            raise ParameterError("--keep needs --init: the policy whose weights it keeps")
        if len(set(self.hold) | set(self.keep)) >= len(outputs):
            raise ParameterError("--hold/--keep: at least one output must be free")
        for name in ("generations", "popsize", "batch", "validation", "validate_every"):
            v = getattr(self, name)
            if not isinstance(v, int) or v < 1:
                raise ParameterError(f"--{name.replace('_', '-')}: must be a whole number >= 1, got {v!r}")
        if self.popsize < 2:
            raise ParameterError("--popsize: CMA-ES needs at least 2 candidates per generation")
        if not (self.sigma0 > 0 and self.max_time > 0):
            raise ParameterError("--sigma0 and --max-time must be positive")


def command_of(config: TuneConfig) -> str:
    """The command that makes this training (DIR for its directory, which does not change it)."""
    c = config
    return (f"cekm tune fields --task {c.task} --out DIR --seed {c.seed} --generations {c.generations} "
            f"--popsize {c.popsize} --sigma0 {c.sigma0:g} --batch {c.batch} --validation {c.validation} "
            f"--validate-every {c.validate_every} --max-time {c.max_time:g}"
            + (f" --mix {c.mix}" if c.mix != "default" else "")
            + "".join(f" --hold {h}" for h in c.hold)
            + (" --per-field" if c.per_field else "")
            + (f" --init {c.init}" if c.init else "")
            + "".join(f" --keep {k}" for k in c.keep))


def free_rows(config: TuneConfig) -> np.ndarray:
    """Which rows of W the strategy searches (the outputs neither held nor kept)."""
    return np.array([o not in config.hold and o not in config.keep for o in OUTPUTS[config.task]])


def free_field_rows(config: TuneConfig) -> np.ndarray:
    """Which rows of V the strategy searches (none without --per-field; else the widths neither held nor kept)."""
    return np.array([config.per_field and o not in config.hold and o not in config.keep for o in WIDTHS])


@functools.lru_cache(maxsize=4)
def _init_weights(init: str) -> tuple[np.ndarray, np.ndarray]:
    """--init's W and V (V zeros when it has none), for the rows --keep keeps."""
    p = FieldPolicy.load(init)
    return p.W, np.zeros((len(WIDTHS), N_FIELD_FEATURES)) if p.V is None else p.V


def search_size(config: TuneConfig) -> int:
    """How many numbers the strategy searches: the free rows of W, then those of V."""
    return int(free_rows(config).sum()) * N_FEATURES + int(free_field_rows(config).sum()) * N_FIELD_FEATURES


def start_vector(config: TuneConfig) -> np.ndarray:
    """Where the search starts: 0 (today's constants), or the free entries of ``--init``'s
    policy (:func:`full_weights` of it gives that policy back); a ParameterError when the
    file cannot be a start of this training."""
    n = search_size(config)
    if not config.init:
        return np.zeros(n)
    p = FieldPolicy.load(config.init)
    where = f"--init {config.init}"
    if p.task != config.task:
        raise ParameterError(f"{where}: a {p.task} policy, not {config.task}")
    V = np.zeros((len(WIDTHS), N_FIELD_FEATURES)) if p.V is None else p.V
    if V.any() and not config.per_field:
        raise ParameterError(f"{where}: it has per-field weights V; train it with --per-field")
    for o, wrow, vrow in zip(OUTPUTS[config.task], p.W, list(V) + [None], strict=False):
        if o in config.hold and (wrow.any() or (vrow is not None and vrow.any())):
            raise ParameterError(f"{where}: its weights for {o} are not 0, but --hold {o} holds them at 0")
    x = p.W[free_rows(config)].ravel()
    return np.concatenate([x, V[free_field_rows(config)].ravel()]) if config.per_field else x


def full_weights(config: TuneConfig, x: np.ndarray) -> np.ndarray:
    """The policy's flat weights (:meth:`.policy.FieldPolicy.flat`: W, then V with
    --per-field) of the strategy's vector ``x``: its entries in the free rows, 0 in the held ones,
    --init's in the kept ones."""
    x = np.asarray(x, dtype=np.float64)
    free, vfree = free_rows(config), free_field_rows(config)
    n_w = int(free.sum()) * N_FEATURES
    W = np.zeros((len(free), N_FEATURES))
    V = np.zeros((len(vfree), N_FIELD_FEATURES))
    if config.keep:
        W0, V0 = _init_weights(config.init)
        kept = np.array([o in config.keep for o in OUTPUTS[config.task]])
        W[kept] = W0[kept]
        V[kept[:len(WIDTHS)]] = V0[kept[:len(WIDTHS)]]
    W[free] = x[:n_w].reshape(int(free.sum()), N_FEATURES)
    if not config.per_field:
        return W.ravel()
    V[vfree] = x[n_w:].reshape(int(vfree.sum()), N_FIELD_FEATURES)
    return np.concatenate([W.ravel(), V.ravel()])


def where_of(config: TuneConfig, purpose: str, i: int):
    """A job's scenario (:func:`.rollout.scenario_of`): the ``i``-th seed of ``purpose`` in the config's mix."""
    seed = seed_of(purpose, i)
    return seed if config.mix == "default" else ("mix", config.mix, seed)


def _write_whole(path: Path, data: bytes) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_bytes(data)
    tmp.replace(path)


def _check_dir(out: Path, config: TuneConfig) -> dict | None:
    """The saved state to resume from (None: a fresh start); a ParameterError when DIR
    holds another training's state."""
    cfg, state = out / "config.json", out / "state.pkl"
    if cfg.is_file():
        saved = json.loads(cfg.read_text())
        saved.setdefault("mix", "default")  # a directory of a version before --mix, --hold
        saved.setdefault("hold", [])
        saved.setdefault("per_field", False)  # a directory of a version before --per-field, --init
        saved.setdefault("init", "")
        saved.setdefault("keep", [])  # a directory of a version before --keep
        mine = json.loads(json.dumps(asdict(config)))  # as config.json holds it (a tuple is a list)
        for k in mine:
            if saved.get(k) != mine[k]:
                raise ParameterError(f"{cfg}: {out} holds a training with {k} = {saved.get(k)!r}, not {mine[k]!r}; "
                                     f"give the same settings to resume it, or another --out")
    if state.is_file():
        try:
            doc = pickle.loads(state.read_bytes())
        except Exception as exc:
            raise ParameterError(f"{state}: cannot read the saved training state ({exc}); remove it to start afresh") \
                from None
        if doc.get("version") != STATE_VERSION:
            raise ParameterError(f"{state}: state version {doc.get('version')!r}, this code reads {STATE_VERSION}")
        n, mine_n = int(getattr(doc.get("es"), "N", -1)), search_size(config)
        if n != mine_n:
            raise ParameterError(f"{state}: a search over {n} weights, but this version's policy has {mine_n} for "
                                 f"these settings (its features or outputs changed since); train into another --out")
        return doc
    return None


def validate(config: TuneConfig, weights: np.ndarray, model_path: str | None, workers: int) -> float:
    """Mean score of ``weights`` on the validation scenarios."""
    jobs = [(config.task, tuple(float(x) for x in weights), where_of(config, "validation", i), config.max_time,
             model_path)
            for i in range(config.validation)]
    rows = run_many(jobs, workers)
    return float(np.mean([r["score"] for r in rows]))


def tune(config: TuneConfig, out: Path, model_path: str | None = None, workers: int = 1,
         progress: bool = True) -> dict[str, Any]:
    """Train (or resume) the field policy in ``out``; returns the summary (also in policy.json's meta)."""
    import cma

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    state = _check_dir(out, config)
    (out / "config.json").write_text(json.dumps(asdict(config), indent=1) + "\n")
    if state is None:
        x0 = start_vector(config)
        es = cma.CMAEvolutionStrategy(x0, config.sigma0,
                                      {"seed": config.seed, "popsize": config.popsize, "verbose": -9})
        zero = np.zeros(FieldPolicy.size(config.task, config.per_field))  # today's constants (not --keep's rows)
        base = validate(config, zero, model_path, workers)
        best = {"generation": 0, "score": base, "weights": zero.tolist()}
        if config.init:  # the start is a candidate too: kept if it beats the constants on validation
            start = validate(config, full_weights(config, x0), model_path, workers)
            if start > base:
                best = {"generation": 0, "score": start, "weights": full_weights(config, x0).tolist()}
        state = {"version": STATE_VERSION, "generation": 0, "es": es, "rng": np.random.get_state(),
                 "best": best, "base_score": base}
        _write_whole(out / "state.pkl", pickle.dumps(state))
        (out / "history.jsonl").write_text("")
    es = state["es"]
    np.random.set_state(state["rng"])
    total = (config.generations - state["generation"]) * config.popsize * config.batch
    bar = tqdm(total=total, disable=not progress, desc=f"tune {config.task} fields", unit="run",
               initial=0, postfix={"gen": state["generation"], "best": round(state["best"]["score"], 3)})
    while state["generation"] < config.generations:
        g = state["generation"]
        candidates = es.ask()
        seeds = [where_of(config, "train", g * config.batch + i) for i in range(config.batch)]
        jobs = [(config.task, tuple(float(x) for x in full_weights(config, c)), s, config.max_time, model_path)
                for c in candidates for s in seeds]
        rows = run_many(jobs, workers, bar.update)
        scores = np.array([r["score"] for r in rows]).reshape(len(candidates), config.batch).mean(axis=1)
        es.tell(candidates, (-scores).tolist())  # cma minimizes
        g += 1
        line = {"generation": g, "mean_score": float(scores.mean()), "best_score": float(scores.max()),
                "sigma": float(es.sigma)}
        if g % config.validate_every == 0 or g == config.generations:
            mean = full_weights(config, np.asarray(es.mean, dtype=np.float64))
            v = validate(config, mean, model_path, workers)
            line["validation"] = v
            if v > state["best"]["score"]:
                state["best"] = {"generation": g, "score": v, "weights": mean.tolist()}
        state.update(generation=g, es=es, rng=np.random.get_state())
        _write_whole(out / "state.pkl", pickle.dumps(state))
        with open(out / "history.jsonl", "a") as f:
            f.write(json.dumps(line) + "\n")
        bar.set_postfix({"gen": g, "best": round(state["best"]["score"], 3)})
    bar.close()
    best = state["best"]
    meta = {"trained_by": "cekm tune fields", "command": command_of(config), "config": asdict(config),
            "kept_generation": best["generation"], "validation_score": best["score"],
            "validation_score_of_constants": state["base_score"]}
    policy = FieldPolicy.from_flat(config.task, best["weights"])
    policy.meta = meta
    policy.save(out / "policy.json")
    return meta
