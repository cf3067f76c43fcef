"""png_check: finds what the viewer must have drawn in a screenshot of its page: the true robot
pose and the laser points of the sample shown (from viewer-gen --truth), at pixels computed here
from the map's size and the canvas's place on the page, independently of the page's own code.
  python3 tests/viewer/png_check.py SHOT.png CANVAS.json TRUTH.txt T
CANVAS.json: [left, top, width, height] of the map canvas's drawing area in the screenshot.
Decodes the PNG with zlib only. Exit 0 when the pose and at least 90% of the in-view laser
points are found on screen in their colours, 1 (with the reason) otherwise."""
import json
import math
import struct
import sys
import zlib

MAP_W, MAP_H = 400 * 0.05, 300 * 0.05      # viewer-gen's map, origin (0, 0)


def read_png(path):
    data = open(path, "rb").read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError("not a PNG")
    pos, idat, hdr = 8, b"", None
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        pos += 12 + n
        if kind == b"IHDR":
            hdr = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        elif kind == b"IEND":
            break
    w, h, depth, ctype, _, _, interlace = hdr
    if depth != 8 or ctype not in (2, 6) or interlace:
        raise ValueError("unsupported PNG (depth %d, colour type %d, interlace %d)" % (depth, ctype, interlace))
    bpp = 3 if ctype == 2 else 4
    raw = zlib.decompress(idat)
    stride = w * bpp
    rows, prev, off = [], bytearray(stride), 0
    for _ in range(h):
        f, line = raw[off], bytearray(raw[off + 1:off + 1 + stride])
        off += 1 + stride
        for i in range(stride):
            a = line[i - bpp] if i >= bpp else 0
            b = prev[i]
            c = prev[i - bpp] if i >= bpp else 0
            if f == 1:
                line[i] = (line[i] + a) & 255
            elif f == 2:
                line[i] = (line[i] + b) & 255
            elif f == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append(line)
        prev = line
    return w, h, lambda x, y: tuple(rows[y][x * bpp:x * bpp + 3])


def near(px, x, y, r, want, w, h):
    for j in range(int(y) - r, int(y) + r + 1):
        for i in range(int(x) - r, int(x) + r + 1):
            if 0 <= i < w and 0 <= j < h and want(px(i, j)):
                return True
    return False


def red(c):        # laser points: rgba(229,57,53,0.85)
    return c[0] > 180 and c[1] < 110 and c[2] < 110


def robot_colour(c):    # true pose #2e7d32 (green), the estimate over it #1565c0 (blue)
    return (c[1] > c[0] + 40 and c[1] > c[2] + 40) or (c[2] > c[0] + 60 and c[2] > c[1] + 40)


def check(sample, px, w, h, canvas):
    left, top, cw, chh = canvas
    scale = min(cw / MAP_W, chh / MAP_H) * 0.98
    to = lambda x, y: (left + cw / 2 + (x - MAP_W / 2) * scale, top + chh / 2 - (y - MAP_H / 2) * scale)
    ts, x, y, th = sample[:4]
    ranges = sample[4:]
    # the robot's circle: radius max(4, 0.25 m) around the pose, heading line through the centre
    cx, cy = to(x, y)
    rr = max(4, 0.25 * scale)
    ring = sum(near(px, cx + rr * math.cos(a), cy - rr * math.sin(a), 2, robot_colour, w, h)
               for a in [k * math.pi / 8 for k in range(16)])
    pts = found = 0
    for b, r in enumerate(ranges):
        if r >= 8.0:
            continue
        a = th - math.pi / 2 + b * math.pi / 180
        lx, ly = to(x + r * math.cos(a), y + r * math.sin(a))
        if not (left + 3 <= lx < left + cw - 3 and top + 3 <= ly < top + chh - 3):
            continue
        pts += 1
        found += near(px, lx, ly, 2, red, w, h)
    return ts, ring, pts, found


def main():
    shot, canvas_f, truth_f, t = sys.argv[1], sys.argv[2], sys.argv[3], float(sys.argv[4])
    w, h, px = read_png(shot)
    canvas = json.load(open(canvas_f))
    samples = [[float(v) for v in line.split()] for line in open(truth_f)]
    # the page shows the last sample at or before T; allow the one either side of it
    near_t = [s for s in samples if abs(s[0] - t) <= 0.15]
    best = None
    for s in near_t:
        ts, ring, pts, found = check(s, px, w, h, canvas)
        print("sample %.1f s: pose ring %d/16 in robot colours, laser %d/%d points red" % (ts, ring, found, pts))
        if ring >= 12 and pts >= 20 and found >= 0.9 * pts:
            best = ts
    if best is None:
        print("png_check: no sample near %.1f s is drawn at its place in %s" % (t, shot))
        sys.exit(1)
    print("png_check: pose and laser of %.1f s drawn where they belong" % best)


if __name__ == "__main__":
    main()
