"""What an env is built from: `EnvConfig`, the arguments of `mwjax.make`, checked and frozen.

An `Env` keeps its config; `env.replace(**changes)` builds a new env from a copy of it with some
fields changed. Fields left `None` take a default that depends on the task set (ML sets hide the
goal and resample goals only on request), which the `Env` resolves.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

from mwjax import benchmarks
from mwjax.physics import PhysicsConfig

# The reference env's `max_path_length`.
MAX_EPISODE_STEPS = 500
AUTORESET_MODES = ("same_step", "next_step", "disabled")
GOAL_SAMPLING = ("on_reset", "on_request")


@dataclasses.dataclass(frozen=True)
class EnvConfig:
    """A batched task set, as `mwjax.make` describes it (see its docstring for the task sets)."""

    tasks: str | Sequence[str] | benchmarks.Benchmark
    envs_per_task: int = 1
    seed: int = 0
    reward_version: str = "v2"
    split: str = "train"
    # The task of "MT1"/"ML1".
    task: str | None = None
    # Goal zeroed in observations; by default, for ML sets.
    partially_observable: bool | None = None
    max_episode_steps: int = MAX_EPISODE_STEPS
    autoreset: str = "same_step"
    terminate_on_success: bool = False
    # "on_reset" draws a goal variant at every reset, "on_request" only at `sample_goals`; by
    # default, "on_request" for ML sets.
    goal_sampling: str | None = None
    # The first this many of each task's goal variants; by default all of them.
    variants_per_task: int | None = None
    physics: PhysicsConfig | None = None
    # Caller-chosen goal variants, `{task: (n, d)}`, instead of the set's sampled ones.
    goal_variants: Mapping[str, Any] | None = None

    def __post_init__(self) -> None:
        if self.reward_version not in ("v1", "v2"):
            raise ValueError(f"reward_version must be 'v1' or 'v2', got {self.reward_version!r}")
        if not isinstance(self.envs_per_task, int) or self.envs_per_task < 1:
            raise ValueError(f"envs_per_task must be a positive int, got {self.envs_per_task!r}")
        if not isinstance(self.max_episode_steps, int) or self.max_episode_steps < 1:
            raise ValueError(f"max_episode_steps must be a positive int, got {self.max_episode_steps!r}")
        if self.autoreset not in AUTORESET_MODES:
            raise ValueError(f"autoreset must be one of {AUTORESET_MODES}, got {self.autoreset!r}")
        if self.goal_sampling is not None and self.goal_sampling not in GOAL_SAMPLING:
            raise ValueError(f"goal_sampling must be one of {GOAL_SAMPLING}, got {self.goal_sampling!r}")
        if isinstance(self.tasks, list):
            object.__setattr__(self, "tasks", tuple(self.tasks))
