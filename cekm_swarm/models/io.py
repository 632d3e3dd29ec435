"""The saved-model format: one ``.npz`` file per trained network.

Fields (format version 1):

==================  ==========================================================
``format``          the string ``"cekm-model"``
``format_version``  integer, 1
``kind``            ``indirect-gd`` | ``indirect-rls`` | ``direct`` | ``bfn``
``lattice_size``    N (the lattice is N x N)
``w``               (N*N, 2) input weights (alpha rad, d m)
``M``               (N*N, 2, 2) control parameters (indirect; internal units)
``Rinv``            (N*N, 2, 2) RLS state (indirect)
``C``               (N*N, 2) commands (direct)
``W``, ``widths``   (N*N, 2) each (bfn); ``won`` (N*N,) 1 where a centre has won (bfn)
``bfn_rule``        optional (bfn): ``paper`` | ``trained-units`` (absent: ``trained-units``)
``converged``       optional (N*N,) 1 where M_i w_i moves the robot by w_i (indirect)
``params``          JSON: CompetitionParams and LearningParams used
``provenance``      JSON: how it was made (network name, steps, seed, initial M, ...)
==================  ==========================================================

The file is written atomically (to a temporary name, then renamed).
"""

from __future__ import annotations

import io
import json
import os
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any, overload

import numpy as np

from ..errors import ModelFormatError
from .lattice import Lattice
from .networks import BFN_RULES, BasisFunctionNetwork, DirectEKM, IndirectEKM, Network
from .params import CompetitionParams, LearningParams, params_to_dict

FORMAT = "cekm-model"
FORMAT_VERSION = 1
_ARRAYS = {"indirect-gd": ("M", "Rinv"), "indirect-rls": ("M", "Rinv"), "direct": ("C",), "bfn": ("W", "widths", "won")}
_SHAPES = {"w": (2,), "M": (2, 2), "Rinv": (2, 2), "C": (2,), "W": (2,), "widths": (2,), "won": ()}


