"""Rendering: the reference's cameras, RGB and depth images of any env of a batch, videos, and
batched pixel observations, all through MJWarp's ray tracer (`mjx.render`, Warp on CPU or GPU:
no OpenGL, no system package).

    renderer = Renderer(env, camera="corner", width=64, height=64)   # every env of the batch
    images = jax.jit(renderer.render)(state)      # images.rgb: (num_envs, 64, 64, 3) uint8

What is drawn is the reference's scene (`metaworld==3.1.1`): its seven cameras (`CAMERAS`) and
the default free camera that `env.render()` uses when no camera is named, its lights, textures,
skybox colour, shadows and visible sites (goal and end-effector markers); images come top row
first, as Gymnasium's MuJoCo renderer returns them (the `corner` camera is upside down there too).
See docs/rendering.md for how close the images are to the reference's OpenGL ones.

The renderer reads only the poses the env carries (`State.physics`: geom, site and body poses, as
the last step or reset computed them), so it never runs physics. `capture` keeps just what
drawing needs, for the chosen envs, so that a jitted rollout can return a few envs' captures per
step and draw them afterwards (`record_video`).
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import struct
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx

from mwjax import warp_render_lighting
from mwjax.batching import merge_rows
from mwjax.env import Env, State
from mwjax.models import SCENES_DIR
from mwjax.physics import SceneGroup, _graph_mode, local_device

Array = jax.Array
warp_render_lighting.install()
LIGHTING = ("opengl", "mjwarp")

# The cameras of every Meta-World scene (`objects/assets/xyz_base.xml`), in MuJoCo's id order:
# `camera_id=i` is `CAMERAS[i]`, as in the reference.
CAMERAS = ("topview", "corner", "corner2", "corner3", "corner4", "behindGripper", "gripperPOV")
# The reference's default (no `camera_name`/`camera_id`: Gymnasium's `MujocoRenderer` looks up a
# camera "track", finds none and renders MuJoCo's free camera, id -1).
FREE_CAMERA = "free"
DEFAULT_SIZE = 480  # the reference's width and height
RENDER_FPS = 80  # the reference's metadata["render_fps"]
_FREE_NAME = "mwjax_free_camera"
_SITE_PREFIX = "mwjax_site:"
# MuJoCo's default visual options draw geom and site groups 0, 1 and 2.
_VISIBLE_GROUPS = (0, 1, 2)


def camera_name(camera_name: str | None = None, camera_id: int | None = None) -> str:
    """The camera the reference's `camera_name` / `camera_id` kwargs pick (neither: the free camera)."""
    if camera_name is not None and camera_id is not None:
        raise ValueError("Both `camera_id` and `camera_name` cannot be specified at the same time.")
    if camera_id is not None:
        if camera_id == -1:
            return FREE_CAMERA
        if not 0 <= camera_id < len(CAMERAS):
            raise ValueError(f"camera_id must be -1 or in [0, {len(CAMERAS)}), got {camera_id}")
        return CAMERAS[camera_id]
    if camera_name is None:
        return FREE_CAMERA
    if camera_name not in (*CAMERAS, FREE_CAMERA):
        raise ValueError(f"unknown camera {camera_name!r}; known: {', '.join((*CAMERAS, FREE_CAMERA))}")
    return camera_name


class Images(NamedTuple):
    """Rendered images of the chosen envs, in the order they were chosen. With one camera
    `rgb` is `(N, H, W, 3)` uint8 and `depth` `(N, H, W)` float32; with a list of cameras both
    get a camera axis after N. Depth is the distance along the camera's axis in metres, 0 where
    a ray hits nothing. Either is None when not rendered."""

    rgb: Array | None
    depth: Array | None


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class Capture:
    """What drawing reads of the chosen envs' state: per scene group, their geom and site poses,
    the poses of the bodies that cameras track, and the goal (where the `goal` site is drawn)."""

    geom_xpos: tuple[Array, ...]
    geom_xmat: tuple[Array, ...]
    site_xpos: tuple[Array, ...]
    site_xmat: tuple[Array, ...]
    body_xpos: tuple[Array, ...]
    body_xquat: tuple[Array, ...]
    target_pos: tuple[Array, ...]


@dataclasses.dataclass(frozen=True)
class _Camera:
    name: str
    mode: str  # "world" (fixed to the world), "body" (fixed to a body), "track" or "free"
    body: int  # index into the captured bodies ("body", "track")
    pos: np.ndarray
    mat: np.ndarray


