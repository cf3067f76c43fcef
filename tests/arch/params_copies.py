#!/usr/bin/env python3
"""params_copies: finds parameters copied by hand, the rule of docs/core.md ("Parameters: declared
once") read from the sources.

A parameter is declared once, in a NAME.params.yaml; code hands the generated struct (or a member
of it) to a library rather than filling a second struct field by field. This reports every
assignment or designated initializer in production code (core map camera ca hw proto managers adapters
sim tools; benchmarks and tests are not production code) of the form

    X.f = R->g;   X->f = (int)R.g;   .f = (int64_t)(R->g * 1e6),   ...

where R is a params struct (a variable of a generated struct type, `params_of(c)`, `*_params(...)`),
g one of its parameters, and f the same name as g, or g with a unit suffix (_us, _ms, _s, _hz):
a config field that repeats the parameter. Casts, parentheses, lround() and a constant factor
are looked through. Reading a parameter (a local, an argument, an expression) is not a copy, and
neither is a field of a message put on the bus (an initializer of an LCM type, `marie_goal_t g =
{ .tolerance = p->tolerance }`): the message carries the value, it does not declare it again.

usage: params_copies.py [--allow FILE] [ROOT]
Prints FILE:LINE: text, one a copy; with --allow, copies listed there (FILE: LHS = FIELD, one a
line, # comments) are not printed, and a listed copy that is no longer in the code is printed
as "FILE: stale allow entry LHS = FIELD". Exit status 1 when anything was printed.
"""
import glob
import os
import re
import sys

import yaml

FOLDERS = "core map camera ca hw proto managers adapters sim tools".split()
UNIT = re.compile(r"_(us|ms|s|hz)$")
NUM = r"(?:\d+(?:\.\d*)?(?:e[+-]?\d+)?|\.\d+)"
CAST = re.compile(r"(?<![\w)\]])\(\s*(?:const\s+)?(?:unsigned\s+)?\w+\s*\**\s*\)")
ASSIGN = re.compile(r"(?:\.|->)\s*([A-Za-z_]\w*)(?:\s*\[[^\]]*\])?\s*=(?!=)\s*([^;,{}]+)")
ACCESS = re.compile(r"^(\w+(?:\([^()]*\))?)\s*(?:->|\.)\s*(\w+)$")
OPENER = re.compile(r"(?:\b(\w+)\s+\w+\s*(?:\[[^\]]*\])?\s*=|\(\s*(\w+)\s*\))\s*$")


class Loader(yaml.SafeLoader):
    pass


Loader.add_constructor("!c", lambda loader, node: loader.construct_scalar(node))


def declared(root):
    """{struct name: set of parameter names} of every NAME.params.yaml under root."""
    out = {}
    for path in sorted(glob.glob(os.path.join(root, "*/*.params.yaml")) +
                       glob.glob(os.path.join(root, "*/*/*.params.yaml"))):
        with open(path, encoding="utf-8") as f:
            spec = yaml.load(f, Loader=Loader)
        names = set()
        for table in (spec.get("tables") or {}).values():
            names |= set(table or {})
        out[spec["struct"]] = names
    return out


def core(rhs):
    """The expression with casts, parentheses, rounding and a constant factor taken away."""
    r = rhs.strip()
    while True:
        before = r
        r = CAST.sub("", r).strip()
        r = re.sub(r"^(?:lround|llround|round|floor|ceil)\s*\((.*)\)$", r"\1", r).strip()
        r = re.sub(r"^\((.*)\)$", r"\1", r).strip()
        r = re.sub(r"\s*[*/]\s*" + NUM + "$", "", r).strip()
        r = re.sub(r"^" + NUM + r"\s*[*/]\s*", "", r).strip()
        if r == before:
            return r


def messages(root):
    """The C names of the LCM types (lcmtypes/NAME.lcm: marie_NAME)."""
    return set("marie_" + os.path.basename(p)[:-4] for p in glob.glob(os.path.join(root, "lcmtypes", "*.lcm")))


def initialized(text, pos):
    """The type of the initializer `TYPE v = {` or `(TYPE){` that encloses pos, or None."""
    depth = 0
    for i in range(pos - 1, -1, -1):
        if text[i] == "}":
            depth += 1
        elif text[i] == "{" and depth:
            depth -= 1
        elif text[i] == "{":
            m = OPENER.search(text[max(0, i - 200):i])
            return m and (m.group(1) or m.group(2))
        elif text[i] == ";":
            return None
    return None


def sources(root):
    for folder in FOLDERS:
        for top, _, files in os.walk(os.path.join(root, folder)):
            for name in sorted(files):
                if name.endswith((".c", ".cpp", ".h")) and not name.startswith("bench_"):
                    yield os.path.join(top, name)


def copies(root):
    """(file relative to root, line, lhs, field, text) of every copy."""
    structs = declared(root)
    if not structs:
        return
    params = set().union(*structs.values())
    msgs = messages(root)
    typed = re.compile(r"\b(?:%s)\s*\*?\s*(?:const\s+)?\*?\s*(\w+)\s*[=;,)]" % "|".join(map(re.escape, structs)))
    for path in sources(root):
        with open(path, encoding="utf-8", errors="replace") as f:
            text = f.read()
        holders = set(typed.findall(text))
        rel = os.path.relpath(path, root)
        start = 0
        for n, line in enumerate(text.split("\n"), 1):
            at, start = start, start + len(line) + 1
            for m in ASSIGN.finditer(line):
                lhs, rhs = m.group(1), m.group(2).strip()
                a = ACCESS.match(core(rhs))
                if not a or a.group(2) not in params:
                    continue
                holder, field = a.groups()
                if not (re.match(r"\w*params(?:_of)?\(", holder) or holder in holders or holder.endswith("params")):
                    continue
                if UNIT.sub("", lhs) == UNIT.sub("", field) and initialized(text, at + m.start()) not in msgs:
                    yield rel, n, lhs, field, "%s = %s" % (lhs, rhs)


def allowed(path):
    out = set()
    with open(path, encoding="utf-8") as f:
        for line in f:
            line = line.split("#", 1)[0].strip()
            if line:
                where, what = line.split(":", 1)
                lhs, field = (x.strip() for x in what.split("="))
                out.add((where.strip(), lhs, field))
    return out


def main(argv):
    allow, args = set(), list(argv[1:])
    if args[:1] == ["--allow"]:
        allow = allowed(args[1])
        args = args[2:]
    root = args[0] if args else "."
    bad, seen = 0, set()
    for rel, n, lhs, field, text in copies(root):
        seen.add((rel, lhs, field))
        if (rel, lhs, field) not in allow:
            print("%s:%d: %s copies the parameter %s by hand" % (rel, n, text, field))
            bad += 1
    for rel, lhs, field in sorted(allow - seen):
        print("%s: stale allow entry %s = %s (no longer in the code: remove it)" % (rel, lhs, field))
        bad += 1
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
