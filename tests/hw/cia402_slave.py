#!/usr/bin/env python3
"""cia402_slave: CiA 402 wheel drives in profile velocity mode, written from CiA 301 and CiA 402
(not from marie's virtual drive), on python-canopen's LocalNode: its object dictionary store,
SDO server (expedited and segmented) and heartbeat producer (0x1017) are python-canopen's; NMT
resets, PDOs (mapped as the master configured them), the drive state machine, the RPDO event
timer (0x1400:05) and EMCY are here. Like many drives it has no consumer heartbeat (0x1016) and
no abort connection option (0x6007): both are optional.

    cia402_slave.py SOCKET [--nodes 1,2] [--no-rpdo-deadline] [--no-producer]

runs the drives on marie-canbus SOCKET until SIGTERM; SIGUSR1 power-cycles the first drive
(a boot-up, its objects back to their defaults), SIGUSR2 puts it in fault without an EMCY.
Prints "ready" once they booted."""
import argparse
import signal
import struct
import sys
import threading
import time

import canopen
from canopen import objectdictionary as odm
from canopen.sdo import SdoAbortedError

from canopen_emubus import EmuBus

TICKS_PER_REV = 4096
DEVICE_TYPE = 0x00020192                # profile 402, servo drive
EMCY_NO_ERROR, EMCY_RPDO_TIMEOUT, EMCY_PDO_LENGTH = 0x0000, 0x8250, 0x8210
NMT_START, NMT_STOP, NMT_PREOP, NMT_RESET_NODE, NMT_RESET_COMM = 0x01, 0x02, 0x80, 0x81, 0x82

# CiA 402 states and their statuswords (bits 0-3, 5, 6)
NOT_READY, SOD, READY, SWITCHED_ON, ENABLED, QUICK_STOP, FAULT_REACTION, FAULT = range(8)
STATUSWORD = {NOT_READY: 0x00, SOD: 0x40, READY: 0x21, SWITCHED_ON: 0x23, ENABLED: 0x27,
              QUICK_STOP: 0x07, FAULT_REACTION: 0x0F, FAULT: 0x08}
POWERED = (ENABLED, QUICK_STOP, FAULT_REACTION)


def variable(index, sub, name, dtype, access="rw", default=0):
    v = odm.ODVariable(name, index, sub)
    v.data_type, v.access_type, v.default = dtype, access, default
    return v


def record(index, name, members):
    r = odm.ODRecord(name, index)
    for sub, vname, dtype, access, default in members:
        r.add_member(variable(index, sub, vname, dtype, access, default))
    return r


def dictionary(node, deadline, producer):
    """The drive's objects; the communication objects' defaults are its power-on values."""
    U8, U16, U32, I8, I32 = odm.UNSIGNED8, odm.UNSIGNED16, odm.UNSIGNED32, odm.INTEGER8, odm.INTEGER32
    od = odm.ObjectDictionary()
    od.add_object(variable(0x1000, 0, "Device type", U32, "ro", DEVICE_TYPE))
    od.add_object(variable(0x1001, 0, "Error register", U8, "ro", 0))
    name = variable(0x1008, 0, "Manufacturer device name", odm.VISIBLE_STRING, "const", "python cia402 slave")
    od.add_object(name)
    if producer:
        od.add_object(variable(0x1017, 0, "Producer heartbeat time", U16, "rw", 0))
    od.add_object(record(0x1018, "Identity", [(0, "n", U8, "ro", 4), (1, "Vendor", U32, "ro", 0x00C1A402),
                                              (2, "Product", U32, "ro", 0x402), (3, "Revision", U32, "ro", 0x10),
                                              (4, "Serial", U32, "ro", 1000 + node)]))
    rpdo = [(0, "n", U8, "ro", 5 if deadline else 2), (1, "COB-ID", U32, "rw", 0x200 + node),
            (2, "Transmission type", U8, "rw", 1)]
    if deadline:
        rpdo.append((5, "Event timer", U16, "rw", 0))
    od.add_object(record(0x1400, "RPDO1 communication", rpdo))
    pdo_map = lambda idx, defaults: record(idx, "mapping %04X" % idx, [(0, "n", U8, "rw", len(defaults))] +
                                           [(k + 1, "entry %d" % (k + 1), U32, "rw", defaults[k] if k < len(defaults) else 0)
                                            for k in range(8)])
    od.add_object(pdo_map(0x1600, [0x60400010, 0x60FF0020]))
    for idx, cob in ((0x1800, 0x180), (0x1801, 0x280)):
        od.add_object(record(idx, "TPDO communication", [(0, "n", U8, "ro", 2), (1, "COB-ID", U32, "rw", cob + node),
                                                         (2, "Transmission type", U8, "rw", 1)]))
    od.add_object(pdo_map(0x1A00, [0x60410010, 0x60640020]))
    od.add_object(pdo_map(0x1A01, [0x606C0020]))
    for idx, vname, dtype, access in ((0x603F, "Error code", U16, "ro"), (0x6040, "Controlword", U16, "rw"),
                                      (0x6041, "Statusword", U16, "ro"), (0x6060, "Modes of operation", I8, "rw"),
                                      (0x6061, "Modes of operation display", I8, "ro"),
                                      (0x6064, "Position actual value", I32, "ro"),
                                      (0x606C, "Velocity actual value", I32, "ro"), (0x60FF, "Target velocity", I32, "rw")):
        od.add_object(variable(idx, 0, vname, dtype, access, 0))
    return od


