"""The default trained model for the controller, trained once and cached.

A new user needs no extra step: the first ``cekm run`` trains R15 by self-organized
learning (100,000 steps from untrained maps, a few seconds) and caches it; later runs load
the cache. The cache key covers everything that determines the model, so a change of
parameters or of this library's format trains anew.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import asdict
from pathlib import Path

from ..models.io import FORMAT_VERSION, load_model, save_model
from ..models.params import CompetitionParams, LearningParams, params_to_dict
from .arena import Arena
from .training import train_network

DEFAULT_NETWORK = "R15"
DEFAULT_STEPS = 100_000
DEFAULT_SEED = 2005
# bump when the training loop changes what it produces (2: convergence mask; 3: stop = c executes as 0)
TRAINING_CODE_VERSION = 3


def cache_dir() -> Path:
    """$CEKM_CACHE, else $XDG_CACHE_HOME/cekm-swarm, else ~/.cache/cekm-swarm."""
    if os.environ.get("CEKM_CACHE"):
        return Path(os.environ["CEKM_CACHE"])
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "cekm-swarm"


def default_model_path(network: str = DEFAULT_NETWORK, steps: int = DEFAULT_STEPS, seed: int = DEFAULT_SEED) -> Path:
    key = json.dumps({"network": network, "steps": steps, "seed": seed, "format": FORMAT_VERSION,
                      "code": TRAINING_CODE_VERSION,
                      "params": params_to_dict(CompetitionParams(), LearningParams()),
                      "arena": asdict(Arena())}, sort_keys=True)
    digest = hashlib.sha256(key.encode()).hexdigest()[:12]
    return cache_dir() / f"{network}-{steps}-seed{seed}-{digest}.npz"


def default_model(progress: bool = True, network: str = DEFAULT_NETWORK, steps: int = DEFAULT_STEPS,
                  seed: int = DEFAULT_SEED):
    """The cached default model, trained on first use."""
    path = default_model_path(network, steps, seed)
    if path.is_file():
        return load_model(path)

    if progress:
        print(f"training the default model ({network}, {steps:,} steps, seed {seed}); cached at {path}")
    net, score = train_network(network, steps, seed, progress=progress)
    save_model(path, net, {"network": network, "steps": steps, "seed": seed, "initial_M": "random",
                           "test_after_training": score, "purpose": "default controller model"})
    return net
