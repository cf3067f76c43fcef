#!/usr/bin/env python3
"""test_lcm_python_peer: upstream LCM for Python (PyPI `lcm`, its own C receiver, in the venv
scripts/peer-venv.sh makes), a reader no one here wrote, gets what marie_bus_publish() sent
from marie's own socket: empty, one byte, around the single-datagram limit, 65 KB and 900 KB,
every byte and in order; and again with MARIE_LCM_SEND=liblcm (liblcm sending), the same."""
import os
import subprocess
import sys
import time

import lcm

B = os.environ.get("B", "build")
URL = "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=4194304"
CHANNEL = "T_PY_PEER"
# "T_PY_PEER" and its NUL take 10 bytes: 65489 is the largest message in one datagram.
SIZES = [0, 1, 65488, 65489, 65490, 66560, 921600, 64]
ok_count = 0
bad_count = 0


def case(name, passed, detail=""):
    global ok_count, bad_count
    print("[ RUN      ] %s" % name)
    if passed:
        print("[       OK ] %s" % name)
        ok_count += 1
    else:
        print("[  FAILED  ] %s%s" % (name, ": " + detail if detail else ""))
        bad_count += 1


def expected(i, n):
    return bytes((k * 31 + i) % 256 for k in range(n))


def run(name, env_extra, want_sends):
    got = []
    lc = lcm.LCM(URL)
    sub = lc.subscribe(CHANNEL, lambda ch, data: got.append(data))
    env = dict(os.environ, **env_extra)
    out = subprocess.run([os.path.join(B, "tests", "lcm_send"), URL, CHANNEL] + [str(s) for s in SIZES],
                         env=env, capture_output=True, text=True, timeout=30)
    end = time.time() + 5
    while len(got) < len(SIZES) and time.time() < end:
        lc.handle_timeout(100)
    lc.unsubscribe(sub)
    sizes = [len(d) for d in got]
    case(name + "_sent_by", out.returncode == 0 and out.stdout.strip() == "sends=%d" % want_sends,
         "%r %r" % (out.stdout, out.stderr))
    case(name + "_sizes_in_order", sizes == SIZES, "got %r" % sizes)
    bad = [i for i, d in enumerate(got) if i < len(SIZES) and d != expected(i, SIZES[i])]
    case(name + "_bytes_exact", len(got) == len(SIZES) and not bad, "messages %r differ" % bad)


run("marie_sends", {}, 1)
run("liblcm_sends", {"MARIE_LCM_SEND": "liblcm"}, 0)
print("[  PASSED  ] %d test(s)." % ok_count)
if bad_count:
    print("[  FAILED  ] %d test(s)." % bad_count)
sys.exit(1 if bad_count else 0)
