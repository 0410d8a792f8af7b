"""Rendering (mwjax.rendering): images that match the reference's, pixels in a jitted rollout,
Gymnasium's render modes and RecordVideo, videos. Small images (32-64 px) so it runs on a CPU."""

from __future__ import annotations

import json
import types
from pathlib import Path

import gymnasium as gym
import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

import mwjax
from mwjax import rendering
from mwjax.models import load_scene
from mwjax.tasks import get_task

FIXTURES = Path(__file__).parent / "fixtures" / "render"
FIXTURE_TASKS = ["reach-v3", "pick-place-v3", "door-open-v3", "drawer-close-v3"]
CAMERAS = ["corner", "topview", "behindGripper", "free", "corner2", "corner3", "corner4", "gripperPOV"]
# Agreement with the reference's OpenGL images (tools/record_render_fixtures.py), as measured
# (docs/rendering.md), 64 px: every image within 0.032 mean absolute difference and with >= 0.90
# of its pixels within 0.1 on every channel (mean over the 36 images 0.022 and 0.93). The bounds leave ~40%
# margin for Warp/driver rounding; a wrong camera, pose or lighting model is far outside them
# (MJWarp's own lighting: 0.17 and 0.26 on `topview`; another camera: > 0.1).
MAX_MEAN_ABS_DIFF = 0.045
MIN_WITHIN = 0.85
TOLERANCE = 0.1


def reference_capture(task: str, fixture: np.lib.npyio.NpzFile, state: int):
    """An object that `Renderer.capture` reads like an env state: the recorded reference state's
    poses (MuJoCo C kinematics of the scene with the recorded joints, mocap and moved bodies)."""
    model = load_scene(get_task(task).scene)
    data = mujoco.MjData(model)
    model.body_pos[:] = fixture["body_pos"][state]
    model.body_quat[:] = fixture["body_quat"][state]
    data.qpos[:] = fixture["qpos"][state]
    data.mocap_pos[:] = fixture["mocap_pos"][state][:1]
    data.mocap_quat[:] = fixture["mocap_quat"][state][:1]
    mujoco.mj_kinematics(model, data)
    site_xpos = fixture["site_xpos"][state]  # as the reference drew them (goal markers moved)

    def batch(x, shape=None):
        x = np.asarray(x, np.float32)
        return jnp.asarray(x.reshape(1, *(shape or x.shape)))

    physics = types.SimpleNamespace(
        geom_xpos=batch(data.geom_xpos),
        geom_xmat=batch(data.geom_xmat, (model.ngeom, 3, 3)),
        site_xpos=batch(site_xpos),
        site_xmat=batch(data.site_xmat, (model.nsite, 3, 3)),
        xpos=batch(data.xpos),
        xquat=batch(data.xquat),
    )
    goal = site_xpos[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "goal")]
    return types.SimpleNamespace(physics=(physics,), target_pos=batch(goal)), model


@pytest.fixture(scope="module")
def fixture_images():
    """mwjax's images of every fixture state, with the reference's: {(task, state, camera): (ours, ref)}."""
    out, depth = {}, {}
    for task in FIXTURE_TASKS:
        fixture = np.load(FIXTURES / f"{task}.npz")
        size = json.loads(str(fixture["meta"]))["size"]
        cameras = [c for c in CAMERAS if f"rgb/{c}" in fixture]  # the first task has every camera
        renderer = rendering.Renderer(
            mwjax.make("MT1", task=task), camera=cameras, width=size, height=size, depth=True
        )
        draw = jax.jit(renderer.draw)
        for state in range(2):
            capture, model = reference_capture(task, fixture, state)
            images = draw(renderer.capture(capture))
            for k, camera in enumerate(cameras):
                if len(fixture[f"rgb/{camera}"]) > state:
                    out[task, state, camera] = (np.asarray(images.rgb[0, k]), fixture[f"rgb/{camera}"][state])
                if f"depth/{camera}" in fixture:
                    ours = rendering.depth_buffer(np.asarray(images.depth[0, k]), model)
                    depth[task, state, camera] = (ours, fixture[f"depth/{camera}"][state])
    return out, depth


def test_images_match_the_reference(fixture_images):
    images, _ = fixture_images
    scores = {key: rendering.image_agreement(ours, ref, TOLERANCE) for key, (ours, ref) in images.items()}
    bad = {key: s for key, s in scores.items() if s[0] > MAX_MEAN_ABS_DIFF or s[1] < MIN_WITHIN}
    assert not bad, bad
    assert np.mean([s[0] for s in scores.values()]) < 0.03
    # The metric tells cameras apart: mwjax's corner view against the reference's topview.
    ours, _ = images["pick-place-v3", 0, "corner"]
    _, other = images["pick-place-v3", 0, "topview"]
    assert rendering.image_agreement(ours, other)[0] > 0.1


