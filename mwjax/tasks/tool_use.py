"""Tasks where a grasped tool acts on another object: stick-push, stick-pull, hammer."""

from __future__ import annotations

from mwjax.tasks.spec import TaskSpec

TASKS: tuple[TaskSpec, ...] = ()
