"""Tasks on a hinged or sliding fixture that the reset moves: door, drawer, window, button."""

from __future__ import annotations

from mwjax.tasks.spec import TaskSpec

TASKS: tuple[TaskSpec, ...] = ()
