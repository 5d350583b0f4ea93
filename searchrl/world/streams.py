"""One random stream per world, so that what a world draws does not depend on the worlds batched beside it.

A single `np.random.Generator` shared by K batched worlds hands world k the k-th row of each (K, …) draw: split
the same worlds into batches of another size and every world draws other numbers. `WorldStreams` gives each world
its own generator, seeded from its own key (an evaluation keys world k by (seed, cell, map, repeat)), and offers the
two Generator methods the world and the controllers draw with, for sizes whose first axis is K: row k always comes
from world k's generator. Anything that takes a Generator for a (K, …) draw takes a WorldStreams too.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


class WorldStreams:
    """K independent generators; world k's is `np.random.default_rng(keys[k])` (a key is a sequence of ints >= 0,
    the entropy of its SeedSequence)."""

    def __init__(self, keys: Sequence[Sequence[int]]) -> None:
        self.generators = [np.random.default_rng([int(part) for part in key]) for key in keys]

    def restart(self, worlds: Sequence[int], keys: Sequence[Sequence[int]]) -> None:
        """World worlds[i]'s generator becomes `np.random.default_rng(keys[i])`: a new episode's stream."""
        for k, key in zip(worlds, keys, strict=True):
            self.generators[int(k)] = np.random.default_rng([int(part) for part in key])

    def __len__(self) -> int:
        return len(self.generators)

    def _rows(self, size: int | tuple[int, ...]) -> tuple[int, ...]:
        size = (size,) if isinstance(size, (int, np.integer)) else tuple(size)
        if not size or size[0] != len(self.generators):
            raise ValueError(
                f"a draw of size {size} from {len(self.generators)} world streams: its first axis must "
                f"be the number of worlds, {len(self.generators)}"
            )
        return size[1:]

    def random(self, size: int | tuple[int, ...]) -> np.ndarray:
        """Uniforms in [0, 1), shape `size` = (K, …): row k from world k's generator."""
        rest = self._rows(size)
        return np.stack([g.random(rest) for g in self.generators]) if self.generators else np.empty(size)

    def integers(self, low: int, high: int, size: int | tuple[int, ...]) -> np.ndarray:
        """Integers in [low, high), int64, shape `size` = (K, …): row k from world k's generator."""
        rest = self._rows(size)
        if not self.generators:
            return np.empty(size, np.int64)
        return np.stack([g.integers(low, high, size=rest) for g in self.generators])


def random_source(seed: int | np.random.Generator | WorldStreams | None) -> np.random.Generator | WorldStreams:
    """What a controller draws from: world streams as they are, else `np.random.default_rng(seed)`."""
    return seed if isinstance(seed, WorldStreams) else np.random.default_rng(seed)
