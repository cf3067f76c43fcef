"""params: a Python component's parameters from its NAME.params.yaml, the format of C components
(core/params_gen.py, docs/core.md "Parameters"): NAME: [TYPE, DEFAULT, HELP] under a table.

A fourth item, `dynamic`, lets `marie param set` change the parameter while the component runs
(the component's on_param hook may still refuse the value). Python has no C macros: a `!c`
default is refused; `members:` (a library's parameters inside a component's) is C only."""
TYPES = ("int", "double", "bool", "string", "node")


class ParamsError(Exception):
    pass


def _loader():
    """PyYAML's safe loader that refuses `!c` (imported only when a component has a file)."""
    import yaml

    class Loader(yaml.SafeLoader):
        pass

    def c_default(loader, node):
        raise ParamsError("%s:%d: a `!c` default is a C macro: give the YAML text in a Python component's file"
                          % (node.start_mark.name, node.start_mark.line + 1))
    Loader.add_constructor("!c", c_default)
    return yaml, Loader


def load(path, table=None):
    """[{"name", "type", "default", "help", "dynamic"}] of the file's table (the only one, or
    `table`). ParamsError with FILE:LINE on a mistake."""
    yaml, loader = _loader()
    try:
        with open(path, encoding="utf-8") as f:
            doc = yaml.load(f, Loader=loader)
    except (OSError, yaml.YAMLError) as e:
        raise ParamsError("%s: %s" % (path, e)) from None
    tables = (doc or {}).get("tables") if isinstance(doc, dict) else None
    if not isinstance(tables, dict) or not tables:
        raise ParamsError("%s: expected `tables:` with one table of NAME: [TYPE, DEFAULT, HELP]" % path)
    if "members" in doc:
        raise ParamsError("%s: `members:` is for C components" % path)
    if table is None and len(tables) != 1:
        raise ParamsError("%s: several tables (%s): name the one this component uses" % (path, ", ".join(tables)))
    entries = tables.get(table or next(iter(tables)))
    if not isinstance(entries, dict):
        raise ParamsError("%s: table %s: expected NAME: [TYPE, DEFAULT, HELP] lines" % (path, table))
    out = []
    for name, spec in entries.items():
        if not isinstance(spec, list) or len(spec) not in (3, 4) or spec[0] not in TYPES or \
                (spec[1] is not None and not isinstance(spec[1], str)) or (len(spec) == 4 and spec[3] != "dynamic"):
            raise ParamsError("%s: %s: expected [TYPE, \"DEFAULT\" or null, \"HELP\"(, dynamic)], TYPE one of %s"
                              % (path, name, ", ".join(TYPES)))
        out.append({"name": str(name), "type": spec[0], "default": spec[1], "help": spec[2] or "",
                    "dynamic": len(spec) == 4})
    return out
