#!/usr/bin/env python
"""Record the reference scripted experts' actions on reference observations (metaworld==3.1.1).

Runs in the reference venv (see tools/README_reference.md); never imports mwjax. For every v3
task: `metaworld.MT1(task, seed=42)`, goal variants 0..E-1, one episode each of T steps driven
by the task's expert, episode 0 as is, later ones with Gaussian noise on the executed action
(sd 0.1 x episode index) so that the experts' branches are visited off their own path. Each step
stores the observation (float32, as mwjax sees it) and the expert's action *for that float32
observation*, so a port can be checked exactly, without any physics.

    .venv-ref/bin/python tools/record_expert_actions.py   # -> tests/fixtures/reference/expert_actions.npz
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import warnings
from importlib import metadata

import metaworld
import metaworld.env_dict as mw_env_dict
import metaworld.policies as mw_policies
import numpy as np


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--out", default="tests/fixtures/reference/expert_actions.npz")
    parser.add_argument("--seed", type=int, default=42)
    parser.add_argument("--episodes", type=int, default=3)
    parser.add_argument("--steps", type=int, default=150)
    args = parser.parse_args()
    warnings.filterwarnings("ignore")  # the experts warn whenever a response exceeds 1

    arrays: dict[str, np.ndarray] = {}
    noise_rng = np.random.RandomState(args.seed)
    for task in mw_env_dict.ALL_V3_ENVIRONMENTS:
        bench = metaworld.MT1(task, seed=args.seed)
        env = bench.train_classes[task]()
        policy = mw_policies.ENV_POLICY_MAP[task]()
        obs_rows, action_rows, successes = [], [], []
        for episode in range(args.episodes):
            env.set_task(bench.train_tasks[episode])
            obs, _ = env.reset()
            solved = False
            for _ in range(args.steps):
                obs32 = obs.astype(np.float32)
                action = policy.get_action(obs32.astype(np.float64))
                obs_rows.append(obs32)
                action_rows.append(np.asarray(action, np.float32))
                executed = action + noise_rng.normal(0.0, 0.1 * episode, size=action.shape)
                obs, _, _, _, info = env.step(np.clip(executed, -1.0, 1.0).astype(np.float32))
                solved |= bool(info["success"])
            successes.append(solved)
        arrays[f"{task}/obs"] = np.stack(obs_rows)
        arrays[f"{task}/action"] = np.stack(action_rows)
        print(f"{task:32s} solved per episode: {successes}", flush=True)
    meta = {
        "how": " ".join(shlex.quote(a) for a in sys.argv),
        "seed": args.seed,
        "episodes": args.episodes,
        "steps": args.steps,
        "versions": {p: metadata.version(p) for p in ("metaworld", "mujoco", "numpy")},
    }
    np.savez_compressed(args.out, meta=json.dumps(meta), **arrays)


if __name__ == "__main__":
    main()
