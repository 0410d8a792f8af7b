"""The atomic operations inside dynamic loops of the Warp kernels a set's physics step launches.

Warp's deterministic mode (`mwjax.determinism`) sizes each kernel's record buffer from a static
count of its atomic sites, one record per site and thread. A site inside a loop that Warp does not
unroll runs once per iteration: beyond the count the launch raises outside graph capture, and
inside it (an env step) the extra records are dropped silently, so such a site can make the mode
neither exact nor repeatable. `mwjax.determinism` raises the count for the sites it knows of
(`LOOP_RECORDS`, `CONE_HESSIAN`); this lists every site it finds, from the kernels' source, with
whether the mode covers it.

A dry run of each scene's step (as `mwjax.kernels` lists modules: nothing runs or compiles) names
the kernels launched. In their source (and the Warp functions they call, transitively), an atomic
site is `wp.atomic_add/sub/min/max` or an augmented assignment to an element of an array
argument; a loop is dynamic unless Warp unrolls it (`Adjoint.get_unroll_range`): a `range` of
constants (a `wp.static` bound folds to one) of at most the module's `max_unroll` iterations
without `break`/`continue`, or of any length when its body holds a `wp.static` expression Warp
could not fold at declaration.

    python tools/loop_atomics.py --set MT10 --out loop-atomics-MT10.json
"""

from __future__ import annotations

import argparse
import ast
import inspect
import json
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import warp

sys.path.insert(0, str(Path(__file__).parents[1]))
import mwjax  # noqa: E402
from benchmarks.common import add_set_argument, provenance, tasks_arg  # noqa: E402
from mwjax import determinism, kernels  # noqa: E402

ATOMICS = frozenset({"atomic_add", "atomic_sub", "atomic_min", "atomic_max"})


def launched_kernels(scene: str, bodies: tuple[str, ...], config: mwjax.PhysicsConfig) -> list[Any]:
    """The Warp kernels one step and one kinematics call of the scene launch (a dry run)."""
    seen: dict[int, Any] = {}
    launches: list[kernels.Launch] = []
    with kernels._recording_launches(launches):
        for name in ("launch", "launch_tiled"):
            setattr(warp, name, _noting_kernel(getattr(warp, name), seen, launches))
        kernels.step_once(scene, bodies, config)
    return list(seen.values())


def _noting_kernel(launch: Any, seen: dict[int, Any], launches: list) -> Any:
    """`launch`, noting its kernel where the recording counts it (a launch of no threads does
    not run, e.g. the kernels of features a scene lacks)."""

    def noted(kernel: Any, *args: Any, **kwargs: Any) -> Any:
        before = len(launches)
        result = launch(kernel, *args, **kwargs)
        if len(launches) > before:
            seen.setdefault(id(kernel), kernel)
        return result

    return noted


class _Scope:
    """What names in a kernel's or function's source refer to: its array parameters, and the
    values its closure and module hold."""

    def __init__(self, func: Any, array_params: set[str]) -> None:
        closure = inspect.getclosurevars(func)
        self.values = {**closure.builtins, **closure.globals, **closure.nonlocals}
        self.array_params = array_params

    def constant(self, node: ast.expr) -> int | None:
        """`node`'s value where Warp knows it at build time (a literal or an int it closes over)."""
        if isinstance(node, ast.Constant) and isinstance(node.value, int):
            return node.value
        if isinstance(node, ast.Name) and isinstance(self.values.get(node.id), int):
            return self.values[node.id]
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
            value = self.constant(node.operand)
            return None if value is None else -value
        return None

    def resolve(self, node: ast.expr) -> Any:
        """The object a call's function expression names, where it is a plain or dotted name."""
        if isinstance(node, ast.Name):
            return self.values.get(node.id)
        if isinstance(node, ast.Attribute):
            owner = self.resolve(node.value)
            return getattr(owner, node.attr, None) if owner is not None else None
        return None


def _call_name(node: ast.Call) -> str | None:
    func = node.func
    return func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", None)


def _is_static(node: ast.expr) -> bool:
    return isinstance(node, ast.Call) and _call_name(node) == "static"


def loop_kind(loop: ast.For | ast.While, scope: _Scope, max_unroll: int) -> str:
    """ "unrolled" where Warp unrolls the loop, else "dynamic"."""
    if isinstance(loop, ast.While):
        return "dynamic"
    it = loop.iter
    if not (isinstance(it, ast.Call) and isinstance(it.func, ast.Name) and it.func.id == "range"):
        return "dynamic"
    values = [scope.constant(arg) for arg in it.args]
    if not 1 <= len(values) <= 3 or None in values:
        return "dynamic"
    if any(_is_static(node) for node in ast.walk(loop)):
        return "unrolled"  # Warp unrolls a constant range holding a wp.static it could not fold
    bounds = range(*values)  # range(stop), range(start, stop) and range(start, stop, step) alike
    iterations = abs(bounds.stop - bounds.start) // abs(bounds.step)  # Warp's count
    breaks = any(isinstance(node, ast.Break | ast.Continue) for node in ast.walk(loop))
    return "unrolled" if iterations <= max_unroll and not breaks else "dynamic"