def test_the_moving_parts_match_the_reference(fixture_images):
    """The whole-image scores are dominated by the static scene: the reference's own two states
    (the arm 40 expert steps apart) score 0.01-0.045 and 0.81-0.95 against each other. On the
    pixels where those two differ (the arm and what it moved), mwjax's image of a state agrees
    with the reference's image of the same state (measured >= 0.64 within 0.1) and not with the
    other state's (<= 0.25)."""
    images, _ = fixture_images
    for task, state, camera in images:
        if state != 0 or (task, 1, camera) not in images:
            continue
        refs = [images[task, s, camera][1] for s in range(2)]
        moved = np.abs(refs[0].astype(int) - refs[1].astype(int)).max(axis=-1) > 25
        assert moved.sum() > 100, (task, camera)
        for s in range(2):
            ours = images[task, s, camera][0]
            same = rendering.image_agreement(ours, refs[s], TOLERANCE, mask=moved)[1]
            other = rendering.image_agreement(ours, refs[1 - s], TOLERANCE, mask=moved)[1]
            assert same >= 0.5 and same > other + 0.3, (task, s, camera, same, other)


def test_depth_matches_the_reference(fixture_images):
    _, depth = fixture_images
    for key, (ours, ref) in depth.items():
        error = np.abs(ours - ref)
        # Depth-buffer values; 1e-3 is ~2 cm at 1 m. Edge pixels differ (no multisampling here).
        assert np.median(error) < 1e-3 and np.mean(error < 1e-3) > 0.9, key


def test_camera_kwargs():
    assert rendering.camera_name() == "free"
    assert rendering.camera_name(camera_id=-1) == "free"
    assert rendering.camera_name(camera_id=1) == "corner"
    assert rendering.camera_name("behindGripper") == "behindGripper"
    with pytest.raises(ValueError):
        rendering.camera_name("corner", 1)
    with pytest.raises(ValueError):
        rendering.camera_name("nope")
    with pytest.raises(ValueError):
        rendering.camera_name(camera_id=7)


@pytest.mark.parametrize("size", [{"width": 0}, {"height": -32}, {"width": 32.0}, {"height": True}])
def test_image_sizes_that_are_not_positive_ints_are_refused_when_the_env_is_made(size):
    with pytest.raises(ValueError, match="width and height must be positive ints"):
        gym.make_vec("mwjax/MT1", env_name="reach-v3", num_envs=1, render_mode="rgb_array", **size)


def test_image_sizes_may_be_numpy_ints():
    assert rendering.image_size(np.int64(48), 32) == (48, 32)


@pytest.fixture(scope="module")
def rollout():
    """A jitted `lax.scan` of pixel observations (32x32, corner) while the hand moves forward."""
    env = rendering.PixelObservations(
        mwjax.make("MT1", task="reach-v3"), camera="corner", width=32, height=32
    )
    first = jax.jit(env.reset)(jax.random.key(0))
    action = jnp.tile(jnp.array([[0.0, 1.0, 0.0, 0.0]]), (env.num_envs, 1))

    def body(state, _):
        state = env.step(state, action)
        return state, (state.pixels, env.renderer.capture(state.state))

    last, (pixels, captures) = jax.jit(lambda s: jax.lax.scan(body, s, None, length=15))(first)
    return env, np.asarray(first.pixels), np.asarray(pixels), captures


def test_pixel_observations_in_a_jitted_scan(rollout):
    env, first, pixels, _ = rollout
    assert first.shape == (1, 32, 32, 3) and first.dtype == np.uint8
    assert pixels.shape == (15, 1, 32, 32, 3) and pixels.dtype == np.uint8
    image = first[0]
    assert image.std() > 10 and len(np.unique(image.reshape(-1, 3), axis=0)) > 50


def test_the_arm_moves_in_the_images(rollout):
    _, first, pixels, _ = rollout
    before, after = first[0].astype(int), pixels[-1, 0].astype(int)
    changed = np.abs(before - after).max(axis=-1) > 30
    assert changed.sum() >= 20
    # What changed is the (red) arm, in the lower-left part of the corner view where it stands.
    red = lambda im: im[..., 0] > im[..., 1] + 40  # noqa: E731
    assert (changed & (red(before) | red(after))).sum() >= 0.8 * changed.sum()
    rows, cols = np.nonzero(changed)
    assert rows.mean() > 12 and cols.mean() < 20


