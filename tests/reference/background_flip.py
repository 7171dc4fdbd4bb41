#!/usr/bin/env python3
"""How close previz's background is to the reference's: mean FLIP of previz's background layer
(`previz composite SCENE --layers DIR` -> DIR/background.png) against B, the reference's render of
the environment alone (16 spp, seed 0, as render_reference.py renders it), with the path tracer's
own noise floor (B at seed 1) and exact CPU evaluations of other lookups beside it
(docs/accuracy.md, "Eighth session: the background looked up in the equirect"):

  cube S        previz's cube map of S-texel faces (each texel the mean of 2x2 bilinear lookups
                of the equirect, scene::environment::Equirect::to_cube), one bilinear lookup per
                pixel (faces clamped at their edges)
  direct NxN    the equirect looked up directly (Equirect::sample_uv), NxN lookups per pixel
  mitsuba NxN   the same on the reference's row-resampled map (its own lookup)

Needs mitsuba, numpy, pillow and NVIDIA's flip-evaluator (pip install flip-evaluator).

Usage:
  previz bench accuracy --export-reference DIR SCENE.toml
  previz composite SCENE.toml --layers LAYERS
  python background_flip.py DIR LAYERS/background.png [--save PREFIX]
"""

import argparse
import json
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import render_reference as rr  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("frame_dir", help="folder from `previz bench accuracy --export-reference`")
    ap.add_argument("previz_background", help="previz's background.png (composite --layers)")
    ap.add_argument("--save", help="also write PREFIX_NAME.png for B and every variant")
    args = ap.parse_args()
    import flip_evaluator as flip
    from PIL import Image

    with open(os.path.join(args.frame_dir, "frame.json")) as f:
        frame = json.load(f)
    mi = rr.pick_variant(None)
    env = rr.load_env(mi, frame["environment"])
    H, W = env.shape[:2]
    bmp = mi.Bitmap(np.ascontiguousarray(rr.previz_to_mitsuba_rows(env)).astype(np.float32))
    exposure = frame["exposure"]
    heading = math.radians(frame["env_heading_deg"])
    # The reference's row-resampled map before its roll: row r holds previz's value at v = r/(H-1).
    y = np.clip(np.arange(H) / (H - 1) * H - 0.5, 0.0, H - 1.0)
    y0 = np.floor(y).astype(int)
    fy = (y - y0)[:, None, None]
    resampled = env[y0] * (1 - fy) + env[np.minimum(y0 + 1, H - 1)] * fy

    def render_b(spp, seed):
        scene = rr.build_scene(mi, frame, args.frame_dir, bmp, np.array([0.2] * 3), "env", spp, seed)
        return rr.render(mi, scene, spp, seed)

    def srgb8(lin):
        return np.round(rr.srgb_encode(lin * exposure) * 255.0).astype(np.uint8)

    def equirect(d, src=env, mitsuba_rows=False):
        """Bilinear lookup of ENU directions d, previz's convention (or the reference's rows)."""
        az = np.arctan2(d[..., 0], d[..., 1])
        el = np.arctan2(d[..., 2], np.hypot(d[..., 0], d[..., 1]))
        u = np.mod(0.5 + (az - heading) / (2 * math.pi), 1.0)
        v = 0.5 - el / math.pi
        x = u * W - 0.5
        yy = np.clip(v * (H - 1), 0, H - 1) if mitsuba_rows else np.clip(v * H - 0.5, 0, H - 1)
        x0 = np.floor(x)
        fx = (x - x0)[..., None]
        x0 = x0.astype(int) % W
        x1 = (x0 + 1) % W
        r0 = np.floor(yy).astype(int)
        r1 = np.minimum(r0 + 1, H - 1)
        fr = (yy - r0)[..., None]
        top = src[r0, x0] * (1 - fx) + src[r0, x1] * fx
        bottom = src[r1, x0] * (1 - fx) + src[r1, x1] * fx
        return top * (1 - fr) + bottom * fr

    def face_uv(c):
        a = np.abs(c)
        x, yy, z = c[..., 0], c[..., 1], c[..., 2]
        on_x = (a[..., 0] >= a[..., 1]) & (a[..., 0] >= a[..., 2])
        on_y = ~on_x & (a[..., 1] >= a[..., 2])
        face = np.where(on_x, np.where(x >= 0, 0, 1), np.where(on_y, np.where(yy >= 0, 2, 3), np.where(z >= 0, 4, 5)))
        faces = [face == k for k in range(6)]
        sc = np.select(faces, [-z, z, x, x, x, -x])
        tc = np.select(faces, [-yy, -yy, z, -z, -yy, -yy])
        ma = np.select([on_x, on_y, ~on_x & ~on_y], [a[..., 0], a[..., 1], a[..., 2]])
        return face, 0.5 * (sc / ma + 1), 0.5 * (tc / ma + 1)

    def face_dir(face, u, v):
        sc, tc = 2 * u - 1, 2 * v - 1
        one = np.ones_like(sc)
        dirs = [(one, -tc, -sc), (-one, -tc, sc), (sc, one, tc), (sc, -one, -tc), (sc, -tc, one), (-sc, -tc, -one)]
        d = np.select([face[..., None] == k for k in range(6)], [np.stack(t, -1) for t in dirs])
        return d / np.linalg.norm(d, axis=-1, keepdims=True)

    def cube(d, size):
        # Turn by -heading (frame.wgsl env_dir), then ENU -> cube space (x, z, y).
        c, s = math.cos(heading), math.sin(heading)
        r = np.stack([c * d[..., 0] - s * d[..., 1], s * d[..., 0] + c * d[..., 1], d[..., 2]], -1)
        face, u, v = face_uv(np.stack([r[..., 0], r[..., 2], r[..., 1]], -1))
        x = np.clip(u * size - 0.5, 0, size - 1)
        yy = np.clip(v * size - 0.5, 0, size - 1)
        x0, r0 = np.floor(x).astype(int), np.floor(yy).astype(int)
        x1, r1 = np.minimum(x0 + 1, size - 1), np.minimum(r0 + 1, size - 1)
        fx, fr = (x - x0)[..., None], (yy - r0)[..., None]

        def texel(i, j):  # Equirect::to_cube at heading 0: 2x2 lookups over the texel
            acc = 0
            for ox, oy in [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)]:
                cd = face_dir(face, (i + ox) / size, (j + oy) / size)
                enu = np.stack([cd[..., 0], cd[..., 2], cd[..., 1]], -1)
                c2, s2 = math.cos(heading), math.sin(heading)  # undo the turn: equirect() turns by heading
                acc = acc + equirect(np.stack([c2 * enu[..., 0] + s2 * enu[..., 1], -s2 * enu[..., 0] + c2 * enu[..., 1], enu[..., 2]], -1))
            return acc / 4

        return (texel(x0, r0) * (1 - fx) + texel(x1, r0) * fx) * (1 - fr) + (texel(x0, r1) * (1 - fx) + texel(x1, r1) * fx) * fr

    def camera_image(n, lookup):
        w, h = frame["width"], frame["height"]
        f = np.array(frame["target"]) - np.array(frame["eye"])
        f /= np.linalg.norm(f)
        up = np.array(frame["up"])
        right = np.cross(f, up)
        right /= np.linalg.norm(right)
        t = math.tan(math.radians(frame["vfov_deg"]) / 2)
        acc = np.zeros((h, w, 3))
        for sy in range(n):
            for sx in range(n):
                px = (np.arange(w) + (sx + 0.5) / n) / w * 2 - 1
                py = 1 - (np.arange(h) + (sy + 0.5) / n) / h * 2
                X, Y = np.meshgrid(px * t * w / h, py * t)
                d = X[..., None] * right + Y[..., None] * up + f
                acc += lookup(d / np.linalg.norm(d, axis=-1, keepdims=True))
        return acc / (n * n)

    b8 = srgb8(render_b(16, 0))
    images = {
        "B seed 1 (noise floor)": srgb8(render_b(16, 1)),
        "B 256 spp seed 2": srgb8(render_b(256, 2)),
        "previz": np.asarray(Image.open(args.previz_background).convert("RGB")),
        "cube 256": srgb8(camera_image(1, lambda d: cube(d, 256))),
        "cube 512": srgb8(camera_image(1, lambda d: cube(d, 512))),
        "direct 1x1": srgb8(camera_image(1, equirect)),
        "direct 2x2": srgb8(camera_image(2, equirect)),
        "direct 4x4": srgb8(camera_image(4, equirect)),
        "mitsuba 4x4": srgb8(camera_image(4, lambda d: equirect(d, resampled, True))),
    }
    ref = b8.astype(np.float32) / 255.0
    report = {"frame_dir": args.frame_dir}
    for name, img in images.items():
        report[name] = round(float(flip.evaluate(ref, img.astype(np.float32) / 255.0, "LDR")[1]), 4)
        if args.save:
            Image.fromarray(img).save(f"{args.save}_{name.split(' (')[0].replace(' ', '_')}.png")
    if args.save:
        Image.fromarray(b8).save(f"{args.save}_B.png")
    print(json.dumps(report))


if __name__ == "__main__":
    main()
