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
        rate_hz: [double, "5", "arbitration rate"]      # NAME: [TYPE, DEFAULT, HELP]
        map: [string, null, "map_server map.yaml"]       # null: the system file must set it
TYPE is int, double, bool, string or node; DEFAULT is the YAML text of the value, quoted, or
`!c NAME` for a C macro holding that text (one the C code shares; the file that uses the table
includes its header). A name in several tables is one field and must have the same type in each.

usage: params_gen.py IN.params.yaml OUT.h
Errors are printed as FILE:LINE: message, and the exit status is 1.
"""
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
    if not isinstance(node, yaml.SequenceNode) or len(node.value) != 3:
        raise SpecError(node, "%s: expected [TYPE, DEFAULT, HELP]" % name)
    tnode, dnode, hnode = node.value
    ptype = scalar(tnode, name + " type")
    if ptype not in CTYPES:
        raise SpecError(tnode, "%s: type '%s' is not one of %s" % (name, ptype, ", ".join(CTYPES)))
    default = scalar(dnode, name + " default")
    if dnode.tag == "!c":
        if not IDENT.match(default):
            raise SpecError(dnode, "%s: !c takes the name of a C macro" % name)
        return ptype, CExpr(default), scalar(hnode, name + " help")
    if dnode.tag.endswith(":null") or (dnode.style is None and default in ("null", "~", "")):
        default = None
    elif dnode.style not in ('"', "'"):
        raise SpecError(dnode, "%s: quote the default (it is YAML text: \"%s\")" % (name, default))
    return ptype, default, scalar(hnode, name + " help")


def load(path):
    with open(path, encoding="utf-8") as f:
        root = yaml.compose(f)
    top = dict((k, v) for k, _, v in mapping(root, "file"))
    for key, knode, _ in mapping(root, "file"):
        if key not in ("struct", "tables"):
            raise SpecError(knode, "unknown key '%s' (struct, tables)" % key)
    if "struct" not in top or "tables" not in top:
        raise SpecError(root, "expected struct: and tables:")
    struct = scalar(top["struct"], "struct")
    if not IDENT.match(struct):
        raise SpecError(top["struct"], "struct: '%s' is not a C identifier" % struct)
    fields, tables = {}, []
    for tname, tknode, tnode in mapping(top["tables"], "tables"):
        if not IDENT.match(tname):
            raise SpecError(tknode, "table '%s' is not a C identifier" % tname)
        entries = []
        for name, knode, pnode in mapping(tnode, tname):
            ptype, default, help_ = param(name, knode, pnode)
            if fields.setdefault(name, (ptype, help_))[0] != ptype:
                raise SpecError(pnode, "%s: %s here, %s in an earlier table" % (name, ptype, fields[name][0]))
            entries.append((name, ptype, default, help_))
        tables.append((tname, entries))
    return struct, fields, tables


def generate(src, struct, fields, tables):
    guard = "MARIE_GEN_" + re.sub(r"[^A-Za-z0-9]", "_", src.replace(".params.yaml", "_params.h")).upper()
    out = ["/* Generated by core/params_gen.py from %s: edit that file. */" % src,
           "#ifndef " + guard, "#define " + guard, "", '#include "core/component.h"', "",
           "typedef struct {"]
    for name, (ptype, help_) in fields.items():
        ctype = CTYPES[ptype]
        decl = "    %s%s%s;" % (ctype, "" if ctype.endswith("*") else " ", name)
        out.append(decl + ("  /* %s */" % help_.replace("*/", "* /") if help_ else ""))
    out += ["} %s;" % struct, ""]
    for tname, entries in tables:
        out.append("#define %s { \\" % tname)
        for name, ptype, default, help_ in entries:
            out.append("    MARIE_PARAM_AT(%s, %s, %s, %s, %s), \\" % (
                struct, name, ptype.upper(), "NULL" if default is None else default if isinstance(default, CExpr) else c_string(default), c_string(help_)))
        out += ["    { 0 } }", ""]
    out += ["#endif", ""]
    return "\n".join(out)


def main(argv):
    if len(argv) != 3:
        sys.stderr.write(__doc__.split("usage: ")[1])
        return 2
    src, dst = argv[1], argv[2]
    try:
        text = generate(src, *load(src))
    except SpecError as e:
        sys.stderr.write("%s:%d: %s\n" % (src, e.line, e))
        return 1
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        sys.stderr.write("%s:%d: %s\n" % (src, mark.line + 1 if mark else 1, getattr(e, "problem", e)))
        return 1
    with open(dst, "w", encoding="utf-8") as f:
        f.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
