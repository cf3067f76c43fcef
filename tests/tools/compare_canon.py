#!/usr/bin/env python3
"""compare_canon: compares two files of "#CHANNEL" headers and "path=value" lines, message by
message and field by field: reals numerically (NaN equals NaN), a Java (signed) byte equal to
the C (unsigned) byte it stands for, everything else as text. Field order does not matter."""
import math
import sys


def messages(path):
    msgs, cur = [], None
    for line in open(path, encoding="utf-8", errors="surrogateescape"):
        line = line.rstrip("\n")
        if line.startswith("#"):
            cur = (line[1:], {})
            msgs.append(cur)
        elif cur is not None and "=" in line:
            k, v = line.split("=", 1)
            cur[1][k] = v
    return msgs


def same(a, b):
    if a == b:
        return True
    try:
        ia, ib = int(a), int(b)
        return ia == ib or (-128 <= ib < 0 and ia == ib + 256) or (-128 <= ia < 0 and ib == ia + 256)
    except ValueError:
        pass
    try:
        fa, fb = float(a), float(b)
    except ValueError:
        return False
    return fa == fb or (math.isnan(fa) and math.isnan(fb))


def main():
    want, got = messages(sys.argv[1]), messages(sys.argv[2])
    if len(want) != len(got):
        print("compare_canon: %d messages expected, %d decoded" % (len(want), len(got)))
        return 1
    bad = 0
    fields = 0
    for (cw, fw), (cg, fg) in zip(want, got):
        if cw != cg:
            print("compare_canon: channel %s, decoded %s" % (cw, cg))
            bad += 1
            continue
        if set(fw) != set(fg):
            print("compare_canon: %s: fields differ: %s" % (cw, sorted(set(fw) ^ set(fg))[:8]))
            bad += 1
            continue
        for k in fw:
            fields += 1
            if not same(fw[k], fg[k]):
                print("compare_canon: %s %s: expected %s, decoded %s" % (cw, k, fw[k], fg[k]))
                bad += 1
    print("compare_canon: %d messages, %d fields, %d differences" % (len(want), fields, bad))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
