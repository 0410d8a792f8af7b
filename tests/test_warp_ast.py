"""Warp's kernel-source parsing, serialized across threads (`mwjax.warp_ast`)."""

import ast
import gc
import threading
import time

import warp._src.codegen as warp_codegen

import mwjax.physics  # noqa: F401  (installs the workaround)

SOURCE = "\n".join(
    f"def f{i}(x):\n    return [[(x + {i}) * y for y in range(3)] for _ in range(2)]" for i in range(300)
)


class _ReleasesTheGil:
    def __del__(self) -> None:
        time.sleep(0)


def test_parses_on_several_threads_at_once_do_not_fail():
    """Threads that parse while the collector runs finalizers releasing the GIL: with the plain
    `ast.parse` of CPython 3.11 this fails ("AST constructor recursion depth mismatch") at the
    first parse of a thread that starts while another parses, so 20 parses per thread leave a wide
    margin; Warp's `ast.parse` must not fail."""
    errors: list[str] = []

    def parse_many() -> None:
        for _ in range(20):
            cycles = [_ReleasesTheGil() for _ in range(50)]
            for c in cycles:
                c.me = c  # freed by the collector, during the next parse's allocations
            del cycles
            try:
                tree = warp_codegen.ast.parse(SOURCE)
            except SystemError as e:
                errors.append(str(e))
                return
            assert len(tree.body) == 300

    threshold = gc.get_threshold()
    gc.set_threshold(50)
    try:
        threads = [threading.Thread(target=parse_many) for _ in range(3)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    finally:
        gc.set_threshold(*threshold)
    assert errors == []
    assert warp_codegen.ast.Name is ast.Name  # the rest is the standard module


def test_every_parse_in_the_process_takes_the_lock():
    """A parse outside Warp (a traceback's caret line, `inspect`) collides with Warp's as well:
    the `ast` module's own `parse` is the serialized one, and it still parses."""
    from mwjax import warp_ast

    assert ast.parse is warp_ast.locked_parse
    assert warp_codegen.ast.parse(SOURCE).body[0].name == ast.parse(SOURCE).body[0].name == "f0"