def save_model(path: str | os.PathLike[str], net: Network, provenance: dict[str, Any] | None = None) -> Path:
    """Write ``net`` to ``path`` (``.npz``); returns the path written."""
    path = Path(path)
    arrays: dict[str, Any] = {"w": net.w}
    for name in _ARRAYS[net.kind]:
        arrays[name] = np.asarray(getattr(net, name), dtype=np.float64)
    if isinstance(net, IndirectEKM) and net.converged is not None:  # the only kind with converged units
        arrays["converged"] = np.asarray(net.converged, dtype=np.float64)
    meta: dict[str, Any] = {"bfn_rule": np.array(net.rule)} if isinstance(net, BasisFunctionNetwork) else {}
    meta |= {
        "format": np.array(FORMAT),
        "format_version": np.array(FORMAT_VERSION),
        "kind": np.array(net.kind),
        "lattice_size": np.array(net.lattice.size),
        "params": np.array(json.dumps(params_to_dict(net.comp, net.learn_p))),
        "provenance": np.array(json.dumps(provenance or {})),
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as fh:
        np.savez_compressed(fh, **meta, **arrays)
    os.replace(tmp, path)
    return path


@overload
def _scalar(data: Mapping[str, np.ndarray], path: str, key: str, kind: type[str]) -> str: ...
@overload
def _scalar(data: Mapping[str, np.ndarray], path: str, key: str, kind: type[int]) -> int: ...


def _scalar(data: Mapping[str, np.ndarray], path: str, key: str, kind: type[str] | type[int]) -> str | int:
    """The scalar ``key`` of a model file, as ``kind``."""
    if key not in data:
        raise ModelFormatError(path, key, "missing")
    value = data[key]
    if value.shape != ():
        raise ModelFormatError(path, key, f"expected a scalar, got shape {value.shape}")
    try:
        return kind(value.item())
    except (TypeError, ValueError) as exc:
        raise ModelFormatError(path, key, f"expected {kind.__name__}: {exc}") from None


def load_model(path: str | os.PathLike[str]) -> Network:
    """Read a saved network; raises :class:`ModelFormatError` naming the file and field on any problem."""
    path = Path(path)
    if not path.is_file():
        raise ModelFormatError(path, None, "no such file")
    return _parse(path, str(path))


def load_model_bytes(blob: bytes, source: str) -> Network:
    """A saved network from the bytes of its file (e.g. served over Zenoh); ``source``
    names where they came from in any :class:`ModelFormatError`."""
    return _parse(io.BytesIO(blob), source)


def _parse(file: Any, path: str) -> Network:
    """The network in an .npz model file: read, its header and arrays checked, built."""
    data = _read_npz(file, path)
    kind, size = _header(data, path)
    arrays = _arrays(data, path, kind, size)
    comp, learn_p = _params(data, path)
    lat = Lattice(size)
    if kind.startswith("indirect"):
        return IndirectEKM(lat, kind.split("-")[1], arrays["w"], arrays["M"], arrays["Rinv"], comp, learn_p,
                           converged=_converged(data, path, size * size))
    if kind == "direct":
        return DirectEKM(lat, arrays["w"], arrays["C"], comp, learn_p)
    rule = _scalar(data, path, "bfn_rule", str) if "bfn_rule" in data else "trained-units"
    if rule not in BFN_RULES:
        raise ModelFormatError(path, "bfn_rule", f"unknown rule {rule!r}; expected one of {', '.join(BFN_RULES)}")
    return BasisFunctionNetwork(lat, arrays["w"], arrays["widths"], arrays["W"], arrays["won"] > 0.0, comp, learn_p,
                                rule)


def _read_npz(file: Any, path: str) -> dict[str, np.ndarray]:
    """Every array of an .npz archive, or a ModelFormatError saying what the file is not."""
    try:
        loaded = np.load(file, allow_pickle=False)
        if not isinstance(loaded, np.lib.npyio.NpzFile):  # a lone .npy array
            raise ValueError("an .npy array, not an .npz archive")
        with loaded as npz:
            return {k: npz[k] for k in npz.files}
    except (zipfile.BadZipFile, ValueError, OSError, EOFError) as exc:
        # numpy tries a file that is neither .npz nor .npy as a pickle, and its refusal
        # advises loading it unsafely: say what the file is not instead
        why = "not an .npz archive" if "pickle" in str(exc) and "Object arrays" not in str(exc) else str(exc)
        raise ModelFormatError(path, None, f"not a readable .npz model file ({why})") from None


def _header(data: dict[str, np.ndarray], path: str) -> tuple[str, int]:
    """The file's format and version checked; its network kind and lattice size."""
    fmt = _scalar(data, path, "format", str)
    if fmt != FORMAT:
        raise ModelFormatError(path, "format", f"expected {FORMAT!r}, got {fmt!r}")
    version = _scalar(data, path, "format_version", int)
    if version != FORMAT_VERSION:
        raise ModelFormatError(path, "format_version",
                               f"version {version} is not supported (this library reads {FORMAT_VERSION})")
    kind = _scalar(data, path, "kind", str)
    if kind not in _ARRAYS:
        raise ModelFormatError(path, "kind", f"unknown network kind {kind!r}; expected one of {sorted(_ARRAYS)}")
    size = _scalar(data, path, "lattice_size", int)
    if not 2 <= size <= 64:
        raise ModelFormatError(path, "lattice_size", f"must be 2-64, got {size}")
    return kind, size


def _arrays(data: dict[str, np.ndarray], path: str, kind: str, size: int) -> dict[str, np.ndarray]:
    """The arrays of a network of ``kind`` on a ``size`` x ``size`` lattice, each checked
    (present, its shape, floating point, finite) and as float64."""
    n = size * size
    arrays = {}
    for name in ("w", *_ARRAYS[kind]):
        if name not in data:
            raise ModelFormatError(path, name, f"missing (required for kind {kind!r})")
        a = data[name]
        want = (n, *_SHAPES[name])
        if a.shape != want:
            raise ModelFormatError(path, name, f"expected shape {want} for a {size}x{size} lattice, got {a.shape}")
        if not np.issubdtype(a.dtype, np.floating):
            raise ModelFormatError(path, name, f"expected floating point values, got dtype {a.dtype}")
        if not np.all(np.isfinite(a)):
            raise ModelFormatError(path, name, "contains NaN or infinite values")
        arrays[name] = a.astype(np.float64)
    return arrays


def _params(data: dict[str, np.ndarray], path: str) -> tuple[CompetitionParams, LearningParams]:
    """The competition and learning parameters the network was saved with."""
    try:
        params = json.loads(_scalar(data, path, "params", str))
        return CompetitionParams(**params["CompetitionParams"]), LearningParams(**params["LearningParams"])
    except ModelFormatError:
        raise
    except (ValueError, KeyError, TypeError) as exc:
        raise ModelFormatError(path, "params", f"unreadable parameters ({exc})") from None


def _converged(data: dict[str, np.ndarray], path: str, n: int) -> np.ndarray | None:
    """An indirect EKM's converged units (None when the file has none)."""
    if "converged" not in data:
        return None
    c = data["converged"]
    if c.shape != (n,):
        raise ModelFormatError(path, "converged", f"expected shape {(n,)}, got {c.shape}")
    return np.asarray(c) > 0.0


def model_provenance(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The provenance record of a saved model (after the same checks as :func:`load_model`)."""
    load_model(path)
    with np.load(path, allow_pickle=False) as npz:
        doc: dict[str, Any] = json.loads(npz["provenance"].item())
    return doc
