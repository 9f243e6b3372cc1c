"""Training across processes with torch.distributed: the ranks torchrun starts, each rank's share of a
global batch, and the DistributedDataParallel wrapper that averages their gradients."""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np
import torch
import torch.distributed as dist
from torch.nn.parallel import DistributedDataParallel

from engine.errors import ConfigError


@dataclass(frozen=True)
class Ranks:
    """This process's place among ``world`` training processes (rank 0 writes the log and the model)."""

    rank: int = 0
    world: int = 1
    local_rank: int = 0

    @property
    def is_main(self) -> bool:
        """Whether this process writes checkpoints, the log and the model folder."""
        return self.rank == 0

    @property
    def distributed(self) -> bool:
        """Whether more than one process trains."""
        return self.world > 1

    def share(self, n: int) -> np.ndarray:
        """This rank's rows of a global batch of ``n`` (contiguous, equal shares); ConfigError unless
        ``n`` divides evenly, so that the ranks' mean gradient is the global batch's."""
        if n % self.world:
            raise ConfigError(f"a global batch of {n} does not split evenly over {self.world} processes")
        size = n // self.world
        return np.arange(self.rank * size, (self.rank + 1) * size)


SINGLE = Ranks()


def start(device: torch.device) -> Ranks:
    """The ranks torchrun describes in the environment (WORLD_SIZE, RANK, LOCAL_RANK), with the process
    group started (NCCL on CUDA, gloo on CPU); one process without them."""
    world = int(os.environ.get("WORLD_SIZE", "1"))
    if world <= 1:
        return SINGLE
    ranks = Ranks(int(os.environ["RANK"]), world, int(os.environ.get("LOCAL_RANK", "0")))
    if not dist.is_initialized():
        dist.init_process_group("nccl" if device.type == "cuda" else "gloo")
    return ranks


def rank_device(device: torch.device, ranks: Ranks) -> torch.device:
    """The device of this rank: its local GPU when training on CUDA, else ``device``."""
    if device.type == "cuda" and ranks.distributed:
        torch.cuda.set_device(ranks.local_rank)
        return torch.device("cuda", ranks.local_rank)
    return device


def parallel(module: torch.nn.Module, ranks: Ranks) -> torch.nn.Module:
    """``module`` wrapped in DistributedDataParallel across the ranks (itself for one process); parameters
    a step leaves out (a loss term weighted 0) are allowed."""
    if not ranks.distributed:
        return module
    device = next(module.parameters()).device
    ids = [device.index] if device.type == "cuda" else None
    return DistributedDataParallel(module, device_ids=ids, find_unused_parameters=True)


def same_on_every_rank(value: int, what: str, ranks: Ranks) -> None:
    """ConfigError unless every rank holds the same ``value`` (e.g. the epoch each resumed from)."""
    if not ranks.distributed:
        return
    found = _for_backend(torch.tensor([value, -value], dtype=torch.int64))
    dist.all_reduce(found, op=dist.ReduceOp.MAX)
    high, low = int(found[0]), -int(found[1])
    if high != low:
        raise ConfigError(
            f"the processes disagree on {what} ({low} to {high}); is --out on a shared file system?"
        )


def mean_over_ranks(terms: dict[str, float], ranks: Ranks) -> dict[str, float]:
    """Each loss term averaged over the ranks (the global batch's, for the log); as is for one process."""
    if not ranks.distributed:
        return terms
    values = _for_backend(torch.tensor(list(terms.values()), dtype=torch.float64))
    dist.all_reduce(values)
    return dict(zip(terms, (values / ranks.world).tolist(), strict=True))


def _for_backend(tensor: torch.Tensor) -> torch.Tensor:
    """``tensor`` where the process group's backend reduces it (NCCL: this rank's GPU)."""
    return tensor.cuda() if dist.get_backend() == "nccl" else tensor


def finish(ranks: Ranks) -> None:
    """Close the process group (rank 0 may still be writing the bank: nothing waits for it)."""
    if ranks.distributed and dist.is_initialized():
        dist.destroy_process_group()
