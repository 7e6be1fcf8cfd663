"""How a run keeps its memory down: arrays on pages of their own, resident only where
written and given back once spent, and the allocator's freed pages given back."""

from __future__ import annotations

import ctypes
import mmap

import numpy as np


def untouched(shape: int | tuple[int, ...], dtype=np.float64) -> np.ndarray:
    """Zeros of `shape` and `dtype` on private anonymous pages of their own: resident only
    where written, and unmapped when the array is dropped (not kept by the allocator, which
    holds freed blocks of a size for the next of that size). Private, so that `release`
    frees them: the pages of a shared mapping would stay in memory, only unmapped."""
    count = int(np.prod(shape))
    size = count * np.dtype(dtype).itemsize
    private = mmap.mmap(-1, max(size, 1), flags=mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS)
    return np.frombuffer(private, dtype=dtype, count=count).reshape(shape)


def release(array: np.ndarray) -> None:
    """Give the pages of an `untouched` array back to the system: it reads as zeros again,
    and takes memory only where it is written next."""
    owner = array
    while not isinstance(owner, mmap.mmap):
        owner = owner.obj if isinstance(owner, memoryview) else owner.base
    owner.madvise(mmap.MADV_DONTNEED)


def release_freed_memory() -> None:
    """Give the pages of freed memory back to the system (glibc's `malloc_trim`). A state is
    built through temporaries of its own size (the pair list found twice, the generated
    spheres it copies); glibc's allocator keeps the pages they leave for its next
    allocations, so that they stay resident and add to a run's peak memory: 90 B a sphere
    on the fcc benchmark (n = 24, history). Other C libraries have no such call, and nothing
    here to give back."""
    trim = getattr(_LIBC, "malloc_trim", None)
    if trim is not None:
        trim(0)


_LIBC = ctypes.CDLL(None)
