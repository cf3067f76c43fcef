#!/usr/bin/env python3
"""Writes the 0xB0 scan telegrams used by tests/hw/test_lms200.c, with a CRC computed here
independently of hw/lms200 (SICK CRC-16, generator 0x8005, from the LMS2xx telegram listing)."""
import struct, sys, os

def sick_crc(data):
    crc, prev = 0, 0
    for b in data:
        crc = (((crc << 1) & 0xFFFF) ^ 0x8005) if crc & 0x8000 else (crc << 1) & 0xFFFF
        crc ^= b | (prev << 8)
        prev = b
    return crc

def telegram(addr, payload):
    head = bytes([0x02, addr]) + struct.pack('<H', len(payload)) + payload
    return head + struct.pack('<H', sick_crc(head))

def scan(n, unit, values, status=0x10):
    word = n | (unit << 14)
    return telegram(0x80, bytes([0xB0]) + struct.pack('<H', word)
                    + b''.join(struct.pack('<H', v) for v in values) + bytes([status]))

out = os.path.dirname(os.path.abspath(__file__))
# 361 values at 0.5 deg in mm: 1000 + 5*i mm, beam 100 reports "no echo" (0x1FFF).
v361 = [1000 + 5 * i for i in range(361)]
v361[100] = 0x1FFF
open(os.path.join(out, 'scan_361_mm.bin'), 'wb').write(scan(361, 1, v361))
# 181 values at 1 deg in cm: 100 + i cm, beam 0 carries a field flag in bit 13.
v181 = [100 + i for i in range(181)]
v181[0] |= 0x2000
open(os.path.join(out, 'scan_181_cm.bin'), 'wb').write(scan(181, 0, v181))

if len(sys.argv) > 1 and sys.argv[1] == 'check':
    for name, hexs in [('start', '02 00 02 00 20 24 34 08'), ('stop', '02 00 02 00 20 25 35 08'),
                       ('b500k', '02 00 02 00 20 48 58 08'), ('b9600', '02 00 02 00 20 42 52 08'),
                       ('req', '02 00 02 00 30 01 31 18'), ('var', '02 00 05 00 3B B4 00 32 00 3B 1F'),
                       ('reply', '02 80 03 00 A0 00 10 16 0A')]:
        b = bytes.fromhex(hexs)
        c = sick_crc(b[:-2])
        print(name, hex(c), 'ok' if struct.pack('<H', c) == b[-2:] else 'MISMATCH')
