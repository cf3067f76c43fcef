#!/usr/bin/env python3
"""typeinfo_gen: reads lcmtypes/*.lcm and writes descriptors of every type (C), a struct dumper

The bridge encodes and decodes the LCM wire format itself, driven by these descriptors, so a
new .lcm file is bridged without any hand-written code. The fingerprint of every struct is
computed here with lcm-gen's algorithm; tests compare it with the generated code's hash().

usage: typeinfo_gen.py table OUT.c FILE.lcm...     descriptor table (linked into the bridge)
       typeinfo_gen.py dump  OUT.c FILE.lcm...     test helper: prints lcm-gen's C structs field by field
       typeinfo_gen.py xsd   OUT.xsd FILE.lcm...   XML Schema of every type's fields (for peers)
       typeinfo_gen.py py    OUT.py FILE.lcm... [--deps DEP.lcm...]   descriptors for python/marie
       typeinfo_gen.py module DIR/NAME FILE.lcm... [--deps DEP.lcm...]
                                 a user's types as a module (DIR/NAME/lcmtypes/NAME_types.{c,h}):
                                 what marie-types-gen compiles; DEP files are only referred to
"""
import re
import sys

PRIMS = {
    "int8_t": "MARIE_PRIM_INT8", "int16_t": "MARIE_PRIM_INT16", "int32_t": "MARIE_PRIM_INT32", "int64_t": "MARIE_PRIM_INT64",
    "byte": "MARIE_PRIM_BYTE", "float": "MARIE_PRIM_FLOAT", "double": "MARIE_PRIM_DOUBLE", "string": "MARIE_PRIM_STRING",
    "boolean": "MARIE_PRIM_BOOL",
}
INT_PRIMS = ("int8_t", "int16_t", "int32_t", "int64_t", "byte")


class LcmError(Exception):
    pass


def strip_comments(text):
    text = re.sub(r"/\*.*?\*/", lambda m: "\n" * m.group(0).count("\n"), text, flags=re.S)
    return re.sub(r"//[^\n]*", "", text)


def tokenize(text):
    return re.findall(r"[A-Za-z_][A-Za-z0-9_.]*|-?[0-9][0-9A-Za-z_.+\-]*|\S", text)


class Struct:
    def __init__(self, package, name):
        self.package = package
        self.name = name
        self.members = []   # (type, name, [(mode, size_str)])
        self.consts = []    # (type, name, value_str)
        self.nonfinite = set()  # members whose line says @nonfinite: NaN and infinities have a meaning

    @property
    def full(self):
        return "%s.%s" % (self.package, self.name) if self.package else self.name

    @property
    def cname(self):
        return self.full.replace(".", "_")


# A member whose comment says @nonfinite gives NaN and the infinities a meaning (a laser's ranges:
# REP 117's "no reading", "no return"), so the input check lets them through (core/typeinfo.h).
NONFINITE = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)\s*(?:\[[^\]]*\]\s*)*;[^\n]*//[^\n]*@nonfinite")


def parse_file(path):
    raw = open(path, encoding="utf-8").read()
    nonfinite = set(NONFINITE.findall(raw))
    toks = tokenize(strip_comments(raw))
    pos = 0
    package = ""
    structs = []

    def expect(t):
        nonlocal pos
        if pos >= len(toks) or toks[pos] != t:
            raise LcmError("%s: expected '%s' near token %d (%s)" %
                           (path, t, pos, toks[pos] if pos < len(toks) else "EOF"))
        pos += 1

    def take():
        nonlocal pos
        if pos >= len(toks):
            raise LcmError("%s: unexpected end of file" % path)
        pos += 1
        return toks[pos - 1]

    while pos < len(toks):
        t = take()
        if t == "package":
            package = take()
            expect(";")
        elif t == "struct":
            s = Struct(package, take())
            expect("{")
            while toks[pos] != "}":
                if toks[pos] == "const":
                    pos += 1
                    ctype = take()
                    while True:
                        cname = take()
                        expect("=")
                        value = take()
                        s.consts.append((ctype, cname, value))
                        if toks[pos] == ",":
                            pos += 1
                            continue
                        expect(";")
                        break
                    continue
                mtype = take()
                while True:
                    mname = take()
                    dims = []
                    while toks[pos] == "[":
                        pos += 1
                        size = take()
                        expect("]")
                        dims.append((0 if re.match(r"^[0-9]+$", size) else 1, size))
                    s.members.append((mtype, mname, dims))
                    if toks[pos] == ",":
                        pos += 1
                        continue
                    expect(";")
                    break
            expect("}")
            s.nonfinite = nonfinite & {m[1] for m in s.members}
            structs.append(s)
        else:
            raise LcmError("%s: unexpected token '%s'" % (path, t))
    return structs