class _Group:
    """The renderer of one scene group: its visual model (the scene with site markers as geoms
    and the free camera added), the MJWarp render context for its chosen rows, and the maps from
    the env's poses to the visual model's geoms."""

    def __init__(
        self,
        group: SceneGroup,
        rows: np.ndarray,
        cameras: Sequence[str],
        free_lookat: np.ndarray,
        width: int,
        height: int,
        rgb: bool,
        depth: bool,
        shadows: bool,
        samples_per_pixel: int,
        sites: bool,
        lighting: str,
        graph_mode: str | None,
    ) -> None:
        self.rows = rows  # local rows of the group
        host = group.model
        model, geom_source = _visual_model(group.scene, host, sites)
        self.model = model
        # Render geom j takes pose `geom_source[j]` of concat(env geoms, env sites).
        self.geom_source = jnp.asarray(geom_source)
        self.goal_sites = np.array(
            [i for i in range(host.nsite) if host.site_bodyid[i] == 0 and host.site(i).name == "goal"], int
        )
        bodies: list[int] = []
        self.cameras: list[_Camera] = []
        for name in cameras:
            self.cameras.append(_camera(model, host, name, bodies, free_lookat))
        self.bodies = np.array(bodies, int)
        self.light_xpos = jnp.asarray(model.light_pos, jnp.float32)
        self.light_xdir = jnp.asarray(model.light_dir, jnp.float32)
        if np.any(model.light_bodyid != 0) or np.any(model.light_mode != mujoco.mjtCamLight.mjCAMLIGHT_FIXED):
            raise NotImplementedError(f"{group.scene}: only lights fixed to the world are supported")
        device = local_device()
        mode = _graph_mode(graph_mode)
        self.device_model = mjx.put_model(model, device=device, impl="warp", graph_mode=mode)
        skybox = model.tex_type == mujoco.mjtTexture.mjTEXTURE_SKYBOX
        self._new_context = functools.partial(
            mjx.create_render_context,
            mjm=_visible_geoms_model(model),
            cam_res=(width, height),
            render_rgb=rgb,
            render_depth=depth,
            use_textures=True,
            use_shadows=shadows,
            enabled_geom_groups=list(_VISIBLE_GROUPS),
            cam_active=[c.name if c.mode != "free" else _FREE_NAME for c in self.cameras],
            render_skybox=bool(np.any(skybox)),
            samples_per_pixel=samples_per_pixel,
            # OpenGL's shadow maps leave a blocked light nothing; MJWarp's default leaves 0.3.
            **({"shadow_light_fraction": 0.0} if lighting == "opengl" else {}),
        )
        self._opengl_lighting = lighting == "opengl"
        self._device = device
        # Per batch size: the rows chosen, or (under an outer vmap, `merge_rows`) all instances'.
        self._contexts: dict[int, Any] = {}
        self._makers: dict[int, Callable[[], mjx.Data]] = {}
        context = self._context(len(rows))
        self.rgb_adr = [int(a) for a in context.rgb_adr.numpy()]
        self.depth_adr = [int(a) for a in context.depth_adr.numpy()]
        self.width, self.height = width, height

    def _context(self, nworld: int) -> Any:
        if nworld not in self._contexts:
            context = self._new_context(nworld=nworld)
            if self._opengl_lighting:
                warp_render_lighting.use_opengl_lighting(context)
            self._contexts[nworld] = context
        return self._contexts[nworld]

    def _make_data(self, nworld: int) -> mjx.Data:
        if nworld not in self._makers:
            model, device = self.model, self._device
            self._makers[nworld] = jax.jit(
                lambda: jax.vmap(lambda _: mjx.make_data(model, device, impl="warp"))(jnp.arange(nworld))
            )
        return self._makers[nworld]()

    def capture(self, state: State, start: int, g: int) -> tuple[Array, ...]:
        physics = state.physics[g]
        rows = jnp.asarray(self.rows)
        target = state.target_pos[start + self.rows]
        return (
            physics.geom_xpos[rows],
            physics.geom_xmat[rows],
            physics.site_xpos[rows],
            physics.site_xmat[rows],
            physics.xpos[rows][:, self.bodies],
            physics.xquat[rows][:, self.bodies],
            target,
        )

    def draw(self, captured: tuple[Array, ...]) -> tuple[list[Array], list[Array]]:
        """Images of the captured rows (what `capture` returns); under an outer `jax.vmap`, of
        every instance's rows in one render call with a context made for all of them (`merge_rows`)."""
        return merge_rows(self._draw_rows)(captured)

    def _draw_rows(self, captured: tuple[Array, ...]) -> tuple[list[Array], list[Array]]:
        geom_xpos, geom_xmat, site_xpos, site_xmat, body_xpos, body_xquat, target = captured
        n = geom_xpos.shape[0]
        if len(self.goal_sites):
            site_xpos = site_xpos.at[:, self.goal_sites].set(target[:, None, :])
        pos = jnp.concatenate([geom_xpos, site_xpos], axis=1)[:, self.geom_source]
        mat = jnp.concatenate([geom_xmat, site_xmat.reshape(n, -1, 3, 3)], axis=1)[:, self.geom_source]
        cam_pos, cam_mat = self._camera_poses(body_xpos, body_xquat)
        data = self._make_data(n)
        data = data.replace(
            geom_xpos=pos.astype(jnp.float32),
            geom_xmat=mat.reshape(data.geom_xmat.shape).astype(jnp.float32),
            cam_xpos=_all_cameras(data.cam_xpos, self._cam_ids(), cam_pos),
            cam_xmat=_all_cameras(data.cam_xmat, self._cam_ids(), cam_mat),
        )
        impl = data._impl.replace(
            light_xpos=jnp.broadcast_to(self.light_xpos, data._impl.light_xpos.shape),
            light_xdir=jnp.broadcast_to(self.light_xdir, data._impl.light_xdir.shape),
        )
        data = data.replace(_impl=impl)
        context = self._context(n).pytree()
        data = jax.vmap(mjx.refit_bvh, in_axes=(None, 0, None))(self.device_model, data, context)
        packed_rgb, packed_depth, _ = jax.vmap(mjx.render, in_axes=(None, 0, None))(
            self.device_model, data, context
        )
        pixels = self.width * self.height
        rgbs, depths = [], []
        for k in range(len(self.cameras)):
            if self.rgb_adr[k] >= 0:
                packed = packed_rgb[:, self.rgb_adr[k] : self.rgb_adr[k] + pixels]
                channels = [(packed >> shift) & 0xFF for shift in (16, 8, 0)]
                rgbs.append(jnp.stack(channels, -1).astype(jnp.uint8).reshape(n, self.height, self.width, 3))
            if self.depth_adr[k] >= 0:
                raw = packed_depth[:, self.depth_adr[k] : self.depth_adr[k] + pixels]
                depths.append(raw.reshape(n, self.height, self.width).astype(jnp.float32))
        return rgbs, depths

    def _cam_ids(self) -> list[int]:
        return [_camera_id(self.model, c.name if c.mode != "free" else _FREE_NAME) for c in self.cameras]

    def _camera_poses(self, body_xpos: Array, body_xquat: Array) -> tuple[Array, Array]:
        n = body_xpos.shape[0]
        positions, mats = [], []
        for camera in self.cameras:
            # A free camera's pose is per chosen row; merged instances repeat the rows.
            pos, mat = (jnp.asarray(a, jnp.float32) for a in (camera.pos, camera.mat))
            if pos.ndim == 2:
                pos, mat = jnp.tile(pos, (n // len(pos), 1)), jnp.tile(mat, (n // len(mat), 1, 1))
            pos, mat = jnp.broadcast_to(pos, (n, 3)), jnp.broadcast_to(mat, (n, 3, 3))
            if camera.mode == "track":
                pos = body_xpos[:, camera.body] + pos
            elif camera.mode == "body":
                rot = jax.vmap(_quat_to_mat)(body_xquat[:, camera.body])
                pos = body_xpos[:, camera.body] + jnp.einsum("nij,nj->ni", rot, pos)
                mat = rot @ mat
            positions.append(pos)
            mats.append(mat)
        return jnp.stack(positions, 1), jnp.stack(mats, 1)


class Renderer:
    """Renders chosen envs of an `mwjax.Env` batch from one camera or several.

    `envs`: env indices (rows of the batch) to render, in the order images come out; None for
    all. `camera`: a name of `CAMERAS`, `"free"` (the reference's default view), a camera id
    (-1 is the free camera), or a list of them (images then get a camera axis). `rgb` / `depth`:
    which images to make. `shadows`: the scene's shadow-casting light casts shadows, as in the
    reference (costs a second ray per pixel). `samples_per_pixel`: n gives n x n supersampling
    (the reference's OpenGL renders with 4x multisampling). `sites`: draw the visible sites (the
    goal marker at the task's goal, end-effector markers), as the reference does. `lighting`:
    "opengl" lights surfaces as MuJoCo's OpenGL renderer does (`mwjax.warp_render_lighting`),
    "mjwarp" as MJWarp's ray tracer does (brighter where textures face the lights).
    `graph_mode`: who captures the render calls' CUDA graphs, as `PhysicsConfig.graph_mode`
    (default: the env's).

    `render` and `capture`/`draw` are pure JAX functions of the state (jit them, use them in
    `lax.scan`); the batch size of each scene is fixed at construction (under an outer `jax.vmap`,
    one batch of every instance's rows).
    """

    def __init__(
        self,
        env: Env,
        camera: str | int | Sequence[str | int] = "corner",
        width: int = DEFAULT_SIZE,
        height: int = DEFAULT_SIZE,
        envs: Sequence[int] | None = None,
        rgb: bool = True,
        depth: bool = False,
        shadows: bool = True,
        samples_per_pixel: int = 1,
        sites: bool = True,
        lighting: str = "opengl",
        graph_mode: str | None = None,
    ) -> None:
        if not (rgb or depth):
            raise ValueError("render rgb, depth or both")
        if lighting not in LIGHTING:
            raise ValueError(f"lighting must be one of {LIGHTING}, got {lighting!r}")
        width, height = image_size(width, height)
        self.env = env
        self.single_camera = isinstance(camera, (str, int))
        cameras = [camera] if self.single_camera else list(camera)
        if not cameras:
            raise ValueError("give at least one camera")
        self.cameras = tuple(
            camera_name(camera_id=c) if isinstance(c, (int, np.integer)) else camera_name(c) for c in cameras
        )
        self.width, self.height = width, height
        self.rgb, self.depth = rgb, depth
        rows = np.arange(env.num_envs) if envs is None else np.asarray(envs, int).reshape(-1)
        if len(rows) == 0 or np.any(rows < 0) or np.any(rows >= env.num_envs):
            raise ValueError(f"envs must be indices in [0, {env.num_envs}), got {envs!r}")
        if len(np.unique(rows)) != len(rows):
            raise ValueError("envs must not repeat")
        self.envs = tuple(int(r) for r in rows)
        ordered = np.sort(rows)
        # Images come out group by group in batch order; this puts them in the caller's order.
        self._order = jnp.asarray(np.searchsorted(ordered, rows))
        self._identity = bool(np.array_equal(ordered, rows))
        self._groups: list[tuple[int, int, _Group]] = []
        graph_mode = env.physics.config.graph_mode if graph_mode is None else graph_mode
        for g, group in enumerate(env.physics.groups):
            chosen = ordered[(ordered >= group.start) & (ordered < group.start + group.size)]
            if len(chosen) == 0:
                continue
            lookat = np.stack([_free_lookat(env, group, int(r)) for r in chosen])
            self._groups.append(
                (
                    g,
                    group.start,
                    _Group(
                        group,
                        chosen - group.start,
                        self.cameras,
                        lookat,
                        width,
                        height,
                        rgb,
                        depth,
                        shadows,
                        samples_per_pixel,
                        sites,
                        lighting,
                        graph_mode,
                    ),
                )
            )

    @property
    def num_images(self) -> int:
        return len(self.envs)

    def capture(self, state: State) -> Capture:
        """The chosen envs' poses that drawing reads (a few KB per env; jittable)."""
        parts = [group.capture(state, start, g) for g, start, group in self._groups]
        return Capture(*(tuple(p[i] for p in parts) for i in range(7)))

    def draw(self, capture: Capture) -> Images:
        """Images of a `capture` (jittable)."""
        rgbs: list[list[Array]] = []
        depths: list[list[Array]] = []
        for k, (_, _, group) in enumerate(self._groups):
            rgb, depth = group.draw(tuple(getattr(capture, f.name)[k] for f in dataclasses.fields(capture)))
            rgbs.append(rgb)
            depths.append(depth)
        return Images(
            self._assemble(rgbs) if self.rgb else None, self._assemble(depths) if self.depth else None
        )

    def render(self, state: State) -> Images:
        """Images of the chosen envs in `state` (jittable)."""
        return self.draw(self.capture(state))

    def frames(self, captures: Capture | State, rgb: bool = True) -> np.ndarray:
        """Host images of a stack of captures or states (a leading time axis, e.g. what a
        `lax.scan` returned): `(T, N, H, W, 3)` uint8 (`rgb=False`: depth, `(T, N, H, W)`)."""
        if isinstance(captures, State):
            captures = jax.jit(jax.vmap(self.capture))(captures)
        draw = _jitted_draw(self)
        steps = jax.tree.leaves(captures)[0].shape[0]
        out = []
        for t in range(steps):
            images = draw(jax.tree.map(lambda x, t=t: x[t], captures))
            out.append(np.asarray(images.rgb if rgb else images.depth))
        return np.stack(out)

    def _assemble(self, parts: list[list[Array]]) -> Array:
        per_camera = [jnp.concatenate([p[k] for p in parts]) for k in range(len(self.cameras))]
        images = per_camera[0] if self.single_camera else jnp.stack(per_camera, axis=1)
        return images if self._identity else images[self._order]


@functools.cache
def _jitted_draw_cache() -> dict[int, Any]:
    return {}


def _jitted_draw(renderer: Renderer) -> Any:
    cache = _jitted_draw_cache()
    key = id(renderer)
    if key not in cache or cache[key][0] is not renderer:
        cache[key] = (renderer, jax.jit(renderer.draw))
    return cache[key][1]


def image_agreement(
    a: np.ndarray, b: np.ndarray, tolerance: float = 0.1, mask: np.ndarray | None = None
) -> tuple[float, float]:
    """How close two uint8 RGB images are (docs/rendering.md): the mean absolute difference of
    their values in [0, 1], and the fraction of pixels whose channels all differ by at most
    `tolerance`; over the pixels of `mask` (H, W) if given."""
    a = np.asarray(a, np.float64) / 255
    b = np.asarray(b, np.float64) / 255
    if a.shape != b.shape:
        raise ValueError(f"images differ in shape: {a.shape} and {b.shape}")
    diff = np.abs(a - b)
    if mask is not None:
        diff = diff[np.asarray(mask, bool)]
    return float(diff.mean()), float(np.mean(diff.max(axis=-1) <= tolerance))


def depth_buffer(depth: np.ndarray | Array, model: mujoco.MjModel) -> np.ndarray | Array:
    """Metric depth (0 where nothing is hit) as the values OpenGL's depth buffer holds, which is
    what the reference's `render_mode="depth_array"` returns: `(1/near - 1/z) / (1/near - 1/far)`
    with MuJoCo's clip planes (`vis.map.znear/zfar` times the model's extent); 1 where nothing is
    hit (the far plane)."""
    near = model.vis.map.znear * model.stat.extent
    far = model.vis.map.zfar * model.stat.extent
    xp = jnp if isinstance(depth, jax.Array) else np
    z = xp.where(depth > 0, depth, far)
    return ((1.0 / near - 1.0 / z) / (1.0 / near - 1.0 / far)).astype(xp.float32)


# --------------------------------------------------------------------------------------------
# Videos


def record_video(
    env: Env | Renderer,
    states: State | Capture,
    path: str | Path,
    envs: Sequence[int] | None = None,
    fps: int = RENDER_FPS,
    **renderer_kwargs: Any,
) -> Path:
    """Writes a video of chosen envs of a rollout: `states` is a stack of states (or of a
    `Renderer`'s captures) with a leading time axis, as a jitted `lax.scan` returns them; envs
    side by side in one frame. `.gif` (Pillow if installed, else a built-in writer) or `.mp4`
    (needs `imageio` with `imageio-ffmpeg`: `pip install mwjax[video]`).

        record_video(env, states, "pick.gif", envs=[0, 5], camera="corner", width=128, height=128)
    """
    if isinstance(env, Renderer):
        if renderer_kwargs or envs is not None:
            raise ValueError("pass envs and renderer options to the Renderer, not with one")
        renderer = env
    else:
        renderer_kwargs.setdefault("width", 256)
        renderer_kwargs.setdefault("height", 256)
        renderer = Renderer(env, envs=[0] if envs is None else envs, **renderer_kwargs)
    frames = renderer.frames(states)
    if frames.ndim == 6:  # several cameras: side by side too
        frames = frames.reshape(frames.shape[0], -1, *frames.shape[3:])
    tiled = np.concatenate(list(frames.transpose(1, 0, 2, 3, 4)), axis=2)  # envs left to right
    return write_video(tiled, path, fps)


def write_video(frames: np.ndarray, path: str | Path, fps: int = RENDER_FPS) -> Path:
    """Writes `(T, H, W, 3)` uint8 frames as `.gif` or `.mp4`."""
    path = Path(path)
    frames = np.asarray(frames)
    if frames.ndim != 4 or frames.shape[-1] != 3 or frames.dtype != np.uint8:
        raise ValueError(f"frames must be (T, H, W, 3) uint8, got {frames.shape} {frames.dtype}")
    path.parent.mkdir(parents=True, exist_ok=True)
    suffix = path.suffix.lower()
    if suffix == ".gif":
        try:
            from PIL import Image
        except ImportError:
            path.write_bytes(_gif_bytes(frames, fps))
        else:
            images = [Image.fromarray(f) for f in frames]
            images[0].save(
                path, save_all=True, append_images=images[1:], duration=max(1, round(1000 / fps)), loop=0
            )
        return path
    if suffix == ".mp4":
        try:
            import imageio.v2 as imageio
        except ImportError as error:
            raise ImportError("MP4 needs imageio and imageio-ffmpeg: pip install 'mwjax[video]'") from error
        # MP4 encoders want even sizes.
        frames = np.pad(frames, ((0, 0), (0, frames.shape[1] % 2), (0, frames.shape[2] % 2), (0, 0)))
        imageio.mimwrite(path, list(frames), fps=fps, macro_block_size=1)
        return path
    raise ValueError(f"video path must end in .gif or .mp4, got {path.name!r}")


def _gif_bytes(frames: np.ndarray, fps: int) -> bytes:
    """A looping GIF without dependencies: colours rounded to a 6x7x6 palette, and LZW codes
    kept at 9 bits by a clear code every 250 pixels (larger than a compressed GIF, but valid)."""
    levels = np.array([6, 7, 6])
    palette = np.stack(
        np.meshgrid(*(np.round(np.linspace(0, 255, n)) for n in levels), indexing="ij"), -1
    ).reshape(-1, 3)
    palette = np.concatenate([palette, np.zeros((256 - len(palette), 3))]).astype(np.uint8)
    height, width = frames.shape[1:3]
    out = [b"GIF89a", struct.pack("<HHBBB", width, height, 0xF7, 0, 0), palette.tobytes()]
    out.append(b"\x21\xff\x0bNETSCAPE2.0\x03\x01\x00\x00\x00")  # loop forever
    delay = max(1, round(100 / fps))
    for frame in frames:
        q = np.round(frame.astype(np.float32) / 255 * (levels - 1)).astype(np.int64)
        index = (q[..., 0] * levels[1] + q[..., 1]) * levels[2] + q[..., 2]
        out.append(struct.pack("<BBBBHBB", 0x21, 0xF9, 4, 0, delay, 0, 0))  # frame delay
        out.append(b"\x2c" + struct.pack("<HHHHB", 0, 0, width, height, 0))
        pixels = index.reshape(-1)
        chunks = [np.concatenate([[256], pixels[i : i + 250]]) for i in range(0, len(pixels), 250)]
        codes = np.concatenate([*chunks, [257]]).astype(np.int64)
        bits = ((codes[:, None] >> np.arange(9)) & 1).astype(np.uint8).reshape(-1)
        data = np.packbits(bits, bitorder="little").tobytes()
        blocks = b"".join(
            bytes([len(data[i : i + 255])]) + data[i : i + 255] for i in range(0, len(data), 255)
        )
        out.append(b"\x08" + blocks + b"\x00")
    out.append(b"\x3b")
    return b"".join(out)


# --------------------------------------------------------------------------------------------
# Batched pixel observations


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class PixelState:
    """An env state with every env's images of it: `pixels` `(N, H, W, 3)` uint8 (a camera axis
    after N with several cameras), `depth` in metres or None."""

    state: State
    pixels: Array | None
    depth: Array | None

    @property
    def obs(self) -> Array:
        return self.state.obs


class PixelObservations:
    """An `mwjax.Env` whose `reset` and `step` also render every env (MJWarp's batched ray
    tracer, on the device that runs the env): jittable, inside `lax.scan` too.

        env = PixelObservations(mwjax.make("MT10", envs_per_task=64), camera="corner", width=64, height=64)
        ps = jax.jit(env.reset)(key)               # ps.pixels: (640, 64, 64, 3) uint8, ps.obs: (640, 39)
        ps = jax.jit(env.step)(ps, actions)

    With autoreset the images show the state the env returns (a finished episode's next start).
    Other attributes are the wrapped env's. Renderer options as for `Renderer`."""

    def __init__(self, env: Env, **renderer_kwargs: Any) -> None:
        renderer_kwargs.setdefault("width", 64)
        renderer_kwargs.setdefault("height", 64)
        renderer_kwargs.setdefault("shadows", False)
        self.env = env
        self.renderer = Renderer(env, envs=None, **renderer_kwargs)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.env, name)

    def observe(self, state: State) -> PixelState:
        images = self.renderer.render(state)
        return PixelState(state, images.rgb, images.depth)

    def reset(self, key: Array) -> PixelState:
        return self.observe(self.env.reset(key))

    def step(self, state: PixelState, action: Array) -> PixelState:
        return self.observe(self.env.step(state.state, action))


# --------------------------------------------------------------------------------------------
# The visual model


@functools.cache
def _visual_spec_model(scene: str, sites: bool) -> tuple[mujoco.MjModel, tuple[str, ...]]:
    """The scene as the reference draws it, plus: the free camera, and each visible site as a
    geom of the world body (its pose is written at every draw)."""
    spec = mujoco.MjSpec.from_file(str(SCENES_DIR / scene))
    plain = spec.compile()
    spec.worldbody.add_camera(name=_FREE_NAME, fovy=plain.vis.global_.fovy)
    names = []
    if sites:
        for i in range(plain.nsite):
            if plain.site_group[i] not in _VISIBLE_GROUPS or plain.site_rgba[i][3] <= 0:
                continue
            name = f"{_SITE_PREFIX}{i}"
            geom = spec.worldbody.add_geom(
                name=name,
                type=mujoco.mjtGeom(int(plain.site_type[i])),
                size=plain.site_size[i],
                rgba=plain.site_rgba[i],
                group=int(plain.site_group[i]),
                contype=0,
                conaffinity=0,
            )
            if plain.site_matid[i] >= 0:
                geom.material = plain.material(int(plain.site_matid[i])).name
            names.append(name)
    return spec.compile(), tuple(names)


def _visual_model(scene: str, host: mujoco.MjModel, sites: bool) -> tuple[mujoco.MjModel, np.ndarray]:
    model, _ = _visual_spec_model(scene, sites)
    source = []
    next_geom = 0
    for j in range(model.ngeom):
        name = model.geom(j).name
        if name.startswith(_SITE_PREFIX):
            source.append(host.ngeom + int(name[len(_SITE_PREFIX) :]))
            continue
        if next_geom >= host.ngeom or model.geom_bodyid[j] != host.geom_bodyid[next_geom]:
            raise AssertionError(f"{scene}: the visual model's geoms do not line up with the env's")
        source.append(next_geom)
        next_geom += 1
    if next_geom != host.ngeom:
        raise AssertionError(f"{scene}: the visual model lacks geoms of the env's")
    return model, np.array(source, np.int32)


def _visible_geoms_model(model: mujoco.MjModel) -> mujoco.MjModel:
    """The visual model for MJWarp's render context with every transparent geom (alpha 0, the
    colour MJWarp's ray tracer uses: the geom's rgba, or its material's where the geom's is the
    default) moved to a group that is not drawn, so the scene BVH leaves it out instead of every
    ray testing and skipping it. Meta-World's arm has eight such collision shapes (cylinders
    around its links, the head's screen, the mocap sphere) in drawn groups."""
    rgba = model.geom_rgba.copy()
    default = (model.geom_matid >= 0) & np.all(rgba == np.array([0.5, 0.5, 0.5, 1.0], np.float32), axis=1)
    rgba[default] = model.mat_rgba[model.geom_matid[default]]
    hidden = next(g for g in range(mujoco.mjNGROUP) if g not in _VISIBLE_GROUPS)
    visible = copy.copy(model)
    visible.geom_group[rgba[:, 3] == 0] = hidden
    return visible


def _camera_id(model: mujoco.MjModel, name: str) -> int:
    cam = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, name)
    if cam < 0:
        raise ValueError(f"the scene has no camera {name!r}")
    return cam


