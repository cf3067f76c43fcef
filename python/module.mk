# python: marie's Python package (python/marie: the component contract of core/ in Python) and
# marie-resolve, through which a Python component's configuration is read by libmarie itself.
$(eval $(call marie_program,marie-resolve,python/resolve_main.c))
ITESTS += tests/python/test_python_component.sh