def s64(v):
    v &= (1 << 64) - 1
    return v - (1 << 64) if v >> 63 else v


def hash_update(v, c):
    c = s64(c)
    c = ((c + 128) & 0xFF) - 128          # lcm-gen passes a (signed) char
    return s64(((s64(v << 8)) ^ (v >> 55)) + c)


def hash_string_update(v, s):
    v = hash_update(v, len(s))
    for ch in s.encode():
        v = hash_update(v, ch)
    return v


def base_hash(st):
    v = 0x12345678
    for mtype, mname, dims in st.members:
        v = hash_string_update(v, mname)
        if mtype in PRIMS:
            v = hash_string_update(v, mtype)
        v = hash_update(v, len(dims))
        for mode, size in dims:
            v = hash_update(v, mode)
            v = hash_string_update(v, size)
    return v


def resolve(st, mtype, by_name):
    if mtype in PRIMS:
        return None
    full = mtype if "." in mtype else ("%s.%s" % (st.package, mtype) if st.package else mtype)
    if full not in by_name:
        raise LcmError("%s: unknown type '%s'" % (st.full, mtype))
    return by_name[full]


def fingerprint(st, by_name, parents=()):
    if st.full in parents:
        return 0
    h = base_hash(st) & ((1 << 64) - 1)
    for mtype, _, _ in st.members:
        sub = resolve(st, mtype, by_name)
        if sub is not None:
            h = (h + fingerprint(sub, by_name, parents + (st.full,))) & ((1 << 64) - 1)
    return s64(((h << 1) & ((1 << 64) - 1)) + ((h >> 63) & 1))


def cstr(s):
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'


def check(st, by_name):
    names = [m[1] for m in st.members]
    for i, (mtype, mname, dims) in enumerate(st.members):
        resolve(st, mtype, by_name)
        for mode, size in dims:
            if mode == 1:
                if size not in names[:i]:
                    raise LcmError("%s.%s: length field '%s' must come earlier" % (st.full, mname, size))
                ltype = st.members[names.index(size)][0]
                if ltype not in INT_PRIMS or st.members[names.index(size)][2]:
                    raise LcmError("%s.%s: length field '%s' is not an integer" % (st.full, mname, size))


def emit_descriptors(structs, by_name, out, prefix="marie_", storage=""):
    """The marie_typeinfo_t of every struct: PREFIXtypeinfo_CNAME, with their fields and consts."""
    w = out.write
    for st in structs:
        w("%sconst marie_typeinfo_t %stypeinfo_%s;\n" % (storage or "extern ", prefix, st.cname))
    w("\n")
    for st in structs:
        names = [m[1] for m in st.members]
        for i, (mtype, mname, dims) in enumerate(st.members):
            if dims:
                w("static const marie_tdim_t %stdims_%s_%d[] = {" % (prefix, st.cname, i))
                for mode, size in dims:
                    if mode == 0:
                        w(" { %s, -1 }," % size)
                    else:
                        w(" { 0, %d }," % names.index(size))
                w(" };\n")
        w("static const marie_tfield_t %stfields_%s[] = {\n" % (prefix, st.cname))
        for i, (mtype, mname, dims) in enumerate(st.members):
            sub = resolve(st, mtype, by_name)
            prim = PRIMS.get(mtype, "MARIE_PRIM_STRUCT")
            subref = "&%stypeinfo_%s" % (prefix, sub.cname) if sub else "NULL"
            dimref = "%stdims_%s_%d" % (prefix, st.cname, i) if dims else "NULL"
            flags = ", MARIE_TFIELD_NONFINITE" if mname in st.nonfinite else ""
            w("    { %s, %s, %s, %d, %s, offsetof(%s, %s)%s },\n" % (cstr(mname), prim, subref, len(dims), dimref,
                                                                 st.cname, mname, flags))
        w("};\n")
        if st.consts:
            w("static const marie_tconst_t %stconsts_%s[] = {\n" % (prefix, st.cname))
            for ctype, cname, value in st.consts:
                w("    { %s, %s, %s },\n" % (cstr(cname), PRIMS[ctype], cstr(value)))
            w("};\n")
        w("%sconst marie_typeinfo_t %stypeinfo_%s = {\n" % (storage, prefix, st.cname))
        w("    %s, %s, (int64_t)0x%016xULL,\n" % (cstr(st.full), cstr(st.name),
                                                  fingerprint(st, by_name) & ((1 << 64) - 1)))
        w("    %d, %stfields_%s, %d, %s,\n" % (len(st.members), prefix, st.cname, len(st.consts),
                                              "%stconsts_%s" % (prefix, st.cname) if st.consts else "NULL"))
        w("};\n\n")


