#!/usr/bin/env python3
"""Path-traced reference composites for previz, by differential rendering with Mitsuba 3.

Input: a folder written by `previz bench accuracy --export-reference DIR SCENE`, which holds
the scene exactly as previz draws it (frame.json: camera eye/target/up, vertical field of
view, environment file + heading + exposure, ground height; mesh_*.ply: the placed model in
world ENU coordinates with previz's normals and uvs; texture_*.png). Nothing about previz's
conventions is re-derived here except the environment's orientation, which is measured by
`--check-background` (see README.md).

Five renders, all with the environment as the only light (ENU world: +x East, +y North, +z Up):
  B      the environment seen by the camera (no geometry)
  full   model + ground plane
  black  model with a black BSDF + ground (the ground as shadowed by the model)
  ground ground plane alone
  alpha  the model as an emitter of radiance 1 on black: its pixel coverage
Composite (linear):  C = (full - black) + B * black / ground   where alpha > 0,
                     C = B * full / ground                     elsewhere (keeps the model's
                                                               bounce light on the ground),
the ratio taken as 1 where the ground plane is not seen. Output: sRGB(exposure * C), 8-bit PNG,
OUT_roi.png (the model plus its shadow, see region_of_interest), and the linear exposed
composite and alpha as .npy for measurements.

Materials: every mesh is a two-sided Lambertian with albedo = material diffuse colour times
its texture (sRGB-decoded); no specular term (previz's default model material is 0.8 grey).
The ground plane is a two-sided Lambertian whose albedo makes its unshadowed radiance equal to
the mean radiance of the environment's lower hemisphere (so the model sees a ground as bright
as the map's ground).

Usage:
  python render_reference.py DIR --spp 64 --out ref.png [--seed 0] [--variant llvm_ad_rgb]
"""

import argparse
import json
import math
import os
import sys
import time

import numpy as np


def srgb_encode(x):
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)


def srgb_decode(c):
    return np.where(c <= 0.04045, c / 12.92, np.power((c + 0.055) / 1.055, 2.4))


def drjit_threads():
    """Dr.Jit's worker threads (the LLVM backend's; by default one per core), None if unknown."""
    try:
        import drjit as dr

        return dr.thread_count()
    except Exception:
        return None


def pick_variant(requested):
    import mitsuba as mi

    for v in ([requested] if requested else ["llvm_ad_rgb", "scalar_rgb"]):
        try:
            mi.set_variant(v)
            return mi
        except Exception as e:  # llvm needs libLLVM (DRJIT_LIBLLVM_PATH)
            if requested:
                raise SystemExit(f"render_reference: variant {v} unavailable: {e}")
    raise SystemExit("render_reference: no usable Mitsuba variant")


def load_env(mi, path):
    """The equirect in linear RGB, cleaned as previz cleans it (negatives/NaN -> 0)."""
    bmp = mi.Bitmap(path).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32, srgb_gamma=False)
    env = np.array(bmp, dtype=np.float32)[:, :, :3]
    env[~np.isfinite(env)] = 0.0
    return np.maximum(env, 0.0)


