"""The task registry: every ported Meta-World v3 task, by its reference name."""

from __future__ import annotations

from mwjax.tasks import (
    articulated,
    assembly,
    ball,
    box_close,
    coffee,
    handles,
    peg,
    placing,
    plate_slide,
    reach_push_pick_place,
    rotary,
    tool_use,
)
from mwjax.tasks.spec import TaskSpec

TASKS: dict[str, TaskSpec] = {
    spec.name: spec
    for family in (
        reach_push_pick_place,
        articulated,
        peg,
        handles,
        rotary,
        plate_slide,
        assembly,
        placing,
        ball,
        tool_use,
        coffee,
        box_close,
    )
    for spec in family.TASKS
}


def get_task(name: str) -> TaskSpec:
    if name not in TASKS:
        raise ValueError(f"unknown task {name!r}; known tasks: {', '.join(sorted(TASKS))}")
    return TASKS[name]
