#!/usr/bin/env python3
"""SPA evaluations per second: previz (Rust, one thread) against pvlib's numpy SPA, in one run.

Both evaluate the full SPA (geocentric + topocentric + refraction) for random instants in
1600-3000 at random places, with the same estimator: the cases are timed in chunks of 4096
over 5 passes and the fastest chunk counts (on a shared machine a chunk that lost the CPU only
reads slower). pvlib evaluates each chunk as numpy arrays in one call
(spa.solar_position_numpy, no numba); `previz sun bench` evaluates the cases one by one on one
thread. pvlib's rate with the whole array in one call is printed too.

Run from the repository root after `cargo build --release`:
    python3 tests/data/sun/bench_vs_pvlib.py [--cases 200000] [--exe target/release/previz]
"""
import argparse
import json
import platform
import random
import subprocess
import time

import numpy as np
import pvlib
from pvlib import spa


def cpu_model():
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", type=int, default=200_000)
    ap.add_argument("--exe", default="target/release/previz")
    a = ap.parse_args()

    rng = random.Random(1)
    t0 = -11_676_096_000.0  # 1600-01-01T00:00:00Z
    t1 = 32_535_215_999.0  # 3000-12-31T23:59:59Z
    n = a.cases
    unixtime = np.array([rng.uniform(t0, t1) for _ in range(n)])
    lat = np.degrees(np.arcsin(np.array([rng.uniform(-1, 1) for _ in range(n)])))
    lon = np.array([rng.uniform(-180, 180) for _ in range(n)])
    delta_t = np.full(n, 69.0)

    chunk = 4096
    best = float("inf")
    for _ in range(5):
        for i in range(0, n, chunk):
            sl = slice(i, min(n, i + chunk))
            start = time.perf_counter()
            spa.solar_position_numpy(unixtime[sl], lat[sl], lon[sl], 0.0, 1013.25, 15.0, delta_t[sl], 0.5667, 1)
            best = min(best, (time.perf_counter() - start) / (sl.stop - sl.start))
    pvlib_rate = 1.0 / best

    whole = float("inf")
    for _ in range(3):
        start = time.perf_counter()
        spa.solar_position_numpy(unixtime, lat, lon, 0.0, 1013.25, 15.0, delta_t, 0.5667, 1)
        whole = min(whole, time.perf_counter() - start)

    out = subprocess.run([a.exe, "sun", "bench", "--cases", str(n), "--json"],
                         check=True, capture_output=True, text=True).stdout
    ours = json.loads(out)
    ratio = ours["evals_per_s"] / pvlib_rate

    print(f"machine: {cpu_model()}, {platform.machine()}, Python {platform.python_version()}, "
          f"numpy {np.__version__}, pvlib {pvlib.__version__}")
    print(f"cases: {n} (years 1600-3000, random places)")
    print(f"pvlib numpy SPA : {pvlib_rate:12.0f} evaluations/s ({1e9 / pvlib_rate:8.1f} ns each, fastest chunk of {chunk})")
    print(f"previz SPA      : {ours['evals_per_s']:12.0f} evaluations/s ({ours['ns_per_eval']:8.1f} ns each, fastest chunk of {chunk})")
    print(f"(pvlib with all {n} cases in one call: {n / whole:.0f} evaluations/s, best of 3)")
    print(f"ratio previz/pvlib: {ratio:.2f}")


if __name__ == "__main__":
    main()
