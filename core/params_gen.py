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
and hands `&params->slam` to the library: nothing is copied by name. A member's file may take
members of its own (a library over a lower layer's: the virtual drive over the CANopen device's
`opts`); their parameters are the component's too, under their own names (`drive.opts.no_consumer`).

A parameter may carry a fourth element, a mapping of what a command line needs (core/cli.h):
    rate_hz: [double, "10", "scans per second", {option: rate, range: [0.01, 1000], metavar: HZ}]
    units: [string, "mm", "units of measured values", {choices: [mm, cm]}]
`option` is the long option's name (default: the parameter's with '-' for '_'; `no`: not an
option), `range` the values an int or double may take there, `choices` the words a string may
be. `cli: NAME` writes NAME(p), the file's options as marie_cli_opt_t entries whose values go
into the struct *p (a bool is a flag: `--name` alone sets it), for a program that is not a
component:  const marie_cli_opt_t opts[] = { VDEVICES_CLI(&cfg), { "link", ... }, { NULL } };
`fields:` adds C fields that are no parameter (set by code: a node id, a name), and a member
may be named with a prefix (`{file: PATH, prefix: gyro_}`: its `bias` is `gyro_bias`). With
`defaults:`, a file with members initializes them with their files' defaults.

usage: params_gen.py IN.params.yaml OUT.h     (also writes OUT.d: OUT.h's members for make)
Errors are printed as FILE:LINE: message, and the exit status is 1.
"""
import os
import re
import sys

import yaml

CTYPES = {"int": "int64_t", "double": "double", "bool": "bool", "string": "const char *",
          "node": "const marie_node_t *"}
CLI_TYPES = {"int": "MARIE_CLI_INT", "double": "MARIE_CLI_DOUBLE", "bool": "MARIE_CLI_FLAG",
             "string": "MARIE_CLI_STRING"}
METAVARS = {"int": "N", "double": "X", "bool": "", "string": "TEXT"}
IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
OPTION = re.compile(r"[a-z0-9][a-z0-9-]*\Z")
LOADING = []        # the member files being read, outermost first (a file may not take itself)
CDECL = re.compile(r"(const )?[A-Za-z_][A-Za-z0-9_]*( \*)?\Z")


class CExpr(str):
    """A default given as `!c NAME`: a C macro holding the default's text, shared with C code."""


class SpecError(Exception):
    def __init__(self, node, msg):
        super().__init__(msg)
        self.line = node.start_mark.line + 1 if node is not None else 1
        self.path = getattr(node.start_mark, "name", None) if node is not None else None


class Param:
    """One parameter as a table lists it: NAME (the member's prefix included), the FIELD it fills
    (in MEMBER, or the struct itself when None), and what a command line needs."""

    def __init__(self, name, ptype, default, help_, node, extras):
        self.member, self.name, self.field = None, name, name
        self.ptype, self.default, self.help, self.node = ptype, default, help_, node
        self.option = extras.get("option", name.replace("_", "-"))
        self.range, self.choices = extras.get("range"), extras.get("choices")
        self.metavar = extras.get("metavar", METAVARS.get(ptype, ""))

    def within(self, member, prefix, default):
        """The parameter as the file that takes its file as `member` lists it (member None: as
        its own); a member's member is the path `outer.inner`."""
        p = Param.__new__(Param)
        p.__dict__.update(self.__dict__)
        p.member = member if member is None or self.member is None else member + "." + self.member
        p.name, p.default = prefix + self.name, default
        if p.option:
            p.option = prefix.replace("_", "-") + p.option
        return p


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


def number(node, what):
    try:
        return float(scalar(node, what))
    except ValueError:
        raise SpecError(node, "%s: expected a number" % what)


def extras_of(name, ptype, node):
    """The optional fourth element: {option, range, choices, metavar}."""
    out = {}
    for key, knode, vnode in mapping(node, name + " options"):
        if key == "option":
            if isinstance(vnode, yaml.ScalarNode) and vnode.tag.endswith(":bool") and vnode.value in ("no", "false"):
                out["option"] = None
            elif not OPTION.match(scalar(vnode, name + " option")):
                raise SpecError(vnode, "%s: option '%s' is not a long option's name (a-z, 0-9, -)" % (name, vnode.value))
            else:
                out["option"] = vnode.value
        elif key == "range":
            if ptype not in ("int", "double") or not isinstance(vnode, yaml.SequenceNode) or len(vnode.value) != 2:
                raise SpecError(vnode, "%s: range is [MIN, MAX] of an int or double" % name)
            out["range"] = [number(v, name + " range") for v in vnode.value]
        elif key == "choices":
            if ptype != "string" or not isinstance(vnode, yaml.SequenceNode) or not vnode.value:
                raise SpecError(vnode, "%s: choices is a list of the words a string may be" % name)
            out["choices"] = [scalar(v, name + " choice") for v in vnode.value]
        elif key == "metavar":
            out["metavar"] = scalar(vnode, name + " metavar")
        else:
            raise SpecError(knode, "%s: unknown option key '%s' (option, range, choices, metavar)" % (name, key))
    return out


def param(name, knode, node):
    if not IDENT.match(name):
        raise SpecError(knode, "'%s' is not a C identifier" % name)
    if not isinstance(node, yaml.SequenceNode) or len(node.value) not in (3, 4):
        raise SpecError(node, "%s: expected [TYPE, DEFAULT, HELP], with dynamic or {OPTIONS} fourth" % name)
    # A fourth item `dynamic`: `marie param set` may change it while the component runs; or the
    # mapping of what a command line needs.
    fourth = node.value[3] if len(node.value) == 4 else None
    if isinstance(fourth, yaml.ScalarNode) and scalar(fourth, name + " flag") != "dynamic":
        raise SpecError(fourth, "%s: the fourth item may only be `dynamic` or {OPTIONS}" % name)
    tnode, dnode, hnode = node.value[:3]
    ptype = scalar(tnode, name + " type")
    if ptype not in CTYPES:
        raise SpecError(tnode, "%s: type '%s' is not one of %s" % (name, ptype, ", ".join(CTYPES)))
    default = scalar(dnode, name + " default")
    extras = extras_of(name, ptype, fourth) if isinstance(fourth, yaml.MappingNode) else {}
    if dnode.tag == "!c":
        if not IDENT.match(default):
            raise SpecError(dnode, "%s: !c takes the name of a C macro" % name)
        default = CExpr(default)
    elif dnode.tag.endswith(":null"):
        default = None
    elif dnode.style not in ('"', "'"):
        raise SpecError(dnode, "%s: quote the default (it is YAML text: \"%s\")" % (name, default))
    return Param(name, ptype, default, scalar(hnode, name + " help"), node, extras)


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
            if key not in ("struct", "defaults", "members", "tables", "fields", "cli"):
                raise SpecError(knode, "unknown key '%s' (struct, defaults, members, tables, fields, cli)" % key)
        top = dict((k, v) for k, _, v in keys)
        if "struct" not in top or "tables" not in top:
            raise SpecError(root, "expected struct: and tables:")
        self.struct = ident(top["struct"], "struct")
        self.extra = [(ident(knode, "field"),) + field(v, name) for name, knode, v in
                      (mapping(top["fields"], "fields") if "fields" in top else [])]
        self.members = []       # (name, Spec, prefix, {parameter: default text})
        for name, knode, vnode in mapping(top["members"], "members") if "members" in top else []:
            ident(knode, "member")
            member, prefix, overrides = load_member(name, vnode)
            if len(member.tables) != 1:
                raise SpecError(vnode, "%s: a member's file has exactly one table" % name)
            self.members.append((name, member, prefix, overrides))
        self.fields, self.tables = {}, []
        for tname, tknode, tnode in mapping(top["tables"], "tables"):
            ident(tknode, "table")
            entries = []
            for name, knode, pnode in mapping(tnode, tname) if not is_null(tnode) else []:
                p = param(name, knode, pnode)
                if self.fields.setdefault(name, p).ptype != p.ptype:
                    raise SpecError(pnode, "%s: %s here, %s in an earlier table" % (name, p.ptype, self.fields[name].ptype))
                for mname, member, prefix, _ in self.members:
                    if name in member.names(prefix):
                        raise SpecError(knode, "%s: also a parameter of member %s (%s)" % (name, mname, member.path))
                entries.append(p)
            for mname, member, prefix, overrides in self.members:
                entries += [e.within(mname, prefix, overrides.get(prefix + e.name, e.default)) for e in member.tables[0][1]]
            self.tables.append((tname, entries))
        self.check_names(top)
        self.defaults = None
        if "defaults" in top:
            self.defaults = ident(top["defaults"], "defaults")
            if len(self.tables) != 1:
                raise SpecError(top["defaults"], "defaults: for a file with one table")
        self.cli = ident(top["cli"], "cli") if "cli" in top else None
        if self.cli:
            self.check_cli(top["cli"])

    def names(self, prefix=""):
        """Every parameter's name, its members' too."""
        return set(prefix + p.name for _, entries in self.tables for p in entries)

    def files(self):
        """The files of its members, and of theirs."""
        return [f for _, m, _, _ in self.members for f in [m.path] + m.files()]

    def check_names(self, top):
        seen = set(self.fields)
        for mname, member, prefix, _ in self.members:
            if mname in seen:
                raise SpecError(top["members"], "member %s: also the name of a parameter" % mname)
            if member.names(prefix) & seen:
                raise SpecError(top["members"], "member %s: %s also named elsewhere in the file"
                                % (mname, ", ".join(sorted(member.names(prefix) & seen))))
            seen |= member.names(prefix) | {mname}
        for name, _, _ in self.extra:
            if name in seen:
                raise SpecError(top["fields"], "field %s: also the name of a parameter or member" % name)

    def check_cli(self, node):
        if len(self.tables) != 1:
            raise SpecError(node, "cli: for a file with one table")
        seen = {}
        for p in self.tables[0][1]:
            if not p.option:
                continue
            if p.ptype not in CLI_TYPES:
                raise SpecError(p.node, "%s: a %s is no command-line option (option: no)" % (p.name, p.ptype))
            if p.ptype in ("int", "double") and not p.range:
                raise SpecError(p.node, "%s: an option needs its range: [MIN, MAX]" % p.name)
            if p.ptype == "bool" and p.default is not None and yaml.safe_load(p.default) is not False:
                raise SpecError(p.node, "%s: a flag sets true, so its default is \"false\"" % p.name)
            if p.option in seen or p.option == "help":
                raise SpecError(p.node, "option --%s given twice" % p.option)
            seen[p.option] = p


def ident(node, what):
    value = scalar(node, what)
    if not IDENT.match(value):
        raise SpecError(node, "%s '%s' is not a C identifier" % (what, value))
    return value


def field(node, what):
    """A field that is no parameter: CTYPE, or [CTYPE, "what it is"]."""
    text = ""
    if isinstance(node, yaml.SequenceNode) and len(node.value) == 2:
        node, text = node.value[0], scalar(node.value[1], what + " comment")
    value = scalar(node, what)
    if not CDECL.match(value):
        raise SpecError(node, "%s: '%s' is not a C type (TYPE, const TYPE *; or [TYPE, COMMENT])" % (what, value))
    return value, text


def is_null(node):
    return isinstance(node, yaml.ScalarNode) and node.tag.endswith(":null")


def load_member(name, node):
    """A member: PATH, or {file: PATH, prefix: TEXT, defaults: {NAME: "text"}} where the
    component names its parameters with a prefix or its defaults differ from the library's."""
    overrides, prefix = {}, ""
    if isinstance(node, yaml.MappingNode):
        fields = dict((k, v) for k, _, v in mapping(node, name))
        if set(fields) - {"file", "defaults", "prefix"} or "file" not in fields:
            raise SpecError(node, "%s: expected a path or {file: PATH, prefix: TEXT, defaults: {NAME: TEXT}}" % name)
        path_node = fields["file"]
        if "prefix" in fields:
            prefix = scalar(fields["prefix"], name + " prefix")
            if not IDENT.match(prefix + "x"):
                raise SpecError(fields["prefix"], "%s: prefix '%s' does not start a C identifier" % (name, prefix))
        for pname, pknode, dnode in mapping(fields.get("defaults"), name + " defaults") if "defaults" in fields else []:
            if dnode.style not in ('"', "'"):
                raise SpecError(dnode, "%s: quote the default (it is YAML text)" % pname)
            overrides[pname] = (pknode, dnode.value)
    else:
        path_node = node
    path = scalar(path_node, name)
    if os.path.normpath(path) in LOADING:
        raise SpecError(path_node, "member %s: takes itself, through its members" % path)
    LOADING.append(os.path.normpath(path))
    try:
        member = Spec(path)
    except OSError as e:
        raise SpecError(path_node, "member %s: %s" % (path, e.strerror))
    finally:
        LOADING.pop()
    for pname, (pknode, _) in overrides.items():
        if pname not in member.names():
            raise SpecError(pknode, "%s: no parameter '%s' in %s" % (name, pname, path))
    return member, prefix, dict((prefix + k, v[1]) for k, v in overrides.items())


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


def entry(spec, p):
    text = "NULL" if p.default is None else p.default if isinstance(p.default, CExpr) else c_string(p.default)
    if p.member is None:
        where = "AT(%s, " % spec.struct
    elif p.name == p.field:
        where = "IN(%s, %s, " % (spec.struct, p.member)
    else:
        where = "IN_AS(%s, %s, %s, " % (spec.struct, p.member, c_string(p.name))
    return "    MARIE_PARAM_%s%s, %s, %s, %s), \\" % (where, p.field, p.ptype.upper(), text, c_string(p.help))


def defaults_lines(entries, indent):
    """`.field = value,` for every default of entries whose member is None, then each member's."""
    out, members = [], []
    for p in entries:
        if p.member is not None:
            if p.member.split(".")[0] not in members:
                members.append(p.member.split(".")[0])
        elif p.default is not None:
            out.append("%s.%s = %s, \\" % (indent, p.field, c_value(p.ptype, p.default, p.node)))
    for m in members:
        mine = []
        for p in (p for p in entries if p.member and p.member.split(".")[0] == m):
            q = p.within(None, "", p.default)
            q.name, q.member = q.field, p.member.partition(".")[2] or None
            mine.append(q)
        out.append("%s.%s = { \\" % (indent, m))
        out += defaults_lines(mine, indent + "    ")
        out.append("%s}, \\" % indent)
    return out


def cli_help(p):
    """The usage line's text: the value's name, the help, and the default."""
    text = p.help
    if p.default is not None and not isinstance(p.default, CExpr) and p.ptype != "bool":
        value = yaml.safe_load(p.default)
        if value not in ("", None, 0):
            text += " (default %s)" % value
    return ("%-4s %s" % (p.metavar, text)) if p.metavar else "     " + text


def cli_entry(p):
    where = "&(p)->%s%s" % ("" if p.member is None else p.member + ".", p.field)
    lo, hi = ("%.17g" % v for v in (p.range or (0, 0)))
    choices = c_string("|".join(p.choices)) if p.choices else "NULL"
    return "    { %s, %s, %s, %s, %s, %s, %s }, \\" % (c_string(p.option), CLI_TYPES[p.ptype], where, lo, hi,
                                                  c_string(cli_help(p)), choices)


def generate(spec):
    guard = "MARIE_GEN_" + re.sub(r"[^A-Za-z0-9]", "_", header_of(spec.path)).upper()
    out = ["/* Generated by core/params_gen.py from %s: edit that file. */" % spec.path,
           "#ifndef " + guard, "#define " + guard, "", '#include "core/component.h"']
    if spec.cli:
        out.append('#include "core/cli.h"')
    out += ['#include "%s"' % header_of(m.path) for _, m, _, _ in spec.members]
    out += ["", "typedef struct {"]
    for name, p in spec.fields.items():
        ctype_ = CTYPES[p.ptype]
        decl = "    %s%s%s;" % (ctype_, "" if ctype_.endswith("*") else " ", name)
        out.append(decl + ("  /* %s */" % p.help.replace("*/", "* /") if p.help else ""))
    for name, member, prefix, _ in spec.members:
        named = ", parameters %s*" % prefix if prefix else ""
        out.append("    %s %s;  /* %s%s */" % (member.struct, name, member.path, named))
    for name, ctype_, text in spec.extra:
        out.append("    %s%s%s;  /* %s(not a parameter: set by the code) */"
                   % (ctype_, "" if ctype_.endswith("*") else " ", name, text.replace("*/", "* /") + " " if text else ""))
    out += ["} %s;" % spec.struct, ""]
    for tname, entries in spec.tables:
        out.append("#define %s { \\" % tname)
        out += [entry(spec, p) for p in entries]
        out += ["    { 0 } }", ""]
    if spec.defaults:
        out.append("/* The defaults as an initializer: %s d = %s; */" % (spec.struct, spec.defaults))
        out.append("#define %s { \\" % spec.defaults)
        out += defaults_lines(spec.tables[0][1], "    ")
        out += ["}", ""]
    if spec.cli:
        out.append("/* The options of a program (core/cli.h), into *(p): { %s(&cfg), ..., { NULL } } */" % spec.cli)
        out.append("#define %s(p) \\" % spec.cli)
        out += [cli_entry(p) for p in spec.tables[0][1] if p.option]
        out += ["", ""]
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
        f.write("%s: %s\n" % (dst, " ".join(spec.files())))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
