"""The spheres of a scenario as arrays, and the lattices that generate them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

FCC_BASIS = np.array([[0.0, 0.0, 0.0], [0.5, 0.5, 0.0], [0.5, 0.0, 0.5], [0.0, 0.5, 0.5]])
"""The four spheres of a cubic face-centred unit cell, in units of the lattice constant."""


@dataclass(frozen=True, eq=False)
class Spheres:
    """Spheres as arrays: radius (N,), position, velocity, angular velocity (N, 3),
    `material`, the index of each sphere's material among `materials` (N,), and `id`, each
    sphere's identity, which outputs carry (N,): the atom id of the data file it was read
    from, else its number from 1 in the order of its table."""

    radius: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    angular_velocity: np.ndarray
    material: np.ndarray
    materials: tuple[str, ...]
    id: np.ndarray

    def __len__(self) -> int:
        return len(self.radius)

    def taken(self, k) -> Spheres:
        """The spheres `k` (indices or a slice), in that order, with their ids."""
        arrays = (self.radius, self.position, self.velocity, self.angular_velocity)
        return Spheres(*(a[k] for a in arrays), self.material[k], self.materials, self.id[k])

    @classmethod
    def join(cls, parts: list[Spheres], materials: tuple[str, ...]) -> Spheres:
        """The spheres of `parts` in their order, each part's ids after the largest of the
        parts before it, so that every id is its own (a scenario of one table keeps its ids):
        the one part that has spheres as it is (no copy, and no page of an array it has not
        written, such as `uniform`'s spins)."""
        filled = [part for part in parts if len(part)]
        if len(filled) == 1 and filled[0].materials == tuple(materials):
            return filled[0]

        def stacked(name: str, shape: tuple[int, ...], dtype=np.float64) -> np.ndarray:
            arrays = [getattr(part, name) for part in parts]
            return np.concatenate(arrays) if arrays else np.zeros(shape, dtype)

        ids, largest = [], 0
        for part in filled:
            ids.append(part.id + largest)
            largest = int(ids[-1].max())
        return cls(
            stacked("radius", (0,)),
            stacked("position", (0, 3)),
            stacked("velocity", (0, 3)),
            stacked("angular_velocity", (0, 3)),
            stacked("material", (0,), np.int64),
            materials,
            np.concatenate(ids) if ids else np.zeros(0, np.int64),
        )

    def table_id(self, index: int, start: int) -> int:
        """The id sphere `index` has in its own table, whose first sphere is `start`: its id
        less the offset `join` gave the table, the largest id before it."""
        return int(self.id[index]) - (int(self.id[:start].max()) if start else 0)

    def material_names(self) -> list[str]:
        return [self.materials[k] for k in self.material]


def numbered(count: int) -> np.ndarray:
    """The ids of `count` spheres numbered from 1 in their order."""
    return np.arange(1, count + 1, dtype=np.int64)


def uniform(count: int, radius, material: int, materials, position, velocity) -> Spheres:
    """`count` spheres of the given radii (one, or one each), one material, no spin,
    numbered from 1."""
    return Spheres(
        np.broadcast_to(np.asarray(radius, dtype=np.float64), (count,)).copy(),
        np.asarray(position, dtype=np.float64).reshape(count, 3),
        np.broadcast_to(np.asarray(velocity, dtype=np.float64), (count, 3)).copy(),
        np.zeros((count, 3)),
        np.full(count, material, dtype=np.int64),
        tuple(materials),
        numbered(count),
    )


def fcc_positions(cells, spacing: float, origin) -> np.ndarray:
    """Centres of an fcc lattice of cells[0] x cells[1] x cells[2] cubic unit cells of edge
    `spacing` from `origin`, cell by cell (z fastest), four spheres a cell."""
    grid = np.indices(tuple(cells), dtype=np.float64).reshape(3, -1).T
    return ((grid[:, None, :] + FCC_BASIS[None]) * spacing).reshape(-1, 3) + np.asarray(origin)
