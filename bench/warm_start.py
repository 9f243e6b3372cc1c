"""A training run that starts from a saved model's weights (a fine-tune), for the bench scripts."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from engine.motion.motion import Motion
from engine.train.kind_run import WarmStart


def warm_start_from(folder: Path, test_clips: list[Motion], load: Callable[..., Any]) -> WarmStart:
    """The weights of the model in ``folder`` (read with the kind's ``load``); SystemExit if it trained
    on one of ``test_clips``, which the run to be evaluated on them must never have seen."""
    held_out = {Path(c.meta["source"]).name for c in test_clips}

    def unseen(made: dict[str, Any]) -> None:
        if held_out & {Path(s).name for s in made.get("train_sources", [])}:
            raise SystemExit(
                f"{folder}: that model trained on held-out clips; it cannot be warm-started from"
            )

    return WarmStart.from_folder(folder, load, unseen)


def warm_start_line(source: dict[str, Any] | None) -> list[str]:
    """The card's line on the weights the run started from, if any."""
    if not source:
        return []
    before = f"{source['epochs']} epochs" if "epochs" in source else "its own budget"
    weights = f", weights sha256 `{source['weights_sha256'][:12]}`" if "weights_sha256" in source else ""
    made = f", made {source['created']}" if "created" in source else ""
    return [
        f"- Started from the weights of `{source['model']}` ({before}{made}{weights}, trained on the same "
        "split); the budget above is this run's alone."
    ]
