"""Opt-in bit-reproducible physics on the GPU (process-wide).

On the CPU every run is bit-identical: Warp runs each kernel's threads in order. On a GPU two
things reorder floating-point sums from run to run: Warp's atomics (contact and constraint-row
counters, accumulations into shared arrays), whose order follows thread scheduling, and XLA's own
scatter-adds and reductions. `enable()` turns on Warp's deterministic mode (atomics recorded and
reduced, and counter slots assigned, in thread order: `warp.DeterministicMode.RUN_TO_RUN`) and
XLA's deterministic ops. It is process-wide because Warp shares kernel modules between scenes and
envs, and XLA reads its flags once, when JAX first starts a backend: set `MWJAX_DETERMINISTIC=1`
before `import mwjax`, or call `enable()` before JAX runs anything. Kernels compile anew for the
mode (a separate entry in Warp's cache) and run slower.
"""

from __future__ import annotations

import math
import os
import warnings

import warp

XLA_FLAG = "--xla_gpu_deterministic_ops=true"

# Warp sizes a deterministic kernel's record buffer from a static count of its atomic sites: one
# record per site and thread. A site inside a loop records once per iteration, beyond that count:
# outside graph capture the launch then raises, inside it the extra records are dropped silently.
# MJWarp's `smooth` module has such loops: its mass-matrix kernel (`crb`'s `_M`) adds into each
# dof's row once per ancestor dof. Its bound is the deepest chain of dofs of any scene mwjax
# builds (8: the arm's 7 joints and a finger; `tests/test_determinism.py` checks every scene).
LOOP_RECORDS = {"mujoco.mjx.third_party.mujoco_warp._src.smooth": 8}

# MJWarp's elliptic-cone Hessian kernel adds one record per contact it visits, and on a GPU each
# thread visits ceil(naconmax / dim_block) contacts, dim_block = ceil(sm_count * 6 * 256 / ntri)
# (`solver.py`, mujoco-mjx 3.17; on a CPU dim_block = naconmax, one contact per thread): its bound
# grows with the contact buffer, i.e. with the batch. A bound on the whole solver module would size
# every solver kernel's record buffers by it, so the mode gives this kernel a module of its own.
CONE_HESSIAN = "_update_gradient_JTCJ_dense"


def enable() -> None:
    """Deterministic Warp kernels and XLA ops for the rest of the process (see the module doc)."""
    import mujoco.mjx.third_party.mujoco_warp  # noqa: F401  (defines the modules set below)

    mode = warp.DeterministicMode.RUN_TO_RUN
    warp.config.deterministic = mode
    # Modules that exist already (all of MJWarp's, imported above) take the options too; they are
    # rebuilt, with a new hash, at their next launch.
    for name, module in list(warp._src.context.user_modules.items()):
        options = {"deterministic": mode, "deterministic_max_records": LOOP_RECORDS.get(name, 0)}
        if any(module.options.get(k) != v for k, v in options.items()):
            module.options.update(options)
            module.mark_modified()
            module.unload()
    flags = os.environ.get("XLA_FLAGS", "")
    if XLA_FLAG in flags.split():
        return
    if _jax_backend_started():
        warnings.warn(
            f"mwjax.determinism.enable(): JAX already started its backend, so XLA's reductions stay "
            f"non-deterministic on the GPU; set MWJAX_DETERMINISTIC=1 (or XLA_FLAGS={XLA_FLAG}) "
            "before importing jax",
            RuntimeWarning,
            stacklevel=2,
        )
        return
    os.environ["XLA_FLAGS"] = f"{flags} {XLA_FLAG}".strip()


def cone_hessian_records(naconmax: int, nv: int, sm_count: int) -> int:
    """Records per thread of MJWarp's elliptic-cone Hessian kernel for `naconmax` contacts in a
    scene of `nv` dofs on a GPU of `sm_count` multiprocessors, rounded up to a power of two so
    that batches of similar size share one compiled kernel."""
    ntri = nv * (nv + 1) // 2
    per_thread = math.ceil(naconmax / math.ceil(sm_count * 6 * 256 / ntri))
    return 1 << max(0, per_thread - 1).bit_length()


def reserve_cone_hessian(naconmax: int, nv: int) -> None:
    """In the mode, make MJWarp's elliptic-cone Hessian kernel record enough for a contact buffer
    of `naconmax` contacts in a scene of `nv` dofs (on every GPU of this process); call before
    the physics that uses it first launches. A no-op outside the mode or where it suffices."""
    if not enabled():
        return
    import mujoco.mjx.third_party.mujoco_warp._src.solver as solver

    gpus = [warp.get_device(f"cuda:{i}") for i in range(warp.get_cuda_device_count())]
    bound = max((cone_hessian_records(naconmax, nv, gpu.sm_count) for gpu in gpus), default=1)
    kernel = getattr(solver, CONE_HESSIAN)
    if kernel.module.name != solver.__name__ and kernel.module.options["deterministic_max_records"] >= bound:
        return
    # The solver module's options (its mode included) come along: a re-homed kernel's are a copy.
    options = dict(kernel.module.options, deterministic_max_records=bound)
    setattr(solver, CONE_HESSIAN, warp.kernel(kernel.func, module="unique", module_options=options))


def enabled() -> bool:
    """Whether `enable()` took effect for Warp (XLA: see `XLA_FLAGS`)."""
    return warp.config.deterministic != warp.DeterministicMode.NOT_GUARANTEED


def _jax_backend_started() -> bool:
    import jax._src.xla_bridge as xla_bridge

    return bool(xla_bridge._backends)
