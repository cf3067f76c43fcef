#!/usr/bin/env python3
"""mkworld: writes marie's simulator worlds (map_server map.yaml + P5 PGM) into sim/worlds/.

The committed worlds are this script's output: `python3 sim/mkworld.py sim/worlds`.
Geometry is given in metres in the map frame (x right, y up, origin at the lower-left corner).
"""
import os
import sys

FREE, WALL = 254, 0


class Grid:
    def __init__(self, width_m, height_m, res):
        self.res = res
        self.w = int(round(width_m / res))
        self.h = int(round(height_m / res))
        self.px = [bytearray([FREE]) * self.w for _ in range(self.h)]  # row 0 = bottom

    def rect(self, x0, y0, x1, y1, val=WALL):
        """Fill cells whose centres lie inside [x0,x1] x [y0,y1]."""
        i0 = max(0, int(round(x0 / self.res)))
        i1 = min(self.w, int(round(x1 / self.res)))
        j0 = max(0, int(round(y0 / self.res)))
        j1 = min(self.h, int(round(y1 / self.res)))
        for j in range(j0, j1):
            self.px[j][i0:i1] = bytearray([val]) * (i1 - i0)

    def border(self, t):
        W, H = self.w * self.res, self.h * self.res
        self.rect(0, 0, W, t)
        self.rect(0, H - t, W, H)
        self.rect(0, 0, t, H)
        self.rect(W - t, 0, W, H)

    def write(self, directory, name, comment, extra="", yaw=0.0):
        with open(os.path.join(directory, name + ".pgm"), "wb") as f:
            f.write(b"P5\n# marie sim world %s, %g m/cell\n%d %d\n255\n" %
                    (name.encode(), self.res, self.w, self.h))
            for j in reversed(range(self.h)):  # the image's top row is the map's last row
                f.write(bytes(self.px[j]))
        with open(os.path.join(directory, name + ".yaml"), "w") as f:
            f.write("# %s\n" % comment)
            f.write("image: %s.pgm\nresolution: %g\norigin: [0.0, 0.0, %.1f]\n" % (name, self.res, yaw))
            f.write("negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n")
            f.write(extra)


def test_world(d):
    # 10 x 8 m box; walls 0.1 m thick, so the free space is x 0.1..9.9, y 0.1..7.9.
    g = Grid(10.0, 8.0, 0.05)
    g.border(0.1)
    g.rect(7.0, 0.1, 7.2, 5.0)   # wall A: x 7.0..7.2, y 0.1..5.0 (a gap above it)
    g.rect(1.0, 5.0, 2.0, 6.0)   # pillar B: x 1.0..2.0, y 5.0..6.0
    g.write(d, "test", "marie test world: 10x8 m box, wall A x 7.0-7.2 y 0.1-5.0, "
            "pillar B x 1.0-2.0 y 5.0-6.0, outer walls 0.1 m thick")


def office_world(d):
    W, H, t, wt = 40.0, 30.0, 0.2, 0.15   # size, outer and inner wall thickness
    g = Grid(W, H, 0.05)
    g.border(t)
    cy0, cy1 = 13.5, 16.5                 # main corridor along x
    cx0, cx1 = 18.5, 21.5                 # cross corridor along y
    door = 1.1                            # a real office door; the 0.3 m robot plus 0.1 m clearance leaves 0.3 m
    # Corridor walls, with one door per room.
    room_x = [t, 8.0, 14.0, cx0, cx1, 26.0, 33.0, W - t]
    for (ya, yb) in ((cy0 - wt, cy0), (cy1, cy1 + wt)):
        g.rect(0, ya, cx0, yb)
        g.rect(cx1, ya, W, yb)
    for (xa, xb) in ((cx0 - wt, cx0), (cx1, cx1 + wt)):
        g.rect(xa, 0, xb, cy0)
        g.rect(xa, cy1, xb, H)
    # Room partitions perpendicular to the corridor, and the doors into the corridor.
    for k in range(len(room_x) - 1):
        a, b = room_x[k], room_x[k + 1]
        if a == cx0:
            continue                      # that span is the cross corridor
        if k > 0 and a != cx1:
            g.rect(a - wt / 2, 0, a + wt / 2, cy0)
            g.rect(a - wt / 2, cy1, a + wt / 2, H)
        mid = (a + b) / 2
        g.rect(mid - door / 2, cy0 - wt - 0.05, mid + door / 2, cy0 + 0.05, FREE)
        g.rect(mid - door / 2, cy1 - 0.05, mid + door / 2, cy1 + wt + 0.05, FREE)
    # Doors from the cross corridor into the rooms beside it.
    for (ya, yb) in ((5.0, 5.0 + door), (24.0, 24.0 + door)):
        g.rect(cx0 - wt - 0.05, ya, cx0 + 0.05, yb, FREE)
        g.rect(cx1 - 0.05, ya, cx1 + wt + 0.05, yb, FREE)
    # A door between two neighbouring rooms on each side.
    g.rect(8.0 - wt, 6.0, 8.0 + wt, 6.0 + door, FREE)
    g.rect(33.0 - wt, 22.0, 33.0 + wt, 22.0 + door, FREE)
    # Furniture: tables and cabinets, so rooms differ for localisation.
    for (x0, y0, x1, y1) in ((3.0, 4.0, 5.0, 5.0), (10.0, 20.0, 11.0, 23.0), (28.0, 5.0, 30.5, 6.0),
                             (36.0, 25.0, 37.0, 26.0), (1.0, 26.0, 2.5, 29.5), (15.0, 2.0, 17.5, 2.6),
                             (23.0, 27.5, 25.0, 29.0), (34.5, 9.0, 35.5, 11.0)):
        g.rect(x0, y0, x1, y1)
    g.rect(5.0, 14.6, 5.4, 15.0)          # a pillar in the corridor
    g.write(d, "office", "marie office world: 40x30 m, corridors y 13.5-16.5 and x 18.5-21.5, "
            "14 rooms with 1.1 m doors", office_signs(room_x, cx0, cy0, cy1, door))


