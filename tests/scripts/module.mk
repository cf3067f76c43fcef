# tests/scripts: the set-up scripts the README relies on.
ITESTS += tests/scripts/test_install_deps.sh
