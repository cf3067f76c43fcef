#!/bin/sh
# install.sh: installs marie's Python package, the generated Python types and the Python
# components (NAME=SCRIPT pairs) under PREFIX/lib/marie/python, each component with a launcher
# PREFIX/bin/NAME.   python/install.sh DESTDIR PREFIX B NAME=SCRIPT...
set -eu
dest=$1 prefix=$2 b=$3; shift 3
lib=$prefix/lib/marie/python
install -d "$dest$lib/marie" "$dest$lib/lcmtypes/marie" "$dest$prefix/bin"
install -m 644 python/marie/*.py "$dest$lib/marie/"
install -m 644 "$b"/python/lcmtypes/marie/*.py "$dest$lib/lcmtypes/marie/"
for pair in "$@"; do
    name=${pair%%=*} script=${pair#*=}
    dir=$lib/programs/$name
    install -d "$dest$dir"
    install -m 755 "$script" "$dest$dir/"
    for f in "$(dirname "$script")"/*.params.yaml; do [ -f "$f" ] && install -m 644 "$f" "$dest$dir/"; done
    sed -e "s|@NAME@|$name|g" -e "s|@SCRIPT@|$dir/$(basename "$script")|g" -e "s|@BIN@|$prefix/bin|g" \
        -e "s|@PYPATH@|$lib|g" python/wrapper.sh.in > "$dest$prefix/bin/$name"
    chmod 755 "$dest$prefix/bin/$name"
done
