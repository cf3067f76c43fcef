# tools/bag: `marie bag` (export, import, info of ROS 2 bags), Python on rosbags in the venv that
# scripts/bag-venv.sh makes under $(B); marie's types for Python are the one generated tree
# $(B)/python (lcmtypes.marie) that python/marie uses too, and the users' come from marie-types-gen.
BAG_SRCS := tools/bag/marie_bag.py tools/bag/bag_ops.py tools/bag/bag_conv.py tools/bag/bag_custom.py
$(B)/venv-bag/bin/python: scripts/bag-venv.sh
	B=$(B) scripts/bag-venv.sh > /dev/null
	@touch $@
$(B)/bin/marie-bag: $(BAG_SRCS) $(PY_TYPES) $(B)/venv-bag/bin/python
	@mkdir -p $(@D)
	printf '#!/bin/sh\n# marie bag (tools/bag/marie_bag.py) in its venv\nPYTHONPATH="%s:%s:%s" exec "%s" "%s" "$$@"\n' \
	    "$(abspath tools/bag)" "$(abspath python)" "$(abspath $(B)/python)" "$(abspath $(B)/venv-bag/bin/python)" \
	    "$(abspath tools/bag/marie_bag.py)" > $@ && chmod 755 $@
EXTRA_TARGETS += $(B)/bin/marie-bag
# Installed beside marie's Python package, with the venv's pinned libraries copied (a venv does not
# move; the libraries are plain files for the same python3).
INSTALL_EXTRA += tools/bag/install.sh '$(DESTDIR)' '$(PREFIX)' '$(B)' $(BAG_SRCS);
ITESTS += tests/tools/test_marie_bag.sh tests/tools/test_bag_types.sh
