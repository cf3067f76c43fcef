# adapters/odometer: marie-odometer-py, a Python component (python/marie) of the robot's application.
$(eval $(call marie_py_program,marie-odometer-py,adapters/odometer/odometer.py))