def test_transparent_geoms_are_left_out_of_the_bvh_and_no_pixel_changes(rollout, monkeypatch):
    """The ray tracer's scene BVH holds only geoms a ray can hit: the arm's transparent collision
    shapes move to an undrawn group (fewer boxes for every ray to cross), and every pixel of the
    rollout's last frame is as with them in the BVH."""
    env, _, _, captures = rollout
    ((_, _, group),) = env.renderer._groups
    visible = rendering._visible_geoms_model(group.model)
    moved = np.flatnonzero(visible.geom_group != group.model.geom_group)
    assert len(moved) >= 6 and set(visible.geom_group[moved]) == {3}
    last = jax.tree.map(lambda x: x[-1], captures)
    draw = lambda renderer: np.asarray(jax.jit(renderer.draw)(last).rgb)  # noqa: E731
    lean = draw(rendering.Renderer(env.env, camera="corner", width=32, height=32))
    monkeypatch.setattr(rendering, "_visible_geoms_model", lambda model: model)
    every_geom = draw(rendering.Renderer(env.env, camera="corner", width=32, height=32))
    assert lean.std() > 10 and np.array_equal(lean, every_geom)


def test_pixel_observations_vmapped_over_keys_are_each_keys_own():
    """Pixel observations under an outer `jax.vmap` (over seeds, say) render every instance's envs
    in one call with a context made for all of them; each instance's images, the per-env free
    camera's included, are those it renders alone."""
    env = rendering.PixelObservations(
        mwjax.make("MT1", task="reach-v3", envs_per_task=2), camera=["corner", "free"], width=16, height=16
    )
    keys = jax.random.split(jax.random.key(2), 3)
    together = jax.jit(jax.vmap(env.reset))(keys)
    assert together.pixels.shape == (3, 2, 2, 16, 16, 3)
    for i, key in enumerate(keys):
        alone = jax.jit(env.reset)(key)
        np.testing.assert_array_equal(np.asarray(together.pixels[i]), np.asarray(alone.pixels))
    assert np.asarray(together.pixels).std() > 10


def test_record_video_of_a_rollout(rollout, tmp_path):
    env, _, pixels, captures = rollout
    path = rendering.record_video(env.renderer, captures, tmp_path / "reach.gif")
    from PIL import Image

    with Image.open(path) as gif:
        assert gif.n_frames == 15 and gif.size == (32, 32)
    # The built-in writer (no Pillow) decodes to the same frame count.
    raw = tmp_path / "raw.gif"
    raw.write_bytes(rendering._gif_bytes(pixels[:, 0], fps=20))
    with Image.open(raw) as gif:
        assert gif.n_frames == 15
        gif.seek(14)
        decoded = np.asarray(gif.convert("RGB")).astype(int)
    assert np.abs(decoded - pixels[14, 0]).max() <= 26  # the 6x7x6 palette's rounding


def test_gym_rgb_array_and_record_video(tmp_path):
    env = gym.make(
        "mwjax/MT1", env_name="reach-v3", render_mode="rgb_array", camera_name="corner", width=32, height=32
    )
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (32, 32, 3) and frame.dtype == np.uint8 and frame.std() > 10
    pytest.importorskip("moviepy")
    folder = tmp_path / "videos"
    video = gym.wrappers.RecordVideo(env, str(folder), episode_trigger=lambda _: True, video_length=4)
    video.reset(seed=0)
    for _ in range(4):
        video.step(np.array([0.0, 1.0, 0.0, 0.0], np.float32))
    video.close()
    assert [p.suffix for p in folder.iterdir()] == [".mp4"]
    assert next(folder.iterdir()).stat().st_size > 0


def test_gym_depth_array():
    env = gym.make(
        "mwjax/MT1", env_name="reach-v3", render_mode="depth_array", camera_id=0, width=32, height=32
    )
    env.reset(seed=0)
    depth = env.render()
    assert depth.shape == (32, 32) and depth.dtype == np.float32
    assert 0.9 < depth.min() < depth.max() <= 1.0


def test_gym_vector_render(tmp_path):
    envs = gym.make_vec(
        "mwjax/MT1", env_name="reach-v3", num_envs=2, render_mode="rgb_array", width=32, height=32
    )
    envs.reset(seed=0)
    frames = envs.render()  # the first env of each task by default
    assert isinstance(frames, tuple) and len(frames) == 1 and frames[0].shape == (32, 32, 3)
    everything = gym.make_vec(
        "mwjax/MT1",
        env_name="reach-v3",
        num_envs=2,
        render_mode="rgb_array",
        render_envs="all",
        width=32,
        height=32,
    )
    everything.reset(seed=0)
    frames = everything.render()
    assert len(frames) == 2 and all(f.dtype == np.uint8 for f in frames)
    assert not np.array_equal(frames[0], frames[1])  # two envs, two goals
    # Gymnasium's vector RecordVideo wants one frame per env: render_envs="all".
    pytest.importorskip("moviepy")
    folder = tmp_path / "videos"
    video = gym.wrappers.vector.RecordVideo(
        everything, str(folder), episode_trigger=lambda _: True, video_length=3
    )
    video.reset(seed=0)
    for _ in range(3):
        video.step(np.zeros((2, 4), np.float32))
    video.close()
    assert [p.suffix for p in folder.iterdir()] == [".mp4"]
