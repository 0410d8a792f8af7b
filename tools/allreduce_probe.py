"""Time NCCL all-reduces (`pmean` under `jax.shard_map`) between a run's devices: 100 in a row
inside one jitted `lax.scan`, of 1 KB and of 4 MB per device.

    python tools/allreduce_probe.py --devices 4                             # one process, 4 GPUs
    python -m mwjax.distributed --processes 4 tools/allreduce_probe.py      # one process per GPU
    NCCL_DEBUG=INFO ...                                                     # and NCCL's transports

A data-parallel PPO update makes ~150 of them; this tells whether they cost what an update loses.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import jax
import numpy as np
from jax.sharding import Mesh, NamedSharding
from jax.sharding import PartitionSpec as P

sys.path.insert(0, str(Path(__file__).parents[1]))
from mwjax import distributed  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--devices", type=int, default=None, help="devices to use (default: all)")
    args = parser.parse_args()
    distributed.initialize()
    devices = jax.devices()[: args.devices]
    mesh = Mesh(np.array(devices), ("d",))
    sharding = NamedSharding(mesh, P("d"))
    mode = f"{jax.process_count()} process(es), {len(devices)} devices"
    for size in (256, 1 << 20):  # float32 values per device
        x = jax.make_array_from_callback(
            (len(devices), size), sharding, lambda i, size=size: np.ones((1, size), np.float32)
        )
        mean = jax.shard_map(
            lambda a: jax.lax.pmean(a, "d") * 1.0001, mesh=mesh, in_specs=P("d"), out_specs=P("d")
        )
        run = jax.jit(lambda x, mean=mean: jax.lax.scan(lambda c, _: (mean(c), None), x, None, length=100)[0])
        run(x).block_until_ready()
        t0 = time.perf_counter()
        run(x).block_until_ready()
        if distributed.is_main():
            print(
                f"{mode}: 100 all-reduces of {size * 4} bytes: {(time.perf_counter() - t0) * 10:.3f} ms each"
            )


if __name__ == "__main__":
    main()
