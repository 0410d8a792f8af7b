"""Prints where each Warp call of a step program is traced and the call id it gets.

For one MT1 reach env, lowers `step` and `step` twice in one program, and prints for every Warp
call traced: its callable, its id (as Warp leaves `call_id` afterwards: the id used, plus one),
the chain of traces it was traced in and mwjax's innermost frames; then each program's call ids
and FFI targets. A call that a program uses but that is not printed came from a trace JAX reused.

    python tools/warp_call_sites.py
"""

import re
import traceback
from typing import Any

import jax
import jax.numpy as jnp
from warp._src.jax import ffi

import mwjax
from mwjax import warp_call_ids


def main() -> None:
    env = mwjax.make("MT1:reach-v3", envs_per_task=1)  # installs warp_call_ids
    call = ffi.FfiCallable.__call__

    def logged(self: ffi.FfiCallable, *args: Any, **kwargs: Any) -> Any:
        chain = [f"{type(t).__name__}@{id(t) % 100000}" for t in warp_call_ids.trace_chain()]
        out = call(self, *args, **kwargs)
        frames = [f"{f.name}:{f.lineno}" for f in traceback.extract_stack()[:-1] if "/mwjax/" in f.filename]
        print(f"CALL {self.name[-14:]} id={self.call_id} traces={chain} mwjax={frames[-4:]}")
        return out

    ffi.FfiCallable.__call__ = logged
    print("jax", jax.__version__)
    state = jax.eval_shape(env.reset, jax.random.key(0))
    actions = jnp.zeros((1, 4))
    programs = {"one": lambda s, a: env.step(s, a), "two": lambda s, a: env.step(env.step(s, a), a)}
    for label, fn in programs.items():
        print("==", label)
        text = jax.jit(fn).lower(state, actions).as_text()
        print(label, "ids", re.findall(r"call_id = (\d+)", text))
        print(label, "targets", re.findall(r"custom_call @(\S+)\(", text))


if __name__ == "__main__":
    main()
