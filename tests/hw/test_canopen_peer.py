#!/usr/bin/env python3
"""test_canopen_peer: python-canopen, a CANopen master no one here wrote, against marie's
virtual drives and gyro on the emulated bus (marie-canbus): the identity object 0x1018 and the
device type, an expedited SDO download without size indication, reset communication restoring
communication objects and keeping application ones, and the drive's heartbeat consumer: a
master that configures 0x1016, sets the motor turning and falls silent sees 0x606C reach 0
within 300 ms. Also the bus's filter packet, packed here from docs/hw/canopen.md: a client that
told it one filter is sent only the frames that filter takes."""
import os
import select
import socket
import struct
import subprocess
import sys
import time

import canopen

from canopen_emubus import EmuBus

B = os.environ.get("B", "build")
SOCK = "/tmp/marie-test-canopen-peer-%d.sock" % os.getpid()
ok_count = 0
bad_count = 0


def check(name, fn):
    global ok_count, bad_count
    print("[ RUN      ] %s" % name, flush=True)
    try:
        fn()
        print("[       OK ] %s" % name, flush=True)
        ok_count += 1
    except Exception as e:  # report and go on: every check runs
        print("  %s: %r" % (name, e), flush=True)
        print("[  FAILED  ] %s" % name, flush=True)
        bad_count += 1


def u32(node, index, sub):
    return struct.unpack("<I", node.sdo.upload(index, sub).ljust(4, b"\0")[:4])[0]


def i32(node, index, sub):
    return struct.unpack("<i", node.sdo.upload(index, sub)[:4])[0]


procs = []
os.makedirs(B + "/test-logs", exist_ok=True)
log = open(B + "/test-logs/test_canopen_peer.devices.log", "w")
procs.append(subprocess.Popen([B + "/bin/marie-canbus", SOCK], stdout=log, stderr=log))
for _ in range(50):
    if os.path.exists(SOCK):
        break
    time.sleep(0.1)
procs.append(subprocess.Popen([B + "/bin/marie-vcan-devices", "--can", "emu:" + SOCK], stdout=log, stderr=log))
time.sleep(0.5)
net = canopen.Network(EmuBus(SOCK))
net.connect()
drive = net.add_node(1, canopen.ObjectDictionary())
gyro = net.add_node(0x20, canopen.ObjectDictionary())


def identity():
    for node, n in ((drive, 1), (gyro, 0x20)):
        assert node.sdo.upload(0x1018, 0)[0] == 4, "0x1018 sub 0"
        for sub in (1, 2, 3):
            u32(node, 0x1018, sub)                      # present and readable
        assert u32(node, 0x1018, 4) == n, "serial"
    assert u32(drive, 0x1000, 0) & 0xFFFF == 402


def download_without_size():
    answers = []

    def on_answer(cid, data, ts):
        answers.append(bytes(data))
    net.subscribe(0x581, on_answer)
    net.send_message(0x601, bytes([0x22, 0x60, 0x60, 0, 3, 0, 0, 0]))      # 0x6060 := 3, no size
    end = time.time() + 1
    while not answers and time.time() < end:
        time.sleep(0.01)
    net.unsubscribe(0x581, on_answer)               # the SDO client listens there too
    assert answers and answers[0][0] == 0x60, "answer %r" % answers
    assert drive.sdo.upload(0x6060, 0)[0] == 3


def reset_communication():
    drive.sdo.download(0x1017, 0, struct.pack("<H", 50))
    drive.sdo.download(0x6060, 0, bytes([3]))
    boots = []

    def on_hb(cid, data, ts):
        if bytes(data) == b"\0":
            boots.append(ts)
    net.subscribe(0x701, on_hb)      # before the command: the boot-up may be quicker than us
    drive.nmt.send_command(0x82)
    end = time.time() + 2
    while not boots and time.time() < end:
        time.sleep(0.01)
    net.unsubscribe(0x701, on_hb)
    assert boots, "no boot-up after reset communication"
    assert struct.unpack("<H", drive.sdo.upload(0x1017, 0))[0] == 0, "0x1017 back to its power-on 0"
    assert drive.sdo.upload(0x6060, 0)[0] == 3, "0x6060 (application) kept"


