#!/usr/bin/env python3
"""Measure how well the reference renderer's environment lookup matches previz's equirect
convention (u*W - 0.5, v*H - 0.5 bilinear; centre column = heading): renders the bare environment
with Mitsuba and compares with a numpy evaluation of previz's lookup (6x6 supersampled) at four
views; prints the mean relative luminance difference and the difference after shifting by whole
rows/columns (the best shift must be 0). NOCORR=1 skips the row correction for comparison."""
import sys, os, math, numpy as np
HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import render_reference as rr
mi = rr.pick_variant(None)
env = rr.load_env(mi, os.path.join(HERE, '../data/hdri/polyhaven_1k/quarry_01_1k.hdr'))
H, W = env.shape[:2]
NOCORR = os.environ.get("NOCORR") == "1"  # 1: skip the row resampling, to measure what it fixes
def previz_sample(d, heading):
    az = np.arctan2(d[...,0], d[...,1]); el = np.arctan2(d[...,2], np.hypot(d[...,0], d[...,1]))
    u = np.mod(0.5 + (az - heading)/(2*math.pi), 1.0); v = 0.5 - el/math.pi
    x = u*W - 0.5; y = np.clip(v*H - 0.5, 0, H-1)
    x0 = np.floor(x); fx = x - x0; x0 = x0.astype(int) % W; x1 = (x0+1) % W
    y0 = np.floor(y).astype(int); y1 = np.minimum(y0+1, H-1); fy = (y - y0)
    p = lambda yy, xx: env[yy, xx]
    top = p(y0,x0)*(1-fx)[...,None] + p(y0,x1)*fx[...,None]
    bot = p(y1,x0)*(1-fx)[...,None] + p(y1,x1)*fx[...,None]
    return top*(1-fy)[...,None] + bot*fy[...,None]
for heading_deg, cam_az, pitch in [(0, 36, 5), (30, 66, 5), (0, 200, 30), (0, 36, -30)]:
    w, h, vfov = 160, 120, 20.0
    f = np.array([math.sin(math.radians(cam_az))*math.cos(math.radians(pitch)), math.cos(math.radians(cam_az))*math.cos(math.radians(pitch)), math.sin(math.radians(pitch))])
    right = np.cross(f, [0,0,1]); right /= np.linalg.norm(right); up = np.cross(right, f)
    frame = dict(width=w, height=h, vfov_deg=vfov, eye=[0,0,0], target=f.tolist(), up=up.tolist(), env_heading_deg=heading_deg)
    bmp = mi.Bitmap(np.ascontiguousarray(np.roll(env, -W//2, axis=1) if NOCORR else rr.previz_to_mitsuba_rows(env)).astype(np.float32))
    sc = rr.build_scene(mi, frame, '.', bmp, np.array([0.2]*3), 'env', 64, 0)
    B = rr.render(mi, sc, 64, 0)
    # numpy: supersample 8x8 per pixel with the previz camera convention
    t = math.tan(math.radians(vfov)/2); a = w/h
    acc = np.zeros((h,w,3))
    n=6
    for sy in range(n):
        for sx in range(n):
            px = (np.arange(w)+(sx+0.5)/n)/w*2-1; py = 1-(np.arange(h)+(sy+0.5)/n)/h*2
            X, Y = np.meshgrid(px*t*a, py*t)
            d = X[...,None]*right + Y[...,None]*up + f
            d /= np.linalg.norm(d, axis=-1, keepdims=True)
            acc += previz_sample(d, math.radians(heading_deg))
    acc /= n*n
    lum = lambda x: x@np.array([0.2126,0.7152,0.0722])
    rel = np.abs(lum(B)-lum(acc)).mean()/lum(acc).mean()
    # best vertical shift in pixels (image rows) of B vs acc
    errs = {}
    for s in [-2,-1,0,1,2]:
        errs[s] = float(np.abs(np.roll(lum(B), s, axis=0)[3:-3]-lum(acc)[3:-3]).mean()/lum(acc).mean())
    errsx = {s: float(np.abs(np.roll(lum(B), s, axis=1)[:,3:-3]-lum(acc)[:,3:-3]).mean()/lum(acc).mean()) for s in [-2,-1,0,1,2]}
    print(heading_deg, cam_az, pitch, 'rel', round(rel,4), 'rows', {k: round(v,4) for k,v in errs.items()}, 'cols', {k: round(v,4) for k,v in errsx.items()})
