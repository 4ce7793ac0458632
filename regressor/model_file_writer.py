"""Writing model files (regressor.model_file reads them): training writes them, ``track`` only
reads them."""
from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path
from typing import Mapping

import numpy as np

from .model_file import _RESERVED, FORMAT_VERSION, ModelFileError, _validate, checksum


def _as_array(name: str, value) -> np.ndarray:
    if isinstance(value, dict):
        value = json.dumps(value, sort_keys=True)
    a = np.asarray(value)
    if a.dtype.kind not in "biufU":
        raise ModelFileError(f"part {name!r} has dtype {a.dtype}; only numbers and strings can "
                             f"be stored")
    return a


def save_model(path: str | Path, parts: Mapping | None = None, /, **more) -> Path:
    """Validate the parts (name -> array, number, str, or a JSON-able dict for
    ``description``) and write them to ``path`` (.npz) with FORMAT_VERSION and a checksum.
    The file is written to a temporary name and renamed, so a crash never leaves half a
    model."""
    path = Path(path)
    merged = {**(dict(parts) if parts is not None else {}), **more}
    bad = [k for k in merged if k in _RESERVED]
    if bad:
        raise ModelFileError(f"{path}: part names {bad} are reserved")
    arrays = {k: _as_array(k, v) for k, v in merged.items()}
    _validate(str(path), arrays)
    out = dict(arrays, format_version=np.int64(FORMAT_VERSION), checksum=np.str_(checksum(arrays)))
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(suffix=".npz", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            np.savez_compressed(fh, **out)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path
