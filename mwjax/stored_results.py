"""Results that `mwjax.make` computes on the device, kept on disk so that every later process
uses the same bits.

An env computes a few tables when it is made (the settled state of each goal variant of the
tasks that settle per goal, `mwjax.placement`) and its reset and step carry them as constants.
On a GPU, Warp's atomics make such a computation differ in the last bits from one process to
the next, so every process traced programs with other constants: JAX's persistent cache
missed for the MT50 step and reset in every process (their compile, ~70 s on an H200, ran
each time), and two processes with the same seed started their episodes from different bits.

`run(jitted, *args)` returns `jitted(*args)`, read from `$XDG_CACHE_HOME/mwjax/results`
(`~/.cache/mwjax/results`) when the same computation ran before on the same kind of device. The
key is the lowered program (everything the computation closes over, the model and the physics
settings included), its arguments, the device kind, the versions of JAX, jaxlib, Warp, MuJoCo and
MJX, and mwjax's files (`caches.sources_digest`); a changed program, input or version is a new entry.
Tracing and lowering a program only to find its key took most of a stored read (~7 of MT50's ~10 s
in `mwjax.make` on the CPU), so a caller that can name what its program closes over passes that
description instead (`described_by`, with the result's tree): the program is then traced only when
it has to run.
`MWJAX_NO_CACHE=1` turns this off with JAX's cache (`mwjax.caches`). Every edit of mwjax's files
makes new entries, so the directory keeps the most recently used ones up to `LIMIT_BYTES`.
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib.metadata
import os
import tempfile
import threading
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

import jax
import jax.numpy as jnp
import jaxlib
import mujoco
import numpy as np
import warp

from mwjax import caches, determinism

# Writes under way; the interpreter waits for them at exit (they are not daemon threads).
_writes: list[threading.Thread] = []
# The directory's size kept after a write, least recently used entries removed first (MT50's
# settled states take about 1 MB).
LIMIT_BYTES = 256 * 2**20


def directory() -> Path:
    """Where the results are kept."""
    return caches.user_cache_dir() / "results"


def run(jitted: Any, *args: Any, described_by: str | None = None, out_tree: Any = None) -> Any:
    """`jitted(*args)` (a `jax.jit` function), read from disk if this computation was stored;
    otherwise computed, and stored once its result is ready (in a thread: this returns at once,
    as the call would).

    `described_by`, with `out_tree` (the result's `jax.tree.structure`), keys the entry by that
    text instead of the lowered program: it must name everything `jitted` closes over that
    mwjax's files do not fix (settings, models chosen, sizes not in `args`). JAX's x64 mode and
    `mwjax.determinism` are added here."""
    if not caches.enabled():
        return jitted(*args)
    if described_by is None:
        lowered = jitted.lower(*args)
        program, out_tree = lowered.as_text(debug_info=False), lowered.out_tree
        expected = [(info.shape, info.dtype) for info in jax.tree.leaves(lowered.out_info)]
        compute = lambda: lowered.compile()(*args)  # noqa: E731 - traced once, not twice
    else:
        if out_tree is None:
            raise ValueError("described_by needs out_tree, the structure of the result")
        x64 = jax.config.jax_enable_x64
        program = f"described: {described_by}; x64 {x64}; deterministic {determinism.enabled()}"
        expected = None
        compute = lambda: jitted(*args)  # noqa: E731
    path = directory() / f"{_key(program, args)}.npz"
    stored = _load(path, out_tree, expected)
    if stored is not None:
        return stored
    result = compute()
    if jax.tree.structure(result) != out_tree:
        raise ValueError(f"out_tree {out_tree} does not describe the result, {jax.tree.structure(result)}")
    write = threading.Thread(target=_store, args=(path, result), name="mwjax-store-result")
    write.start()
    _writes.append(write)
    return result


def wait() -> None:
    """Return once every result computed so far is on disk."""
    while _writes:
        _writes.pop().join()


def _key(program: str, args: tuple[Any, ...]) -> str:
    digest = hashlib.sha256()
    digest.update(program.encode())
    for leaf in jax.tree.leaves(args):
        value = np.asarray(leaf)
        digest.update(f"{value.dtype}{value.shape}".encode())
        digest.update(value.tobytes())
    device = jax.devices()[0]
    for part in (device.platform, device.device_kind, jax.__version__, jaxlib.__version__):
        digest.update(part.encode())
    digest.update(f"{warp.config.version}{mujoco.__version__}{_mjx_version()}".encode())
    # Warp kernels are named, not spelled out, in the program: mwjax's own code is part of the key.
    digest.update(caches.sources_digest().encode())
    return digest.hexdigest()


def _mjx_version() -> str:
    try:
        return importlib.metadata.version("mujoco-mjx")
    except importlib.metadata.PackageNotFoundError:
        return "unknown"


def _load(path: Path, out_tree: Any, expected: list[tuple[Any, Any]] | None) -> Any | None:
    """The stored result at `path` as a tree of structure `out_tree`, or None when there is none,
    it has another number of leaves, or (where `expected` lists them) other shapes and dtypes:
    a damaged file is computed again."""
    try:
        with np.load(path) as archive:
            leaves = [archive[f"leaf{i}"] for i in range(len(archive.files))]
    except (OSError, ValueError, KeyError):
        return None
    if len(leaves) != out_tree.num_leaves:
        return None
    if expected is not None and any(
        (leaf.shape, leaf.dtype) != (tuple(shape), dtype)
        for leaf, (shape, dtype) in zip(leaves, expected, strict=True)
    ):
        return None
    with contextlib.suppress(OSError):
        os.utime(path)  # used now: the last to go when the directory is trimmed
    return jax.tree.unflatten(out_tree, [jnp.asarray(leaf) for leaf in leaves])


def _store(path: Path, result: Any) -> None:
    """Write `result`'s leaves to `path` atomically (another process may write the same file)."""
    leaves = {f"leaf{i}": np.asarray(leaf) for i, leaf in enumerate(jax.tree.leaves(result))}
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        write_atomically(path, lambda file: np.savez(file, **leaves))
        _trim(path.parent)
    except OSError:  # a read-only or full disk: the next process computes it again
        pass


def write_atomically(path: Path, write: Callable[[IO[bytes]], object]) -> None:
    """`write(file)` into a temporary file in `path`'s folder, then that file moved to `path`:
    a reader, another writer or a process stopped mid-write never leaves or finds half a file
    there. The temporary file is removed if writing or moving it fails."""
    file = tempfile.NamedTemporaryFile(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp", delete=False)
    partial = Path(file.name)
    try:
        with file:
            write(file)
        os.replace(partial, path)
    except BaseException:
        partial.unlink(missing_ok=True)
        raise


def _trim(folder: Path) -> None:
    """Remove the least recently used entries until the folder holds at most `LIMIT_BYTES`."""
    entries = []
    for entry in folder.glob("*.npz"):
        with contextlib.suppress(OSError):  # another process may remove it meanwhile
            stat = entry.stat()
            entries.append((stat.st_mtime, stat.st_size, entry))
    total = sum(size for _, size, _ in entries)
    for _, size, entry in sorted(entries, key=lambda item: item[0]):
        if total <= LIMIT_BYTES:
            break
        entry.unlink(missing_ok=True)
        total -= size