def office_signs(room_x, cx0, cy0, cy1, door):
    """Door signs for the simulator's camera (docs/vision.md): a tag36h11 tag on the corridor
    wall beside each room's door, at the camera's height, facing the corridor. Rooms are
    lettered A, B, ... west to east, south side first; the tag id is the letter's rank + 1."""
    lines = ["# door signs: tag id k+1 is room chr(ord('A')+k); x, y on the wall face, yaw: where it faces",
             "camera: {width: 640, height: 480, fx: 500, fy: 500, mount_x: 0.2, mount_z: 0.5, noise: 2, blur: 0.5}",
             "tags:"]
    k = 0
    for (wall_y, yaw, side) in ((cy0 + 0.01, 1.5708, "south"), (cy1 - 0.01, -1.5708, "north")):
        for i in range(len(room_x) - 1):
            a, b = room_x[i], room_x[i + 1]
            if a == cx0:
                continue
            x = (a + b) / 2 + door / 2 + 0.45
            lines.append("  - {id: %d, x: %.2f, y: %.2f, z: 0.5, yaw: %.4f, size: 0.2}   # room %s, %s side"
                         % (k + 1, x, wall_y, yaw, chr(ord('A') + k), side))
            k += 1
    return "\n".join(lines) + "\n"


def small_world(d):
    # 10 x 6 m for a robot of 0.18 m radius: three rooms joined by a 0.6 m door and a 0.7 m
    # corridor, and a 0.5 m slot into a closet. None of it is passable at the default 0.3 m.
    g = Grid(10.0, 6.0, 0.05)
    g.border(0.1)
    g.rect(4.0, 0.1, 4.2, 2.7)            # west wall, door y 2.7..3.3 (0.6 m)
    g.rect(4.0, 3.3, 4.2, 5.9)
    g.rect(7.0, 0.1, 7.2, 2.0)            # east block: a corridor y 2.0..2.7 (0.7 m) from x 7.0
    g.rect(7.2, 1.8, 9.0, 2.0)            # to x 9.0, then south into the south-east room
    g.rect(7.0, 2.7, 9.9, 2.9)
    g.rect(7.0, 2.9, 7.2, 3.5)            # north-east room, door y 3.5..4.1 (0.6 m)
    g.rect(7.0, 4.1, 7.2, 5.9)
    g.rect(7.2, 4.2, 8.6, 4.4)            # closet wall, slot x 8.6..9.1 (0.5 m)
    g.rect(9.1, 4.2, 9.9, 4.4)
    for (x0, y0, x1, y1) in ((1.0, 1.0, 1.6, 1.4), (2.5, 4.5, 3.0, 5.2), (5.2, 0.8, 5.6, 1.6),
                             (5.5, 4.6, 6.3, 5.0), (8.0, 0.6, 8.6, 1.0)):
        g.rect(x0, y0, x1, y1)            # furniture, so places differ for localisation
    g.write(d, "small", "marie small-robot world: 10x6 m, a 0.6 m door at x 4.0-4.2 y 2.7-3.3, "
            "a 0.7 m corridor y 2.0-2.7 x 7.0-9.0, a 0.6 m door x 7.0-7.2 y 3.5-4.1, a 0.5 m slot x 8.6-9.1 y 4.2-4.4")


# ---- the evaluation worlds (marie-eval), written at build time, not committed ----