def heartbeat_consumer_stops_the_motor():
    hb = net.send_periodic(0x77E, b"\x05", 0.02)     # we are node 0x7E, operational
    drive.sdo.download(0x1016, 1, struct.pack("<I", 0x7E << 16 | 100))
    drive.sdo.download(0x6060, 0, bytes([3]))
    drive.nmt.state = "OPERATIONAL"
    drive.sdo.download(0x60FF, 0, struct.pack("<i", 3000))
    for cw in (0x06, 0x07, 0x0F):
        drive.sdo.download(0x6040, 0, struct.pack("<H", cw))
    end = time.time() + 3
    while i32(drive, 0x606C, 0) != 3000 and time.time() < end:
        time.sleep(0.02)
    assert i32(drive, 0x606C, 0) == 3000, "turning"
    time.sleep(0.3)                                  # still turning while we beat
    assert i32(drive, 0x606C, 0) == 3000, "kept turning with our heartbeat"
    hb.stop()
    t0 = time.time()
    stopped = None
    while time.time() - t0 < 2:
        if i32(drive, 0x606C, 0) == 0:
            stopped = time.time() - t0
            break
    print("  0x606C = 0 %.0f ms after our heartbeat stopped" % (1000 * stopped if stopped is not None else -1))
    assert stopped is not None and stopped <= 0.3
    # 0x606C is whole counts/s: it reads 0 a tick or two before the ramp ends the fault
    # reaction (transition 14, automatic): wait for it, bounded
    end = time.time() + 0.2
    while True:
        sw = struct.unpack("<H", drive.sdo.upload(0x6041, 0))[0]
        if sw & 0x4F == 0x08 or time.time() > end:
            break
        time.sleep(0.01)
    assert sw & 0x4F == 0x08, "fault after the fault reaction, statusword 0x%04X" % sw


def raw_ids(sock, seconds):
    ids, end = [], time.time() + seconds
    while time.time() < end:
        r, _, _ = select.select([sock], [], [], 0.05)
        if r:
            data = sock.recv(128)
            ids.append(struct.unpack("=I", data[:4])[0] if len(data) == 16 else -len(data))
    return ids


def filters_told_to_the_bus():
    # The filter packet as docs/hw/canopen.md gives it: "MFLT", n, the error mask, then n x
    # (can_id, can_mask), u32 each in host order; the bus then sends us only what they take.
    told = socket.socket(socket.AF_UNIX, socket.SOCK_SEQPACKET)
    whole = socket.socket(socket.AF_UNIX, socket.SOCK_SEQPACKET)
    told.connect(SOCK)
    whole.connect(SOCK)
    try:
        told.send(struct.pack("=4sIIII", b"MFLT", 1, 0, 0x581, 0x7FF))
        time.sleep(0.2)
        for s in (told, whole):
            raw_ids(s, 0.1)                          # what came before the filter took hold
        for index in (0x1000, 0x1018):
            drive.sdo.upload(index, 0)
            gyro.sdo.upload(index, 0)
        seen, all_ids = raw_ids(told, 0.3), raw_ids(whole, 0.3)
        assert seen and set(seen) == {0x581}, "filtered client got %s" % sorted(set(seen))
        assert {0x601, 0x581, 0x620, 0x5A0} <= set(all_ids), "unfiltered client got %s" % sorted(set(all_ids))
    finally:
        told.close()
        whole.close()


try:
    check("the bus sends a client what the filters it told take", filters_told_to_the_bus)
    check("identity 0x1018 in drive and gyro", identity)
    check("expedited download without size indication", download_without_size)
    check("reset communication restores 0x1017, keeps 0x6060", reset_communication)
    check("heartbeat consumer stops the motor within 300 ms", heartbeat_consumer_stops_the_motor)
finally:
    net.disconnect()
    for p in reversed(procs):
        p.terminate()
        try:
            p.wait(5)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()
    try:
        os.unlink(SOCK)
    except OSError:
        pass
print("[  PASSED  ] %d test(s)." % ok_count)
if bad_count:
    print("[  FAILED  ] %d test(s)." % bad_count)
sys.exit(1 if bad_count else 0)
