"""The evaluation of any generator kind: each kind's own procedure behind one call."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

from engine.errors import ConfigError

if TYPE_CHECKING:
    from engine.generators.base import Generator
    from engine.metrics.classifier import Classifier
    from engine.motion.motion import Motion


def check_evaluable(
    generator: Generator, real_clips: Sequence[Motion], classifier: Classifier | None, truncation: float = 1.0
) -> None:
    """ConfigError/DataError (one line) unless the clips, classifier and truncation fit the model (before
    any work)."""
    from engine.metrics.evaluate import check_compatible

    _check_truncation(generator, truncation)
    if generator.kind in ("modi", "dvgan"):
        from engine.metrics import dvgan_eval, modi_eval

        spec = (modi_eval if generator.kind == "modi" else dvgan_eval).evaluable_spec(generator, classifier)
        check_compatible(spec, real_clips, classifier)
    else:
        check_compatible(generator, real_clips, classifier)


def evaluate_generator(
    generator: Generator,
    real_clips: Sequence[Motion],
    classifier: Classifier | None,
    *,
    repeats: int = 10,
    n_per_action: int = 50,
    seed: int = 0,
    strategy: str | None = None,
    truncation: float = 1.0,
    progress: Callable[[str, float], None] | None = None,
) -> dict[str, Any]:
    """``evaluate``'s report (real and generated metrics, per action, meta) for a model of any kind.

    ``strategy`` picks how ODMO (None: mode-preserving) and Action2Motion (None: its learned prior) draw
    codes; MoDi and DVGAN are evaluated on their prior, and a strategy given for them is refused.
    ``truncation`` ψ ≠ 1 samples truncated, for kinds that truncate (CapabilityError for the others).
    """
    options = {"repeats": repeats, "n_per_action": n_per_action, "seed": seed, "progress": progress}
    _check_truncation(generator, truncation)
    if truncation != 1.0:  # only the kinds that truncate take it
        options["truncation"] = truncation
    if generator.kind == "odmo":
        from engine.metrics.evaluate import evaluate

        return evaluate(
            generator.loaded, real_clips, classifier, strategy=strategy or "mode_preserving", **options
        )
    if generator.kind == "a2m":
        from engine.metrics.a2m_eval import evaluate_a2m

        return evaluate_a2m(generator.loaded, real_clips, classifier, strategy=strategy or "prior", **options)
    if generator.kind == "modi":
        if strategy is not None:
            raise ConfigError(f"{generator.path}: a modi model is evaluated on its prior; drop --strategy")
        from engine.metrics.modi_eval import evaluate_modi

        return evaluate_modi(generator, real_clips, classifier, **options)
    if generator.kind == "dvgan":
        if strategy is not None:
            raise ConfigError(
                f"{generator.path}: a dvgan model is evaluated on N(0, I) codes; drop --strategy"
            )
        from engine.metrics.dvgan_eval import evaluate_dvgan

        return evaluate_dvgan(generator, real_clips, classifier, **options)
    raise ConfigError(f"{generator.path}: no evaluation for {generator.kind} models")


def _check_truncation(generator: Generator, truncation: float) -> None:
    """ConfigError unless ``truncation`` is 1 or a valid ψ of a kind that truncates."""
    from engine.generators.base import check_psi, require

    if truncation != 1.0:
        check_psi(truncation)
        require(generator, "truncate", f"evaluate at truncation {truncation:g}")
