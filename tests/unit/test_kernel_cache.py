"""The kernel cache's housekeeping: each import stamps its cache as used, a fresh one removes
all but the most recently used of the others (and nothing else beside them), and `revdem
info --system` says how much each holds."""

import json
import os
import subprocess
import sys
import time

import numba

from revdem_cli import kernel_cache
from revdem_cli.kernel_cache import CACHES_KEPT, USED, prune_caches, use_cache
from tests.conftest import ROOT

HOUR = 3600.0


def caches(base, ages_h, stamped=True):
    """Kernel caches in `base`, one per age (hours since last used), each with 1 000 bytes of
    compiled code; the time in their USED stamp, or where not `stamped` their folder's."""
    made = []
    now = time.time()
    for k, age in enumerate(ages_h):
        cache = base / f"{numba.__version__}-{k:016x}"
        (cache / "kernels").mkdir(parents=True)
        (cache / "kernels" / "code.nbc").write_bytes(b"x" * 1000)
        when = now - age * HOUR
        if stamped:
            (cache / USED).touch()
            os.utime(cache / USED, (when, when))
        os.utime(cache, (when, when))
        made.append(cache)
    return made


def test_a_prune_keeps_the_most_recently_used_and_what_is_not_a_kernel_cache(tmp_path):
    current = tmp_path / f"{numba.__version__}-{'f' * 16}"
    current.mkdir()
    old = caches(tmp_path, [5, 1, 300, 2, 40, 0.5])
    unstamped = caches(tmp_path / "other", [0.1, 1000, 50], stamped=False)  # folders' times
    foreign = [tmp_path / "benchmarks_0123abcd", tmp_path / "notes.txt"]
    foreign[0].mkdir()
    foreign[1].write_text("kept")
    removed = prune_caches(current, kept=3)
    assert sorted(removed) == sorted([old[0], old[2], old[4]])  # 5, 300 and 40 hours
    assert sorted(p for p in tmp_path.iterdir() if p.name != "other") == sorted(
        [current, old[1], old[3], old[5], *foreign]
    )
    assert prune_caches(unstamped[0], kept=1) == [unstamped[1]]


def test_an_import_stamps_its_cache_and_a_fresh_one_prunes_the_others(tmp_path):
    old = caches(tmp_path, [10, 20, 30, 40, 50, 60, 70])
    use_cache(old[6])  # in use again: stamped, nothing removed
    assert time.time() - (old[6] / USED).stat().st_mtime < HOUR
    assert all(p.exists() for p in old)
    fresh = tmp_path / f"{numba.__version__}-{'e' * 16}"
    use_cache(fresh)
    assert (fresh / USED).exists()
    assert sorted(p for p in tmp_path.iterdir() if p != fresh) == sorted(
        [old[6], *old[:CACHES_KEPT - 1]]
    )  # fmt: skip


def test_revdem_prunes_at_import_and_info_says_what_the_caches_hold(tmp_path):
    """A first import of sources new to NUMBA_CACHE_DIR makes their cache and keeps the
    CACHES_KEPT last used of the others, which `revdem info --system` counts and sizes."""
    old = caches(tmp_path, range(1, CACHES_KEPT + 3))
    env = os.environ | {"NUMBA_CACHE_DIR": str(tmp_path)}
    info = [sys.executable, "-m", "revdem_cli.cli", "info", "--system", "--json"]
    done = subprocess.run(info, env=env, cwd=ROOT, capture_output=True, text=True, check=True)
    system = json.loads(done.stdout)
    assert system["other_kernel_caches"] == CACHES_KEPT
    assert system["other_kernel_caches_bytes"] == CACHES_KEPT * 1000
    current = tmp_path / kernel_cache.cache_dir().name  # these sources' cache
    assert system["kernel_cache"] == str(current) and (current / USED).exists()
    assert sorted(p for p in tmp_path.iterdir() if p != current) == old[:CACHES_KEPT]
