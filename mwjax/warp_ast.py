"""Serializes Warp's parsing of kernel sources across threads (a workaround for CPython 3.11).

Warp builds a kernel by parsing its Python source with `ast.parse`. MJX-Warp builds some kernels
inside its FFI calls, which XLA runs on threads of its own (the renderer's kernel, for one), while
the Python thread may build others at the same time (models, render contexts, data). CPython 3.11
keeps `ast.parse`'s recursion count in per-interpreter state, and the interpreter may switch
threads in the middle of a parse (a finalizer run by the collector that releases the GIL), so two
threads parsing at once can fail with "SystemError: AST constructor recursion depth mismatch"
(cpython gh-106905). It failed the renderer's kernel build inside an FFI call in a test run.

`install()` gives Warp's code generator and context an `ast` whose `parse` holds one process-wide
(re-entrant) lock, and puts the same locked `parse` in the `ast` module itself: a parse on
another thread that is not Warp's collides as well (CPython 3.11 formats a traceback's caret
line with `ast.parse`, `inspect` parses builtins' signatures with it), and a cold-cache test run
failed the renderer's kernel build so with Warp's parses already serialized. The lock only
orders the parses; what they return is unchanged.
"""

from __future__ import annotations

import ast
import threading
from typing import Any

import warp._src.codegen as warp_codegen
import warp._src.context as warp_context

_lock = threading.RLock()
_parse = ast.parse


class _LockedAst:
    """The `ast` module, with `parse` serialized."""

    def __getattr__(self, name: str) -> Any:
        return getattr(ast, name)

    @staticmethod
    def parse(*args: Any, **kwargs: Any) -> ast.AST:
        return locked_parse(*args, **kwargs)


def locked_parse(*args: Any, **kwargs: Any) -> ast.AST:
    """`ast.parse`, one thread at a time."""
    with _lock:
        return _parse(*args, **kwargs)


def install() -> None:
    """Give Warp's modules the serialized `ast`, and `ast` the serialized `parse` (idempotent)."""
    for module in (warp_codegen, warp_context):
        if not isinstance(module.ast, _LockedAst):
            module.ast = _LockedAst()
    ast.parse = locked_parse