def emit_table(structs, by_name, out):
    w = out.write
    w("/* Generated by lcmtypes/typeinfo_gen.py from the .lcm files of lcmtypes/; do not edit. */\n")
    w('#include "core/typeinfo.h"\n\n')
    emit_descriptors(structs, by_name, out)
    w("const marie_typeinfo_t *const marie_typeinfos[] = {\n")
    for st in structs:
        w("    &marie_typeinfo_%s,\n" % st.cname)
    w("    NULL\n};\n")
    w("const size_t marie_typeinfos_count = %d;\n" % len(structs))


def reachable(structs, by_name):
    """The structs and every struct their fields name, each once, sorted by name."""
    seen = {}
    todo = list(structs)
    while todo:
        st = todo.pop()
        if st.full in seen:
            continue
        seen[st.full] = st
        for mtype, _, _ in st.members:
            sub = resolve(st, mtype, by_name)
            if sub is not None:
                todo.append(sub)
    return sorted(seen.values(), key=lambda s: s.full)


def emit_module(name, structs, by_name, out_c, out_h):
    """A user's types as a marie_types_module_t (core/typeinfo.h): codecs behind marie_type_t and
    descriptors of the types and of every type they name. Linked into a program, the module
    registers itself at start-up; built with -DMARIE_TYPES_SHARED into a shared library, it is
    found by its `marie_types_module` symbol (marie_types_load)."""
    every = reachable(structs, by_name)
    guard = "MARIE_TYPES_%s_H" % re.sub(r"\W", "_", name).upper()
    h = out_h.write
    h("/* Generated by marie-types-gen; do not edit. The marie descriptors of module %s. */\n" % name)
    h("#ifndef %s\n#define %s\n" % (guard, guard))
    h('#include "core/typeinfo.h"\n')
    for st in every:
        h('#include "lcmtypes/%s.h"\n' % st.cname)
    h('#ifdef __cplusplus\nextern "C" {\n#endif\n')
    for st in structs:
        h("extern const marie_type_t marie_type_%s;\n" % st.cname)
    h("extern const marie_types_module_t marie_types_module_%s;\n" % name)
    h("#ifdef __cplusplus\n}\n#endif\n#endif\n")
    w = out_c.write
    w("/* Generated by marie-types-gen; do not edit. */\n")
    w('#include "lcmtypes/%s_types.h"\n\n' % name)
    emit_descriptors(every, by_name, out_c, prefix="mt_", storage="static ")
    for st in structs:
        c = st.cname
        w("const marie_type_t marie_type_%s = {\n" % c)
        w('    %s, sizeof(%s), __%s_get_hash,\n' % (cstr(st.full), c, c))
        w("    (int (*)(void *, int, int, const void *))%s_encode,\n" % c)
        w("    (int (*)(const void *, int, int, void *))%s_decode,\n" % c)
        w("    (int (*)(void *))%s_decode_cleanup,\n" % c)
        w("    (int (*)(const void *))%s_encoded_size,\n};\n" % c)
    w("static const marie_type_t *const mt_types[] = {\n")
    for st in structs:
        w("    &marie_type_%s,\n" % st.cname)
    w("    NULL\n};\nstatic const marie_typeinfo_t *const mt_infos[] = {\n")
    for st in structs:
        w("    &mt_typeinfo_%s,\n" % st.cname)
    w("    NULL\n};\n")
    w("const marie_types_module_t marie_types_module_%s = {MARIE_TYPES_MODULE_VERSION, %s, mt_types, mt_infos};\n"
      % (name, cstr(name)))
    w("#ifdef MARIE_TYPES_SHARED\n")
    w('__attribute__((visibility("default"))) const marie_types_module_t *const marie_types_module =\n'
      "    &marie_types_module_%s;\n#else\n" % name)
    w("__attribute__((constructor)) static void mt_register(void)\n{\n"
      "    marie_types_register(&marie_types_module_%s);\n}\n#endif\n" % name)


