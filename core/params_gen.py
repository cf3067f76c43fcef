#!/usr/bin/env python3
"""params_gen: writes a component's parameter struct and spec tables from its NAME.params.yaml

A parameter is declared once, in the YAML file beside the component's code; the generated header
holds the C struct whose fields receive the values and one macro per table of MARIE_PARAM_AT
entries (the default, the --help text and the field's offset), used as
    static const marie_param_spec_t params[] = BHV_PARAMS;

The file (docs/core.md, "Parameters"):
    struct: bhv_params_t           # the C struct to generate
    tables:                        # one or more tables: a component kind each
      BHV_PARAMS:
        rate_hz: [double, "5", "arbitration rate"]      # NAME: [TYPE, DEFAULT, HELP(, dynamic)]
        map: [string, null, "map_server map.yaml"]       # null: the system file must set it
TYPE is int, double, bool, string or node; DEFAULT is the YAML text of the value, quoted, or
`!c NAME` for a C macro holding that text (one the C code shares; the file that uses the table
includes its header). A name in several tables is one field and must have the same type in each.

A library's parameters live in a file of their own with one table and `defaults: NAME`: NAME is
then also an initializer of the struct with the defaults (`slam_params_t p = SLAM_PARAMS_DEFAULTS;`),
so the library's defaults and the component's are the same line. A component takes them whole:
    members:
      slam: adapters/mapper/slam.params.yaml   # a field `slam_params_t slam;` of the struct,
                                               # and the file's parameters in every table
      model: {file: sim/world.params.yaml, defaults: {start_x: "2.0"}}   # its own defaults
and hands `&params->slam` to the library: nothing is copied by name.

usage: params_gen.py IN.params.yaml OUT.h     (also writes OUT.d: OUT.h's members for make)
Errors are printed as FILE:LINE: message, and the exit status is 1.
"""
import os
import re
import sys

import yaml

CTYPES = {"int": "int64_t", "double": "double", "bool": "bool", "string": "const char *",
          "node": "const marie_node_t *"}
IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")


class CExpr(str):
    """A default given as `!c NAME`: a C macro holding the default's text, shared with C code."""


class SpecError(Exception):
    def __init__(self, node, msg):
        super().__init__(msg)
        self.line = node.start_mark.line + 1 if node is not None else 1
        self.path = getattr(node.start_mark, "name", None) if node is not None else None


def c_string(s):
    out = []
    for ch in s:
        if ch in '"\\':
            out.append("\\" + ch)
        elif ch == "\n":
            out.append("\\n")
        elif ord(ch) < 0x20:
            out.append("\\x%02x" % ord(ch))
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def scalar(node, what):
    if not isinstance(node, yaml.ScalarNode):
        raise SpecError(node, "%s: expected a scalar" % what)
    return node.value


def mapping(node, what):
    if not isinstance(node, yaml.MappingNode):
        raise SpecError(node, "%s: expected a mapping" % what)
    seen = set()
    for k, _ in node.value:
        key = scalar(k, what + " key")
        if key in seen:
            raise SpecError(k, "%s: '%s' given twice" % (what, key))
        seen.add(key)
    return [(k.value, k, v) for k, v in node.value]


def param(name, knode, node):
    if not IDENT.match(name):
        raise SpecError(knode, "'%s' is not a C identifier" % name)
    if not isinstance(node, yaml.SequenceNode) or len(node.value) not in (3, 4):
        raise SpecError(node, "%s: expected [TYPE, DEFAULT, HELP]" % name)
    # A fourth item `dynamic`: `marie param set` may change it while the component runs.
    if len(node.value) == 4 and scalar(node.value[3], name + " flag") != "dynamic":
        raise SpecError(node.value[3], "%s: the fourth item may only be `dynamic`" % name)
    tnode, dnode, hnode = node.value[:3]
    ptype = scalar(tnode, name + " type")
    if ptype not in CTYPES:
        raise SpecError(tnode, "%s: type '%s' is not one of %s" % (name, ptype, ", ".join(CTYPES)))
    default = scalar(dnode, name + " default")
    if dnode.tag == "!c":
        if not IDENT.match(default):
            raise SpecError(dnode, "%s: !c takes the name of a C macro" % name)
        return ptype, CExpr(default), scalar(hnode, name + " help")
    if dnode.tag.endswith(":null"):
        default = None
    elif dnode.style not in ('"', "'"):
        raise SpecError(dnode, "%s: quote the default (it is YAML text: \"%s\")" % (name, default))
    return ptype, default, scalar(hnode, name + " help")


