"""Motion data: skeletons, clips, file formats and dataset folders."""

from engine.motion.motion import Motion
from engine.motion.skeleton import Skeleton, sanitize_name

__all__ = ["Motion", "Skeleton", "sanitize_name"]
