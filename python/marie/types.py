"""types: LCM types by name (lcm-gen's Python classes under lcmtypes.PACKAGE) and the payload
check every input goes through before lcm-gen's decoder runs, with the rules of core/typeinfo.c:
the fingerprint first; every string NUL-terminated within its length; every array count
non-negative and within the payload; nothing trailing; and for input a NaN or infinity in any
float or double is refused. The descriptors come from typeinfo_gen.py (PACKAGE/_typeinfo.py)."""
import glob
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


def known():
    """Every type whose package has descriptors on the path (marie's and the users' packages made by
    marie-types-gen), as {name: MessageType}."""
    for entry in sys.path:
        for info in sorted(glob.glob(os.path.join(entry or ".", "lcmtypes", "*", "_typeinfo.py"))):
            pkg = os.path.basename(os.path.dirname(info))
            try:
                names = list(importlib.import_module("lcmtypes.%s._typeinfo" % pkg).TYPES)
            except ImportError:
                continue
            for name in names:
                try:
                    find(name)
                except KeyError:
                    pass
    return dict(_by_name)


class MessageType:
    def __init__(self, name, cls, info):
        self.name = name
        self.cls = cls
        fp, fields, consts = info
        self.fingerprint = fp
        self.fields = fields
        self.consts = {c[0]: c[2] for c in consts}
        self.packed_fp = struct.pack(">q", fp)
        self._walker = None

    def walker(self):
        """The check of this type's fields as one Python function, made once from the descriptor
        (a generic walk over the fields took 5.5 us for a counter_t, this 1 us)."""
        if self._walker is None:
            self._walker = _compile_walker(self)
        return self._walker

    def check(self, data, finite=True):
        """Raises BadMessage unless data is one well-formed payload of this type."""
        if len(data) < 8 or data[:8] != self.packed_fp:
            raise BadMessage("bad_fingerprint", "not a %s" % self.name)
        st = [False]
        try:
            pos = self.walker()(data, 8, len(data), finite, st, 0)
        except (struct.error, IndexError, ValueError):
            raise BadMessage("bad_payload", "not a well-formed %s" % self.name) from None
        if pos != len(data):
            raise BadMessage("bad_payload", "%d bytes after a %s" % (len(data) - pos, self.name))
        if st[0]:
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


def _compile_walker(t):
    """Python source for walk(buf, pos, n, fin, st, depth) -> pos: raises ValueError (or
    struct.error, IndexError) at the first thing that does not fit, sets st[0] on a NaN or
    infinity when fin."""
    L = ["def walk(buf, pos, n, fin, st, depth):", " if depth > %d: raise ValueError('deep')" % MAX_DEPTH]
    env = {"struct": struct, "isfinite": math.isfinite, "find": find, "unpack_i": struct.Struct(">i").unpack_from}
    run, run_fields, fields = "", [], t.fields

    def flush():
        nonlocal run, run_fields
        if not run:
            return
        sname = "S%d" % len(env)
        env[sname] = struct.Struct(">" + run)
        L.append(" if pos + %d > n: raise ValueError('short')" % env[sname].size)
        wanted = [(k, i, prim) for k, (i, prim) in enumerate(run_fields)
                  if prim in ("float", "double") or any(lf == i for f in fields for _, lf in f[3])]
        if wanted:
            L.append(" _v = %s.unpack_from(buf, pos)" % sname)
            for k, i, prim in wanted:
                if prim in ("float", "double"):
                    L.append(" if fin and not isfinite(_v[%d]): st[0] = True" % k)
                else:
                    L.append(" v%d = _v[%d]" % (i, k))
        L.append(" pos += %d" % env[sname].size)
        run, run_fields = "", []

    for i, (fname, prim, sub, dims) in enumerate(fields):
        if prim in PRIMS and not dims:
            run += PRIMS[prim]
            run_fields.append((i, prim))
            continue
        flush()
        count = "1"
        for size, lenfield in dims:
            c = str(size) if lenfield is None else "v%d" % lenfield
            L.append(" if %s < 0 or %s > n - pos: raise ValueError('count')" % (c, c))
            count = "(%s * %s)" % (count, c)
        if prim in PRIMS:
            size = struct.calcsize(PRIMS[prim])
            L.append(" _c = %s" % count)
            L.append(" if pos + _c * %d > n: raise ValueError('short')" % size)
            if prim in ("float", "double"):
                L.append(" if fin and _c and not all(map(isfinite, struct.unpack_from('>%%d%s' %% _c, buf, pos))): "
                         "st[0] = True" % PRIMS[prim])
            L.append(" pos += _c * %d" % size)
        elif prim == "string":
            L.append(" for _ in range(%s):" % count)
            L.append("  if pos + 4 > n: raise ValueError('short')")
            L.append("  _k = unpack_i(buf, pos)[0]")
            L.append("  if _k < 1 or _k > n - pos - 4 or buf[pos + 3 + _k] != 0: raise ValueError('string')")
            L.append("  pos += 4 + _k")
        else:
            L.append(" _w = find(%r).walker()" % sub)
            L.append(" for _ in range(%s):" % count)
            L.append("  pos = _w(buf, pos, n, fin, st, depth + 1)")
    flush()
    L.append(" return pos")
    exec(compile("\n".join(L), "<walker of %s>" % t.name, "exec"), env)
    return env["walk"]
