"""The coffee machine: coffee-button, coffee-pull, coffee-push."""

from __future__ import annotations

from mwjax.tasks.spec import TaskSpec

TASKS: tuple[TaskSpec, ...] = ()