def previz_to_mitsuba_rows(env):
    """Mitsuba's envmap puts row r at v = r/(H-1) (bilinear over uv*(res-1)); previz puts it at
    v = (r+0.5)/H. Resample the rows so Mitsuba's row r holds what previz sees at v = r/(H-1).
    Columns agree (Mitsuba shifts u by half a texel), but Mitsuba's u = 0 is local -Z where
    previz's u = 0.5 (the centre column) is: roll by half the width."""
    h = env.shape[0]
    y = np.clip(np.arange(h) / (h - 1) * h - 0.5, 0.0, h - 1.0)
    y0 = np.floor(y).astype(int)
    y1 = np.minimum(y0 + 1, h - 1)
    f = (y - y0)[:, None, None]
    rows = env[y0] * (1 - f) + env[y1] * f
    return np.roll(rows, -env.shape[1] // 2, axis=1)


def env_to_world(heading_deg):
    """Mitsuba envmap local frame (+Y up, u = 0 at -Z, u = 0.25 at +X) to ENU, with the map's
    centre column facing azimuth `heading` (clockwise from North)."""
    h = math.radians(heading_deg)
    c, s = math.cos(h), math.sin(h)
    # local X -> East, local Y -> Up, local Z -> South; then turn clockwise (seen from above) by h.
    base = np.array([[1, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1]], dtype=float)
    turn = np.array([[c, s, 0, 0], [-s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], dtype=float)
    return turn @ base


def equirect_dirs(h, w):
    """ENU directions of previz equirect pixel centres (heading 0) and their solid angles."""
    v = (np.arange(h) + 0.5) / h
    u = (np.arange(w) + 0.5) / w
    el = (0.5 - v) * math.pi
    az = (u - 0.5) * 2 * math.pi
    ce, se = np.cos(el)[:, None], np.sin(el)[:, None]
    d = np.stack([ce * np.sin(az)[None, :], ce * np.cos(az)[None, :], np.broadcast_to(se, (h, w))], axis=-1)
    edges = (0.5 - np.arange(h + 1) / h) * math.pi
    omega = (2 * math.pi / w) * (np.sin(edges[:-1]) - np.sin(edges[1:]))
    return d, np.broadcast_to(omega[:, None], (h, w))


def ground_albedo(env):
    """Albedo making the ground plane's unshadowed radiance rho * E_up / pi equal to the mean
    radiance of the map's lower hemisphere (solid-angle weighted)."""
    d, omega = equirect_dirs(*env.shape[:2])
    up = d[..., 2] > 0
    e_up = (env * (d[..., 2] * omega * up)[..., None]).sum(axis=(0, 1))
    down = ~up
    l_down = (env * (omega * down)[..., None]).sum(axis=(0, 1)) / (omega * down).sum()
    rho = np.where(e_up > 0, math.pi * l_down / np.maximum(e_up, 1e-12), 0.2)
    return np.clip(rho, 0.0, 0.95)


def mesh_bsdf(mi, mesh, frame_dir, black=False, emitter=False):
    if black or emitter:
        return {"type": "twosided", "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0, 0.0, 0.0]}}}
    albedo = [float(a) for a in mesh["albedo"]]
    if mesh.get("texture"):
        from PIL import Image  # noqa: F401  (only when a texture exists)

        img = np.asarray(Image.open(os.path.join(frame_dir, mesh["texture"])).convert("RGB"), dtype=np.float32) / 255.0
        lin = srgb_decode(img) * np.array(albedo, dtype=np.float32)
        refl = {"type": "bitmap", "bitmap": mi.Bitmap(lin.astype(np.float32)), "raw": True, "filter_type": "bilinear"}
    else:
        refl = {"type": "rgb", "value": albedo}
    return {"type": "twosided", "bsdf": {"type": "diffuse", "reflectance": refl}}


def build_scene(mi, frame, frame_dir, env_bitmap, rho_ground, what, spp, seed):
    T = mi.ScalarTransform4f
    w, h = frame["width"], frame["height"]
    scene = {
        "type": "scene",
        "sensor": {
            "type": "perspective",
            "fov_axis": "y",
            "fov": frame["vfov_deg"],
            "near_clip": 1e-3,
            "far_clip": 1e7,
            "to_world": T().look_at(origin=frame["eye"], target=frame["target"], up=frame["up"]),
            "film": {"type": "hdrfilm", "width": w, "height": h, "rfilter": {"type": "box"}, "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": spp, "seed": seed},
        },
        "integrator": {"type": "path", "max_depth": 1 if what == "alpha" else 8},
    }
    if what != "alpha":
        scene["env"] = {"type": "envmap", "bitmap": env_bitmap, "to_world": T(env_to_world(frame["env_heading_deg"]).tolist())}
    if what in ("full", "black", "ground"):
        r = 400.0 * max(frame["model_radius"], 1e-3)
        scene["ground"] = {
            "type": "rectangle",
            "to_world": T().translate([0.0, 0.0, frame["ground_z"]]) @ T().scale([r, r, 1.0]),
            "bsdf": {"type": "twosided", "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": rho_ground.tolist()}}},
        }
    if what in ("full", "black", "alpha"):
        for i, m in enumerate(frame["meshes"]):
            shape = {
                "type": "ply",
                "filename": os.path.join(frame_dir, m["ply"]),
                "flip_tex_coords": False,
                "bsdf": mesh_bsdf(mi, m, frame_dir, black=(what == "black"), emitter=(what == "alpha")),
            }
            if what == "alpha":
                shape["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": [1.0, 1.0, 1.0]}}
            scene[f"mesh_{i}"] = shape
    return mi.load_dict(scene)


def render(mi, scene, spp, seed):
    img = mi.render(scene, spp=spp, seed=seed)
    return np.array(img, dtype=np.float64)[:, :, :3]


def composite(B, full, black, ground, alpha):
    a = alpha[..., :1].mean(axis=-1, keepdims=True) if alpha.ndim == 3 else alpha[..., None]
    a = np.clip(a, 0.0, 1.0)
    safe = np.where(ground > 1e-9, ground, 1.0)
    ratio_black = np.where(ground > 1e-9, black / safe, 1.0)
    ratio_full = np.where(ground > 1e-9, full / safe, 1.0)
    on_model = a > 1e-4
    return np.where(on_model, (full - black) + B * ratio_black, B * ratio_full), a[..., 0], ratio_black