class Spec:
    """One NAME.params.yaml: its struct, own fields, members and tables."""

    def __init__(self, path):
        self.path = path
        with open(path, encoding="utf-8") as f:
            root = yaml.compose(f)
        if root is None:
            raise SpecError(None, "empty file")
        keys = mapping(root, "file")
        for key, knode, _ in keys:
            if key not in ("struct", "defaults", "members", "tables"):
                raise SpecError(knode, "unknown key '%s' (struct, defaults, members, tables)" % key)
        top = dict((k, v) for k, _, v in keys)
        if "struct" not in top or "tables" not in top:
            raise SpecError(root, "expected struct: and tables:")
        self.struct = ident(top["struct"], "struct")
        self.members = []       # (name, Spec, {parameter: default text})
        for name, knode, vnode in mapping(top["members"], "members") if "members" in top else []:
            ident(knode, "member")
            member, overrides = load_member(name, vnode)
            if member.members:
                raise SpecError(vnode, "%s: a member's file has members of its own" % name)
            if len(member.tables) != 1:
                raise SpecError(vnode, "%s: a member's file has exactly one table" % name)
            self.members.append((name, member, overrides))
        self.fields, self.tables = {}, []
        for tname, tknode, tnode in mapping(top["tables"], "tables"):
            ident(tknode, "table")
            entries = []
            for name, knode, pnode in mapping(tnode, tname) if not is_null(tnode) else []:
                ptype, default, help_ = param(name, knode, pnode)
                if self.fields.setdefault(name, (ptype, help_))[0] != ptype:
                    raise SpecError(pnode, "%s: %s here, %s in an earlier table" % (name, ptype, self.fields[name][0]))
                for mname, member, _ in self.members:
                    if name in member.fields:
                        raise SpecError(knode, "%s: also a parameter of member %s (%s)" % (name, mname, member.path))
                entries.append((None, name, ptype, default, help_, pnode))
            for mname, member, overrides in self.members:
                entries += [(mname, e[1], e[2], overrides.get(e[1], e[3])) + e[4:] for e in member.tables[0][1]]
            self.tables.append((tname, entries))
        for mname, _, _ in self.members:
            if mname in self.fields:
                raise SpecError(top["members"], "member %s: also the name of a parameter" % mname)
        self.defaults = None
        if "defaults" in top:
            self.defaults = ident(top["defaults"], "defaults")
            if len(self.tables) != 1 or self.members:
                raise SpecError(top["defaults"], "defaults: for a file with one table and no members")


def ident(node, what):
    value = scalar(node, what)
    if not IDENT.match(value):
        raise SpecError(node, "%s '%s' is not a C identifier" % (what, value))
    return value


def is_null(node):
    return isinstance(node, yaml.ScalarNode) and node.tag.endswith(":null")


def load_member(name, node):
    """A member: PATH, or {file: PATH, defaults: {NAME: "text"}} where the component's defaults
    differ from the library's."""
    overrides = {}
    if isinstance(node, yaml.MappingNode):
        fields = dict((k, v) for k, _, v in mapping(node, name))
        if set(fields) - {"file", "defaults"} or "file" not in fields:
            raise SpecError(node, "%s: expected a path or {file: PATH, defaults: {NAME: TEXT}}" % name)
        path_node = fields["file"]
        for pname, pknode, dnode in mapping(fields.get("defaults"), name + " defaults") if "defaults" in fields else []:
            if dnode.style not in ('"', "'"):
                raise SpecError(dnode, "%s: quote the default (it is YAML text)" % pname)
            overrides[pname] = (pknode, dnode.value)
    else:
        path_node = node
    path = scalar(path_node, name)
    try:
        member = Spec(path)
    except OSError as e:
        raise SpecError(path_node, "member %s: %s" % (path, e.strerror))
    for pname, (pknode, _) in overrides.items():
        if pname not in member.fields:
            raise SpecError(pknode, "%s: no parameter '%s' in %s" % (name, pname, path))
    return member, dict((k, v[1]) for k, v in overrides.items())


