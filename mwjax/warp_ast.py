"""Serializes `ast.parse` across threads, Warp's kernel-source parses among them (a CPython 3.11 workaround).

Warp builds a kernel by parsing its Python source with `ast.parse`. MJX-Warp builds some kernels
inside its FFI calls, which XLA runs on threads of its own (the renderer's kernel, for one), while
the Python thread may build others at the same time (models, render contexts, data). CPython 3.11
keeps `ast.parse`'s recursion count in per-interpreter state, and the interpreter may switch
threads in the middle of a parse (a finalizer run by the collector that releases the GIL), so two
threads parsing at once can fail with "SystemError: AST constructor recursion depth mismatch"
(cpython gh-106905). It failed the renderer's kernel build inside an FFI call in a test run.

`install()` puts a `parse` that holds one process-wide (re-entrant) lock in the `ast` module
itself, which Warp's code generator and context call (`ast.parse`, looked up at each call). Every
parse takes it, not only Warp's: a parse on another thread collides as well (CPython 3.11 formats
a traceback's caret line with `ast.parse`, `inspect` parses builtins' signatures with it), and a
cold-cache test run failed the renderer's kernel build so while only Warp's own parses were
serialized. The lock only orders the parses; what they return is unchanged.
"""

from __future__ import annotations

import ast
import threading
from typing import Any

_lock = threading.RLock()
_parse = ast.parse


def locked_parse(*args: Any, **kwargs: Any) -> ast.AST:
    """`ast.parse`, one thread at a time."""
    with _lock:
        return _parse(*args, **kwargs)


def install() -> None:
    """Make `ast.parse` the serialized one (idempotent)."""
    ast.parse = locked_parse
