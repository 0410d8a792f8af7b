"""Ball tasks: basketball (pick and dunk) and soccer (push into a goal)."""

from __future__ import annotations

from mwjax.tasks.spec import TaskSpec

TASKS: tuple[TaskSpec, ...] = ()