def emit_py(structs, by_name, out):
    """Descriptors for marie's Python package (python/marie/check.py): per type its fingerprint and
    fields as (name, primitive, struct type or None, dims), a dim being (size, None) or (None,
    index of the length field)."""
    w = out.write
    w("# Generated by typeinfo_gen.py; do not edit. Field descriptors of this package's LCM types.\n")
    w("TYPES = {\n")
    for st in structs:
        names = [m[1] for m in st.members]
        w("    %r: (%d, [\n" % (st.full, fingerprint(st, by_name)))
        for mtype, mname, dims in st.members:
            sub = resolve(st, mtype, by_name)
            d = tuple((int(size), None) if mode == 0 else (None, names.index(size)) for mode, size in dims)
            w("        (%r, %r, %r, %r),\n" % (mname, "struct" if sub else mtype, sub.full if sub else None, d))
        w("    ], %r),\n" % ([(c[1], c[0], c[2]) for c in st.consts],))
    w("}\n")


def emit_dump(structs, by_name, out):
    """C code that prints lcm-gen's C structs in the canonical 'path=value' form the tests use."""
    w = out.write
    w("/* Generated by lcmtypes/typeinfo_gen.py (test helper); do not edit. */\n")
    w('#include <stdio.h>\n#include "lcmtypes/marie_types.h"\n#include "tests/xml_bridge/xb_canon.h"\n\n')
    for st in structs:
        w("static void xb_sdump_%s(xb_canon_t *d, const char *pre, const %s *p);\n" % (st.cname, st.cname))
    for st in structs:
        w("\nstatic void xb_sdump_%s(xb_canon_t *d, const char *pre, const %s *p)\n{\n" % (st.cname, st.cname))
        w("    char path[512];\n    (void)path;\n")
        for mtype, mname, dims in st.members:
            sub = resolve(st, mtype, by_name)
            idx = ""
            fmt_path = '"%s%s'
            args = ["pre", cstr(mname)]
            for k, (mode, size) in enumerate(dims):
                bound = size if mode == 0 else "p->%s" % size
                w("    " * (k + 1) + "for (long i%d = 0; i%d < (long)(%s); i%d++) {\n" % (k, k, bound, k))
                idx += "[i%d]" % k
                fmt_path += "[%ld]"
                args.append("i%d" % k)
            ind = "    " * (len(dims) + 1)
            fmt_path += '"'
            w('%ssnprintf(path, sizeof path, %s, %s);\n' % (ind, fmt_path, ", ".join(args)))
            val = "p->%s%s" % (mname, idx)
            if sub is not None:
                w("%s{ char sp[520]; snprintf(sp, sizeof sp, \"%%s.\", path); xb_sdump_%s(d, sp, &%s); }\n"
                  % (ind, sub.cname, val))
            elif mtype == "string":
                w("%sxb_canon_str(d, path, %s);\n" % (ind, val))
            elif mtype == "float":
                w("%sxb_canon_float(d, path, %s);\n" % (ind, val))
            elif mtype == "double":
                w("%sxb_canon_double(d, path, %s);\n" % (ind, val))
            elif mtype == "boolean":
                w("%sxb_canon_int(d, path, %s != 0);\n" % (ind, val))
            else:
                w("%sxb_canon_int(d, path, (long long)%s);\n" % (ind, val))
            for k in range(len(dims), 0, -1):
                w("    " * k + "}\n")
        w("}\n")
    w("\nint xb_struct_dump(xb_canon_t *d, const char *type, const void *msg)\n{\n")
    for st in structs:
        w("    if (strcmp(type, %s) == 0) { xb_sdump_%s(d, \"\", msg); return 0; }\n" % (cstr(st.full), st.cname))
    w("    return -1;\n}\n")


XSD_SCALAR = {
    "int8_t": "xs:byte", "int16_t": "xs:short", "int32_t": "xs:int", "int64_t": "xs:long",
    "byte": "xs:unsignedByte", "float": "xs:float", "double": "xs:double", "boolean": "xs:boolean",
}