def c_value(ptype, default, node):
    """The C literal of a default, for the DEFAULTS initializer."""
    v = None if isinstance(default, CExpr) else yaml.safe_load(default)
    if ptype == "double" and isinstance(v, str):
        try:
            v = float(v)        # YAML 1.1 reads 1e-5 as text; the config loader reads it as a number
        except ValueError:
            pass
    ok = {"int": isinstance(v, int) and not isinstance(v, bool),
          "double": isinstance(v, (int, float)) and not isinstance(v, bool),
          "bool": isinstance(v, bool),
          "string": isinstance(v, str) and "${" not in v}.get(ptype, False)
    if not ok:
        raise SpecError(node, "default %s is not a plain %s for defaults:" % (default, ptype))
    if ptype == "double":
        return repr(float(v))
    if ptype == "bool":
        return "true" if v else "false"
    return c_string(v) if ptype == "string" else str(v)


def header_of(path):
    return path.replace(".params.yaml", "_params.h")


def generate(spec):
    guard = "MARIE_GEN_" + re.sub(r"[^A-Za-z0-9]", "_", header_of(spec.path)).upper()
    out = ["/* Generated by core/params_gen.py from %s: edit that file. */" % spec.path,
           "#ifndef " + guard, "#define " + guard, "", '#include "core/component.h"']
    out += ['#include "%s"' % header_of(m.path) for _, m, _ in spec.members]
    out += ["", "typedef struct {"]
    for name, (ptype, help_) in spec.fields.items():
        ctype = CTYPES[ptype]
        decl = "    %s%s%s;" % (ctype, "" if ctype.endswith("*") else " ", name)
        out.append(decl + ("  /* %s */" % help_.replace("*/", "* /") if help_ else ""))
    for name, member, _ in spec.members:
        out.append("    %s %s;  /* %s */" % (member.struct, name, member.path))
    out += ["} %s;" % spec.struct, ""]
    for tname, entries in spec.tables:
        out.append("#define %s { \\" % tname)
        for member, name, ptype, default, help_, _ in entries:
            text = "NULL" if default is None else default if isinstance(default, CExpr) else c_string(default)
            where = "AT(%s, " % spec.struct if member is None else "IN(%s, %s, " % (spec.struct, member)
            out.append("    MARIE_PARAM_%s%s, %s, %s, %s), \\" % (where, name, ptype.upper(), text, c_string(help_)))
        out += ["    { 0 } }", ""]
    if spec.defaults:
        out.append("/* The defaults as an initializer: %s d = %s; */" % (spec.struct, spec.defaults))
        out.append("#define %s { \\" % spec.defaults)
        values = dict((e[1], e) for e in spec.tables[0][1])
        for name in spec.fields:
            _, _, ptype, default, _, node = values[name]
            if default is not None:
                out.append("    .%s = %s, \\" % (name, c_value(ptype, default, node)))
        out += ["}", ""]
    out += ["#endif", ""]
    return "\n".join(out)


def main(argv):
    if argv[1:] == ["--help"]:
        sys.stdout.write(__doc__)
        return 0
    if argv[1:] == ["--version"]:
        sys.stdout.write("marie-params-gen (marie %s)\n" % os.environ.get("MARIE_VERSION", "0.1.0"))
        return 0
    if len(argv) != 3:
        sys.stderr.write(__doc__.split("usage: ")[1])
        return 2
    src, dst = argv[1], argv[2]
    try:
        spec = Spec(src)
        text = generate(spec)
    except SpecError as e:
        where = e.path if e.path and e.path != "<file>" else src
        sys.stderr.write("%s:%d: %s\n" % (where, e.line, e))
        return 1
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        sys.stderr.write("%s:%d: %s\n" % (src, mark.line + 1 if mark else 1, getattr(e, "problem", e)))
        return 1
    with open(dst, "w", encoding="utf-8") as f:
        f.write(text)
    # make: the header is also out of date when a member's file changes
    with open(dst[:-2] + ".d", "w", encoding="utf-8") as f:
        f.write("%s: %s\n" % (dst, " ".join(m.path for _, m, _ in spec.members)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
