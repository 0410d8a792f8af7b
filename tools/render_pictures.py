#!/usr/bin/env python
"""Pictures of mwjax's rendering (run in mwjax's venv), for docs/rendering.md:

<out>/<task>-vs-reference.png  per camera of a render fixture (tools/record_render_fixtures.py):
                               mwjax | reference | 4x their absolute difference, both states,
                               with the agreement metric printed per image
<out>/<task>-cameras.png       every camera (CAMERAS, then the free camera) after a reset
<out>/mt10-corner.png          each MT10 task after a reset, from the corner camera

  python tools/render_pictures.py                                   # 64 px committed fixtures
  python tools/render_pictures.py --fixtures /tmp/ref192            # larger reference images
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import jax
import numpy as np
from PIL import Image, ImageDraw

sys.path.insert(0, str(Path(__file__).parents[1] / "tests"))

from test_rendering import CAMERAS, reference_capture  # noqa: E402

import mwjax  # noqa: E402
from mwjax import rendering  # noqa: E402


def labelled(image: np.ndarray, text: str) -> np.ndarray:
    picture = Image.fromarray(image)
    ImageDraw.Draw(picture).text((3, 2), text, fill=(255, 255, 0))
    return np.asarray(picture)


def grid(images: list[np.ndarray], columns: int) -> np.ndarray:
    blank = np.zeros_like(images[0])
    rows = [images[i : i + columns] for i in range(0, len(images), columns)]
    rows[-1] = rows[-1] + [blank] * (columns - len(rows[-1]))
    return np.concatenate([np.concatenate(r, axis=1) for r in rows], axis=0)


def versus_reference(fixture_path: Path, out: Path) -> None:
    task = fixture_path.stem
    fixture = np.load(fixture_path)
    size = json.loads(str(fixture["meta"]))["size"]
    cameras = [c for c in CAMERAS if f"rgb/{c}" in fixture]
    renderer = rendering.Renderer(mwjax.make("MT1", task=task), camera=cameras, width=size, height=size)
    draw = jax.jit(renderer.draw)
    scale = max(1, 192 // size)
    rows = []
    for state in range(2):
        capture, _ = reference_capture(task, fixture, state)
        ours = np.asarray(draw(renderer.capture(capture)).rgb[0])
        for k, camera in enumerate(cameras):
            if len(fixture[f"rgb/{camera}"]) <= state:
                continue  # a camera recorded for the reset state only
            ref = fixture[f"rgb/{camera}"][state]
            mad, within = rendering.image_agreement(ours[k], ref)
            print(
                f"{task} {size}px state {state} {camera:14s} mean abs diff {mad:.4f}, within 0.1 {within:.3f}"
            )
            diff = np.clip(np.abs(ours[k].astype(int) - ref.astype(int)) * 4, 0, 255).astype(np.uint8)
            row = np.concatenate([ours[k], ref, diff], axis=1)
            row = np.asarray(Image.fromarray(row).resize((row.shape[1] * scale, size * scale), Image.NEAREST))
            rows.append(labelled(row, f"{camera} s{state}: mwjax | reference | 4x diff  (MAD {mad:.3f})"))
    Image.fromarray(np.concatenate(rows, axis=0)).save(out / f"{task}-vs-reference.png")


def after_reset(env: mwjax.Env, camera, size: int) -> np.ndarray:
    renderer = rendering.Renderer(env, camera=camera, width=size, height=size)
    state = jax.jit(env.reset)(jax.random.key(0))
    return np.asarray(jax.jit(renderer.render)(state).rgb)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--fixtures", default="tests/fixtures/render")
    p.add_argument("--out", default="benchmarks/results/render")
    p.add_argument("--task", default="pick-place-v3", help="the task whose every camera is drawn")
    p.add_argument("--size", type=int, default=160)
    p.add_argument("--skip-mt10", action="store_true")
    args = p.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for path in sorted(Path(args.fixtures).glob("*.npz")):
        versus_reference(path, out)
    cameras = [*rendering.CAMERAS, rendering.FREE_CAMERA]
    images = after_reset(mwjax.make("MT1", task=args.task), cameras, args.size)[0]
    Image.fromarray(grid([labelled(i, c) for i, c in zip(images, cameras, strict=True)], 4)).save(
        out / f"{args.task}-cameras.png"
    )
    if not args.skip_mt10:
        env = mwjax.make("MT10")
        images = after_reset(env, "corner", args.size)
        tiles = [labelled(i, t) for i, t in zip(images, env.task_names, strict=True)]
        Image.fromarray(grid(tiles, 5)).save(out / "mt10-corner.png")
    print(f"pictures in {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