def region_of_interest(alpha, ratio_black):
    """The model (coverage > 1 %) plus its shadow: where the ground keeps less than 95 % of its
    light (luminance of the ratio, 3x3 box-smoothed against Monte-Carlo noise)."""
    r = ratio_black @ np.array([0.2126, 0.7152, 0.0722])
    p = np.pad(r, 1, mode="edge")
    smooth = sum(p[1 + dy : 1 + dy + r.shape[0], 1 + dx : 1 + dx + r.shape[1]] for dy in (-1, 0, 1) for dx in (-1, 0, 1)) / 9.0
    return (alpha > 0.01) | (smooth < 0.95)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("frame_dir", help="folder from `previz bench accuracy --export-reference`")
    ap.add_argument("--spp", type=int, default=64, help="samples per pixel of the lit renders")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", required=True, help="reference composite PNG (sRGB)")
    ap.add_argument("--variant", default=None, help="Mitsuba variant (default llvm_ad_rgb, else scalar_rgb)")
    ap.add_argument(
        "--time-frame",
        action="store_true",
        help="render each lit layer (ground, black, full) once more than --time-repeats and report the sum of each layer's "
        "median timed render as frame_seconds: the path tracer's time per frame without its one-time start-up (loading, "
        "scene building, JIT compilation; the first render compiles the kernels), measured as previz's frames are "
        "(median after warm-up); the same seed gives the same image",
    )
    ap.add_argument(
        "--time-repeats",
        type=int,
        default=3,
        help="timed renders per lit layer with --time-frame (their median counts)",
    )
    ap.add_argument("--previz-model", help="previz's model_rgba.png (composite --layers): print silhouette IoU")
    ap.add_argument("--previz-background", help="previz's background.png: print the mean background difference")
    args = ap.parse_args()

    frame_path = os.path.join(args.frame_dir, "frame.json")
    try:
        with open(frame_path) as f:
            frame = json.load(f)
    except OSError as e:
        sys.exit(f"render_reference: cannot read {frame_path}: {e}")
    if args.spp < 1:
        sys.exit("render_reference: --spp must be at least 1")
    if args.time_repeats < 1:
        sys.exit("render_reference: --time-repeats must be at least 1")
    mi = pick_variant(args.variant)
    t0 = time.time()
    env = load_env(mi, frame["environment"])
    env_bitmap = mi.Bitmap(np.ascontiguousarray(previz_to_mitsuba_rows(env)).astype(np.float32))
    rho = ground_albedo(env)
    layers = {}
    warm = {}
    for what, spp in [("B", 16), ("alpha", 16), ("ground", args.spp), ("black", args.spp), ("full", args.spp)]:
        scene = build_scene(mi, frame, args.frame_dir, env_bitmap, rho, "env" if what == "B" else what, spp, args.seed)
        if args.time_frame and what in ("ground", "black", "full"):
            render(mi, scene, spp, args.seed)  # start-up: the first render compiles its kernels
            times = []
            for _ in range(args.time_repeats):
                t = time.time()
                layers[what] = render(mi, scene, spp, args.seed)
                times.append(time.time() - t)
            warm[what] = float(np.median(times))
        else:
            layers[what] = render(mi, scene, spp, args.seed)
    C, alpha, ratio = composite(layers["B"], layers["full"], layers["black"], layers["ground"], layers["alpha"])
    roi = region_of_interest(alpha, ratio)
    exposed = C * frame["exposure"]
    out8 = np.round(srgb_encode(exposed) * 255.0).astype(np.uint8)
    from PIL import Image

    tmp = args.out + ".tmp.png"
    Image.fromarray(out8, "RGB").save(tmp)
    os.replace(tmp, args.out)
    np.save(os.path.splitext(args.out)[0] + "_linear.npy", exposed.astype(np.float32))
    np.save(os.path.splitext(args.out)[0] + "_alpha.npy", alpha.astype(np.float32))
    Image.fromarray((roi * 255).astype(np.uint8), "L").save(os.path.splitext(args.out)[0] + "_roi.png")
    Image.fromarray(np.round(np.clip(alpha, 0, 1) * 255).astype(np.uint8), "L").save(os.path.splitext(args.out)[0] + "_alpha.png")
    report = {
        "out": args.out,
        "spp": args.spp,
        "seed": args.seed,
        "variant": mi.variant(),
        "ground_albedo": [round(float(x), 4) for x in rho],
        "seconds": round(time.time() - t0, 2),
        # The differential composite's lit renders at --spp, each the median of its timed runs
        # after the first: what one more frame of the same scene costs the path tracer (B is the
        # camera image, alpha the coverage: previz has both without tracing).
        **(
            {
                "frame_seconds": round(sum(warm.values()), 3),
                "layer_seconds": {k: round(v, 3) for k, v in warm.items()},
                "time_repeats": args.time_repeats,
                "threads": drjit_threads(),
            }
            if warm
            else {}
        ),
        "model_pixels": int((alpha > 0.5).sum()),
        "roi_pixels": int(roi.sum()),
    }
    if args.previz_model:
        pm = np.asarray(Image.open(args.previz_model).convert("RGBA"))[:, :, 3] > 127
        rm = alpha > 0.5
        union = (pm | rm).sum()
        report["silhouette_iou"] = round(float((pm & rm).sum() / union), 4) if union else None
    if args.previz_background:
        pb = srgb_decode(np.asarray(Image.open(args.previz_background).convert("RGB"), dtype=np.float64) / 255.0)
        rb = np.clip(layers["B"] * frame["exposure"], 0, 1)
        report["background_mean_abs_diff_linear"] = round(float(np.abs(pb - rb).mean()), 5)
        report["background_mean_linear_previz_ref"] = [round(float(pb.mean()), 5), round(float(rb.mean()), 5)]
    print(json.dumps(report))


if __name__ == "__main__":
    main()
