"""Equality constraints' reference acceleration as MuJoCo 3.3.0, the reference's engine, computes it.

MuJoCo after 3.3.0 subtracts a velocity-product term, Jdot * qvel, from the reference
acceleration (`efc_aref`) of every connect and weld constraint row; MuJoCo C 3.17 and MJX-Warp
3.17 both do, and no option turns it off. The Sawyer hand of every Meta-World task follows its
mocap target through a weld, so the term changes how the arm moves at every step: from the same
start, the 250 physics steps of a reset's hand settling end up to 7e-3 rad apart in the arm's
joints between 3.3.0 and 3.17 (MuJoCo C on both sides), and 2e-6 apart between 3.3.0 and
MJX-Warp without the term (docs/fidelity.md).

`install()` gives MJX-Warp 3.3.0's rows: it replaces the row writer that MJWarp's constraint
kernels call (`_efc_row`) with one that drops the shift, which only connect and weld rows pass.
Warp resolves the function when it first builds a constraint kernel, so this must run before
any MJX-Warp step; `mwjax.physics` installs it on import.
"""

import inspect
import threading

import warp as wp
from mujoco.mjx.third_party.mujoco_warp._src import constraint
from mujoco.mjx.third_party.mujoco_warp._src.types import vec5

# The row writer as MJWarp defines it; the replacement forwards every argument but the shift.
_efc_row_with_shift = constraint._efc_row
_lock = threading.Lock()
_installed = False


@wp.func
def _efc_row_without_shift(
    opt_disableflags: int,
    worldid: int,
    timestep: float,
    efcid: int,
    pos_aref: float,
    pos_imp: float,
    invweight: float,
    solref: wp.vec2,
    solimp: vec5,
    margin: float,
    vel: float,
    frictionloss: float,
    type: int,
    id: int,
    is_discrete: bool,
    aref_shift: float,
    type_out: wp.array2d[int],
    id_out: wp.array2d[int],
    pos_out: wp.array2d[float],
    margin_out: wp.array2d[float],
    D_out: wp.array2d[float],
    vel_out: wp.array2d[float],
    aref_out: wp.array2d[float],
    frictionloss_out: wp.array2d[float],
) -> None:
    _efc_row_with_shift(
        opt_disableflags,
        worldid,
        timestep,
        efcid,
        pos_aref,
        pos_imp,
        invweight,
        solref,
        solimp,
        margin,
        vel,
        frictionloss,
        type,
        id,
        is_discrete,
        0.0,
        type_out,
        id_out,
        pos_out,
        margin_out,
        D_out,
        vel_out,
        aref_out,
        frictionloss_out,
    )


def install() -> None:
    """Make MJWarp's constraint kernels write 3.3.0's equality rows (idempotent)."""
    global _installed
    with _lock:
        if _installed:
            return
        expected = list(inspect.signature(_efc_row_without_shift.func).parameters)
        found = list(inspect.signature(_efc_row_with_shift.func).parameters)
        if found != expected:
            raise RuntimeError(
                "mujoco-mjx's MJWarp `_efc_row` changed signature; mwjax's equality-row patch "
                f"expects {expected}, found {found}"
            )
        constraint._efc_row = _efc_row_without_shift
        _installed = True


def installed() -> bool:
    """Whether MJWarp's constraint kernels use 3.3.0's equality rows in this process."""
    return constraint._efc_row is _efc_row_without_shift
