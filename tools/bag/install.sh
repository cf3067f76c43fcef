#!/bin/sh
# install.sh: installs `marie bag` under PREFIX/lib/marie/bag (its sources, and the pinned libraries
# of the build's venv, scripts/bag-venv.sh, in site/), with its launcher PREFIX/bin/marie-bag. It
# runs on the python3 that made the venv, with marie's Python package (python/install.sh).
#   tools/bag/install.sh DESTDIR PREFIX B SOURCE...
set -eu
dest=$1 prefix=$2 b=$3; shift 3
lib=$prefix/lib/marie/bag
install -d "$dest$lib/site" "$dest$prefix/bin"
install -m 644 "$@" "$dest$lib/"
site=$(echo "$b"/venv-bag/lib/python3*/site-packages)
for f in "$site"/*; do
    case ${f##*/} in pip|pip-*|setuptools|setuptools-*|_distutils_hack|pkg_resources|distutils-precedence.pth|__pycache__) ;;
    *) cp -R "$f" "$dest$lib/site/" ;;
    esac
done
py=$(readlink -f "$b/venv-bag/bin/python")
cat > "$dest$prefix/bin/marie-bag" <<SH
#!/bin/sh
# marie bag ($lib/marie_bag.py) on its pinned libraries ($lib/site)
PYTHONPATH="$lib:$lib/site:$prefix/lib/marie/python" exec $py "$lib/marie_bag.py" "\$@"
SH
chmod 755 "$dest$prefix/bin/marie-bag"
