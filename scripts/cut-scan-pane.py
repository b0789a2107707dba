#!/usr/bin/env python3
# Usage: python3 scripts/cut-scan-pane.py SRC_SCAN DST_SCAN (python3 alone, no numpy).
# Copies a Redwood-layout Cycles scan, setting the depth to 0 (no return) where a frame
# sees the truth's emitter pane: frosted glass that returned no depth.
import json, os, shutil, struct, sys, zlib
src, dst = sys.argv[1], sys.argv[2]
shutil.rmtree(dst, ignore_errors=True)
shutil.copytree(src, dst)
intr = json.load(open(os.path.join(src, 'intrinsics.json')))
fx, fy, cx, cy = intr['fx'], intr['fy'], intr['cx'], intr['cy']
truth = json.load(open(os.path.join(src, 'truth.json')))
c = truth['emitters'][0]['corners']
lo = [min(p[k] for p in c) for k in range(3)]; hi = [max(p[k] for p in c) for k in range(3)]
lines = open(os.path.join(src, 'trajectory.log')).read().split('\n')
poses = []
for i in range(0, len(lines) - 4, 5):
    if not lines[i].strip(): continue
    poses.append([[float(x) for x in lines[i + 1 + r].split()] for r in range(4)])

def read_png16(path):
    d = open(path, 'rb').read(); pos = 8; idat = b''
    while pos < len(d):
        n, t = struct.unpack('>I4s', d[pos:pos + 8]); body = d[pos + 8:pos + 8 + n]
        if t == b'IHDR': w, h, bd, ct = struct.unpack('>IIBB', body[:10])
        if t == b'IDAT': idat += body
        pos += 12 + n
    assert bd == 16 and ct == 0
    raw = zlib.decompress(idat); stride = 2 * w; out = []; prev = bytearray(stride); p = 0
    for y in range(h):
        f = raw[p]; line = bytearray(raw[p + 1:p + 1 + stride]); p += 1 + stride
        for i in range(stride):
            a = line[i - 2] if i >= 2 else 0; b = prev[i]; cc = prev[i - 2] if i >= 2 else 0
            if f == 1: line[i] = (line[i] + a) & 255
            elif f == 2: line[i] = (line[i] + b) & 255
            elif f == 3: line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                pa, pb, pc = abs(b - cc), abs(a - cc), abs(a + b - 2 * cc)
                pr = a if pa <= pb and pa <= pc else (b if pb <= pc else cc)
                line[i] = (line[i] + pr) & 255
        out.append([struct.unpack('>H', line[2 * x:2 * x + 2])[0] for x in range(w)]); prev = line
    return w, h, out

def write_png16(path, w, h, rows):
    raw = b''.join(b'\x00' + b''.join(struct.pack('>H', v) for v in r) for r in rows)
    def chunk(t, b): return struct.pack('>I', len(b)) + t + b + struct.pack('>I', zlib.crc32(t + b) & 0xffffffff)
    png = b'\x89PNG\r\n\x1a\n' + chunk(b'IHDR', struct.pack('>IIBBBBB', w, h, 16, 0, 0, 0, 0)) + chunk(b'IDAT', zlib.compress(raw, 6)) + chunk(b'IEND', b'')
    open(path + '.tmp', 'wb').write(png); os.replace(path + '.tmp', path)

names = sorted(os.listdir(os.path.join(src, 'depth')))
total = 0
for k, name in enumerate(names):
    w, h, rows = read_png16(os.path.join(src, 'depth', name))
    P = poses[k]; cut = 0
    for y in range(h):
        for x in range(w):
            z = rows[y][x] / 1000.0
            if z <= 0: continue
            X = (x - cx) / fx * z; Y = (y - cy) / fy * z
            wp = [P[r][0] * X + P[r][1] * Y + P[r][2] * z + P[r][3] for r in range(3)]
            if all(lo[i] - 0.03 <= wp[i] <= hi[i] + 0.03 for i in range(3)):
                rows[y][x] = 0; cut += 1
    total += cut
    write_png16(os.path.join(dst, 'depth', name), w, h, rows)
    print(name, cut, flush=True)
print('pixels cut', total)
