"""ModelConfig: what the config of every generator kind shares (checks and the model.json round trip)."""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar, Self

from engine.errors import ConfigError, ModelFormatError
from engine.limits import check_config


class ModelConfig:
    """Base of each kind's config dataclass: declared types and size limits, positive and non-negative
    fields, rates in [0, 1], the kind's ``arch``, and a strict dict round trip.

    A subclass lists its fields in ``POSITIVE``, ``NON_NEGATIVE`` and ``RATES``, names its ``ARCH``, puts
    the fields added after its first saved models in ``BEFORE`` (with the value those models had) and
    adds its own checks in :meth:`check`.
    """

    POSITIVE: ClassVar[tuple[str, ...]] = ()
    NON_NEGATIVE: ClassVar[tuple[str, ...]] = ()
    RATES: ClassVar[tuple[str, ...]] = ()
    CHOICES: ClassVar[dict[str, tuple[str, ...]]] = {}
    ARCH: ClassVar[str] = ""
    BEFORE: ClassVar[dict[str, Any]] = {}

    def __post_init__(self) -> None:
        check_config(self)
        for name in self.POSITIVE:
            if not getattr(self, name) > 0:
                raise ConfigError(f"{name} must be positive, got {getattr(self, name)!r}")
        for name in self.NON_NEGATIVE:
            if getattr(self, name) < 0:
                raise ConfigError(f"{name} must be >= 0, got {getattr(self, name)!r}")
        for name in self.RATES:
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ConfigError(f"{name} must lie in [0, 1], got {getattr(self, name)!r}")
        for name, choices in self.CHOICES.items():
            if getattr(self, name) not in choices:
                raise ConfigError(f"{name} must be one of {', '.join(choices)}, got {getattr(self, name)!r}")
        if getattr(self, "window", 2) < 2:
            raise ConfigError(f"window must be at least 2 frames, got {self.window}")
        if getattr(self, "arch", self.ARCH) != self.ARCH:
            raise ConfigError(f"unknown architecture {self.arch!r} (expected {self.ARCH!r})")
        self.check()

    def check(self) -> None:
        """The kind's own checks (ConfigError), after the shared ones."""

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-serialisable dictionary of every field."""
        return dataclasses.asdict(self)  # type: ignore[call-overload]

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Self:
        """Config from ``to_dict`` output (fields newer than the file get ``BEFORE``'s values); unknown or
        missing required keys raise ModelFormatError."""
        if not isinstance(d, dict):
            raise ModelFormatError(f"model config must be a JSON object, got {type(d).__name__}")
        d = cls.BEFORE | d
        unknown = sorted(set(d) - {f.name for f in dataclasses.fields(cls)})  # type: ignore[arg-type]
        if unknown:
            raise ModelFormatError(f"unknown model config keys: {', '.join(unknown)}")
        try:
            return cls(**d)
        except (TypeError, ConfigError) as exc:
            raise ModelFormatError(f"invalid model config: {exc}") from exc
