"""MuJoCo's OpenGL lighting for MJWarp's ray tracer, so images look like the reference's.

MuJoCo's OpenGL renderer (the reference's `env.render()`) lights a surface like OpenGL's fixed
pipeline: the sum of emission, ambient, and each light's diffuse and specular terms, computed
with the geom's colour, is clamped to 1 and only then multiplied by the texture; a light that
casts shadows (with shadows on) is drawn in a second, additive pass, so its share is added on top
of that clamp and is zero where the light is blocked. MJWarp sums the terms with the textured
colour and clamps once. With Meta-World's lights (headlight ambient 0.4 and diffuse 0.4, three
directional lights of 0.3, material specular 0.5) textured surfaces facing the camera saturate in
OpenGL but not in MJWarp: MJWarp's table seen from `topview` came out ~1.6x as bright as the
reference's (mean absolute difference 0.17 of full scale; measured in tools/README_reference.md's
render fixtures, see docs/rendering.md).

`install()` gives MJWarp's render kernel that lighting for the render contexts marked with
`use_opengl_lighting(context)`; others render as MJWarp does. It rewrites a few lines of the
kernel builder's source (`render._build_megakernel`, mujoco-mjx 3.17.0) and raises if they are
not found, so a changed MJWarp fails loudly instead of rendering differently.
"""

from __future__ import annotations

import inspect
import linecache
import textwrap
import threading
from typing import Any

from mujoco.mjx.third_party.mujoco_warp._src import render

_ATTRIBUTE = "mwjax_opengl_lighting"
_lock = threading.Lock()
_installed = False

# (original, replacement) pairs of the builder's source, each original found exactly once.
_EDITS = [
    (
        "  M_NLIGHT = m.nlight\n",
        '  M_NLIGHT = m.nlight\n  GL_LIGHTING = bool(getattr(rc, "' + _ATTRIBUTE + '", False))\n',
    ),
    (
        "    base_color = wp.vec3(color[0], color[1], color[2])\n",
        "    base_color = wp.vec3(color[0], color[1], color[2])\n"
        "    surface_rgb = base_color\n"
        "    texel = wp.vec3(1.0, 1.0, 1.0)\n",
    ),
    (
        "          base_color = wp.cw_mul(base_color, tex_color)\n",
        "          base_color = wp.cw_mul(base_color, tex_color)\n"
        "          texel = wp.vec3(tex_color[0], tex_color[1], tex_color[2])\n",
    ),
    (
        "    view_dir = -ray_dir_world\n",
        "    gl_lit = wp.vec3(0.0)\n"
        "    gl_shadow_pass = wp.vec3(0.0)\n"
        "    if wp.static(GL_LIGHTING):\n"
        "      if wp.static(rc_static['enable_emission']):\n"
        "        gl_lit = surface_rgb * mat_emis\n"
        "      if wp.static(rc_static['use_ambient_lighting']):\n"
        "        if wp.static(rc_static['headlight_active']):\n"
        "          gl_lit = gl_lit + wp.cw_mul(surface_rgb, wp.static(rc_static['headlight_ambient']))\n"
        "        elif wp.static(M_NLIGHT == 0):\n"
        "          gl_lit = gl_lit + surface_rgb * NO_LIGHT_AMBIENT_FALLBACK\n"
        "        if wp.static(rc_static['enable_per_light_ambient']):\n"
        "          for light_index in range(wp.static(M_NLIGHT)):\n"
        "            if light_active[worldid % light_active.shape[0], light_index]:\n"
        "              gl_lit = gl_lit + wp.cw_mul(\n"
        "                surface_rgb, light_ambient[worldid % light_ambient.shape[0], light_index]\n"
        "              )\n"
        "    view_dir = -ray_dir_world\n",
    ),
    (
        "      result = result + wp.cw_mul(base_color, diff_rgb) + spec_rgb\n",
        "      result = result + wp.cw_mul(base_color, diff_rgb) + spec_rgb\n"
        "      if wp.static(GL_LIGHTING):\n"
        "        if use_shadows and light_castshadow_worldid[light_index]:\n"
        "          gl_shadow_pass = gl_shadow_pass + wp.cw_mul(surface_rgb, diff_rgb) + spec_rgb\n"
        "        else:\n"
        "          gl_lit = gl_lit + wp.cw_mul(surface_rgb, diff_rgb) + spec_rgb\n",
    ),
    (
        "      result = result + wp.cw_mul(base_color, hl_diff) + hl_spec\n",
        "      result = result + wp.cw_mul(base_color, hl_diff) + hl_spec\n"
        "      if wp.static(GL_LIGHTING):\n"
        "        gl_lit = gl_lit + wp.cw_mul(surface_rgb, hl_diff) + hl_spec\n",
    ),
    (
        "    hit_color = wp.min(result, wp.vec3(1.0, 1.0, 1.0))\n",
        "    if wp.static(GL_LIGHTING):\n"
        "      result = wp.cw_mul(wp.min(gl_lit, wp.vec3(1.0, 1.0, 1.0)) + gl_shadow_pass, texel)\n"
        "    hit_color = wp.min(result, wp.vec3(1.0, 1.0, 1.0))\n",
    ),
]


def use_opengl_lighting(context: Any) -> None:
    """Marks an MJX render context (`mjx.create_render_context`) for OpenGL's lighting."""
    for warp_context in getattr(context, "_contexts", {}).values() or [context]:
        setattr(warp_context, _ATTRIBUTE, True)


def install() -> None:
    """Replaces MJWarp's render-kernel builder with one that can light like OpenGL (idempotent)."""
    global _installed
    with _lock:
        if _installed:
            return
        source = textwrap.dedent(inspect.getsource(render._build_megakernel))
        for original, replacement in _EDITS:
            if source.count(original) != 1:
                raise RuntimeError(
                    "MJWarp's render kernel is not the one mwjax patches (mujoco-mjx 3.17.0): "
                    f"{original.strip()!r} found {source.count(original)} times"
                )
            source = source.replace(original, replacement)
        # Warp reads a kernel's source through `inspect`, so the patched builder gets a file name
        # in the line cache (mtime None: never checked against a file).
        filename = "<mwjax.warp_render_lighting:_build_megakernel>"
        linecache.cache[filename] = (len(source), None, source.splitlines(keepends=True), filename)
        namespace = dict(vars(render))
        exec(compile(source, filename, "exec"), namespace)  # noqa: S102
        render._build_megakernel = namespace["_build_megakernel"]
        _installed = True
