"""One process per device (`python -m mwjax.distributed`): two CPU processes, one host device each,
joined into one JAX process group, against the unsharded env in one process.

The child runs this file as a script under the launcher. Each process builds the env sharded over
`jax.devices()` (both processes' devices), rolls it out jitted (autoreset inside), and gathers the
rows; each also runs the unsharded env alone on its own device. Process 0 saves both, and the
test compares them row for row, bit for bit. XLA's CPU instruction set is capped at AVX as in
tests/test_sharding.py (with FMA, a device's share of the batch may round a reward differently).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import children
import numpy as np
import pytest

from mwjax import distributed

TASKS = ["reach-v3", "push-v3"]  # one scene, two tasks: rows of both tasks on each device
EPISODE, STEPS = 4, 7  # every env resets inside the rollout


def _child(workdir: Path) -> tuple[list[str], dict[str, str]]:
    flags = os.environ.get("XLA_FLAGS", "")
    env = {**os.environ, "XLA_FLAGS": f"{flags} --xla_cpu_max_isa=AVX".strip()}
    argv = [sys.executable, "-m", "mwjax.distributed", "--processes", "2", "--cpu", __file__, str(workdir)]
    return argv, env


@pytest.mark.child.with_args(_child)
def test_two_processes_step_the_unsharded_envs_rows(request):
    result, workdir = children.result(request.node)
    assert result.returncode == 0, (result.stdout + result.stderr)[-6000:]
    runs = np.load(workdir / "rollouts.npz")
    assert int(runs["processes"]) == 2 and int(runs["local_devices"]) == 1
    order = runs["row_order"]
    for name in ("obs", "reward", "success", "truncated"):
        unsharded = runs[f"unsharded_{name}"][:, order]
        np.testing.assert_array_equal(runs[f"sharded_{name}"], unsharded, err_msg=name)
    assert runs["sharded_truncated"].any()  # the rollout crossed an episode end


def test_launch_stops_the_others_when_one_process_fails(tmp_path):
    script = tmp_path / "fails.py"
    script.write_text(
        "import os, sys, time\n"
        f"if os.environ['{distributed.PROCESS_ID}'] == '1':\n"
        "    sys.exit(3)\n"
        "time.sleep(120)\n"
    )
    t0 = time.perf_counter()
    assert distributed.launch([str(script)], 2, cpu=True) == 3
    assert time.perf_counter() - t0 < 60  # process 0 was stopped, not waited for


def test_launch_refuses_more_processes_than_gpus(monkeypatch):
    monkeypatch.setenv("CUDA_VISIBLE_DEVICES", "0")
    with pytest.raises(ValueError, match="2 processes need 2 GPUs, 1 visible"):
        distributed.launch(["script.py"], 2)
    with pytest.raises(ValueError, match="at least 1"):
        distributed.launch(["script.py"], 0, cpu=True)


def test_initialize_does_nothing_outside_the_launcher(monkeypatch):
    monkeypatch.delenv(distributed.PROCESS_ID, raising=False)
    assert distributed.initialize() is False
    assert distributed.is_main()


def test_each_process_gets_its_own_gpu():
    env = distributed.process_env(1, 2, "localhost:1", ["4", "6"])
    assert env["CUDA_VISIBLE_DEVICES"] == "6"
    assert env["MWJAX_PROGRESS"] == "0"  # process 0's progress lines are the run's
    assert (env[distributed.PROCESS_ID], env[distributed.NUM_PROCESSES]) == ("1", "2")
    cpu = distributed.process_env(0, 2, "localhost:1", None)
    assert cpu["JAX_PLATFORMS"] == "cpu" and "device_count" not in cpu["XLA_FLAGS"]


def _rollouts(out: Path) -> None:
    """In each launched process: the sharded and the unsharded rollout; process 0 saves them."""
    assert distributed.initialize()
    import jax
    from jax._src import distributed as jax_distributed
    from jax.experimental import multihost_utils

    import mwjax

    # 4 envs per task, as in tests/test_sharding.py: with 2 rows per device, XLA's CPU code
    # rounds a reward term 1 ulp away from the whole batch's.
    env = mwjax.make(TASKS, envs_per_task=4, seed=3, max_episode_steps=EPISODE, devices=jax.devices())
    actions = jax.random.uniform(jax.random.key(1), (STEPS, env.num_envs, 4), minval=-1.0, maxval=1.0)

    def rollout(env: mwjax.Env, actions: jax.Array) -> dict:
        def body(state: mwjax.State, action: jax.Array) -> tuple:
            state = env.step(state, action)
            return state, {
                "obs": state.obs,
                "reward": state.reward,
                "success": state.info["success"],
                "truncated": state.truncated,
            }

        return jax.lax.scan(body, env.reset(jax.random.key(0)), actions)[1]

    sharded = jax.block_until_ready(jax.jit(lambda a: rollout(env, a))(actions))
    # Gloo gives a process 30 s to meet the other at its first collective (the allgather); under
    # load (the suite's other children) one process came more than 30 s after the other. The
    # coordination service's barrier waits as long as it is told.
    jax_distributed.global_state.client.wait_at_barrier("mwjax-allgather", 600_000)
    sharded = multihost_utils.process_allgather(sharded, tiled=True)
    alone = env.replace(devices=None)
    unsharded = jax.device_get(jax.jit(lambda a: rollout(alone, a))(actions[:, np.argsort(env.row_order)]))
    if distributed.is_main():
        np.savez(
            out / "rollouts.npz",
            processes=jax.process_count(),
            local_devices=jax.local_device_count(),
            row_order=env.row_order,
            **{f"sharded_{k}": np.asarray(v) for k, v in sharded.items()},
            **{f"unsharded_{k}": np.asarray(v) for k, v in unsharded.items()},
        )


if __name__ == "__main__":
    _rollouts(Path(sys.argv[1]))


def test_the_gymnasium_adapter_takes_this_processs_devices_only():
    from types import SimpleNamespace

    from mwjax.wrappers.gymnasium import make_vector

    other_process = SimpleNamespace(process_index=1, platform="gpu")
    with pytest.raises(ValueError, match="devices=jax.local_devices()"):
        make_vector("MT1", task="reach-v3", envs_per_task=2, devices=[other_process])


def test_independent_runs_take_turns_and_report_each_exit(tmp_path, monkeypatch):
    script = tmp_path / "run.py"
    code = "import sys, time\ntime.sleep(0.5)\nprint('ran', sys.argv[1])\nsys.exit(int(sys.argv[1]))\n"
    script.write_text(code)
    logs = [tmp_path / f"{i}.log" for i in range(3)]
    t0 = time.perf_counter()
    codes = distributed.run_independent([[str(script), str(i)] for i in range(3)], logs, 2, cpu=True)
    assert codes == [0, 1, 2]
    assert [log.read_text().strip() for log in logs] == ["ran 0", "ran 1", "ran 2"]
    assert time.perf_counter() - t0 >= 1.0  # two at a time: the third waited for a slot
    monkeypatch.setenv("CUDA_VISIBLE_DEVICES", "0")
    with pytest.raises(ValueError, match="2 processes at a time need 2 GPUs, 1 visible"):
        distributed.run_independent([[str(script), "0"]], logs[:1], 2)


def test_independent_runs_stop_in_order_on_sigterm(tmp_path):
    """A time limit's SIGTERM ends the running runs and returns, keeping the finished one's code
    (what lets a training script still write the summary of the seeds that finished)."""
    run = tmp_path / "run.py"
    run.write_text("import sys, time\ntime.sleep(float(sys.argv[1]))\nprint('ran')\n")
    driver = tmp_path / "driver.py"
    driver.write_text(
        "from pathlib import Path\nfrom mwjax import distributed\n"
        f"logs = [Path({str(tmp_path)!r}) / f'{{i}}.log' for i in range(3)]\n"
        f"commands = [[{str(run)!r}, seconds] for seconds in ('0', '600', '0')]\n"
        "print('codes', distributed.run_independent(commands, logs, 2, cpu=True), flush=True)\n"
    )
    output = tmp_path / "driver.log"
    with open(output, "w") as out:
        process = subprocess.Popen([sys.executable, str(driver)], stdout=out, cwd=Path(__file__).parents[1])
    deadline = time.perf_counter() + 60
    while "run 3/3 done" not in output.read_text():  # runs 1 and 3 done, run 2 sleeping
        assert time.perf_counter() < deadline and process.poll() is None
        time.sleep(0.2)
    process.send_signal(signal.SIGTERM)
    assert process.wait(timeout=30) == 0
    out = output.read_text()
    assert f"codes [0, {-int(signal.SIGTERM)}, 0]" in out
    assert "interrupted: runs [2] stopped or never started" in out
