"""types: LCM types by name (lcm-gen's Python classes under lcmtypes.PACKAGE) and the payload
check every input goes through before lcm-gen's decoder runs, with the rules of core/typeinfo.c:
the fingerprint first; every string NUL-terminated within its length; every array count
non-negative and within the payload; nothing trailing; and for input a NaN or infinity in any
float or double is refused. The descriptors come from typeinfo_gen.py (PACKAGE/_typeinfo.py)."""
import importlib
import math
import os
import struct
import sys

PRIMS = {"int8_t": "b", "int16_t": "h", "int32_t": "i", "int64_t": "q", "byte": "B", "boolean": "b",
         "float": "f", "double": "d"}
INTS = ("int8_t", "int16_t", "int32_t", "int64_t", "byte")
MAX_DEPTH = 16


class BadMessage(Exception):
    """A payload refused; .counter names the bad-input counter, as marie_decode_input does."""

    def __init__(self, counter, why=""):
        super().__init__(why or counter)
        self.counter = counter


def add_path(d):
    """A directory made by marie-types-gen (or its python/ folder): its Python types importable."""
    p = os.path.join(d, "python") if os.path.isdir(os.path.join(d, "python")) else d
    if p not in sys.path:
        sys.path.append(p)
        importlib.invalidate_caches()


_by_name = {}


def find(name):
    """The MessageType called `name` ("marie.pose2d_t", "pose2d_t" for marie's, "ux.reading_t");
    KeyError when no package on the path has it."""
    full = name if "." in name else "marie." + name
    t = _by_name.get(full)
    if t is None:
        pkg, _, short = full.rpartition(".")
        try:
            info = importlib.import_module("lcmtypes.%s._typeinfo" % pkg).TYPES[full]
            cls = getattr(importlib.import_module("lcmtypes.%s.%s" % (pkg, short)), short)
        except (ImportError, KeyError, AttributeError):
            raise KeyError("unknown LCM type '%s' (no lcmtypes.%s with its descriptors on the path: "
                           "MARIE_TYPES_PATH or the system file's types:)" % (name, pkg)) from None
        t = _by_name[full] = MessageType(full, cls, info)
    return t


class MessageType:
    def __init__(self, name, cls, info):
        self.name = name
        self.cls = cls
        fp, fields, consts = info
        self.fingerprint = fp
        self.fields = fields
        self.consts = {c[0]: c[2] for c in consts}
        self.packed_fp = struct.pack(">q", fp)
        self._ops = None

    def ops(self):
        """The check as a list of steps, made once: runs of fixed-size scalars become one
        struct.Struct each (one unpack), the rest a step per field."""
        if self._ops is None:
            ops, run, run_fields = [], "", []
            for i, (fname, prim, sub, dims) in enumerate(self.fields):
                if prim in PRIMS and not dims:
                    run += PRIMS[prim]
                    run_fields.append((i, prim))
                    continue
                if run:
                    ops.append(("fixed", struct.Struct(">" + run), run_fields))
                    run, run_fields = "", []
                ops.append(("field", i, prim, sub, dims))
            if run:
                ops.append(("fixed", struct.Struct(">" + run), run_fields))
            self._ops = ops
        return self._ops

    def check(self, data, finite=True):
        """Raises BadMessage unless data is one well-formed payload of this type."""
        if len(data) < 8 or data[:8] != self.packed_fp:
            raise BadMessage("bad_fingerprint", "not a %s" % self.name)
        st = {"nonfinite": False}
        try:
            pos = _walk(self, data, 8, finite, st, 0)
        except (struct.error, IndexError, ValueError):
            raise BadMessage("bad_payload", "not a well-formed %s" % self.name) from None
        if pos != len(data):
            raise BadMessage("bad_payload", "%d bytes after a %s" % (len(data) - pos, self.name))
        if st["nonfinite"]:
            raise BadMessage("bad_nonfinite", "a NaN or infinity in a %s" % self.name)

    def decode(self, data, finite=True):
        self.check(data, finite)
        return self.cls.decode(data)

    def encode(self, msg):
        return msg.encode()

    def new(self, **fields):
        m = self.cls()
        for k, v in fields.items():
            setattr(m, k, v)
        return m


def _walk(t, buf, pos, finite, st, depth):
    if depth > MAX_DEPTH:
        raise ValueError("too deep")
    values = {}
    n = len(buf)
    for op in t.ops():
        if op[0] == "fixed":
            s = op[1]
            if pos + s.size > n:
                raise ValueError("short")
            vals = s.unpack_from(buf, pos)
            for (i, prim), v in zip(op[2], vals):
                values[i] = v
                if finite and prim in ("float", "double") and not math.isfinite(v):
                    st["nonfinite"] = True
            pos += s.size
            continue
        _, i, prim, sub, dims = op
        count = 1
        for size, lenfield in dims:
            k = size if lenfield is None else values.get(lenfield, -1)
            if k < 0 or k > n - pos:
                raise ValueError("count")
            count *= k
        if prim in PRIMS:
            size = struct.calcsize(PRIMS[prim])
            if pos + count * size > n:
                raise ValueError("short")
            if finite and prim in ("float", "double") and count:
                if not all(math.isfinite(v) for v in struct.unpack_from(">%d%s" % (count, PRIMS[prim]), buf, pos)):
                    st["nonfinite"] = True
            pos += count * size
        elif prim == "string":
            for _ in range(count):
                if pos + 4 > n:
                    raise ValueError("short")
                k = struct.unpack_from(">i", buf, pos)[0]
                if k < 1 or k > n - pos - 4 or buf[pos + 4 + k - 1] != 0:
                    raise ValueError("string")
                pos += 4 + k
        else:
            subt = find(sub)
            for _ in range(count):
                pos = _walk(subt, buf, pos, finite, st, depth + 1)
    return pos
