#!/usr/bin/env python3
"""Writes the ELF kernel packed in a bzImage (vmlinuz) to OUT, when it has a PVH entry point:
qemu then boots it directly, and the emulated CPU does not decompress it first (3-4 s of
every boot under TCG here). Exit status 1, and nothing written, when the image holds no such
kernel (run-in-vm.sh then boots the vmlinuz as it is).
  scripts/vm/unpack-kernel.py VMLINUZ OUT"""
import lzma
import os
import struct
import sys
import zlib


def xz(data):
    return lzma.LZMADecompressor(format=lzma.FORMAT_XZ).decompress(data)


def gz(data):
    return zlib.decompressobj(16 + zlib.MAX_WBITS).decompress(data)


FORMATS = ((b"\xfd7zXZ\x00", xz), (b"\x1f\x8b\x08", gz))


def has_pvh_entry(elf):
    """A 64-bit ELF with a Xen note of type 18 (XEN_ELFNOTE_PHYS32_ENTRY) in a PT_NOTE segment."""
    if elf[:5] != b"\x7fELF\x02":
        return False
    phoff, = struct.unpack_from("<Q", elf, 0x20)
    phentsize, phnum = struct.unpack_from("<HH", elf, 0x36)
    for k in range(phnum):
        ptype, = struct.unpack_from("<I", elf, phoff + k * phentsize)
        if ptype != 4:      # PT_NOTE
            continue
        off, = struct.unpack_from("<Q", elf, phoff + k * phentsize + 0x08)
        size, = struct.unpack_from("<Q", elf, phoff + k * phentsize + 0x20)
        i, end = off, off + size
        while i + 12 <= end:
            namesz, descsz, ntype = struct.unpack_from("<III", elf, i)
            name = elf[i + 12:i + 12 + namesz]
            if name == b"Xen\x00" and ntype == 18:
                return True
            i += 12 + (namesz + 3) // 4 * 4 + (descsz + 3) // 4 * 4
    return False


def main():
    if len(sys.argv) != 3:
        print(__doc__.strip().splitlines()[-1].strip(), file=sys.stderr)
        return 2
    image = open(sys.argv[1], "rb").read()
    for magic, decompress in FORMATS:
        at = image.find(magic)
        while at >= 0:
            try:
                elf = decompress(image[at:])
            except (lzma.LZMAError, zlib.error):
                elf = b""
            try:
                pvh = has_pvh_entry(elf)
            except struct.error:    # not an ELF after all
                pvh = False
            if pvh:
                tmp = "%s.%d" % (sys.argv[2], os.getpid())
                with open(tmp, "wb") as f:
                    f.write(elf)
                os.replace(tmp, sys.argv[2])
                return 0
            at = image.find(magic, at + 1)
    return 1


if __name__ == "__main__":
    sys.exit(main())
