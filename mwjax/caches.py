"""Persistent compile caches, on by default, so that only a machine's first run compiles.

- JAX's compilation cache (XLA programs taking over a second to compile, JAX's default
  threshold) goes to `$XDG_CACHE_HOME/mwjax/jax` (`~/.cache/mwjax/jax`), unless a directory is
  already set (`JAX_COMPILATION_CACHE_DIR` or `jax.config`) or `MWJAX_NO_CACHE=1`.
- Tables an env computes when it is made (`mwjax.stored_results`) go to
  `$XDG_CACHE_HOME/mwjax/results` (the most recently used, up to 256 MB), unless
  `MWJAX_NO_CACHE=1`.
- Warp caches its kernel modules itself, in `~/.cache/warp` (or `WARP_CACHE_PATH`).

Sharing a cache directory with users you do not trust lets them run code as you (JAX's warning).
"""

from __future__ import annotations

import functools
import hashlib
import os
from pathlib import Path

import jax


def user_cache_dir() -> Path:
    """mwjax's directory in the user's cache: `$XDG_CACHE_HOME/mwjax` (`~/.cache/mwjax`)."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "mwjax"


def jax_cache_dir() -> Path:
    """Where mwjax puts JAX's compilation cache when nothing else chose a place."""
    return user_cache_dir() / "jax"


def enabled() -> bool:
    """Whether mwjax's caches are on (`MWJAX_NO_CACHE` unset, empty or "0")."""
    return os.environ.get("MWJAX_NO_CACHE", "0") in ("", "0")


@functools.cache
def sources_digest() -> str:
    """A digest of every file mwjax ships (its code and its scene files), for cache keys that must
    change with any edit of them."""
    package = Path(__file__).parent
    digest = hashlib.sha256()
    for path in sorted(p for p in package.rglob("*") if p.is_file() and "__pycache__" not in p.parts):
        digest.update(str(path.relative_to(package)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def configure() -> None:
    """Turn JAX's persistent compilation cache on (see the module docstring). It takes effect
    for every later compile, also when something was compiled before."""
    if not enabled():
        return
    if jax.config.jax_compilation_cache_dir is None:
        jax.config.update("jax_compilation_cache_dir", str(jax_cache_dir()))
