"""Pick an object and place it: pick-out-of-hole, shelf-place, bin-picking."""

from __future__ import annotations

from mwjax.tasks.spec import TaskSpec

TASKS: tuple[TaskSpec, ...] = ()
