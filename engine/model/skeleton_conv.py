"""MoDi's skeleton topology and skeleton-aware convolutions (Raab et al. 2023, §3.2 and appendix B.2).

A skeleton is a tree of edges: each joint owns the edge directed into it, the root an abstract edge from
the origin. An entity of a level is one of its edges, then the root-displacement entity, then one
foot-contact entity per foot joint (attached to the edge holding that foot). Pooling a level merges pairs
of adjacent edges along every chain (a chain runs from the root or a joint with several children down to
a leaf or the next such joint; an odd chain's last group takes three edges, a chain of one edge stays);
when no chain has two edges, the leaf edges sharing a parent joint merge instead; a skeleton with nothing
left to merge keeps its edges. Convolutions are dense over ``entities × channels`` with each output
entity's kernel restricted to a set of input entities: its neighbourhood within a graph distance (in
place) or the edges its pooling group holds (the scalers between levels).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F  # noqa: N812
from scipy.sparse.csgraph import shortest_path
from torch import Tensor, nn

from engine.errors import ConfigError


@dataclass(frozen=True)
class SkeletonLevel:
    """One level of the pooled hierarchy: its edge tree, what each edge merges and where the feet are.

    ``parents[e]`` is the edge above edge ``e`` (-1 for the root's), parents first; ``groups[e]`` the edges
    of the finer level merged into ``e`` (the finest level: ``(e,)``); ``feet[i]`` the edge holding foot i.
    """

    parents: tuple[int, ...]
    groups: tuple[tuple[int, ...], ...]
    feet: tuple[int, ...]

    @property
    def n_edges(self) -> int:
        """Number of skeleton edges."""
        return len(self.parents)

    @property
    def n_entities(self) -> int:
        """Edges, the root displacement and the foot contacts."""
        return self.n_edges + 1 + len(self.feet)

    @property
    def displacement(self) -> int:
        """Entity index of the root displacement."""
        return self.n_edges


def _children(parents: Sequence[int]) -> list[list[int]]:
    kids: list[list[int]] = [[] for _ in parents]
    for e, p in enumerate(parents):
        if p >= 0:
            kids[p].append(e)
    return kids


def _chain_groups(parents: Sequence[int], kids: list[list[int]]) -> list[list[int]]:
    """Groups pairing adjacent edges along every chain; the root's edge alone."""
    groups = [[e] for e, p in enumerate(parents) if p < 0]
    for e, p in enumerate(parents):
        if p < 0 or (parents[p] >= 0 and len(kids[p]) == 1):
            continue  # not the first edge of a chain
        chain = [e]
        while len(kids[chain[-1]]) == 1:
            chain.append(kids[chain[-1]][0])
        pairs = [chain[i : i + 2] for i in range(0, len(chain), 2)]
        if len(pairs) > 1 and len(pairs[-1]) == 1:
            last = pairs.pop()
            pairs[-1] += last
        groups += pairs
    return groups


def _leaf_groups(parents: Sequence[int], kids: list[list[int]]) -> list[list[int]]:
    """Groups merging the leaf edges of each joint; every other edge alone."""
    groups = []
    for e in range(len(parents)):
        leaves = [c for c in kids[e] if not kids[c]]
        groups += [[c] for c in kids[e] if kids[c]]
        if leaves:
            groups.append(leaves)
    return [[e] for e, p in enumerate(parents) if p < 0] + groups


def pool_skeleton(parents: Sequence[int]) -> tuple[tuple[int, ...], tuple[tuple[int, ...], ...]]:
    """The next coarser edge tree of ``parents`` (parents first, one root) and, per new edge, the edges it
    merges; unchanged when nothing can merge."""
    parents = [int(p) for p in parents]
    kids = _children(parents)
    groups = _chain_groups(parents, kids)
    if all(len(g) == 1 for g in groups):
        groups = _leaf_groups(parents, kids)
    groups.sort(key=lambda g: g[0])
    owner = {e: i for i, g in enumerate(groups) for e in g}
    new_parents = tuple(-1 if parents[g[0]] < 0 else owner[parents[g[0]]] for g in groups)
    return new_parents, tuple(tuple(g) for g in groups)


def skeleton_hierarchy(parents: Sequence[int], feet: Sequence[int], n_levels: int) -> list[SkeletonLevel]:
    """``n_levels`` levels, finest first: the skeleton of ``parents`` (joint tree, parents first) with foot
    joints ``feet``, then each one pooled from the one before."""
    parents = [int(p) for p in parents]
    if sum(p < 0 for p in parents) != 1 or any(p >= i for i, p in enumerate(parents)):
        raise ConfigError("a skeleton needs one root and parents before their children")
    levels = [SkeletonLevel(tuple(parents), tuple((e,) for e in range(len(parents))), tuple(feet))]
    for _ in range(n_levels - 1):
        coarse, groups = pool_skeleton(levels[-1].parents)
        owner = {e: i for i, g in enumerate(groups) for e in g}
        levels.append(SkeletonLevel(coarse, groups, tuple(owner[f] for f in levels[-1].feet)))
    return levels


def neighbourhood(level: SkeletonLevel, distance: int) -> np.ndarray:
    """(E, E) bool: entity pairs within ``distance`` of each other. Edges sharing a joint are adjacent; the
    root displacement is adjacent to the root's edge and its neighbours, a contact to its foot's edge."""
    n = level.n_entities
    adj = np.zeros((n, n), dtype=bool)
    parents = level.parents
    for e, p in enumerate(parents):
        if p >= 0:
            adj[e, p] = True
        for f in range(e):
            if p >= 0 and parents[f] == p:
                adj[e, f] = True
    adj |= adj.T
    root = parents.index(-1)
    d = level.displacement
    adj[d, : level.n_edges] = adj[root, : level.n_edges]
    adj[d, root] = True
    for i, foot in enumerate(level.feet):
        adj[d + 1 + i, foot] = True
    adj |= adj.T
    hops = shortest_path(adj.astype(np.float64), unweighted=True, directed=False)
    return hops <= distance


def pooling_mask(fine: SkeletonLevel, coarse: SkeletonLevel) -> np.ndarray:
    """(E_coarse, E_fine) bool: each coarse entity and the fine entities it pools (the extra entities map
    one to one)."""
    mask = np.zeros((coarse.n_entities, fine.n_entities), dtype=bool)
    for c, group in enumerate(coarse.groups):
        mask[c, list(group)] = True
    for k in range(1 + len(fine.feet)):
        mask[coarse.n_edges + k, fine.n_edges + k] = True
    return mask


#: The cost, in entity pairs, of one more matrix product in a skeletal convolution (measured on a CPU).
BLOCK_OVERHEAD = 4


def plan_blocks(mask: np.ndarray) -> list[tuple[int, int, np.ndarray]]:
    """Runs of consecutive output entities (start, stop, the input entities any of them sees), greedily
    grown while one product over the run's inputs costs less than a separate one."""
    blocks: list[tuple[int, int, np.ndarray]] = []
    for e in range(mask.shape[0]):
        if blocks:
            start, _, seen = blocks[-1]
            union = seen | mask[e]
            merged = (e + 1 - start) * union.sum()
            apart = (e - start) * seen.sum() + mask[e].sum() + BLOCK_OVERHEAD
            if merged <= apart:
                blocks[-1] = (start, e + 1, union)
                continue
        blocks.append((e, e + 1, mask[e].copy()))
    return [(a, b, np.flatnonzero(seen)) for a, b, seen in blocks]


class SkeletalConv(nn.Module):
    """Temporal convolution over (B, E_in·C_in, T) features (entity-major) to (B, E_out·C_out, T′), each
    output entity's kernel seeing only the input entities ``mask`` (E_out, E_in) allows.

    Weights are stored only for allowed entity pairs, drawn N(0, 1) and scaled at run time by
    1/√fan-in (equalised learning rate). ``forward`` with a style (B, C_in) modulates the input channels
    and, with ``demodulate``, normalises each output channel's weights (StyleGAN2, eqs. 10 and 11).
    ``resample``: "up" doubles the frames (linear) before the kernel, "down" halves them (mean) after it.
    The convolution runs as one matrix product per block of output entities (``plan_blocks``) over the
    frames of the inputs the block sees.
    """

    def __init__(
        self,
        mask: np.ndarray,
        c_in: int,
        c_out: int,
        kernel: int,
        *,
        demodulate: bool = False,
        resample: str = "none",
        bias: bool = True,
    ):
        super().__init__()
        mask = np.asarray(mask, dtype=bool)
        if resample not in ("none", "up", "down") or not mask.any(axis=1).all():
            raise ConfigError(f"bad skeletal convolution (resample {resample!r}, an output with no input)")
        self.e_out, self.e_in = mask.shape
        self.c_in, self.c_out, self.kernel = c_in, c_out, kernel
        self.demodulate, self.resample = demodulate, resample
        pairs = np.argwhere(mask)
        self.register_buffer("pairs", torch.as_tensor(pairs.T.copy(), dtype=torch.int64), persistent=False)
        self.weight = nn.Parameter(torch.empty(len(pairs), c_out, c_in, kernel))
        fan_in = mask.sum(axis=1).repeat(c_out) * c_in * kernel
        self.register_buffer("scale", torch.as_tensor(1.0 / np.sqrt(fan_in), dtype=torch.float32), False)
        self.bias = nn.Parameter(torch.zeros(self.e_out * c_out)) if bias else None
        self.blocks = []
        for start, stop, inputs in plan_blocks(mask):
            rows = np.flatnonzero((pairs[:, 0] >= start) & (pairs[:, 0] < stop))
            local = np.stack([pairs[rows, 0] - start, np.searchsorted(inputs, pairs[rows, 1])])
            gather = None if len(inputs) == self.e_in else torch.as_tensor(inputs)
            full = len(rows) == (stop - start) * len(inputs)  # rows run output-major, inputs ascending
            place = None if full else torch.as_tensor(local)
            self.blocks.append((start, stop, len(inputs), gather, torch.as_tensor(rows), place))

    def dense_weight(self) -> Tensor:
        """(E_out·C_out, E_in·C_in, U) scaled weights, zero outside the mask."""
        dense = self.weight.new_zeros(self.e_out, self.e_in, self.c_out, self.c_in, self.kernel)
        dense = dense.index_put((self.pairs[0], self.pairs[1]), self.weight)
        dense = dense.permute(0, 2, 1, 3, 4).reshape(self.e_out * self.c_out, self.e_in * self.c_in, -1)
        return dense * self.scale[:, None, None]

    def _block_weight(self, start: int, stop: int, n_in: int, rows: Tensor, place: Tensor | None) -> Tensor:
        """(n_out·C_out, n_in·C_in·U) scaled weights of one block (``place``: where its pairs go, None when
        the block holds every pair)."""
        weight = self.weight[rows]
        if place is None:
            block = weight.view(stop - start, n_in, self.c_out, self.c_in, self.kernel)
        else:
            block = weight.new_zeros(stop - start, n_in, self.c_out, self.c_in, self.kernel)
            block = block.index_put((place[0], place[1]), weight)
        block = block.permute(0, 2, 1, 3, 4).reshape((stop - start) * self.c_out, -1)
        return block * self.scale[start * self.c_out : stop * self.c_out, None]

    def forward(self, x: Tensor, style: Tensor | None = None) -> Tensor:
        """Convolve ``x`` (B, E_in·C_in, T), modulated by ``style`` (B, C_in) when given."""
        if style is not None:
            x = x * style.repeat(1, self.e_in)[:, :, None]
        if self.resample == "up":
            x = F.interpolate(x, scale_factor=2.0, mode="linear", align_corners=False)
        b, _, t = x.shape
        pad = self.kernel // 2
        frames = F.pad(x, (pad, pad)).unfold(2, self.kernel, 1).transpose(1, 2).reshape(b * t, self.e_in, -1)
        parts = []
        for start, stop, n_in, gather, rows, place in self.blocks:
            seen = frames if gather is None else frames.index_select(1, gather)
            weight = self._block_weight(start, stop, n_in, rows, place)
            parts.append(seen.flatten(1) @ weight.T)
        out = torch.cat(parts, 1).view(b, t, -1).transpose(1, 2)
        if style is not None and self.demodulate:
            energy = self.weight.square().sum(-1)  # (pairs, C_out, C_in)
            per_out = energy.new_zeros(self.e_out, self.c_out, self.c_in).index_add(0, self.pairs[0], energy)
            per_out = per_out.flatten(0, 1) * self.scale[:, None].square()
            out = out * torch.rsqrt(style.square() @ per_out.T + 1e-8)[:, :, None]
        if self.resample == "down":
            out = F.avg_pool1d(out, 2)
        if self.bias is not None:
            out = out + self.bias[:, None]
        return out

    @torch.no_grad()
    def reset_parameters(self, generator: torch.Generator) -> None:
        """Weights N(0, 1) from ``generator``, biases 0."""
        self.weight.normal_(generator=generator)
        if self.bias is not None:
            self.bias.zero_()


def lrelu(x: Tensor) -> Tensor:
    """Leaky ReLU (slope 0.2) with StyleGAN's √2 gain."""
    return F.leaky_relu(x, 0.2) * math.sqrt(2.0)
