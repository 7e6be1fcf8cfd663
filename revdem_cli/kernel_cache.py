"""Where numba caches the kernels' compiled code, and how much of it is kept.

numba invalidates a cached function only when its own file changes, yet a caller's cache
holds the compiled code of the functions it calls from other files; so the cache directory
is keyed by a hash of every kernel source file, every contact law (revdem_cli/laws) and
every wall shape (revdem_cli/wall_shapes), and any change to any of them starts a fresh
cache. Inside it, code lies by module (`_PackageLocator`), not by the sources' absolute
path: a fresh clone of the same sources compiles nothing. Each import stamps its cache as
used, and a fresh cache removes all but the CACHES_KEPT most recently used of the others
(`prune_caches`), so that upgrades do not pile up compiled code.

Imported by `revdem_cli.kernels` before anything is compiled; it lies outside the kernels,
so that the hash does not cover it.
"""

import hashlib
import os
import re
import shutil
from pathlib import Path

import numba
from numba.core.caching import CacheImpl, UserProvidedCacheLocator

_PACKAGE = Path(__file__).resolve().parent

CACHES_KEPT = 4
"""Kernel caches of other sources (other revdem versions, or installs beside this one) kept
when a fresh one starts: the most recently used. Each holds tens of MB of compiled code (up
to about 200 MB once the test suite has compiled its variants); one removed too soon costs
its install a compile (3 to 4 min on 2 cores) when next used."""

CACHE_NAME = re.compile(r"\d+\.\d+\S*-[0-9a-f]{16}")
"""How `cache_dir` names a kernel cache: numba's version and the sources' hash. Nothing
else in the caches' folder is touched."""

USED = "used"
"""The file in a kernel cache whose time says when an import last used it."""


def cache_dir() -> Path:
    """The kernel cache of these sources: under NUMBA_CACHE_DIR, or revdem/numba in the user's
    cache folder, by numba's version and the hash of the sources it compiles."""
    sources = sorted(_PACKAGE.joinpath("kernels").glob("*.py"))
    for registry in ("laws", "wall_shapes"):  # compiled helpers found by name
        sources += sorted(_PACKAGE.joinpath(registry).glob("*.py"))
    digest = hashlib.sha256(b"".join(p.read_bytes() for p in sources)).hexdigest()[:16]
    base = os.environ.get("NUMBA_CACHE_DIR") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "revdem", "numba"
    )
    return Path(base, f"{numba.__version__}-{digest}")


def last_used(cache: Path) -> float:
    """When a kernel cache was last used (its USED stamp, or where it has none the folder's
    time; 0 for one gone meanwhile: another process may be removing it)."""
    for path in (cache / USED, cache):
        try:
            return path.stat().st_mtime
        except FileNotFoundError:
            continue
    return 0.0


def others(current: Path) -> list[Path]:
    """The kernel caches beside `current` (named as CACHE_NAME), the most recently used
    first (`last_used`)."""
    found = [
        p
        for p in current.parent.iterdir()
        if p != current and p.is_dir() and CACHE_NAME.fullmatch(p.name)
    ]
    return sorted(found, key=last_used, reverse=True)


def prune_caches(current: Path, kept: int = CACHES_KEPT) -> list[Path]:
    """Remove the kernel caches beside `current` but the `kept` most recently used; returns
    those removed."""
    removed = others(current)[kept:]
    for old in removed:
        shutil.rmtree(old, ignore_errors=True)  # another process may be removing it too
    return removed


def use_cache(cache: Path) -> None:
    """Stamp `cache` as used now; where this makes it, `prune_caches`. A cache that cannot
    be written is left to numba, which says so when it saves code there."""
    try:
        cache.mkdir(parents=True)
        fresh = True
    except FileExistsError:
        fresh = False
    except OSError:
        return
    try:
        (cache / USED).touch()
    except OSError:
        return
    if fresh:
        prune_caches(cache)


def size(path: Path) -> int:
    """Bytes of the files under `path` (none for one that another process removes meanwhile,
    `prune_caches`)."""
    total = 0
    for f in path.rglob("*"):
        try:
            total += f.stat().st_size if f.is_file() else 0
        except FileNotFoundError:
            continue
    return total


class _PackageLocator(UserProvidedCacheLocator):
    """Where numba caches revdem's compiled functions: under CACHE_DIR by the module's place
    in the package, not (as numba does) by the absolute path of its folder, so that every
    copy of the same sources (a clone, a reinstall, a CI checkout) finds the code compiled
    for them; numba still checks each file's content against the cache index."""

    def __init__(self, py_func, py_file):
        super().__init__(py_func, py_file)
        place = Path(py_file).resolve().relative_to(_PACKAGE).parent
        self._cache_path = os.path.join(numba.config.CACHE_DIR, *place.parts)

    @classmethod
    def from_function(cls, py_func, py_file):
        if not Path(py_file).resolve().is_relative_to(_PACKAGE):
            return None
        return super().from_function(py_func, py_file)


numba.config.CACHE_DIR = str(cache_dir())
use_cache(Path(numba.config.CACHE_DIR))
CacheImpl._locator_classes.insert(0, _PackageLocator)
