"""spy_check: reads a screenshot of lcm-spy (xwd -root) and checks that the real Spy decoded
the marie types: its table's first row (channel AAA.unknown, bytes of no known type) counts
its message in the Undecodable column ("1"), and the rows after it (marie types published by
the test) show the very same Undecodable cell as one another ("0") and unlike the first row,
with a type name in their Type cell. Without the types jar every row would read "1".
lcm-spy's default layout: a 20 px header, rows 16 px high, Type x 158-313, Undecodable
x 690-782.
  python3 tests/tools/spy_check.py SHOT.xwd      exit 0 when both hold"""
import struct
import sys


def read_xwd(path):
    d = open(path, "rb").read()
    h = struct.unpack(">25I", d[:100])
    hsize, w, hgt, byte_order, bpp, bpl, ncolors = h[0], h[4], h[5], h[7], h[11], h[12], h[19]
    if bpp != 32:
        raise ValueError("xwd with %d bits per pixel" % bpp)
    off = hsize + ncolors * 12

    def dark(x, y):
        p = d[off + y * bpl + x * 4: off + y * bpl + x * 4 + 4]
        r, g, b = (p[2], p[1], p[0]) if byte_order == 0 else (p[1], p[2], p[3])
        return r + g + b < 300
    return w, hgt, dark


def main():
    w, h, dark = read_xwd(sys.argv[1])
    rows = [(20 + 16 * i + 2, 20 + 16 * i + 14) for i in range(6)]
    channel = [sum(dark(x, y) for y in range(a, b) for x in range(2, 150)) for a, b in rows]
    if min(channel) == 0:
        print("spy_check: the Spy's table has fewer than 6 rows (channel text %s)" % channel)
        sys.exit(1)
    typed = [sum(dark(x, y) for y in range(a, b) for x in range(160, 312)) for a, b in rows]
    undec = [sum(dark(x, y) for y in range(a, b) for x in range(692, 780)) for a, b in rows]
    print("spy_check: dark pixels in the first rows' Type cells %s, Undecodable cells %s" % (typed, undec))
    marie = undec[1:]
    ok = all(n > 20 for n in typed[1:]) and len(set(marie)) == 1 and marie[0] != undec[0] and undec[0] > 0
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
