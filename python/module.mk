# python: marie's Python package (python/marie: the component contract of core/ in Python) and
# marie-resolve, through which a Python component's configuration is read by libmarie itself.
$(eval $(call marie_program,marie-resolve,python/resolve_main.c))
ITESTS += tests/python/test_python_component.sh
ITESTS += tests/python/test_python_shm.sh
# bench_python: a Python port against upstream LCM for Python's raw pub/sub (PyPI lcm, in the
# venv of scripts/peer-venv.sh), run by make bench through this wrapper.
$(B)/bench/bench_python: bench/bench_python.py python/wrapper.sh.in
	@mkdir -p $(@D)
	printf '#!/bin/sh\n# bench_python: bench/bench_python.py in the peers venv, with marie'"'"'s Python package (generated)\nexport MARIE_RESOLVE=%s/marie-resolve\nPYTHONPATH=%s exec %s %s "$$@"\n' \
	    '$(CURDIR)/$(B)/bin' '$(CURDIR)/python:$(CURDIR)/$(B)/python' '$(CURDIR)/$(B)/peers/bin/python' '$(CURDIR)/bench/bench_python.py' > $@ && chmod 755 $@
BENCHES += $(B)/bench/bench_python
INSTALL_EXTRA += python/install.sh '$(DESTDIR)' '$(PREFIX)' '$(B)' $(PY_PROGRAMS);