def command(state, cw, prev_cw):
    """CiA 402 table: the state a controlword leads to (transition numbers in comments)."""
    if state == FAULT:
        return SOD if cw & 0x80 and not prev_cw & 0x80 else FAULT      # 15: fault reset, rising edge
    if state in (NOT_READY, FAULT_REACTION):
        return state                                                    # automatic transitions only
    low = cw & 0x0F
    if not low & 0x02:                                                  # disable voltage: 7, 9, 10, 12
        return SOD
    if not low & 0x04:                                                  # quick stop: 7, 10, 11
        return QUICK_STOP if state == ENABLED else (state if state == QUICK_STOP else SOD)
    if low & 0x07 == 0x06:                                              # shutdown: 2, 6, 8
        return READY if state in (SOD, SWITCHED_ON, ENABLED) else state
    if low == 0x07:                                                     # switch on: 3; disable operation: 5
        return SWITCHED_ON if state in (READY, ENABLED) else state
    if low == 0x0F:                                                     # enable operation: 3+4, 4, 16
        return {READY: ENABLED, SWITCHED_ON: ENABLED, QUICK_STOP: ENABLED}.get(state, state)
    return state


class Drive:
    def __init__(self, network, node, deadline, producer):
        self.net, self.id, self.producer = network, node, producer
        self.lock = threading.RLock()
        self.node = canopen.LocalNode(node, dictionary(node, deadline, producer))
        network.add_node(self.node)                 # its SDO server and NMT slave come first
        network.subscribe(0x000, self.on_nmt)
        network.subscribe(0x080, self.on_sync)
        network.subscribe(0x200 + node, self.on_rpdo)
        self.node.add_read_callback(self.on_read)
        self.node.add_write_callback(self.on_write)
        self.power_on()

    # ---- objects ----
    def value(self, index, sub=0):
        if isinstance(self.node.object_dictionary[index], odm.ODVariable):
            return self.node.sdo[index].raw
        return self.node.sdo[index][sub].raw

    def mapping(self, index):
        n = self.value(index, 0)
        return [self.value(index, k) for k in range(1, n + 1)]

    def on_read(self, index, subindex, od):
        live = {0x6041: lambda: STATUSWORD[self.state] | 0x0200, 0x6064: lambda: self.position(),
                0x606C: lambda: self.velocity, 0x6061: lambda: self.mode, 0x603F: lambda: self.error}
        return live[index]() if index in live else None

    def on_write(self, index, subindex, od, data):
        if index == 0x6060:
            mode = struct.unpack("<b", data)[0]
            if mode not in (0, 3):
                raise SdoAbortedError(0x06090030)   # only profile velocity
            self.mode = mode

    def position(self):
        return (int(round(self.pos)) + 2 ** 31) % 2 ** 32 - 2 ** 31      # an i32 that wraps

    # ---- NMT ----
    def power_on(self):
        with self.lock:
            self.node.data_store.clear()
            self.state, self.prev_cw, self.mode, self.error = SOD, 0, 0, 0   # transition 1 after self test
            self.velocity, self.pos, self.target, self.cw = 0, 0.0, 0, 0
            self.latched, self.deadline, self.last_sync = None, None, None
            self.boot()

    def boot(self):
        """Reset communication: communication objects back to power-on, boot-up, pre-operational."""
        for index in [i for i in self.node.data_store if 0x1000 <= i < 0x2000]:
            del self.node.data_store[index]
        self.node.nmt.stop_heartbeat()
        self.node.nmt.send_command(NMT_RESET_COMM)  # python-canopen sends the boot-up
        if self.producer:
            self.node.nmt.send_command(NMT_PREOP)   # and starts the heartbeat per 0x1017
        else:
            canopen.nmt.NmtBase.send_command(self.node.nmt, NMT_PREOP)
        self.deadline = None

    def on_nmt(self, can_id, data, timestamp):
        cmd, node = struct.unpack_from("BB", data)
        if node not in (0, self.id):
            return
        with self.lock:
            if cmd == NMT_RESET_NODE:
                self.power_on()
            elif cmd == NMT_RESET_COMM:
                self.leave_operational()
                self.boot()
            elif cmd in (NMT_STOP, NMT_PREOP):
                self.leave_operational()

    def operational(self):
        return self.node.nmt.state == "OPERATIONAL"

    def leave_operational(self):
        """Out of operational while the power stage drives: no abort connection option
        (0x6007) here, so the manufacturer's choice: power off."""
        if self.state in POWERED:
            self.state, self.velocity = SOD, 0
        self.deadline = None

    # ---- PDOs ----
    def on_rpdo(self, can_id, data, timestamp):
        with self.lock:
            cob = self.value(0x1400, 1)
            if not self.operational() or cob & 0x80000000 or (cob & 0x7FF) != can_id:
                return
            entries = self.mapping(0x1600)
            if len(data) < sum(e & 0xFF for e in entries) // 8:
                self.emcy(EMCY_PDO_LENGTH, 0x10)
                return
            self.latched = bytes(data)              # synchronous (type 1): applied at SYNC
            if 5 in self.node.object_dictionary[0x1400]:
                ms = self.value(0x1400, 5)
                self.deadline = time.monotonic() + ms / 1000.0 if ms else None

    def apply_rpdo(self):
        off, values = 0, {}
        for e in self.mapping(0x1600):
            index, size = e >> 16, (e & 0xFF) // 8
            values[index] = int.from_bytes(self.latched[off:off + size], "little", signed=index == 0x60FF)
            off += size
        self.latched = None
        if 0x60FF in values:
            self.target = values[0x60FF]
        if 0x6040 in values:
            self.cw = values[0x6040]
            new = command(self.state, self.cw, self.prev_cw)
            if self.state == FAULT and new == SOD:
                self.error = 0
                self.emcy(EMCY_NO_ERROR, 0)         # the fault is gone
            self.state, self.prev_cw = new, self.cw

    def on_sync(self, can_id, data, timestamp):
        with self.lock:
            if not self.operational():
                return
            if self.latched is not None:
                self.apply_rpdo()
            now = time.monotonic()
            dt = now - self.last_sync if self.last_sync else 0.0
            self.last_sync = now
            self.pos += self.velocity * dt
            self.velocity = self.target if self.state == ENABLED and self.mode == 3 else 0
            if self.state == FAULT_REACTION:
                self.state = FAULT                  # 14: stopped
            for comm, maps in ((0x1800, 0x1A00), (0x1801, 0x1A01)):
                self.tpdo(comm, maps)

    def tpdo(self, comm, maps):
        cob = self.value(comm, 1)
        if cob & 0x80000000:
            return
        data = b""
        for e in self.mapping(maps):
            index, size = e >> 16, (e & 0xFF) // 8
            data += (self.on_read(index, 0, None) & ((1 << 8 * size) - 1)).to_bytes(size, "little")
        self.net.send_message(cob & 0x7FF, data)

    # ---- errors ----
    def emcy(self, code, reg):
        self.net.send_message(0x80 + self.id, struct.pack("<HB5x", code, reg))

    def check_deadline(self):
        """0x1400:05: an RPDO received in operational must come again within its event time."""
        with self.lock:
            if self.deadline is None or time.monotonic() <= self.deadline or not self.operational():
                return
            self.deadline = None
            self.emcy(EMCY_RPDO_TIMEOUT, 0x11)
            if self.state in POWERED:       # 13 and, the ideal motor standing at once, 14
                self.state, self.error, self.velocity = FAULT, EMCY_RPDO_TIMEOUT, 0

    def silent_fault(self):
        """A fault told by the statusword alone, no EMCY (some drives do)."""
        with self.lock:
            self.state, self.error, self.velocity = FAULT, 0x4310, 0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("socket")
    ap.add_argument("--nodes", default="1,2")
    ap.add_argument("--no-rpdo-deadline", action="store_true")
    ap.add_argument("--no-producer", action="store_true")
    a = ap.parse_args()
    net = canopen.Network(EmuBus(a.socket))
    net.connect()
    drives = [Drive(net, int(n), not a.no_rpdo_deadline, not a.no_producer) for n in a.nodes.split(",")]
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    signal.signal(signal.SIGUSR1, lambda *_: drives[0].power_on())
    signal.signal(signal.SIGUSR2, lambda *_: drives[0].silent_fault())
    print("ready", flush=True)
    while not stop.wait(0.005):
        for d in drives:
            d.check_deadline()
    net.disconnect()


if __name__ == "__main__":
    sys.exit(main())