def maze_world(d, corridor=0.8, wall=0.1, n=8, seed=7):
    """A perfect maze of n x n cells of `corridor` m, walls `wall` m, from a seeded depth-first walk."""
    import random
    rnd = random.Random(seed)
    pitch = corridor + wall
    size = n * pitch + wall
    g = Grid(size, size, 0.05)
    g.rect(0, 0, size, size)              # all wall, then carve
    seen = {(0, 0)}
    stack = [(0, 0)]

    def carve_cell(i, j):
        g.rect(wall + i * pitch, wall + j * pitch, wall + i * pitch + corridor, wall + j * pitch + corridor, FREE)
    carve_cell(0, 0)
    while stack:
        i, j = stack[-1]
        nb = [(i + di, j + dj) for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1))
              if 0 <= i + di < n and 0 <= j + dj < n and (i + di, j + dj) not in seen]
        if not nb:
            stack.pop()
            continue
        a, b = rnd.choice(nb)
        carve_cell(a, b)
        x0 = wall + min(i, a) * pitch
        y0 = wall + min(j, b) * pitch
        if a != i:
            g.rect(x0 + corridor, y0, x0 + corridor + wall, y0 + corridor, FREE)
        else:
            g.rect(x0, y0 + corridor, x0 + corridor, y0 + corridor + wall, FREE)
        seen.add((a, b))
        stack.append((a, b))
    g.write(d, "maze", "eval maze: %dx%d cells, %.1f m corridors, %.1f m walls" % (n, n, corridor, wall))


def warehouse_world(d):
    g = Grid(24.0, 16.0, 0.05)
    g.border(0.2)
    for k in range(6):                     # racks 0.8 m deep, 2.0 m aisles, a cross aisle at y 7-9
        x = 3.0 + k * 2.8
        g.rect(x, 2.0, x + 0.8, 7.0)
        g.rect(x, 9.0, x + 0.8, 14.0)
    g.rect(0.2, 10.5, 1.5, 11.5)           # a pallet by the dock
    g.write(d, "warehouse", "eval warehouse: 24x16 m, 12 racks 0.8x5 m, 2.0 m aisles, cross aisle y 7-9")


def hall_world(d):
    g = Grid(20.0, 14.0, 0.05)
    g.border(0.2)
    for i in range(4):
        for j in range(3):
            x, y = 3.5 + i * 4.0, 3.5 + j * 3.5
            g.rect(x - 0.25, y - 0.25, x + 0.25, y + 0.25)
    g.write(d, "hall", "eval open hall: 20x14 m, 12 pillars 0.5 m square on a 4 x 3.5 m grid")


def cluttered_world(d, seed=11):
    import random
    rnd = random.Random(seed)
    g = Grid(12.0, 10.0, 0.05)
    g.border(0.15)
    for _ in range(22):                    # boxes 0.3-1.0 m, kept 1.2 m apart so the room stays connected
        for _try in range(200):
            w, h = rnd.uniform(0.3, 1.0), rnd.uniform(0.3, 1.0)
            x, y = rnd.uniform(0.8, 11.2 - w), rnd.uniform(0.8, 9.2 - h)
            if all(x > bx + bw + 1.2 or bx > x + w + 1.2 or y > by + bh + 1.2 or by > y + h + 1.2
                   for bx, by, bw, bh in getattr(g, "boxes", [])):
                g.boxes = getattr(g, "boxes", []) + [(x, y, w, h)]
                g.rect(x, y, x + w, y + h)
                break
    g.write(d, "cluttered", "eval cluttered room: 12x10 m, random boxes 0.3-1.0 m at least 1.2 m apart")


def eval_worlds(d):
    office_world(d)
    maze_world(d)
    warehouse_world(d)
    hall_world(d)
    cluttered_world(d)
    # The hall again with its origin turned by 0.4 rad: the map frame is not the image's.
    g = Grid(20.0, 14.0, 0.05)
    g.border(0.2)
    for (x0, y0, x1, y1) in ((5.0, 4.0, 6.0, 5.0), (12.0, 8.0, 12.5, 11.0), (15.0, 3.0, 17.0, 3.5)):
        g.rect(x0, y0, x1, y1)
    g.write(d, "rotated", "eval room with origin yaw 0.4 rad: 20x14 m, three obstacles", yaw=0.4)
    # Fine and coarse cells: the warehouse at 0.025 m, the hall at 0.1 m.
    for name, res, build in (("fine", 0.025, "warehouse"), ("coarse", 0.1, "hall")):
        g = Grid(24.0 if build == "warehouse" else 20.0, 16.0 if build == "warehouse" else 14.0, res)
        g.border(0.2)
        if build == "warehouse":
            for k in range(6):
                x = 3.0 + k * 2.8
                g.rect(x, 2.0, x + 0.8, 7.0)
                g.rect(x, 9.0, x + 0.8, 14.0)
        else:
            for i in range(4):
                for j in range(3):
                    x, y = 3.5 + i * 4.0, 3.5 + j * 3.5
                    g.rect(x - 0.3, y - 0.3, x + 0.3, y + 0.3)
        g.write(d, name, "eval %s at %g m cells" % (build, res))


if __name__ == "__main__":
    if len(sys.argv) > 2 and sys.argv[1] == "--eval":
        os.makedirs(sys.argv[2], exist_ok=True)
        eval_worlds(sys.argv[2])
        sys.exit(0)
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "worlds")
    os.makedirs(out, exist_ok=True)
    test_world(out)
    office_world(out)
    small_world(out)
