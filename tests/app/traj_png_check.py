"""traj_png_check: the demo's trajectories.png is the office map at 2 px per cell, with a goal
ring at every goal and the true trajectory (green) passing by each of them: within the mission's
goal tolerance (the robot stops when its estimate is that close) plus 0.3 m of localization error.
  python3 tests/app/traj_png_check.py PNG MAP.pgm RESOLUTION TOLERANCE X,Y...   (metres)"""
import math
import sys

sys.path.insert(0, "tests/viewer")
from png_check import read_png  # noqa: E402


def pgm_size(path):
    fields, data = [], open(path, "rb").read()
    for tok in data.split(b"\n"):
        if tok.startswith(b"#"):
            continue
        fields += tok.split()
        if len(fields) >= 3:
            return int(fields[1]), int(fields[2])
    raise ValueError("bad PGM header")


def main():
    png, pgm, res, tolerance = sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4])
    goals = [tuple(float(v) for v in g.split(",")) for g in sys.argv[5:]]
    near = int((tolerance + 0.3) / res * 2)     # px
    w, h, px = read_png(png)
    mw, mh = pgm_size(pgm)
    ok = (w, h) == (2 * mw, 2 * mh)
    print("image %dx%d, map %dx%d cells" % (w, h, mw, mh))
    blue = lambda c: c[2] > 150 and c[0] < 80           # goal rings, RGB (20, 90, 200)
    green = lambda c: c[1] > 130 and c[0] < 110 and c[2] < 110   # truth, RGB (60, 170, 60)

    def any_near(x, y, r, want):
        return any(want(px(i, j)) for j in range(max(0, y - r), min(h, y + r + 1))
                   for i in range(max(0, x - r), min(w, x + r + 1)) if (i - x) ** 2 + (j - y) ** 2 <= r * r)
    for gx, gy in goals:
        x, y = int(gx / res * 2), int(h - gy / res * 2)
        ring = sum(any_near(int(x + 14 * math.cos(a)), int(y - 14 * math.sin(a)), 2, blue)
                   for a in [k * math.pi / 4 for k in range(8)])
        path = any_near(x, y, near, green)
        print("goal (%.1f, %.1f): ring %d/8, true trajectory %s" % (gx, gy, ring, "passes" if path else "absent"))
        ok = ok and ring >= 6 and path
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
