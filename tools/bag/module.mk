# tools/bag: `marie bag` (export, import, info of ROS 2 bags), Python on rosbags in the venv that
# scripts/bag-venv.sh makes under $(B); marie's types for Python from lcm-gen.
BAG_PY := $(B)/gen/bag-python
$(BAG_PY)/marie/__init__.py: $(LCM_FILES)
	@rm -rf $(BAG_PY) && mkdir -p $(BAG_PY)
	lcm-gen -p --ppath $(BAG_PY) $(LCM_FILES)
$(B)/venv-bag/bin/python: scripts/bag-venv.sh
	B=$(B) scripts/bag-venv.sh > /dev/null
	@touch $@
$(B)/bin/marie-bag: tools/bag/marie_bag.py tools/bag/bag_conv.py $(BAG_PY)/marie/__init__.py $(B)/venv-bag/bin/python
	@mkdir -p $(@D)
	printf '#!/bin/sh\n# marie bag (tools/bag/marie_bag.py) in its venv\nPYTHONPATH="%s:%s" exec "%s" "%s" "$$@"\n' \
	    "$(abspath tools/bag)" "$(abspath $(BAG_PY))" "$(abspath $(B)/venv-bag/bin/python)" \
	    "$(abspath tools/bag/marie_bag.py)" > $@ && chmod 755 $@
EXTRA_TARGETS += $(B)/bin/marie-bag
ITESTS += tests/tools/test_marie_bag.sh
