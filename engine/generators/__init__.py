"""Generator kinds behind one interface (see :mod:`engine.generators.base`)."""

from engine.generators.base import (
    CAPABILITIES,
    CapabilityError,
    CodeSpace,
    Generator,
    SampleRequest,
    kinds,
    model_kind,
    open_generator,
    refusal,
    register_kind,
    require,
)

__all__ = [
    "CAPABILITIES",
    "CapabilityError",
    "CodeSpace",
    "Generator",
    "SampleRequest",
    "kinds",
    "model_kind",
    "open_generator",
    "refusal",
    "register_kind",
    "require",
]
