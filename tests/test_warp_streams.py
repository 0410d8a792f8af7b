"""The workaround for Warp's not reference-counted external stream registration."""

import gc

import pytest
import warp as wp

import mwjax.physics  # noqa: F401  (installs the workaround)
from mwjax import warp_streams


@pytest.mark.gpu
def test_capture_on_a_stream_whose_older_wrapper_was_collected():
    """Warp's JAX callback wraps XLA's stream anew at every capture. An older wrapper of it that
    the cyclic collector deletes must not unregister the stream under a newer one: without the
    workaround, the capture below fails with 'Warp error: unknown stream'."""
    device = wp.get_cuda_device()
    owned = wp.Stream(device)
    handle = owned.cuda_stream
    older = wp.Stream(device, cuda_stream=handle)
    newer = wp.Stream(device, cuda_stream=handle)
    assert warp_streams.live_wrappers(int(handle)) == 2
    del older
    gc.collect()
    assert warp_streams.live_wrappers(int(handle)) == 1
    values = wp.zeros(8, dtype=float, device=device)
    with wp.ScopedStream(newer, sync_enter=False):
        with wp.ScopedCapture() as capture:
            values.fill_(2.0)
        wp.capture_launch(capture.graph)
    wp.synchronize_stream(newer)
    assert values.numpy().tolist() == [2.0] * 8
    del newer
    gc.collect()
    assert warp_streams.live_wrappers(int(handle)) == 0