def _camera(
    model: mujoco.MjModel, host: mujoco.MjModel, name: str, bodies: list[int], free_lookat: np.ndarray
) -> _Camera:
    if name == FREE_CAMERA:
        return _Camera(name, "free", -1, *_free_camera_pose(free_lookat, host))
    cam = _camera_id(model, name)
    body = int(model.cam_bodyid[cam])
    mode = model.cam_mode[cam]
    if mode == mujoco.mjtCamLight.mjCAMLIGHT_FIXED:
        mat = _quat_to_mat_np(model.cam_quat[cam])
        if body == 0:
            return _Camera(name, "world", -1, model.cam_pos[cam].copy(), mat)
        bodies.append(body)
        return _Camera(name, "body", len(bodies) - 1, model.cam_pos[cam].copy(), mat)
    if mode == mujoco.mjtCamLight.mjCAMLIGHT_TRACK:
        bodies.append(body)
        return _Camera(
            name, "track", len(bodies) - 1, model.cam_pos0[cam].copy(), model.cam_mat0[cam].reshape(3, 3)
        )
    raise NotImplementedError(f"camera {name!r}: mode {mujoco.mjtCamLight(mode).name} is not supported")


def _free_camera_pose(lookat: np.ndarray, model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's free camera as Gymnasium's offscreen viewer sets it up (`MjvCamera` defaults:
    azimuth 90, elevation -45; distance the model's extent; lookat given), per row."""
    azimuth, elevation = np.deg2rad(90.0), np.deg2rad(-45.0)
    forward = np.array(
        [np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth), np.sin(elevation)]
    )
    up = np.array(
        [-np.sin(elevation) * np.cos(azimuth), -np.sin(elevation) * np.sin(azimuth), np.cos(elevation)]
    )
    right = np.cross(forward, up)
    mat = np.stack([right, up, -forward], axis=1)  # columns: camera x, y, z in the world
    pos = lookat - model.stat.extent * forward
    return pos, np.broadcast_to(mat, (*lookat.shape[:-1], 3, 3)).copy()


def _free_lookat(env: Env, group: SceneGroup, row: int) -> np.ndarray:
    """The free camera's look-at point for an env: the median of its scene's geom positions, as
    Gymnasium computes it when the reference first renders. Taken here from the task's settled
    reset state (hand at its start, objects where the recorded reset left them)."""
    task = env.task_names[row]
    geom_xpos = np.asarray(env.settled_kinematics(task).geom_xpos)
    return np.median(geom_xpos, axis=0)


def _all_cameras(current: Array, ids: list[int], values: Array) -> Array:
    """`current` (rows, ncam, ...) with the given cameras' entries set."""
    return current.at[:, jnp.asarray(ids)].set(values.astype(current.dtype))


def _quat_to_mat(q: Array) -> Array:
    w, x, y, z = q[0], q[1], q[2], q[3]
    return jnp.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def _quat_to_mat_np(q: np.ndarray) -> np.ndarray:
    mat = np.zeros(9)
    mujoco.mju_quat2Mat(mat, np.asarray(q, np.float64))
    return mat.reshape(3, 3)


# --------------------------------------------------------------------------------------------
# Gymnasium's render()

RENDER_MODES = ("rgb_array", "depth_array")


def image_size(width: Any, height: Any) -> tuple[int, int]:
    """`(width, height)` as ints, or a `ValueError` unless both are positive integers."""
    sizes = (width, height)
    if not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) and v > 0 for v in sizes):
        raise ValueError(f"width and height must be positive ints, got {width!r}, {height!r}")
    return int(width), int(height)


