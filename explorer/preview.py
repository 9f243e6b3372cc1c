"""A quick look at a model folder's latent bank (numpy only) so the map paints before the model loads.

The full, validated load (:func:`engine.modelio.load_model`, which brings in torch and scikit-learn)
runs in a worker afterwards and replaces the preview; any problem here just means no preview.
"""

from __future__ import annotations

import json
import logging
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from engine.latent.columns import MetaColumns

log = logging.getLogger(__name__)

BANK_FILE = "latent_bank.npz"  # engine.modelio.BANK_FILE, not imported: that module loads torch
BANK_FORMAT = "odmo-latent-bank"


@dataclass(frozen=True, eq=False)
class BankPreview:
    """What the map needs from a bank: actions, names, sources and the stored 2-D embeddings.

    Parameters
    ----------
    path : the model folder.
    actions : (N,) int64 action index of each code.
    action_names : the model's action names.
    sources : (N,) clip names.
    meta : N rows of clip information (style …), each a dict.
    embeddings : projection name -> (N, 2) float64 map positions.
    """

    path: Path
    actions: np.ndarray
    action_names: list[str]
    sources: np.ndarray
    meta: Sequence[dict[str, Any]]
    embeddings: dict[str, np.ndarray]


def read_preview(model_dir: str | Path) -> BankPreview | None:
    """The bank preview of ``model_dir``, or None when it has no readable bank with a stored map."""
    folder = Path(model_dir)
    try:
        with (
            open(folder / BANK_FILE, "rb") as handle,
            np.load(handle, allow_pickle=False) as npz,
        ):
            if str(npz["format"]) != BANK_FORMAT:
                return None
            actions = np.asarray(npz["actions"], dtype=np.int64)
            names = [str(n) for n in npz["action_names"]]
            if "sources" in npz.files:  # format versions 1 and 2: a name and a JSON dict per row
                sources = np.asarray(npz["sources"])
                meta: Sequence[dict[str, Any]] = [json.loads(str(m)) for m in npz["meta"]]
            else:
                sources = npz["source_names"].astype(object)[npz["source_index"]]
                meta = MetaColumns.from_arrays(npz, len(actions))
            embeddings = {}
            for name in npz["projection_names"]:
                key = f"projections/{name}/embedding"
                if key in npz.files:
                    embeddings[str(name)] = np.asarray(npz[key], dtype=np.float64)
    except (OSError, ValueError, KeyError, IndexError, EOFError, zipfile.BadZipFile) as exc:
        log.debug("%s: no bank preview (%s)", folder, exc)
        return None
    n = len(actions)
    if not embeddings or n == 0 or sources.shape != (n,) or len(meta) != n:
        return None
    if actions.min() < 0 or actions.max() >= len(names):
        return None
    if any(e.shape != (n, 2) or not np.all(np.isfinite(e)) for e in embeddings.values()):
        return None
    return BankPreview(folder, actions, names, sources, meta, embeddings)