def _array_params(adj: Any) -> set[str]:
    return {arg.label for arg in adj.args if warp.types.is_array(arg.type)}


def _function_sites(function: Any, seen: set[int]) -> list[str]:
    """The atomic sites of a Warp function and of those it calls, wherever they sit: called in
    a dynamic loop, every one of them runs once per iteration."""
    if id(function) in seen:
        return []
    seen.add(id(function))
    user = getattr(function, "user_overloads", None) or {}
    overloads = list(user.values()) or [function]
    sites = []
    for overload in overloads:
        adj = getattr(overload, "adj", None)
        if adj is None:
            continue
        scope = _Scope(adj.func, _array_params(adj))
        for node in ast.walk(adj.tree):
            if site := _site(node, scope):
                sites.append(f"{_where(adj, node)} {site}")
            elif callee := _user_function(node, scope):
                sites += _function_sites(callee, seen)
    return sites


def _user_function(node: ast.AST, scope: _Scope) -> Any | None:
    """The Warp function (not a builtin) that `node` calls, if it is such a call."""
    if not isinstance(node, ast.Call):
        return None
    callee = scope.resolve(node.func)
    is_user = isinstance(callee, warp._src.context.Function) and not callee.is_builtin()
    return callee if is_user else None


def _walk(node: ast.AST, scope: _Scope, max_unroll: int, loops: tuple[str, ...]) -> Iterator[tuple]:
    """Every node under `node`, with the kinds of the loops around it."""
    for child in ast.iter_child_nodes(node):
        inner = loops
        if isinstance(child, ast.For | ast.While):
            inner = (*loops, loop_kind(child, scope, max_unroll))
        yield child, inner
        yield from _walk(child, scope, max_unroll, inner)


def _where(adj: Any, node: ast.AST) -> str:
    """The node's file and line (the adjoint's tree counts lines from the function's first)."""
    return f"{Path(adj.filename).name}:{adj.fun_lineno + node.lineno - 1}"


def _site(node: ast.AST, scope: _Scope) -> str | None:
    """The atomic operation at `node`, if it is one."""
    if isinstance(node, ast.Call) and _call_name(node) in ATOMICS:
        return _call_name(node)
    if isinstance(node, ast.AugAssign) and isinstance(node.target, ast.Subscript):
        base = node.target.value
        while isinstance(base, ast.Subscript):
            base = base.value
        if isinstance(base, ast.Name) and base.id in scope.array_params:
            return f"{type(node.op).__name__.lower()} into an array element"
    return None


def loop_sites(kernel: Any) -> list[dict]:
    """The kernel's atomic sites inside dynamic loops, directly or through the functions it calls."""
    adj = kernel.adj
    scope = _Scope(adj.func, _array_params(adj))
    max_unroll = kernel.module.options.get("max_unroll", 16)
    rows = []
    for node, loops in _walk(adj.tree, scope, max_unroll, ()):
        if "dynamic" not in loops:
            continue
        site = _site(node, scope)
        via: list[str] = []
        if site is None and (callee := _user_function(node, scope)):
            via = _function_sites(callee, set())
            site = f"calls {callee.key}" if via else None
        if site:
            rows.append({"at": _where(adj, node), "site": site, "loops": list(loops), "through": via})
    return rows


def covered(kernel: Any) -> str | None:
    """How `mwjax.determinism` raises the kernel's record count, if it does."""
    if kernel.key == determinism.CONE_HESSIAN:
        return "its own module, bounded by the contacts a thread visits"
    bound = determinism.LOOP_RECORDS.get(kernel.module.name)
    return f"deterministic_max_records={bound} for its module" if bound else None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_set_argument(parser, default="MT10")
    parser.add_argument("--out", type=Path, default=None, help="JSON path")
    args = parser.parse_args()
    config = mwjax.PhysicsConfig()
    found: dict[tuple[str, str], dict] = {}
    for scene, bodies in kernels.scenes(tasks_arg(args.set)):
        for kernel in launched_kernels(scene, bodies, config):
            sites = loop_sites(kernel)
            if sites:
                key = (kernel.module.name, kernel.key)
                row = found.setdefault(key, {"module": key[0], "kernel": key[1], "sites": sites})
                row.setdefault("scenes", [])
                row["scenes"].append(scene)
                row["covered"] = covered(kernel)
    rows = sorted(found.values(), key=lambda r: (r["covered"] is not None, r["module"], r["kernel"]))
    for row in rows:
        status = row["covered"] or "NOT COVERED"
        print(f"{row['module']}.{row['kernel']}: {status} ({len(row['scenes'])} scenes)")
        for site in row["sites"]:
            print(f"    {site['at']}: {site['site']}, loops {site['loops']}")
    result = {"set": args.set, "kernels": rows, **provenance()}
    if args.out:
        args.out.write_text(json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":
    main()