class GymFrames:
    """Frames for Gymnasium's `render()` with the reference's kwargs: NumPy images of chosen envs
    of an env's current state, `(H, W, 3)` uint8 for `"rgb_array"` and, for `"depth_array"`,
    `(H, W)` float32 depth-buffer values as the reference returns them (`depth_buffer`). The
    renderer is built at the first frame (a few seconds), as the reference opens its viewer."""

    def __init__(
        self,
        env: Env,
        render_mode: str | None,
        envs: Sequence[int],
        camera_name: str | None = None,
        camera_id: int | None = None,
        width: int = DEFAULT_SIZE,
        height: int = DEFAULT_SIZE,
    ) -> None:
        if render_mode is not None and render_mode not in RENDER_MODES:
            raise ValueError(f"render_mode must be None or one of {RENDER_MODES}, got {render_mode!r}")
        self.env = env
        self.render_mode = render_mode
        self.envs = tuple(int(e) for e in envs)
        self.camera = camera_name_of(camera_name, camera_id)
        # Checked when the env is made, not at the first frame, where the renderer is built.
        self.width, self.height = image_size(width, height)
        self._renderer: Renderer | None = None
        self._render: Any = None

    def __call__(self, state: State | None) -> list[np.ndarray] | None:
        if self.render_mode is None:
            return None
        if state is None:
            raise RuntimeError("call reset() before render()")
        if self._renderer is None:
            depth = self.render_mode == "depth_array"
            self._renderer = Renderer(
                self.env, self.camera, self.width, self.height, envs=self.envs, rgb=not depth, depth=depth
            )
            self._render = jax.jit(self._renderer.render)
        images = self._render(state)
        if self.render_mode == "rgb_array":
            return list(np.asarray(images.rgb))
        depth = np.asarray(images.depth)
        models = [self.env.physics.groups[_group_of(self.env, e)].model for e in self.envs]
        return [depth_buffer(d, m) for d, m in zip(depth, models, strict=True)]


camera_name_of = camera_name


def _group_of(env: Env, row: int) -> int:
    groups = env.physics.groups
    return next(g for g, group in enumerate(groups) if group.start <= row < group.start + group.size)
