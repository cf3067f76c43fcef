"""canopen_emubus: python-can on marie's emulated CAN bus (marie-canbus): one 16-byte struct
can_frame per SOCK_SEQPACKET packet, written from docs/hw/canopen.md only. Shared by the
python-canopen peer tests."""
import select
import socket
import struct
import time

import can


class EmuBus(can.BusABC):
    """A python-can bus on marie-canbus PATH."""

    def __init__(self, path, **kwargs):
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        self.sock.connect(path)
        self.channel_info = "emu:" + path
        super().__init__(channel=path, **kwargs)

    def send(self, msg, timeout=None):
        cid = msg.arbitration_id | (0x80000000 if msg.is_extended_id else 0)
        cid |= 0x40000000 if msg.is_remote_frame else 0
        self.sock.send(struct.pack("=IB3x8s", cid, msg.dlc, bytes(msg.data).ljust(8, b"\0")))

    def _recv_internal(self, timeout):
        r, _, _ = select.select([self.sock], [], [], timeout)
        if not r:
            return None, False
        data = self.sock.recv(128)
        if len(data) != 16:
            return None, False
        cid, dlc, payload = struct.unpack("=IB3x8s", data)
        return can.Message(timestamp=time.time(), arbitration_id=cid & 0x1FFFFFFF,
                           is_extended_id=bool(cid & 0x80000000), is_remote_frame=bool(cid & 0x40000000),
                           dlc=dlc, data=payload[:dlc]), False

    def shutdown(self):
        super().shutdown()
        self.sock.close()
