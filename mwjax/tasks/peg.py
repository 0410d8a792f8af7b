"""peg-insert-side: a peg to grasp and push into a hole in a box the reset moves."""

from __future__ import annotations

from mwjax.tasks.spec import TaskSpec

TASKS: tuple[TaskSpec, ...] = ()