def emit_xsd(structs, by_name, out):
    """One complexType per struct, named like the type: the children of <publish type="T"> and
    <message type="T"> follow complexType T (see docs/xml-bridge.md)."""
    w = out.write
    w('<?xml version="1.0" encoding="UTF-8"?>\n')
    w("<!-- Generated by lcmtypes/typeinfo_gen.py from the .lcm files of lcmtypes/; do not edit.\n"
      "     Fields of every marie type as the XML bridge reads and writes them. Every field is\n"
      "     optional on input (missing means zero) and present on output. -->\n")
    w('<xs:schema xmlns:xs="http://www.w3.org/2001/XMLSchema" elementFormDefault="unqualified">\n')
    w('  <xs:complexType name="string"><xs:simpleContent><xs:extension base="xs:string">'
      '<xs:attribute name="encoding"><xs:simpleType><xs:restriction base="xs:string">'
      '<xs:enumeration value="base64"/></xs:restriction></xs:simpleType></xs:attribute>'
      '</xs:extension></xs:simpleContent></xs:complexType>\n')
    for prim, xt in sorted(XSD_SCALAR.items()):
        if prim == "byte":
            continue
        w('  <xs:simpleType name="%s.list"><xs:list itemType="%s"/></xs:simpleType>\n' % (prim, xt))
    for st in structs:
        w('  <xs:complexType name="%s">\n    <xs:all>\n' % st.full)
        for mtype, mname, dims in st.members:
            sub = resolve(st, mtype, by_name)
            fixed = all(mode == 0 for mode, _ in dims)
            count = 1
            for mode, size in dims:
                count *= int(size) if mode == 0 else 1
            if not dims:
                t = sub.full if sub else ("string" if mtype == "string" else XSD_SCALAR[mtype])
                w('      <xs:element name="%s" type="%s" minOccurs="0"/>\n' % (mname, t))
            elif mtype == "byte":
                w('      <xs:element name="%s" type="xs:base64Binary" minOccurs="0"/>\n' % mname)
            elif sub or mtype == "string":
                occurs = 'minOccurs="%d" maxOccurs="%d"' % (count, count) if fixed else \
                    'minOccurs="0" maxOccurs="unbounded"'
                w('      <xs:element name="%s" minOccurs="0"><xs:complexType><xs:sequence>'
                  '<xs:element name="item" type="%s" %s/></xs:sequence></xs:complexType></xs:element>\n'
                  % (mname, sub.full if sub else "string", occurs))
            elif fixed:
                w('      <xs:element name="%s" minOccurs="0"><xs:simpleType><xs:restriction base="%s.list">'
                  '<xs:length value="%d"/></xs:restriction></xs:simpleType></xs:element>\n' % (mname, mtype, count))
            else:
                w('      <xs:element name="%s" type="%s.list" minOccurs="0"/>\n' % (mname, mtype))
        w("    </xs:all>\n  </xs:complexType>\n")
    w("</xs:schema>\n")


def load(paths):
    structs = []
    for path in paths:
        structs.extend(parse_file(path))
    return structs


def main(argv):
    if len(argv) < 3 or argv[0] not in ("table", "dump", "xsd", "py", "module"):
        sys.stderr.write(__doc__)
        return 2
    import os
    mode, out_path, rest = argv[0], argv[1], argv[2:]
    deps = []
    if "--deps" in rest:
        deps = rest[rest.index("--deps") + 1:]
        rest = rest[:rest.index("--deps")]
    try:
        structs = load(rest)
        known = load(deps)
        by_name = {s.full: s for s in known}
        by_name.update({s.full: s for s in structs})
        for st in structs:
            check(st, by_name)
    except (LcmError, OSError) as e:
        sys.stderr.write("typeinfo_gen: %s\n" % e)
        return 1
    structs.sort(key=lambda s: s.full)
    if mode == "module":
        name = os.path.basename(out_path)
        os.makedirs(os.path.join(out_path, "lcmtypes"), exist_ok=True)
        paths = [os.path.join(out_path, "lcmtypes", name + "_types." + x) for x in ("c", "h")]
        with open(paths[0] + ".tmp", "w", encoding="utf-8") as c, open(paths[1] + ".tmp", "w", encoding="utf-8") as h:
            emit_module(name, structs, by_name, c, h)
        for p in paths:
            os.replace(p + ".tmp", p)
        return 0
    tmp = out_path + ".tmp"
    with open(tmp, "w", encoding="utf-8") as out:
        if mode == "table":
            emit_table(structs, by_name, out)
        elif mode == "xsd":
            emit_xsd(structs, by_name, out)
        elif mode == "py":
            emit_py(structs, by_name, out)
        else:
            out.write("#include <string.h>\n")
            emit_dump(structs, by_name, out)
    os.replace(tmp, out_path)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
