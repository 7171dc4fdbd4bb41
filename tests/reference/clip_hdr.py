# Clipped-map recovery check (tests/reference/README.md): read a Radiance .hdr (new RLE),
# scale it, clip at 1.0 and write flat RGBE. Usage: clip_hdr.py IN.hdr OUT.hdr SCALE

import sys, math
src, dst, scale = sys.argv[1], sys.argv[2], float(sys.argv[3])
data = open(src, 'rb').read()
i = data.index(b'\n\n') + 2
j = data.index(b'\n', i)
dims = data[i:j].split(); h, w = int(dims[1]), int(dims[3]); p = j + 1
out = bytearray(b'#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n' + f'-Y {h} +X {w}\n'.encode())
def enc(r, g, b):
    m = max(r, g, b)
    if m < 1e-32: return bytes(4)
    f, e = math.frexp(m); s = f * 256.0 / m
    return bytes([int(r * s), int(g * s), int(b * s), e + 128])
for y in range(h):
    assert data[p] == 2 and data[p+1] == 2; p += 4
    ch = [bytearray() for _ in range(4)]
    for c in range(4):
        while len(ch[c]) < w:
            n = data[p]; p += 1
            if n > 128: ch[c] += bytes([data[p]]) * (n - 128); p += 1
            else: ch[c] += data[p:p+n]; p += n
    for x in range(w):
        e = ch[3][x]
        if e == 0: out += bytes(4); continue
        f = math.ldexp(1.0, e - 136)
        r, g, b = [min((ch[k][x] + 0.5) * f * scale, 1.0) for k in range(3)]
        out += enc(r, g, b)
open(dst, 'wb').write(out)
